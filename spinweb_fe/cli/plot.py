"""``spinweb plot RESULT.h5 [MORE.h5 ...] -o FIG.png``: four-panel plot (L, phi, omega_centre,
omega_tip) overlaying the files."""


def add_parser(sub):
    p = sub.add_parser("plot", help="four-panel plot of result files", description=__doc__)
    p.add_argument("results", nargs="+", help="results.h5 / analytic.h5 files")
    p.add_argument("-o", "--output", required=True, help="figure file (.png, .pdf, .svg)")
    p.add_argument("--arm", type=int, default=0, help="which arm to draw")
    p.add_argument("--title", default=None)
    return p


def run(args) -> int:
    from spinweb_fe.post.plot import four_panel

    four_panel(args.results, args.output, arm=args.arm, title=args.title)
    return 0
