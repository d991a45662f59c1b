"""Guards of the sweeps and the design search (issue #47): each Monte-Carlo member's draws
from its own generator, with the normal's clip and every choice reachable; the design's
bisection from either side of its bracket; the observed order of a grid study on both of
its branches (the fixed point and the bisection); the pass rate's Wilson interval and the
robust design's worst member. No run: stand-ins for the solver where one is needed."""

import itertools
import math
from types import SimpleNamespace

import numpy as np
import pytest

from spinweb_fe.sweep import design as ds
from spinweb_fe.sweep import gci
from spinweb_fe.sweep import verify as vf
from spinweb_fe.sweep.draws import Draw, member_values
from spinweb_fe.sweep.report import pass_rate

DRAWS = (Draw("a.u", "uniform", {"low": 2.0, "high": 5.0}),
         Draw("a.n", "normal", {"mean": 0.0, "std": 1.0, "low": -0.5, "high": 1.0}),
         Draw("a.c", "choice", {"values": [10, 20, 30, 40]}))


def test_each_member_draws_from_its_own_generator_in_the_keys_order():
    """Member m's values are numpy's default_rng((seed, m)) drawn key after key: a uniform
    on [low, high), a normal clipped to [low, high], a choice by an integer in [0, n).
    Exact, for members 0..199 of seed 7; over them every choice value and both clips
    occur (the last of the four values too)."""
    seen, clipped = set(), set()
    for m in range(200):
        rng = np.random.default_rng((7, m))
        u = rng.uniform(2.0, 5.0)
        x = min(max(rng.normal(0.0, 1.0), -0.5), 1.0)
        c = [10, 20, 30, 40][int(rng.integers(4))]
        got = member_values(DRAWS, 7, m)
        assert got == {"a.u": u, "a.n": x, "a.c": c}, m
        assert 2.0 <= got["a.u"] < 5.0 and -0.5 <= got["a.n"] <= 1.0
        seen.add(got["a.c"])
        clipped |= {got["a.n"]} & {-0.5, 1.0}
    assert seen == {10, 20, 30, 40} and clipped == {-0.5, 1.0}
    assert member_values(DRAWS, 8, 0) != member_values(DRAWS, 7, 0)


class _Design:
    """One key x on [0, 1] in unit coordinates (the design file's map is the identity)."""

    keys = ("x",)
    scan, minimise, maxiter = 11, "parameter", 12

    def to_unit(self, values):
        return np.array([values["x"]])

    def from_unit(self, u):
        return {"x": float(u[0])}

    def unit_tol(self, key):
        return 1e-6


class _Evaluator:
    """Feasible where ``ok(x)``; remembers what it was asked (ds.Evaluator's ``many``)."""

    def __init__(self, ok):
        self.ok, self.points, self.phase = ok, [], ""

    def many(self, batch):
        out = [SimpleNamespace(values=v, feasible=self.ok(v["x"]), objective=v["x"],
                               margin=0.0) for v in batch]
        self.points += out
        return out

    def __call__(self, values):
        return self.many([values])[0]


@pytest.mark.parametrize("threshold, feasible_above", [(0.4123, True), (0.6871, False)])
def test_the_design_bisects_to_the_feasible_side_of_its_boundary(threshold, feasible_above):
    """A design feasible above (or below) a threshold: the search's scan brackets it, the
    bisection returns a feasible point within the unit tolerance 1e-6 of it (closed form:
    the boundary), from the feasible side; with bisect directly, from either end of the
    bracket as given."""
    def ok(x):
        return x >= threshold if feasible_above else x <= threshold

    ev = _Evaluator(ok)
    ds.search(_Design(), ev)
    feas = [p.values["x"] for p in ev.points if p.feasible]
    best = min(feas) if feasible_above else max(feas)
    assert ok(best) and abs(best - threshold) <= 1e-6
    good = SimpleNamespace(values={"x": 1.0 if feasible_above else 0.0}, feasible=True)
    bad = SimpleNamespace(values={"x": 0.0 if feasible_above else 1.0}, feasible=False)
    end = ds.bisect(_Design(), _Evaluator(ok), "x", good, bad)
    assert end.feasible and abs(end.values["x"] - threshold) <= 1e-6


def _exact_order(r21, r32, ratio):
    """The root p of eps32 / eps21 = r21^p (r32^p - 1) / (r21^p - 1) by bisection on a
    bracket where the function changes sign (a second method, 200 halvings)."""
    def f(p):
        return r21 ** p * (r32 ** p - 1.0) / (r21 ** p - 1.0) - ratio
    lo, hi = 1e-6, 20.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) < 0 else (lo, mid)
    return 0.5 * (lo + hi)


def test_the_observed_order_of_exact_power_laws_on_both_branches():
    """phi = 1 + h^p on grids h = 1, r21, r21 r32: observed_order recovers p to 3.4e-12
    relative (measured 2.3e-12, 1.5x) for 80 combinations of ratios 1.1-3 and 1.05-4 and orders
    0.3-3.5, 24 of which leave the fixed-point iteration for its bisection (r32 above
    r21); the order of the values themselves is checked by a second root finder (to
    1.6e-13, measured 1.06e-13)."""
    for r21, r32, p in itertools.product([1.1, 1.3, 2.0, 3.0], [1.05, 1.5, 2.0, 4.0],
                                         [0.3, 0.7, 1.0, 2.0, 3.5]):
        e21 = r21 ** p - 1.0
        e32 = (r21 * r32) ** p - r21 ** p
        got = gci.observed_order(r21, r32, e21, e32)
        assert got == pytest.approx(p, rel=3.4e-12), (r21, r32, p)
        assert _exact_order(r21, r32, e32 / e21) == pytest.approx(p, rel=1.6e-13)
    est = gci.triple([1.0, 2.0, 8.0], [1.0 + 1.0, 1.0 + 2.0 ** 1.5, 1.0 + 8.0 ** 1.5])
    assert est.order == pytest.approx(1.5, rel=1e-9)
    assert est.extrapolated == pytest.approx(1.0, rel=1e-9)


def _wilson(k, n, z=1.959963984540054):
    """The Wilson score interval written out (Wilson 1927)."""
    p = k / n
    mid = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return mid - half, mid + half


def test_the_pass_rates_interval_is_wilsons_of_the_passes():
    """pass_rate (a sweep) and robustness (a robust design's members): passes counted,
    the 95 % Wilson interval of the passes (closed form, 1e-12), the failed criteria
    counted, the robust design's worst member the one of least margin."""
    sweep = SimpleNamespace(runs=[SimpleNamespace(name=f"m{i}") for i in range(10)],
                            source="mc.toml")
    passed = [1, 1, 0, 1, 1, 1, 0, 1, 1, 1]
    rows = [{"status": "ok", "severity": 0.5 + 0.1 * i, "passed": float(p),
             "failed": "" if p else "recoil"} for i, p in enumerate(passed)]
    pr = pass_rate(sweep, rows)
    assert pr["passes"] == 8 and pr["rate"] == 0.8
    assert (pr["low"], pr["high"]) == pytest.approx(_wilson(8, 10), rel=1e-12)
    assert pr["failed_counts"] == {"recoil": 2}
    points = [SimpleNamespace(feasible=bool(p), margin=0.3 - 0.05 * i + (0 if p else -1),
                              failed=() if p else ("recoil",), run_dir=f"m{i}")
              for i, p in enumerate(passed)]
    rb = vf.robustness(points)
    assert rb["passes"] == 8
    assert (rb["low"], rb["high"]) == pytest.approx(_wilson(8, 10), rel=1e-12)
    assert rb["worst"]["run_dir"] == "m6" and rb["failed_counts"] == {"recoil": 2}
