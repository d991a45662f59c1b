"""``spinweb plot RESULT.h5 [MORE.h5 ...] -o FIG.png``: four-panel plot (L, phi, omega_centre,
omega_tip) overlaying the files; ``--panels out_of_plane``: the web's distance from the hub
plane, the tip heights, the hub's tilt and transverse rate."""


def add_parser(sub):
    p = sub.add_parser("plot", help="four-panel plot of result files", description=__doc__)
    p.add_argument("results", nargs="+", help="results.h5 / analytic.h5 files")
    p.add_argument("-o", "--output", required=True, help="figure file (.png, .pdf, .svg)")
    p.add_argument("--arm", type=int, default=0, help="which arm to draw")
    p.add_argument("--title", default=None)
    p.add_argument("--panels", default="arms", choices=("arms", "out_of_plane"),
                   help="arms: L, phi, omega_centre, omega_tip; out_of_plane: distance from "
                        "the hub plane, tip heights, hub tilt, hub transverse rate")
    return p


def run(args) -> int:
    from spinweb_fe.post.plot import four_panel

    four_panel(args.results, args.output, arm=args.arm, title=args.title, panels=args.panels)
    return 0
