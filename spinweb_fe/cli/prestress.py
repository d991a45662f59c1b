"""``spinweb prestress CASE``: force-method prestressability of the case's flat web by spin.

The web is built as for a run with the ``flat`` fold and one element per mesh segment
(collinear subdivision nodes would only add trivial mechanisms), the hub-tied nodes are
fixed, and the centrifugal load at ``initial.omega`` (or ``--omega``; for a run that starts
at rest, the final rate of a prescribed-rate law such as the spin ramp) is analysed with
:func:`spinweb_fe.linear.prestress.analyse`. See docs/prestress.md.
"""

import dataclasses

from spinweb_fe.cli.common import add_case_args, load_case
from spinweb_fe.errors import InputError

#: above this many bars the dense SVD gets slow (minutes) and memory-hungry
MAX_BARS = 8000


def add_parser(sub):
    p = sub.add_parser("prestress", help="force-method prestressability of the flat web",
                       description=__doc__)
    add_case_args(p, out=False)
    p.add_argument("--mesh-width", type=float, default=None, metavar="W",
                   help="mesh width t [m] for the analysis (default: web.mesh_width); "
                        "a coarse mesh keeps the dense SVD fast; the cable mass per "
                        "length is scaled by W/t to keep the web's areal density")
    p.add_argument("--omega", type=float, default=None, metavar="RAD_S",
                   help="spin rate [rad/s] (default: initial.omega, or the final rate of a "
                        "prescribed-rate law for a run that starts at rest); forces scale "
                        "with omega^2, the verdict does not")
    p.add_argument("--no-hub", action="store_true",
                   help="analyse the web without the hub cut-out (free web, statically "
                        "determinate supports)")
    return p


def _flat_mesh(case, no_hub):
    from meshgen.build import flat_web
    from meshgen.checks import MeshValueError
    from spinweb_fe.case.scene import build_mesh

    if not no_hub:
        return build_mesh(dataclasses.replace(
            case, fold=dataclasses.replace(case.fold, pattern="flat")))
    w = case.web
    try:
        return flat_web(w.topology, w.side, w.mesh_width, w.elements_per_segment,
                        case.tip_mass.mass, 0.0)
    except MeshValueError as exc:
        raise InputError(case.source, f"web.{exc.param}", exc.reason) from None


def run(args) -> int:
    from spinweb_fe.linear.prestress import analyse, format_report

    case = load_case(args)
    if case.scene != "web":
        raise InputError(case.source, "tethers", "tethers scene has no web to prestress")
    t_case = case.web.mesh_width
    t = t_case if args.mesh_width is None else float(args.mesh_width)
    if not 0 < t <= case.web.side / 2:
        raise InputError("--mesh-width", "", f"must be in (0, side/2 = "
                         f"{case.web.side / 2:g}] m, got {t:g}")
    case = dataclasses.replace(case, web=dataclasses.replace(
        case.web, mesh_width=t, elements_per_segment=1))
    # same areal density on the analysis mesh: cable length per area goes as 1/t
    line_density = case.cable.density * case.cable.area * t / t_case
    given = args.mesh_width is not None  # the analysis mesh is then --mesh-width's
    try:
        mesh = _flat_mesh(case, args.no_hub)
    except InputError as exc:
        if given and exc.key == "web.mesh_width":
            raise InputError("--mesh-width", "", exc.reason) from None
        raise
    if mesh.n_elems > MAX_BARS:
        raise InputError(*(("--mesh-width", "") if given else (case.source, "web.mesh_width")),
                         f"{mesh.n_elems} bars are too many for the dense force method "
                         f"(limit {MAX_BARS}); use --mesh-width with a coarser t")
    from spinweb_fe.case.scene import spin_rate

    omega = spin_rate(case, args.omega)
    rep = analyse(mesh, omega, line_density)
    w = case.web
    title = (f"{w.topology} (S = {w.side:g} m, t = {w.mesh_width:g} m, "
             f"corner mass {case.tip_mass.mass:g} kg, omega = {omega:.6g} rad/s)")
    print(format_report(rep, title, omega))
    return 0
