"""``spinweb design``, the FE side: the candidates of an analytical search verified in FE
on Dask (their Monte-Carlo members with them, for a robust design), refined on the FE where
the two verdicts disagree, and the choice (docs/design.md)."""

from __future__ import annotations

import logging
import math
import time
from pathlib import Path

import numpy as np

from spinweb_fe.sweep.design import (Design, Point, build_case, case_raw, evaluate,
                                     judge_point, metrics_of)

log = logging.getLogger(__name__)

def candidates(d: Design, points) -> list:
    """Up to ``d.candidates`` feasible points, best objective first, at least 2 % of the
    unit range apart."""
    feas = sorted((p for p in points if p.feasible and math.isfinite(p.objective)),
                  key=lambda p: (p.objective, -p.margin))
    out = []
    for p in feas:
        u = d.to_unit(p.values)
        if all(np.max(np.abs(u - d.to_unit(q.values))) > 0.02 for q in out):
            out.append(p)
        if len(out) == d.candidates:
            break
    return out


def safe_step(d: Design, p: Point, points, k: int) -> dict | None:
    """The point ``refine_step * 2**k`` of the unit range from ``p`` away from the nearest
    analytically infeasible point (None: no direction, or the step leaves the range)."""
    u = d.to_unit(p.values)
    bad = [d.to_unit(q.values) for q in points if not q.feasible]
    if not bad:
        return None
    near = min(bad, key=lambda b: float(np.linalg.norm(b - u)))
    step = u - near
    if not np.linalg.norm(step) > 0:
        return None
    nu = u + d.refine_step * 2 ** k * step / np.linalg.norm(step)
    if np.any(nu < -1e-12) or np.any(nu > 1 + 1e-12):
        return None
    return d.from_unit(nu)


def fe_point(d: Design, values: dict, row: dict, out_dir: Path, extra=None) -> Point:
    """Judge a finished FE run (sweep.run.run_one's ``row``) from its results.h5."""
    import h5py

    from spinweb_fe.io.mesh import read_mesh_group
    from spinweb_fe.record import verdict

    allv = {**values, **(extra or {})}
    path = out_dir / "results.h5"
    crits = None
    if path.is_file():
        with h5py.File(path, "r") as h5:
            crits = verdict.read_group(h5)
            if crits is not None:
                h = {k: h5["history"][k][()] for k in h5["history"]}
                mesh = read_mesh_group(h5["mesh"])
    if crits is None:
        return Point(allv, "fe", False, -1.0, math.nan, {}, ("error",),
                     status=row.get("status", "no results.h5") if row.get("status") != "ok"
                     else "no verdict in results.h5", run_dir=str(out_dir),
                     wall_s=row.get("wall_time_s", math.nan))
    frac = verdict.limits_of(build_case(d, values, extra, fe=True).verdict)["deployed_fraction"]
    m = metrics_of(h, crits, verdict.reach_of(mesh), mesh.hub_radius, frac)
    return judge_point(d, allv, "fe", crits, m, run_dir=str(out_dir), wall_s=row.get(
        "wall_time_s", math.nan), note="" if row.get("status", "ok") == "ok" else row["status"])


def run_fe(d: Design, client, jobs, out_dir: Path, stage=None, warmed=None) -> list:
    """FE runs of ``jobs`` = [(name, values, extra)] on Dask, each in out_dir/fe/<name>;
    returns their Points in order. The scene is compiled once on the machine first
    (sweep.cluster.warm: a few steps of the first job, whose kernels the others load from
    numba's cache) unless ``warmed`` (a set of the scenes done) has it; ``stage`` counts
    the runs as they finish."""
    from dask.distributed import as_completed

    from spinweb_fe.sweep.cluster import warm
    from spinweb_fe.sweep.run import run_one

    tasks = [{"raw": case_raw(d, values, extra, fe=True), "source": str(d.base),
              "mode": "fe", "model": "consistent", "out_dir": str(out_dir / "fe" / name)}
             for name, values, extra in jobs]
    if tasks and (warmed is None or "fe" not in warmed):
        warm(client, tasks[0], out_dir / "fe" / "_compile")
        if warmed is not None:
            warmed.add("fe")
    futs = {client.submit(run_one, task, pure=False, key=f"spinweb-design-{name}-"
                          f"{time.monotonic_ns()}"): i
            for i, ((name, _, _), task) in enumerate(zip(jobs, tasks))}
    out = [None] * len(jobs)
    for fut in as_completed(futs):
        i = futs[fut]
        name, values, extra = jobs[i]
        try:
            row = fut.result()
        except Exception as exc:  # noqa: BLE001 - the worker died: a failed run
            row = {"status": f"{type(exc).__name__}: {exc}".splitlines()[0]}
        out[i] = fe_point(d, values, row, out_dir / "fe" / name, extra)
        log.info("FE %s: %s (%.1f s)", name, out[i].verdict(), out[i].wall_s)
        if stage is not None:
            stage.update(note=f"{name}: {out[i].verdict()}")
    return out


def member_jobs(d: Design, prefix: str, values: dict) -> list:
    """The Monte-Carlo members of a design point: (name, values, drawn keys) each, member m
    drawing from its own generator (seed, m) as a sweep's member m does."""
    from spinweb_fe.sweep.draws import member_values

    return [(f"{prefix}_m{m:03d}", values, member_values(d.draws, d.seed, m))
            for m in range(d.members)]


def robustness(points) -> dict:
    """The Monte-Carlo verdict of a design point's members: passes, rate, its 95 % Wilson
    interval, the count of each failed criterion, the worst member."""
    from spinweb_fe.sweep.draws import wilson

    n, k = len(points), sum(p.feasible for p in points)
    low, high = wilson(k, n)
    counts = {}
    for p in points:
        for f in p.failed:
            counts[f] = counts.get(f, 0) + 1
    worst = min(points, key=lambda p: p.margin) if points else None
    return {"members": n, "passes": k, "rate": k / n if n else math.nan, "low": low,
            "high": high, "failed_counts": counts,
            "worst": None if worst is None else {"run_dir": worst.run_dir,
                                                 "failed": list(worst.failed),
                                                 "margin": worst.margin}}


def slug(d: Design, values: dict) -> str:
    return "_".join(f"{k.split('.')[-1]}={v:.5g}" for k, v in values.items())


def verify(d: Design, client, cands, points, out_dir: Path, stages=None, warmed=None) -> list:
    """FE runs of the candidates; while none passes, step the safest failed one toward the
    analytical safe side (``safe_step``, doubling) and run again; once a step passes,
    bisect between it and the last FE failure: ``d.refine`` FE runs at most after the
    candidates. Returns [(analytic point, FE point)] in the order run. ``stages``: the
    progress Stage of the verification and of the refinement."""
    fe_stage, ref_stage = stages or (None, None)
    pairs = list(zip(cands, run_fe(d, client, [(f"{i:02d}_{slug(d, c.values)}", c.values, None)
                                               for i, c in enumerate(cands)], out_dir,
                                   fe_stage, warmed)))
    if any(f.feasible for _, f in pairs):
        return pairs
    bad = [q for q in points if not q.feasible]
    fail = max((a for a, _ in pairs), key=lambda a: min(
        (float(np.linalg.norm(d.to_unit(a.values) - d.to_unit(q.values))) for q in bad),
        default=0.0))
    ok = None
    for k in range(d.refine):
        if ok is None:
            nxt, what = safe_step(d, fail, points, k), "step to the safe side"
        else:
            u0, u1 = d.to_unit(fail.values), d.to_unit(ok.values)
            if np.max(np.abs(u1 - u0)) < 0.25 * d.refine_step:
                break
            nxt, what = d.from_unit(0.5 * (u0 + u1)), "bisect between FE fail and pass"
        if nxt is None:
            log.info("refine: no further step toward the safe side within the search range")
            break
        a = evaluate(d, nxt)
        points.append(a)
        if not a.feasible:
            log.info("refine: %s fails analytically (%s): stop", slug(d, nxt),
                     ",".join(a.failed))
            break
        log.info("refine %d (%s): %s", k + 1, what, slug(d, nxt))
        (f,) = run_fe(d, client, [(f"{len(pairs):02d}_refine_{slug(d, nxt)}", nxt, None)],
                      out_dir, ref_stage, warmed)
        a.note = f"refinement {k + 1}: {what}"
        pairs.append((a, f))
        if f.feasible:
            ok = a
        else:
            fail = a
    return pairs


def verify_members(d: Design, client, pairs, out_dir: Path, stage=None, warmed=None) -> dict:
    """The Monte-Carlo members of every FE-passing verified point (``d.members`` each), in
    one batch: {index of the pair: robustness record}."""
    ok = [i for i, (_, f) in enumerate(pairs) if f.feasible]
    jobs, owner = [], []
    for i in ok:
        a = pairs[i][0]
        for job in member_jobs(d, f"{i:02d}_{slug(d, a.values)}", a.values):
            jobs.append(job)
            owner.append(i)
    pts = run_fe(d, client, jobs, out_dir / "members", stage, warmed) if jobs else []
    return {i: robustness([p for p, o in zip(pts, owner) if o == i]) for i in ok}


def choose(pairs, robust=None, rate=None):
    """The chosen (analytic, FE) pair and its robustness record: without Monte-Carlo
    members the FE-passing pair with the best FE objective (the analytic one where the
    FE's is not finite); with them the best whose members' pass rate has the low end of its
    95 % interval at least ``rate``, or, if none has, the most robust (the highest low
    end). (None, None, False) if the FE rejected all; the flag says the rate is met."""
    ok = [(i, a, f) for i, (a, f) in enumerate(pairs) if f.feasible]
    if not ok:
        return None, None, False

    def objective(iaf):
        a, f = iaf[1], iaf[2]
        return f.objective if math.isfinite(f.objective) else a.objective
    if not robust:
        i, a, f = min(ok, key=objective)
        return (a, f), None, True
    met = [x for x in ok if rate is None or robust[x[0]]["low"] >= rate]
    if met:
        i, a, f = min(met, key=objective)
        return (a, f), robust[i], True
    i, a, f = max(ok, key=lambda x: (robust[x[0]]["low"], -objective(x)))
    return (a, f), robust[i], False


def robust_refine(d: Design, client, pairs, robust, points, out_dir: Path, stage=None,
                  warmed=None) -> int:
    """While no verified point's members reach ``d.pass_rate``: step the most robust
    FE-passing point away from the analytically failing ones (``safe_step``, doubling) and
    run it and its members; ``d.refine`` rounds at most. Extends ``pairs`` and ``robust``
    in place; returns the rounds run."""
    rounds = 0
    while d.pass_rate is not None and rounds < d.refine:
        chosen, _, met = choose(pairs, robust, d.pass_rate)
        if met or chosen is None:
            break
        nxt = safe_step(d, chosen[0], points, rounds)
        if nxt is None:
            log.info("robust refinement: no step toward the safe side within the range")
            break
        a = evaluate(d, nxt)
        points.append(a)
        rounds += 1
        if not a.feasible:
            log.info("robust refinement: %s fails analytically (%s): stop", slug(d, nxt),
                     ",".join(a.failed))
            break
        a.note = f"robust refinement {rounds}: step to the safe side"
        name = f"{len(pairs):02d}_robust_{slug(d, nxt)}"
        (f,) = run_fe(d, client, [(name, nxt, None)], out_dir, stage, warmed)
        pairs.append((a, f))
        if f.feasible:
            pts = run_fe(d, client, member_jobs(d, name, nxt), out_dir / "members", stage,
                         warmed)
            robust[len(pairs) - 1] = robustness(pts)
    return rounds
