"""``spinweb design DESIGN.toml``: search a control law's parameters on the consistent
analytical model, verify the best candidates in FE on Dask and write the design
(DIR/design.toml, .csv, .json, .png); ``--chart``: the least value of the searched key
against one design input (DIR/chart.csv, .json, .png). docs/design.md."""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import time
from pathlib import Path

from spinweb_fe.errors import InputError, RunError
from spinweb_fe.record.criteria import required

log = logging.getLogger(__name__)


def add_parser(sub):
    p = sub.add_parser("design", help="search a control law that deploys (analytic), verify "
                       "it in FE", description=__doc__,
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("design", help="design file (TOML)")
    p.add_argument("-o", "--output", default=None, metavar="DIR",
                   help="design folder (default: out/<design file stem>)")
    p.add_argument("--chart", action="store_true",
                   help="the chart of the file's [chart] table instead of one design")
    p.add_argument("--workers", type=int, default=2,
                   help="worker processes of the local Dask cluster (FE runs, chart rows)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running Dask scheduler, e.g. tcp://host:8786 "
                        "(default: a local cluster; the workers must share DIR)")
    p.add_argument("--no-fe", action="store_true",
                   help="analytical search only: no FE verification (no FE-checked chart "
                        "points)")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bars (they show only on a terminal, not under CI)")
    p.add_argument("--force", action="store_true",
                   help="start more workers than this machine can hold (docs/sweep.md)")
    return p


def _fmt(v) -> str:
    return f"{v:.5g}" if isinstance(v, float) else str(v)


def _print_table(cols, rows):
    lines = [list(cols)] + [[_fmt(v) for v in r] for r in rows]
    widths = [max(len(line[j]) for line in lines) for j in range(len(cols))]
    for line in lines:
        print("  ".join(v.ljust(w) for v, w in zip(line, widths)).rstrip())


def _client(args, d):
    from spinweb_fe.sweep.cluster import dask_client
    from spinweb_fe.sweep.limits import check_workers

    if args.scheduler and args.workers != 2:
        log.warning("--workers is ignored with --scheduler (the cluster has its own workers)")
    if not args.scheduler:  # a cluster of this machine's processes, each running the base
        from spinweb_fe.case.load import validate
        from spinweb_fe.run.estimate import case_elements

        try:
            elements = case_elements(validate(d.base_raw, str(d.base)))
        except InputError:  # the design's own values complete it: the checks come later
            elements = 0.0
        check_workers(args.workers, elements, getattr(args, "force", False))
    return dask_client(args.scheduler, args.workers)


@contextlib.contextmanager
def _claim(out, what):
    """One sweep or design per folder (its ``sweep.lock``, as a run's ``run.lock``)."""
    from spinweb_fe.io.folder import SWEEP_LOCK, FolderLock, busy, holder

    if (info := holder(out, SWEEP_LOCK)) is not None:
        raise busy(out, info, "sweep or design")
    with FolderLock(out, SWEEP_LOCK, what):
        yield


def _ran(name, stage, seconds, what="runs") -> str:
    return f"{name} {stage.done} {what} in {seconds:.1f} s"


def run(args) -> int:
    from spinweb_fe.io.folder import check_writable

    if args.workers < 1:
        raise InputError("--workers", "", f"must be >= 1, got {args.workers}")
    out = Path(args.output) if args.output else Path("out") / Path(args.design).stem
    if args.chart:
        return _chart(args, out, check_writable)
    from spinweb_fe.sweep import design as ds
    from spinweb_fe.sweep import outputs
    from spinweb_fe.sweep import verify as vf
    from spinweb_fe.run.progress import Stage, enabled

    d = ds.load_design(args.design)
    check_writable(out)
    with _claim(out, "design"):
        return _design(args, d, out, ds, outputs, vf, Stage, enabled)


def _design(args, d, out, ds, outputs, vf, Stage, enabled) -> int:
    show = enabled(not args.no_progress)
    t0 = time.perf_counter()
    timing, ran = {}, []
    with _client(args, d) as client:
        with Stage("analytic search", None, show, unit="solve") as st:
            ev = ds.Evaluator(d, client=client, stage=st)
            points = ds.search(d, ev)
        timing["search"] = time.perf_counter() - t0
        ran.append(f"analytic search {len(points)} solves of the consistent model ("
                   + ", ".join(f"{k} {v}" for k, v in ev.counts.items())
                   + f") in {timing['search']:.1f} s {_where(args, client)}")
        cands = vf.candidates(d, points)
        info = {"timing_s": timing, "stages": ran}
        if not cands:
            reason, evidence = ds.diagnose(d, points)
            info.update(no_design=reason, evidence=evidence)
            outputs.write_design(d, points, [], None, out, info)
            print("stages: " + "; ".join(ran))
            raise RunError(f"no design: no {', '.join(d.keys)} within the search range passes "
                           f"({', '.join(required(d.require))}) and meets the bounds on the "
                           f"analytical model: {reason}; see {out / 'design.json'}")
        if args.no_fe:
            best = cands[0]
            paths = outputs.write_design(d, points, [], None, out, info)
            print("stages: " + "; ".join(ran))
            print("design (analytic only): " + ", ".join(f"{k} = {v:.6g}" for k, v in
                                                          best.values.items())
                  + f", {d.minimise} = {best.objective:.5g}")
            print(f"wrote {paths['csv']}, {paths['json']}, {paths['png']} (no FE: no "
                  "design.toml)")
            return 0
        warmed, t1 = set(), time.perf_counter()
        with Stage("FE verification", len(cands), show) as fe_st, \
                Stage("FE refinement", None, show) as ref_st:
            pairs = vf.verify(d, client, cands, points, out, (fe_st, ref_st), warmed)
        timing["fe"] = time.perf_counter() - t1
        ran.append(f"FE verification {fe_st.done} runs of the candidates and "
                   f"{ref_st.done} refinement runs (after one compile of the scene) in "
                   f"{timing['fe']:.1f} s")
        robust = {}
        n_ok = sum(f.feasible for _, f in pairs)
        if d.members and n_ok:
            t2 = time.perf_counter()
            with Stage("FE Monte-Carlo", d.members * n_ok, show) as mc:
                robust = vf.verify_members(d, client, pairs, out, mc, warmed)
            with Stage("FE robust refinement", None, show) as rr:
                rounds = vf.robust_refine(d, client, pairs, robust, points, out, rr, warmed)
            timing["members"] = time.perf_counter() - t2
            ran.append(f"FE Monte-Carlo {mc.done} members of {n_ok} FE-passing point(s)"
                       + (f", robust refinement {rounds} step(s) ({rr.done} runs)"
                          if rounds else "") + f" in {timing['members']:.1f} s")
    timing["total"] = time.perf_counter() - t0
    chosen, rec, met = vf.choose(pairs, robust, d.pass_rate)
    info.update(robust=robust, chosen_robust=rec, rate_met=met)
    paths = outputs.write_design(d, points, pairs, chosen, out, info)
    _print_table(*outputs.pair_table(d, pairs))
    print("stages: " + "; ".join(ran) + f"; total {timing['total']:.1f} s")
    if chosen is None:
        n_ref = sum(1 for a, _ in pairs if a.note.startswith("refinement"))
        raise RunError(f"no FE-verified design: the FE rejected the {len(cands)} candidate(s) "
                       f"and {n_ref} refinement run(s) (see {paths['csv']}); the analytical "
                       "model and the FE disagree here")
    a, f = chosen
    line = ("design: " + ", ".join(f"{k} = {v:.6g}" for k, v in a.values.items())
            + f"; {d.minimise}: analytic {a.objective:.5g}, FE {f.objective:.5g}")
    if rec is not None:
        line += (f"; {rec['passes']} of {rec['members']} Monte-Carlo members pass (95 % "
                 f"interval {100 * rec['low']:.0f} .. {100 * rec['high']:.0f} %)")
        if d.pass_rate is not None:
            line += ("; the required pass rate {:.0%} is met".format(d.pass_rate) if met else
                     "; NOT ROBUST ENOUGH: no verified point's interval reaches the required "
                     "{:.0%}, this is the most robust".format(d.pass_rate))
    print(line)
    print(f"wrote {paths['toml']} (spinweb run it: its [verdict] requires what it was "
          f"verified for), " + (f"{paths['check']} (spinweb sweep it: its members), "
                                if "check" in paths else "")
          + f"{paths['csv']}, {paths['json']}, {paths['png']}; FE result {f.run_dir}")
    return 0


def _where(args, client) -> str:
    """Where the analytical search ran: the cluster only if a batch was worth it."""
    if not client.started:
        return "in this process"
    return f"on {args.scheduler or f'{args.workers} local worker(s)'}"


def _chart(args, out, check_writable) -> int:
    from spinweb_fe.sweep import chart as ch
    from spinweb_fe.sweep import outputs

    d = ch.load_chart(args.design)
    if args.no_fe:
        import dataclasses

        d = dataclasses.replace(d, chart_fe=())
    check_writable(out)
    t0 = time.perf_counter()
    from spinweb_fe.run.progress import enabled

    with _claim(out, "design"):
        with _client(args, d) as client:
            rows = ch.run_chart(d, client, out, enabled(not args.no_progress))
        paths = outputs.write_chart(d, rows, out)
    cols = [d.chart_key, f"least {d.keys[0]}", *outputs.CHART_COLS[2:]]
    _print_table(cols, outputs.chart_table(d, rows))
    n = sum(math.isfinite(r["least"]) for r in rows)
    print(f"{n} of {len(rows)} chart values have a passing {d.keys[0]} in "
          f"{list(d.search[d.keys[0]])}; {time.perf_counter() - t0:.1f} s; wrote "
          f"{paths['csv']}, {paths['json']}, {paths['png']}")
    return 0
