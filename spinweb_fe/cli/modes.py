"""``spinweb modes CASE``: eigenfrequencies and mode shapes of the case's deployed web (or
straight tethers) spinning steadily at omega, in the co-rotating frame.

The steady state (tension-only cables under the centrifugal load, finite strains, tied nodes
fixed) is found by Newton's method from the flat reference; about it the in-plane
(gyroscopic) and out-of-plane motions are solved separately and the lowest ``--count`` modes
printed and written to DIR/modes.h5, DIR/modes/mode_NNN.vtu and DIR/modes.pvd. With
``--sweep omega=A:B:N`` or ``--sweep tip_mass=A:B:N`` the lowest frequencies are followed over
N values instead: DIR/sweep.csv and DIR/sweep.png. See docs/modes.md.
"""

import logging

from spinweb_fe.cli.common import add_case_args, load_case, out_dir
from spinweb_fe.errors import InputError

log = logging.getLogger(__name__)


def add_parser(sub):
    p = sub.add_parser("modes", help="eigenfrequencies of the spinning deployed web",
                       description=__doc__)
    add_case_args(p, out=True)
    p.add_argument("--omega", type=float, default=None, metavar="RAD_S",
                   help="spin rate [rad/s] (default: initial.omega, or the largest rate of a "
                        "prescribed-rate law for a run that starts at rest)")
    p.add_argument("--hub", choices=("driven", "coasting", "free"), default="driven",
                   help="driven: the hub rate is prescribed (tied nodes fixed in the "
                        "rotating frame); coasting: the hub (inertia hub.inertia) turns on its "
                        "fixed axis with no torque ('free' is the old name of coasting, not "
                        "hub.motion = 'free') (default: driven)")
    p.add_argument("--count", type=int, default=10, metavar="K",
                   help="number of modes, the lowest in- and out-of-plane together "
                        "(default: 10)")
    p.add_argument("--sweep", default=None, metavar="NAME=A:B:N",
                   help="design sweep over N values from A to B of omega [rad/s] or "
                        "tip_mass [kg]: DIR/sweep.csv and DIR/sweep.png")
    return p


def run(args) -> int:
    from spinweb_fe.run import modal as study

    if args.hub == "free":
        log.warning("warning: --hub free is now --hub coasting (a hub turning freely on its "
                    "fixed axis, not the free rigid hub of hub.motion = 'free')")
        args.hub = "coasting"
    if args.count < 1:
        raise InputError("--count", "", f"must be >= 1, got {args.count}")
    sweep = study.parse_sweep(args.sweep) if args.sweep is not None else None
    case = load_case(args)
    swept = sweep is not None and sweep[0] == "omega"
    omega = None if swept else study.spin_rate(case, args.omega)
    folder = out_dir(args, case)
    if sweep is not None:
        return _sweep(case, sweep, omega, args, folder)
    from spinweb_fe.linear.modes_io import (format_modes, format_steady, write_mode_vtus,
                                            write_modes_h5)

    res = study.analyse(case, omega, args.count, args.hub)
    folder.mkdir(parents=True, exist_ok=True)
    print(format_steady(res.structure, res.steady, args.hub))
    print(format_modes(res.modes))
    h5 = write_modes_h5(folder / "modes.h5", case, res.mesh, res.structure, res.steady,
                        res.modes)
    vtus = write_mode_vtus(folder, res.structure, res.steady, res.modes)
    log.info("modes: %s, %d mode shapes in %s", h5, len(vtus), folder / "modes")
    return 0


def _sweep(case, sweep, omega, args, folder):
    from spinweb_fe.run import modal as study
    from spinweb_fe.linear.modes_io import format_sweep, write_sweep_csv
    from spinweb_fe.post.modes_plot import plot_sweep

    name, values = sweep
    unit = study.SWEEP_PARAMS[name][0]
    points = study.sweep(case, name, values, omega, args.count, args.hub)
    folder.mkdir(parents=True, exist_ok=True)
    print(format_sweep(name, unit, points))
    csv_path = write_sweep_csv(folder / "sweep.csv", name, points)
    fixed = (f"tip mass {case.tip_mass.mass:g} kg" if name == "omega"
             else f"omega {omega:.4g} rad/s")
    png = plot_sweep(folder / "sweep.png", name, unit, points,
                     f"{case.title or case.scene}: lowest modes against {name} ({fixed}, "
                     f"hub {args.hub})")
    log.info("sweep: %s, %s", csv_path, png)
    return 0
