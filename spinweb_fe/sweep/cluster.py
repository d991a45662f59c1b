"""Running on Dask: the cluster (a running scheduler's or a local one, its log lines
silenced), a sweep's runs, and the one compile of a scene before a batch of FE runs
(:func:`warm`), shared by sweeps and ``spinweb design``."""

from __future__ import annotations

import contextlib
import copy
import logging
import math
import time
from pathlib import Path

from spinweb_fe.errors import RunError
from spinweb_fe.sweep.run import METRICS, Sweep, one_line, run_one

log = logging.getLogger(__name__)


def warm(client, task: dict, out_dir) -> dict:
    """Compile a scene once on the machine before a batch of its FE runs: a few steps of
    ``task`` (two history rows, no frames) on one worker, waited for; the kernels go to
    numba's cache, from which every worker then loads them instead of compiling the same
    scene at once (on a loaded 2-core machine about 220 s each). Returns its row."""
    raw = copy.deepcopy(task["raw"])
    dt_row = raw.get("output", {}).get("history_dt", 1e-3)
    raw.setdefault("time", {})["end"] = 2.0 * dt_row
    raw.setdefault("output", {})["frame_dt"] = 0.0
    raw["output"].pop("checkpoint_dt", None)
    row = client.submit(run_one, {**task, "raw": raw, "out_dir": str(out_dir)}, pure=False,
                        key=f"spinweb-compile-{time.monotonic_ns()}").result()
    log.info("compiled the scene once (%.1f s): %s", row.get("wall_time_s", math.nan),
             row.get("status"))
    return row


def _failed(exc) -> dict:
    row = {name: math.nan for name, _, _ in METRICS}
    row["failed"] = "run failed"
    row["status"] = one_line(exc)
    return row


def execute(sweep: Sweep, out_dir, scheduler=None, workers=2, progress=True) -> list:
    """Run every case of ``sweep`` on Dask; return one row dict per run (index order).

    Parameters
    ----------
    out_dir : Path
        Sweep folder; run ``i`` writes ``out_dir/runs/<name>/``. With ``scheduler`` it must
        be on a file system that the workers share.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://host:8786``); default: a LocalCluster
        of ``workers`` processes with one thread each.
    """
    with dask_client(scheduler, workers) as client:
        return _execute(sweep, Path(out_dir).resolve(), client, scheduler, workers, progress)


@contextlib.contextmanager
def _quiet_dask():
    """Dask's own log lines (nanny, scheduler, comms) off while the sweep runs: a lost
    worker shows as a failed run in the summary."""
    import distributed  # noqa: F401  (creates its loggers)

    names = ["distributed", *(n for n in logging.root.manager.loggerDict
                              if n.startswith("distributed."))]
    saved = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.ERROR)
    try:
        yield
    finally:
        for n, level in saved.items():
            logging.getLogger(n).setLevel(level)


#: a batch of analytical solves (about 35 ms each) worth a local cluster's start (about
#: 2 s, and each worker's imports): smaller batches, and every batch before the cluster
#: has started, run in this process (docs/sweep.md, "Where the work runs")
PARALLEL_MIN = 64


class LazyClient:
    """A Dask client that starts its cluster at the first task sent to it (``submit``,
    ``map``): a design whose analytical search runs in this process and that ends there
    (``--no-fe``, no design) starts none. With ``scheduler`` (a running cluster's address)
    every parallel batch goes there. :meth:`worth` tells a caller whether a batch of ``n``
    analytical solves should go to the cluster."""

    def __init__(self, scheduler=None, workers=2):
        self.scheduler, self.workers = scheduler, workers
        self._client = self._cluster = None

    @property
    def started(self) -> bool:
        return self._client is not None

    def worth(self, n: int) -> bool:
        return n > 1 and (self.started or bool(self.scheduler) or n >= PARALLEL_MIN)

    def client(self):
        """The started client (the cluster started now if not yet). RunError if it cannot
        be started or reached."""
        if self._client is None:
            self._client, self._cluster = _start(self.scheduler, self.workers)
        return self._client

    def submit(self, *args, **kwargs):
        return self.client().submit(*args, **kwargs)

    def map(self, *args, **kwargs):
        return self.client().map(*args, **kwargs)

    def close(self):
        if self._client is not None:
            self._client.close()
        if self._cluster is not None:
            self._cluster.close()
        self._client = self._cluster = None


def _start(scheduler, workers):
    from dask.distributed import Client, LocalCluster

    cluster = None
    try:
        if scheduler:
            return Client(scheduler, timeout="10s"), None
        # ":0": a free port for the scheduler's HTTP server (no clash on 8787)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.WARNING)
        return Client(cluster), cluster
    except (OSError, TimeoutError) as exc:
        if cluster is not None:
            cluster.close()
        raise RunError(f"cannot start or reach the Dask cluster "
                       f"{scheduler or '(local)'}: {exc}") from None


@contextlib.contextmanager
def dask_client(scheduler=None, workers=2):
    """The sweep's and the design's client (:class:`LazyClient`): a running scheduler's,
    or a LocalCluster of ``workers`` processes with one thread each, started at its first
    task; Dask's log lines silenced; client and cluster closed at the end."""
    with _quiet_dask():
        lazy = LazyClient(scheduler, workers)
        try:
            yield lazy
        finally:
            lazy.close()


def _execute(sweep, out_dir, client, scheduler, workers, progress):
    tasks = [{"raw": run.raw, "source": str(sweep.base), "mode": sweep.mode,
              "model": sweep.model, "out_dir": str(out_dir / "runs" / run.name)}
             for run in sweep.runs]
    # a small analytical sweep in this process, one run after another (each a fraction of
    # a second: less than a cluster's start)
    here = sweep.mode != "fe" and not client.worth(len(tasks))
    log.info("sweep: %d %s runs %s", len(tasks), sweep.mode, "in this process" if here else
             f"on {scheduler or f'a local Dask cluster of {workers} worker process(es)'}")
    if sweep.mode == "fe" and len(tasks) > 1:  # one compile of the scene, not one each
        warm(client, tasks[0], out_dir / "runs" / "_compile")
    rows = [None] * len(tasks)
    from spinweb_fe.run.progress import Stage, enabled

    bar = enabled(progress)
    done = ((i, run_one(task)) for i, task in enumerate(tasks)) if here else \
        _on_cluster(client, sweep, tasks)
    with Stage(f"{sweep.mode} runs", len(rows), show=bar) as stage:
        for n, (i, row) in enumerate(done, start=1):
            rows[i] = row
            stage.update(note=f"{sweep.runs[i].name}: {row['status'][:30]}")
            if progress and not bar:
                log.info("[%d/%d] %s: %s (%.1f s)", n, len(rows), sweep.runs[i].name,
                         row["status"], row.get("wall_time_s", math.nan))
    return rows


def _on_cluster(client, sweep, tasks):
    """(index, row) of each task run on the cluster, as they finish."""
    from dask.distributed import as_completed

    futures = {}
    for pos, (run, task) in enumerate(zip(sweep.runs, tasks)):  # (--only keeps some runs)
        fut = client.submit(run_one, task, pure=False, key=f"spinweb-{run.name}-{id(task)}")
        futures[fut] = pos
    for fut in as_completed(futures):
        try:
            row = fut.result()
        except Exception as exc:  # the worker died or the task was lost
            row = _failed(exc)
        yield futures[fut], row
