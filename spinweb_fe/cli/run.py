"""``spinweb run CASE``: explicit FE run -> DIR/results.h5, DIR/web.pvd + DIR/frames/*.vtu.

``--checkpoint-dt T`` also writes DIR/checkpoint.h5 every T seconds of simulated time (and
at the end, and when stopped by SIGINT / SIGTERM); ``spinweb run --restart DIR`` continues
that run bit-identically (``--set time.end=...`` to run further). See docs/robustness.md.
"""

import logging
import math

from spinweb_fe.cli.common import load_case, out_dir
from spinweb_fe.errors import InputError

log = logging.getLogger(__name__)


def add_parser(sub):
    p = sub.add_parser("run", help="explicit FE run of a case", description=__doc__)
    p.add_argument("case", nargs="?", default=None,
                   help="case file (TOML, SI units); omitted with --restart")
    p.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                   help="override a case key, TOML value syntax, e.g. --set time.end=0.5")
    p.add_argument("-o", "--output", default=None, metavar="DIR",
                   help="result folder (default: output.directory or out/<case stem>)")
    p.add_argument("--no-progress", action="store_true",
                   help="no progress bar (it is off anyway when stderr is not a terminal)")
    p.add_argument("--checkpoint-dt", type=float, default=None, metavar="T",
                   help="write DIR/checkpoint.h5 every T s of simulated time [s] "
                        "(default: none; on --restart: the checkpoint's interval)")
    p.add_argument("--threads", type=int, default=None, metavar="N",
                   help="threads of the step loop (default: $SPINWEB_THREADS, else 2 for "
                        "large webs, 1 otherwise; on --restart: the checkpoint's)")
    p.add_argument("--force", action="store_true",
                   help="run even if the estimate exceeds the budget (a day of wall time, "
                        "80 %% of the memory, the free disk space; docs/robustness.md)")
    p.add_argument("--restart", default=None, metavar="DIR",
                   help="continue the run in DIR from DIR/checkpoint.h5 (only time.end may "
                        "be changed with --set)")
    return p


def run(args) -> int:
    ck_dt = getattr(args, "checkpoint_dt", None)
    if ck_dt is not None and not (math.isfinite(ck_dt) and ck_dt > 0):
        raise InputError("--checkpoint-dt", "", f"must be a finite time > 0 s, got {ck_dt:g}")
    threads = getattr(args, "threads", None)
    if threads is not None and threads < 1:
        raise InputError("--threads", "", f"must be >= 1, got {threads}")
    restart = getattr(args, "restart", None)
    if restart is not None:
        if args.case is not None or args.output is not None:
            raise InputError("--restart", "", "give either CASE [-o DIR] or --restart DIR, "
                             "not both (the case and the folder come from the checkpoint)")
        from spinweb_fe.run.restart import restart_case

        res = restart_case(restart, args.sets, progress=not args.no_progress,
                           checkpoint_dt=ck_dt, threads=threads, force=args.force)
        log.info("continued %s to t = %.6g s (%d more history rows, %d frames)",
                 restart, float(res.state.time[0]), len(res.history["time"]), res.frames)
        return 0
    if args.case is None:
        raise InputError("spinweb run", "", "a case file is required (or --restart DIR)")
    case = load_case(args)
    directory = out_dir(args, case)
    from spinweb_fe.run.driver import run_case

    res = run_case(case, directory, progress=not args.no_progress, checkpoint_dt=ck_dt or 0.0,
                   threads=threads, force=args.force)
    log.info("wrote %s (%d history rows, %d frames)", directory / "results.h5",
             len(res.history["time"]), res.frames)
    return 0
