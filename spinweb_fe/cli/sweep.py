"""``spinweb sweep SWEEP.toml``: run a parameter sweep of one base case on Dask and write
DIR/summary.csv, DIR/summary.h5 and DIR/summary.png (docs/sweep.md)."""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path

from spinweb_fe.errors import InputError

log = logging.getLogger(__name__)


def add_parser(sub):
    p = sub.add_parser("sweep", help="parameter sweep of a case on Dask (FE or analytic)",
                       description=__doc__,
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("sweep", help="sweep file (TOML)")
    p.add_argument("-o", "--output", default=None, metavar="DIR",
                   help="sweep folder (default: out/<sweep file stem>)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running Dask scheduler, e.g. tcp://host:8786 "
                        "(default: a local cluster; the workers must share DIR)")
    p.add_argument("--workers", type=int, default=2,
                   help="worker processes of the local cluster (one thread each)")
    p.add_argument("--mode", choices=("fe", "analytic"), default=None,
                   help="override the sweep file's mode")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="add to the sweep's [set] (every run), e.g. --set time.end=2")
    p.add_argument("--only", action="append", default=[], metavar="NAME",
                   help="run only this run (its folder name or index, as --dry-run lists "
                        "them; a Monte-Carlo member keeps its own draws); repeatable")
    p.add_argument("--dry-run", action="store_true",
                   help="validate and list the runs, run nothing")
    p.add_argument("--no-progress", action="store_true", help="no line per finished run")
    p.add_argument("--force", action="store_true",
                   help="start more runs or workers than this machine can hold (the limits "
                        "of docs/sweep.md)")
    return p


def _fmt(v):
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def run(args) -> int:
    from spinweb_fe.io.folder import SWEEP_LOCK, FolderLock, busy, check_writable, holder
    from spinweb_fe.sweep import report as sweep_report
    from spinweb_fe.sweep import run as sw
    from spinweb_fe.sweep.limits import check_workers

    if args.workers < 1:
        raise InputError("--workers", "", f"must be >= 1, got {args.workers}")
    force = getattr(args, "force", False)
    spec = sw.load_sweep(args.sweep, mode=args.mode, sets=args.sets,
                         only=[x for arg in args.only for x in arg.split(",")], force=force)
    out = Path(args.output) if args.output else Path("out") / Path(args.sweep).stem
    check_writable(out)  # before a cluster starts: one line, not a traceback per run
    if not args.scheduler:  # a cluster of this machine's processes
        check_workers(args.workers, max((r.elements for r in spec.runs), default=0.0), force)
    if args.dry_run:
        print(f"{len(spec.runs)} {spec.mode} runs of {spec.base} -> {out}/runs/")
        for r in spec.runs:
            print(f"  {r.name}: " + ", ".join(f"{k} = {_fmt(v)}" for k, v in r.values.items()))
        return 0
    if args.scheduler and args.workers != 2:
        log.warning("--workers is ignored with --scheduler (the cluster has its own workers)")
    if (info := holder(out, SWEEP_LOCK)) is not None:  # one sweep per folder
        raise busy(out, info, "sweep or design")
    with FolderLock(out, SWEEP_LOCK, "sweep"):
        from spinweb_fe.sweep.cluster import execute

        rows = execute(spec, out, scheduler=args.scheduler, workers=args.workers,
                          progress=not args.no_progress)
        paths = sweep_report.write_summary(spec, rows, out)
    cols, data = sweep_report.table(spec, rows)
    shown = ["name", *sw.PLOTTED, "passed", "failed", "wall_time_s", "status"]
    idx = [cols.index(c) for c in shown]
    lines = [[c for c in shown]] + [[_fmt(r[j]) for j in idx] for r in data]
    widths = [max(len(line[j]) for line in lines) for j in range(len(shown) - 1)]
    for line in lines:
        print("  ".join(v.ljust(w) for v, w in zip(line, widths)) + "  " + line[-1])
    n_fail = sum(r["status"] != "ok" for r in rows)
    total = sum(r.get("wall_time_s", 0.0) for r in rows if not math.isnan(r["wall_time_s"]))
    print(f"{len(rows) - n_fail} of {len(rows)} runs ok, {n_fail} failed "
          f"({total:.1f} s of run time); wrote {paths['csv']}, {paths['h5']}, {paths['png']}")
    for line in sweep_report.rate_lines(spec, rows):
        print(line)
    return 0
