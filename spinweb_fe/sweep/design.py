"""Deployment design: judging a point and the search on the consistent analytical model
(docs/design.md, "Design search"); the design file is :mod:`spinweb_fe.sweep.designfile`,
the FE verification :mod:`spinweb_fe.sweep.verify`, the outputs
:mod:`spinweb_fe.sweep.outputs`.

A point is feasible when every required criterion that applies passed and every bound
holds; its *margin* (the least relative margin of those, negative when it fails) is what
the search sees of a failure.
"""

from __future__ import annotations

import itertools
import logging
import math
import time
from dataclasses import dataclass

import numpy as np

from spinweb_fe.errors import InputError
from spinweb_fe.record import criteria as criteria_reg
from spinweb_fe.record import metrics as metric_reg
from spinweb_fe.record import verdict
from spinweb_fe.record.metrics import BOUNDS, METRICS, OBJECTIVES  # noqa: F401  (the registry)
from spinweb_fe.sweep.designfile import (Design, _num, build_case, case_raw,  # noqa: F401
                                         check_cases, load_design)

log = logging.getLogger(__name__)

BIG = 1e30  # the penalised score of an infeasible point: BIG (1 + its violation)


@dataclass
class Point:
    """One evaluated design: the analytical model's or the FE's judgement."""

    values: dict
    model: str                      # 'analytic' | 'fe'
    feasible: bool
    margin: float
    objective: float
    metrics: dict
    failed: tuple                   # failed criteria and violated bounds
    status: str = "ok"
    run_dir: str = ""
    wall_s: float = math.nan
    note: str = ""

    @property
    def score(self) -> float:
        """What the optimiser minimises: the objective, or BIG (1 + violation)."""
        if self.feasible and math.isfinite(self.objective):
            return self.objective
        return BIG * (1.0 + max(0.0, -self.margin if math.isfinite(self.margin) else 1.0))

    def verdict(self) -> str:
        if self.status != "ok":
            return "error"
        return "pass" if self.feasible else "FAIL " + ",".join(self.failed)


# -- judging a point ----------------------------------------------------------------------

def _margin(c) -> float:
    """A criterion's relative margin (>= 0 passed; infinite: passed, no number): a run that
    stopped early, the share of it not done (the analytical model leaving its validity is
    a failure, the later the closer), 'deployed' (a share, larger is better) value/limit -
    1, every other (and deploy_by) 1 - value/limit."""
    if c.name == "completed":
        m = math.inf if c.passed else (c.value - 1.0 if math.isfinite(c.value) else -1.0)
    elif not (math.isfinite(c.value) and math.isfinite(c.limit) and c.limit > 0):
        m = math.inf if c.passed else -1.0
    elif c.name == "deployed" and c.units == "1":
        m = c.value / c.limit - 1.0
    else:
        m = 1.0 - c.value / c.limit
    return min(m, -1e-12) if c.passed is False else m


def metrics_of(h: dict, crits, reach, hub_radius: float, fraction: float,
               ea_fail=None) -> dict:
    """Design metrics of a run's history (FE or analytic) and verdict: the registry's
    (record.metrics.compute)."""
    return metric_reg.compute(h, crits, reach, hub_radius, fraction, ea_fail)


def judge_point(d: Design, values, model, crits, metrics, **kw) -> Point:
    """Feasibility, margin, objective and failures of a point from its criteria and
    metrics (see the module's doc)."""
    need = criteria_reg.required(d.require)
    margins, failed = [], []
    dep = next((c for c in crits if c.name == "deployed" and c.units == "1"), None)
    if dep is not None:
        metrics = {**metrics, "deploy_share": dep.value}  # tips' least share of their reach
    for c in crits:
        if c.name in need and c.passed is not None:
            margins.append(_margin(c))
            if c.passed is False:
                failed.append(c.name)
    for b, lim in d.bounds.items():
        v = metrics.get(b, math.nan)
        if math.isnan(v):
            continue  # does not apply (strength of an analytic web: FE only)
        margins.append(1.0 - v / lim if math.isfinite(v) else -1.0)
        if not v <= lim:
            failed.append(b)
    obj = math.nan
    if d.minimise == "parameter":
        obj = next(iter(values.values()))
    elif d.minimise:
        obj = metrics.get(d.minimise, math.nan)
    margin = min(margins, default=math.inf)
    return Point(dict(values), model, not failed, margin if math.isfinite(margin) else 1.0,
                 obj, metrics, tuple(failed), **kw)


def evaluate(d: Design, values: dict, extra: dict | None = None) -> Point:
    """One analytical run (consistent model) of the point ``values`` (+ chart ``extra``)."""
    from spinweb_fe.analytic import solve

    t0 = time.perf_counter()
    allv = {**values, **(extra or {})}
    try:
        case = build_case(d, values, extra)
        res = solve.solve_case(case, model="consistent")
        crits = solve.judge(case, res)
        ea_fail = None
        if case.scene == "tethers" and case.cable.failure_strain:
            ea_fail = case.cable.youngs_modulus * case.cable.area * case.cable.failure_strain
        p = res.params
        m = metrics_of(res.history, crits, np.full(p.n, p.r0 + p.H), p.r0,
                       verdict.limits_of(case.verdict)["deployed_fraction"], ea_fail)
        return judge_point(d, allv, "analytic", crits, m, wall_s=time.perf_counter() - t0)
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - a failure of the model: an infeasible point
        return Point(allv, "analytic", False, -1.0, math.nan, {}, ("error",),
                     status=f"{type(exc).__name__}: {exc}".splitlines()[0],
                     wall_s=time.perf_counter() - t0)


class Evaluator:
    """Memoised :func:`evaluate` (the bisection and Brent revisit points); ``points`` in
    the order evaluated. With a ``client`` (sweep.cluster.LazyClient) :meth:`many` solves
    its points in parallel on the workers when the batch is worth a cluster's start;
    ``stage`` (run.progress.Stage) counts the solves; ``counts`` per ``phase`` (scan,
    bisection, Brent, differential evolution) for the final message."""

    def __init__(self, d: Design, extra=None, client=None, stage=None):
        self.d, self.extra, self.client, self.stage = d, extra, client, stage
        self.points, self._seen, self.counts, self.phase = [], {}, {}, "search"

    def _key(self, values):
        return tuple(round(float(values[k]), 12) for k in self.d.keys)

    def _add(self, key, p):
        self._seen[key] = p
        self.points.append(p)
        self.counts[self.phase] = self.counts.get(self.phase, 0) + 1
        if self.stage is not None:
            self.stage.update(note=f"{self.phase}: {len(self.points)} solves")

    def __call__(self, values: dict) -> Point:
        return self.many([values])[0]

    def many(self, batch) -> list:
        """The points of ``batch`` (a list of value dicts), the new ones solved at once."""
        keys = [self._key(v) for v in batch]
        new = list({k: v for k, v in zip(keys, batch) if k not in self._seen}.items())
        if new and self.client is not None and self.client.worth(len(new)):
            futs = self.client.map(evaluate, [self.d] * len(new), [v for _, v in new],
                                   [self.extra] * len(new), pure=False)
            for (k, _), fut in zip(new, futs):
                self._add(k, fut.result())
        else:
            for k, v in new:
                self._add(k, evaluate(self.d, v, self.extra))
        return [self._seen[k] for k in keys]


# -- the search ---------------------------------------------------------------------------

def bisect(d: Design, ev: Evaluator, key: str, good: Point, bad: Point) -> Point:
    """Bisect (in unit coordinates) between a feasible and an infeasible point of one key
    down to ``d.rtol``; returns the feasible end."""
    return bisect_all(d, ev, key, [(good, bad)])[0]


def bisect_all(d: Design, ev: Evaluator, key: str, pairs) -> list:
    """Bisect every (feasible, infeasible) pair together, one parallel batch of midpoints
    per step; returns the feasible ends."""
    state = [[d.to_unit(g.values)[0], d.to_unit(b.values)[0], g] for g, b in pairs]
    tol = d.unit_tol(key)
    while True:
        live = [s for s in state if abs(s[0] - s[1]) > tol]
        if not live:
            return [s[2] for s in state]
        mids = ev.many([d.from_unit([0.5 * (s[0] + s[1])]) for s in live])
        for s, mid in zip(live, mids):
            if mid.feasible:
                s[0], s[2] = 0.5 * (s[0] + s[1]), mid
            else:
                s[1] = 0.5 * (s[0] + s[1])


def search(d: Design, ev: Evaluator) -> list:
    """All analytical points of the search (1 key: scan, bisection of every feasibility
    boundary, bounded Brent about the best scanned point; more keys: differential
    evolution on the penalised score), each batch of independent solves in parallel when
    the Evaluator has a client."""
    from scipy.optimize import differential_evolution, minimize_scalar

    if len(d.keys) == 1:
        key = d.keys[0]
        ev.phase = "scan"
        scan = ev.many([d.from_unit([u]) for u in np.linspace(0.0, 1.0, d.scan)])
        ev.phase = "bisection"
        bisect_all(d, ev, key, [((a, b) if a.feasible else (b, a))
                                for a, b in itertools.pairwise(scan) if a.feasible != b.feasible])
        feas = [i for i, p in enumerate(scan) if p.feasible and math.isfinite(p.objective)]
        if feas and d.minimise != "parameter":
            ev.phase = "Brent"
            i = min(feas, key=lambda j: scan[j].objective)
            lo = (i - 1) / (d.scan - 1) if i > 0 else 0.0
            hi = (i + 1) / (d.scan - 1) if i < d.scan - 1 else 1.0
            minimize_scalar(lambda u: ev(d.from_unit([u])).score, bounds=(lo, hi),
                            method="bounded", options={"xatol": d.unit_tol(key),
                                                       "maxiter": d.maxiter})
    else:
        ev.phase = "differential evolution"

        def mapper(_, us):  # a generation at once (updating = "deferred")
            return [p.score for p in ev.many([d.from_unit(u) for u in us])]
        parallel = {"updating": "deferred", "workers": mapper} if ev.client is not None \
            else {"updating": "immediate"}  # one at a time: each trial sees the last
        differential_evolution(lambda u: ev(d.from_unit(u)).score, [(0.0, 1.0)] * len(d.keys),
                               maxiter=d.maxiter, popsize=6, seed=0, tol=1e-3, polish=False,
                               init="sobol", **parallel)
    return ev.points


def _why(p: Point) -> str:
    parts = []
    for f in p.failed:
        c = criteria_reg.CRITERIA.get(f)
        text = c.fails if c else ("the model fails" if f == "error" else f"{f} above its bound")
        if f == "deployed" and math.isfinite(p.metrics.get("deploy_share", math.nan)):
            text += f" (tips at {p.metrics['deploy_share']:.2g} of their reach)"
        parts.append(text)
    return ", ".join(parts) or "passes"


def diagnose(d: Design, points) -> tuple[str, list]:
    """Why no design exists, in one line of physical terms, and its evidence: for one
    searched key the ranges of the key over which the analytical runs fail the same way
    (e.g. a brake alone: below a force the line runs away and a tip falls back, above it
    the arms stay in); for several keys the closest point."""
    pts = sorted((p for p in points if p.status == "ok" or p.failed), key=lambda p: tuple(
        p.values[k] for k in d.keys))
    if len(d.keys) != 1 or not pts:
        near = max(points, key=lambda p: p.margin)
        return ("the closest, " + ", ".join(f"{k} = {v:.4g}" for k, v in near.values.items())
                + f", fails: {_why(near)} (margin {near.margin:.3g})"), [
            {"values": near.values, "failed": list(near.failed), "margin": near.margin}]
    key, groups = d.keys[0], []
    for p in pts:
        sig = tuple(sorted(p.failed))
        if groups and groups[-1]["sig"] == sig:
            groups[-1]["to"], groups[-1]["points"] = p.values[key], groups[-1]["points"] + [p]
        else:
            groups.append({"sig": sig, "from": p.values[key], "to": p.values[key],
                           "points": [p]})
    parts = []
    for i, g in enumerate(groups):
        rng = (f"up to {g['to']:.4g}" if i == 0 else f"from {g['from']:.4g}" if
               i == len(groups) - 1 else f"{g['from']:.4g} to {g['to']:.4g}")
        parts.append(f"{rng}: {_why(g['points'][len(g['points']) // 2])}")
    evidence = [{"from": g["from"], "to": g["to"], "failed": list(g["sig"]),
                 "points": len(g["points"])} for g in groups]
    return f"{key} " + "; ".join(parts), evidence
