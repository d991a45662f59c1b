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
    from spinweb_fe.sweep.limits import check_workers
    from spinweb_fe.sweep.run import dask_client

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


def run(args) -> int:
    from spinweb_fe.io.folder import check_writable

    if args.workers < 1:
        raise InputError("--workers", "", f"must be >= 1, got {args.workers}")
    out = Path(args.output) if args.output else Path("out") / Path(args.design).stem
    if args.chart:
        return _chart(args, out, check_writable)
    from spinweb_fe.sweep import chart as ch
    from spinweb_fe.sweep import design as ds

    d = ds.load_design(args.design)
    check_writable(out)
    with _claim(out, "design"):
        return _design(args, d, out)


def _design(args, d, out) -> int:
    from spinweb_fe.sweep import chart as ch
    from spinweb_fe.sweep import design as ds

    t0 = time.perf_counter()
    ev = ds.Evaluator(d)
    points = ds.search(d, ev)
    t_search = time.perf_counter() - t0
    n_ok = sum(p.feasible for p in points)
    print(f"analytic search: {len(points)} solves of the consistent model in {t_search:.1f} s, "
          f"{n_ok} pass (" + ("scan + bisection + bounded Brent" if len(d.keys) == 1
                              else "differential evolution") + ")")
    cands = ch.candidates(d, points)
    timing = {"search": t_search}
    if not cands:
        near = max(points, key=lambda p: p.margin)
        ch.write_design(d, points, [], None, out, timing)
        raise RunError(f"no design: no {', '.join(d.keys)} within the search range passes "
                       f"({', '.join(d.require or ('every criterion',))}) and meets the "
                       f"bounds on the analytical model; the closest, "
                       + ", ".join(f"{k} = {v:.4g}" for k, v in near.values.items())
                       + f", fails {', '.join(near.failed) or near.status} "
                       f"(margin {near.margin:.3g}); see {out / 'design.json'}")
    if args.no_fe:
        best = cands[0]
        pairs = []
        print("design (analytic only): " + ", ".join(f"{k} = {v:.6g}" for k, v in
                                                      best.values.items())
              + f", {d.minimise} = {best.objective:.5g}")
        paths = ch.write_design(d, points, [], None, out, timing)
        print(f"wrote {paths['csv']}, {paths['json']}, {paths['png']} (no FE: no design.toml)")
        return 0
    t1 = time.perf_counter()
    with _client(args, d) as client:
        pairs = ch.verify(d, client, cands, points, out)
    timing["fe"] = time.perf_counter() - t1
    timing["total"] = time.perf_counter() - t0
    chosen = ch.choose(pairs)
    paths = ch.write_design(d, points, pairs, chosen, out, timing)
    _print_table(*ch.pair_table(d, pairs))
    print(f"timing: search {t_search:.1f} s, FE {timing['fe']:.1f} s, total "
          f"{timing['total']:.1f} s")
    if chosen is None:
        raise RunError("no FE-verified design: the FE rejected every candidate and "
                       f"{d.refine} refinement step(s) (see {paths['csv']}); the analytical "
                       "model and the FE disagree here")
    a, f = chosen
    print("design: " + ", ".join(f"{k} = {v:.6g}" for k, v in a.values.items())
          + f"; {d.minimise}: analytic {a.objective:.5g}, FE {f.objective:.5g}")
    print(f"wrote {paths['toml']} (spinweb run it), {paths['csv']}, {paths['json']}, "
          f"{paths['png']}; FE result {f.run_dir}")
    return 0


def _chart(args, out, check_writable) -> int:
    from spinweb_fe.sweep import chart as ch

    d = ch.load_chart(args.design)
    if args.no_fe:
        import dataclasses

        d = dataclasses.replace(d, chart_fe=())
    check_writable(out)
    t0 = time.perf_counter()
    with _claim(out, "design"):
        with _client(args, d) as client:
            rows = ch.run_chart(d, client, out)
        paths = ch.write_chart(d, rows, out)
    cols = [d.chart_key, f"least {d.keys[0]}", *ch.CHART_COLS[2:]]
    _print_table(cols, ch.chart_table(d, rows))
    n = sum(math.isfinite(r["least"]) for r in rows)
    print(f"{n} of {len(rows)} chart values have a passing {d.keys[0]} in "
          f"{list(d.search[d.keys[0]])}; {time.perf_counter() - t0:.1f} s; wrote "
          f"{paths['csv']}, {paths['json']}, {paths['png']}")
    return 0
