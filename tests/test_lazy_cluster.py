"""Where a sweep's and a design's work runs (sweep.cluster.LazyClient): the local cluster
starts at the first task sent to it; a batch of analytical solves too small to pay its
start runs in this process, with the same results (an analytical design and a small
analytical sweep start none: tests/test_design.py, tests/test_montecarlo.py)."""

from __future__ import annotations

from spinweb_fe.sweep import cluster
from spinweb_fe.sweep import design as ds
from tests.test_design import SMALL, write


class FakeClient:
    """Runs what it is sent at once, here, and counts the batches."""

    def __init__(self):
        self.batches = []

    def map(self, fn, *iterables, pure=True):
        args = list(zip(*iterables))
        self.batches.append(len(args))
        return [Done(fn(*a)) for a in args]

    def close(self):
        pass


class Done:
    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


def test_the_cluster_starts_only_for_a_batch_worth_it(monkeypatch):
    fake = FakeClient()
    monkeypatch.setattr(cluster, "_start", lambda scheduler, workers: (fake, None))
    lazy = cluster.LazyClient()
    assert not lazy.started
    assert not lazy.worth(1) and not lazy.worth(cluster.PARALLEL_MIN - 1)
    assert lazy.worth(cluster.PARALLEL_MIN) and not lazy.started  # asking starts nothing
    lazy.map(abs, [-1])
    assert lazy.started and lazy.worth(2) and not lazy.worth(1)
    lazy.close()
    assert not lazy.started
    assert cluster.LazyClient("tcp://somewhere:8786").worth(2)  # a running cluster: any batch


def test_a_batch_on_the_cluster_gives_the_points_solved_here(tmp_path, monkeypatch):
    fake = FakeClient()
    monkeypatch.setattr(cluster, "_start", lambda scheduler, workers: (fake, None))
    d = ds.load_design(write(tmp_path, SMALL))
    lazy = cluster.LazyClient()
    n = 4  # a smaller threshold: the same rule, eight solves instead of 128
    monkeypatch.setattr(cluster, "PARALLEL_MIN", n)
    batch = [d.from_unit([u / (n - 1)]) for u in range(n)]
    there = ds.Evaluator(d, client=lazy).many(batch)
    assert fake.batches == [n]
    here = ds.Evaluator(d).many(batch)
    assert [(p.values, p.feasible, p.objective, p.failed) for p in there] == \
        [(p.values, p.feasible, p.objective, p.failed) for p in here]
    small = ds.Evaluator(d, client=cluster.LazyClient())  # not started: nothing sent
    small.many(batch[:3])
    assert fake.batches == [n]
