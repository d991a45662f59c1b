"""``spinweb plot RESULT.h5 [MORE.h5 ...] -o FIG.png``: four-panel plot (L, phi, omega_centre,
omega_tip: every arm as the band from the least to the largest with their mean, or one arm
with --arm) overlaying the files; ``--panels out_of_plane``: the web's distance from the hub
plane, the tip heights, the hub's tilt and transverse rate; ``--panels verdict``: what the
verdict judged (tip reach and the deployed line, re-coil, slack share, strength
utilisation, swing, the devices' line tension and speed, the energy and momentum audits),
each with its limit and the time it first failed. The title defaults to the cases'."""


def add_parser(sub):
    p = sub.add_parser("plot", help="four-panel plot of result files", description=__doc__)
    p.add_argument("results", nargs="+", help="results.h5 / analytic.h5 files")
    p.add_argument("-o", "--output", required=True, help="figure file (.png, .pdf, .svg)")
    p.add_argument("--arm", type=int, default=None,
                   help="draw this arm only (default: every arm, their spread and mean)")
    p.add_argument("--title", default=None, help="figure title (default: the cases' titles)")
    p.add_argument("--panels", default="arms", choices=("arms", "out_of_plane", "verdict"),
                   help="arms: L, phi, omega_centre, omega_tip; out_of_plane: distance from "
                        "the hub plane, tip heights, hub tilt, hub transverse rate; verdict: "
                        "each criterion's quantity over time, its limit and first failure")
    return p


def run(args) -> int:
    from spinweb_fe.post.plot import four_panel

    four_panel(args.results, args.output, arm=args.arm, title=args.title, panels=args.panels)
    return 0
