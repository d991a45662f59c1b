"""``spinweb converge CASE.toml``: the case at three or more mesh widths on Dask; for each
quantity of interest its values, observed order, Richardson extrapolation and grid
convergence index (DIR/converge.json, .csv, .png). docs/converge.md."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from spinweb_fe.errors import InputError

log = logging.getLogger(__name__)


def _floats(text: str, what: str) -> list:
    try:
        return [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise InputError(what, "", f"expected comma-separated numbers, got '{text}'") from None


def add_parser(sub):
    p = sub.add_parser("converge", help="mesh convergence: observed order, extrapolation "
                       "and grid convergence index of a case's answers",
                       description=__doc__, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("case", help="case file (TOML, SI units)")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override a case key (every grid), e.g. --set time.end=1")
    p.add_argument("-o", "--output", default=None, metavar="DIR",
                   help="study folder (default: out/<case stem>_converge)")
    p.add_argument("--widths", default=None, metavar="T1,T2,...",
                   help="mesh widths [m] (tethers: element lengths), at least three; "
                        "default: the case's width refined by --ratio")
    p.add_argument("--ratio", type=float, default=2.0,
                   help="refinement ratio between neighbouring grids (>= 1.1; the grid must "
                        "fit the side, so the actual ratios may differ a little)")
    p.add_argument("--levels", type=int, default=3, help="number of grids")
    p.add_argument("--quick", action="store_true",
                   help="a shorter window: the first tenth of time.end")
    p.add_argument("--end", type=float, default=None, metavar="T",
                   help="the window's end [s] (default time.end, or its tenth with --quick)")
    p.add_argument("--times", default=None, metavar="T1,T2,...",
                   help="times [s] of the hub-rate and arm-length quantities "
                        "(default: 1/4, 1/2, 3/4 and the end of the window)")
    p.add_argument("-q", "--quantity", dest="quantities", action="append", default=[],
                   metavar="NAME", help="a quantity instead of the defaults (repeatable): "
                   "COLUMN@T, COLUMN@max|min|end|mean, deploy_time, peak_tension, "
                   "peak_utilisation, margin.<criterion>")
    p.add_argument("--safety", type=float, default=1.25,
                   help="Roache's factor of safety of the grid convergence index")
    p.add_argument("--workers", type=int, default=2,
                   help="worker processes of the local Dask cluster (one thread each)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="address of a running Dask scheduler (the workers must share DIR)")
    p.add_argument("--dry-run", action="store_true", help="check and list the grids, run nothing")
    p.add_argument("--no-progress", action="store_true", help="no line per finished grid")
    return p


def run(args) -> int:
    from spinweb_fe.io.folder import check_writable
    from spinweb_fe.sweep import converge, converge_report

    if args.workers < 1:
        raise InputError("--workers", "", f"must be >= 1, got {args.workers}")
    if not args.safety >= 1.0:
        raise InputError("--safety", "", f"must be >= 1, got {args.safety}")
    widths = _floats(args.widths, "--widths") if args.widths else None
    times = _floats(args.times, "--times") if args.times else None
    plan = converge.plan(args.case, args.sets, widths=widths, ratio=args.ratio,
                         levels=args.levels, quick=args.quick, end=args.end, times=times,
                         quantities=args.quantities or None)
    out = Path(args.output) if args.output else Path("out") / (Path(args.case).stem
                                                               + "_converge")
    check_writable(out)
    print(f"{len(plan.members)} grids of {plan.source} ({plan.key}), 0-{plan.end:g} s -> {out}/")
    for m in plan.members:
        print(f"  {m.name}: h = {m.h:.6g} m")
    if args.dry_run:
        print("quantities: " + ", ".join(plan.quantities))
        return 0
    rows = converge.execute(plan, out, scheduler=args.scheduler, workers=args.workers,
                            progress=not args.no_progress)
    result = converge_report.analyse(plan, rows, args.safety)
    paths = converge_report.write(result, out)
    for line in converge_report.lines(result):
        print(line)
    total = sum(g["wall_time_s"] or 0.0 for g in result["grids"])
    n_fail = sum(g["status"] != "ok" for g in result["grids"])
    print(f"{len(rows) - n_fail} of {len(rows)} grids ok ({total:.1f} s of run time); wrote "
          f"{paths['json']}, {paths['csv']}, {paths['png']}")
    return 0
