"""``spinweb run CASE``: explicit FE run -> DIR/results.h5, DIR/web.pvd + DIR/frames/*.vtu."""

import logging

from spinweb_fe.cli.common import add_case_args, load_case, out_dir

log = logging.getLogger("spinweb")


def add_parser(sub):
    p = sub.add_parser("run", help="explicit FE run of a case", description=__doc__)
    add_case_args(p)
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    return p


def run(args) -> int:
    case = load_case(args)
    directory = out_dir(args, case)
    from spinweb_fe.solver import run_case

    res = run_case(case, directory, progress=not args.no_progress)
    log.info("wrote %s (%d history rows, %d frames)", directory / "results.h5",
             len(res.history["time"]), res.frames)
    return 0
