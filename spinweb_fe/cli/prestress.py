"""``spinweb prestress CASE``: force-method prestressability of the case's flat web by spin.

The web is built as for a run with the ``flat`` fold and one element per mesh segment
(collinear subdivision nodes would only add trivial mechanisms), the hub-tied nodes are
fixed, and the centrifugal load at ``initial.omega`` (or ``--omega``; for a run that starts
at rest, the spin ramp's ``control.omega_max``) is analysed with
:func:`spinweb_fe.prestress.analyse`. See docs/prestress.md.
"""

from spinweb_fe.cli.common import add_case_args, load_case

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
                   help="spin rate [rad/s] (default: initial.omega, or control.omega_max "
                        "for a run that starts at rest); forces scale with omega^2, the "
                        "verdict does not")
    p.add_argument("--no-hub", action="store_true",
                   help="analyse the web without the hub cut-out (free web, statically "
                        "determinate supports)")
    return p


def _flat_mesh(case, no_hub):
    import dataclasses

    from meshgen.build import build_mesh
    from meshgen.checks import MeshValueError
    from meshgen.flat import flat_web
    from spinweb_fe.errors import InputError

    if not no_hub:
        return build_mesh(dataclasses.replace(
            case, fold=dataclasses.replace(case.fold, pattern="flat")))
    try:
        return flat_web(case.web, case.tip_mass.mass, 0.0)
    except MeshValueError as exc:
        raise InputError(case.source, f"web.{exc.param}", exc.reason) from None


def _spin_rate(case, given):
    """--omega, else initial.omega, else (a run that starts at rest) the spin ramp's
    omega_max; InputError if the load would vanish."""
    from spinweb_fe.errors import InputError

    if given is not None:
        if float(given) == 0.0:
            raise InputError("--omega", "", "must be nonzero: the centrifugal load vanishes")
        return float(given)
    omega = case.initial.omega or (case.control.omega_max or 0.0)
    if omega == 0.0:
        raise InputError(case.source, "initial.omega", "the web starts at rest and no spin "
                         "rate is prescribed: the centrifugal load vanishes; pass --omega")
    return omega


def run(args) -> int:
    from spinweb_fe.errors import InputError
    from spinweb_fe.prestress import analyse

    import dataclasses

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
    mesh = _flat_mesh(case, args.no_hub)
    if mesh.n_elems > MAX_BARS:
        raise InputError(case.source, "web.mesh_width",
                         f"{mesh.n_elems} bars are too many for the dense force method "
                         f"(limit {MAX_BARS}); use --mesh-width with a coarser t")
    omega = _spin_rate(case, args.omega)
    rep = analyse(mesh, omega, line_density)
    w = case.web
    if rep.n_mechanisms == 0:
        stiff = "no mechanism"
    elif rep.mechanisms_stiffened is None:
        stiff = "not computed (load not compatible)"
    else:
        stiff = ("yes" if rep.mechanisms_stiffened else
                 f"NO: {rep.n_neutral} neutral, {rep.n_negative} negative") + (
            f" (smallest eigenvalue {rep.stability_min:.4g} N/m)")
    lo, hi = rep.omega_band
    band = ("-" if not rep.prestressable else "every spin rate (statically determinate "
            "for this load)" if lo == 0 and hi == float("inf") else
            f"{lo * omega:.4g} < omega < {hi * omega:.4g} rad/s if the rest lengths "
            "are tailored at this omega (members go slack outside)")
    note = "" if rep.load_compatible else "  (least squares: not in equilibrium)"
    lines = [
        f"topology            {w.topology} (S = {w.side:g} m, t = {w.mesh_width:g} m, "
        f"corner mass {case.tip_mass.mass:g} kg, omega = {omega:.6g} rad/s)",
        f"supports            {rep.supports}",
        f"nodes               {rep.n_nodes}",
        f"free dof            {rep.n_dof}",
        f"bars                {rep.n_bars}",
        f"rank                {rep.rank}",
        f"self-stress states  {rep.n_selfstress}",
        f"mechanisms          {rep.n_mechanisms}   (b - dof = {rep.maxwell} = s - m)",
        f"load residual       {rep.load_residual:.3e} of |f| = {rep.load_norm:.4g} N "
        f"(worst node {rep.node_residual_max:.3g} of its load)",
        f"method              {rep.method}",
        f"min member force    {rep.min_force:.6g} N{note}",
        f"max member force    {rep.max_force:.6g} N{note}",
        f"compressed members  {rep.n_compressed}",
        f"elastic solution    min {rep.elastic_min_force:.6g} N, max "
        f"{rep.elastic_max_force:.6g} N, {rep.elastic_n_compressed} compressed "
        f"(cables cut stress-free to the flat shape, equal EA)",
        f"mechanisms stiffened {stiff}",
        f"tension holds for   {band}",
        f"verdict             {rep.verdict()}",
    ]
    if rep.capped:
        lines.insert(-1, "note                the LP hit its force bound: a tension-only "
                         "self-stress exists")
    print("\n".join(lines))
    return 0
