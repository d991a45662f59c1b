"""A validated case -> the scene of a run: mesh, model, control, initial state and step.

This is where case keys meet the generators and the solver's data: generator errors are
mapped back to the case key at fault (InputError, exit code 2), and derived values that
valid-looking extremes (1e-300, 1e300) can break are checked before anything runs.
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from meshgen.build import web_mesh
from meshgen.checks import MeshValueError, check_mesh
from meshgen.mesh import Mesh
from meshgen.tethers import tethers
from spinweb_fe.case.perturb import (RANDOM, SHAPES, TILT, mode_field, perturbed,
                                     random_field)
from spinweb_fe.errors import InputError, RunError
from spinweb_fe.fe.coil.levels import BUNDLES, COILS
from spinweb_fe.fe.coil.build import build_coil
from spinweb_fe.fe.control import Control, make_control
from spinweb_fe.fe.model import MOTIONS, Model, Nodes, build_model, choose_dt
from spinweb_fe.fe.coil.payout import PAYOUTS, payout_table
from spinweb_fe.fe.hub.rigid import make_body
from spinweb_fe.fe.rupture import make_strength
from spinweb_fe.fe.state import State, initial_state
from spinweb_fe.fe.tidal import R_EARTH, orbit

MAX_STEPS = 1e10  # more steps than this is a units slip (days of run time), not a case
NO_SPIN = "a cable net without spin has no out-of-plane stiffness (the tension vanishes)"

# generator parameter -> case key, per scene
_WEB_KEYS = {"side": "web.side", "mesh_width": "web.mesh_width",
             "elements_per_segment": "web.elements_per_segment",
             "hub_cutout": "web.hub_cutout", "hub_radius": "hub.radius",
             "topology": "web.topology", "pattern": "fold.pattern", "wrap": "fold.wrap",
             "ties": "fold.ties", "corner_mass": "tip_mass.mass", "layer_gap": "fold.layer_gap"}
_TETHER_KEYS = {"count": "tethers.count", "length": "tethers.length",
                "elements": "tethers.elements", "hub_radius": "hub.radius",
                "tip_mass": "tip_mass.mass", "pattern": "fold.pattern", "wrap": "fold.wrap",
                "layer_gap": "fold.layer_gap"}


class Scene(NamedTuple):
    """Everything a run starts from (no output yet)."""

    mesh: Mesh
    model: Model
    control: Control
    state: State
    dt: float


def build_mesh(case) -> Mesh:
    """Initial mesh of a case (see :func:`meshgen.build.web_mesh`, :func:`meshgen.tethers.tethers`).

    Raises
    ------
    InputError
        If a generator rejects the case (key named) or the mesh violates an invariant of
        :func:`meshgen.checks.check_mesh`.
    """
    keys = _WEB_KEYS if case.scene == "web" else _TETHER_KEYS
    try:
        if case.scene == "web":
            w, f = case.web, case.fold
            mesh = web_mesh(w.topology, w.side, w.mesh_width, w.elements_per_segment,
                            case.tip_mass.mass, case.hub.radius, w.hub_cutout, f.pattern,
                            f.wrap, f.ties, f.layer_gap)
        else:
            t = case.tethers
            mesh = tethers(t.count, t.length, t.elements, case.hub.radius, case.tip_mass.mass,
                           case.fold.pattern, case.fold.wrap, case.fold.layer_gap)
    except MeshValueError as exc:
        raise InputError(case.source, keys.get(exc.param, case.scene), exc.reason) from None
    problems = check_mesh(mesh)
    if problems:
        raise InputError(case.source, case.scene, "invalid mesh: " + "; ".join(problems))
    return mesh


def eq7_line_density(mesh: Mesh, arm_mass: float) -> np.ndarray:
    """(m,) line density [kg/m] of tethers carrying ``arm_mass`` each as the paper's Eq. 7,
    rho_L(s) = 2 m (H - s) / H^2: each element's mean over its length, (2 m / H^2)(H - s_mid),
    so the lumped masses hold the profile's exact element masses."""
    s = mesh.node_arm_coord[mesh.elem_nodes].mean(axis=1)
    H = mesh.arm_length
    return 2.0 * arm_mass * (H - s) / (H * H)


def model_from_case(case, mesh: Mesh) -> Model:
    """Model for a validated case and its mesh (with its stowed coil, its cable strength, a
    free hub, the gravity gradient and an arm's scaled tip mass, if any)."""
    cab, hub, pert = case.cable, case.hub, case.perturbation
    arm_mass = case.tethers.arm_mass if case.scene == "tethers" else None
    line_density = None if arm_mass is None else eq7_line_density(mesh, arm_mass)
    model = build_model(mesh, cab.youngs_modulus, cab.density, cab.area, cab.damping_ratio,
                        hub_radius=hub.radius, hub_inertia=hub.inertia,
                        hub_friction=hub.friction, hub_transverse=hub.inertia_transverse,
                        line_density=line_density)
    _check_arm(case, mesh)
    if pert.tip_mass_scale != 1.0:
        model = _scale_tip(model, mesh, pert.arm, pert.tip_mass_scale)
    if cab.failure_strain is not None:
        model = dataclasses.replace(model, strength=make_strength(
            mesh.n_elems, cab.failure_strain, cab.rupture))
    if MOTIONS[hub.motion].code == MOTIONS["free"].code:
        principal = hub.principal_inertia or (hub.inertia_transverse, hub.inertia_transverse,
                                              hub.inertia)
        model = dataclasses.replace(model, body=make_body(hub.mass, principal))
    env = case.environment
    if env.gravity_gradient:
        radius = env.orbit_radius if env.orbit_radius is not None else R_EARTH + env.altitude
        model = dataclasses.replace(model, env=orbit(radius, env.orbit_tilt))
    st = case.stowage
    if st.coil is None or (st.coil == "loose" and st.bundle == "none"):
        return model  # nothing to hold or bundle: the kernels skip the coil
    hold = None
    if pert.delay > 0:
        hold = np.zeros(mesh.n_arms)
        hold[pert.arm] = pert.delay
    mu = cab.density * cab.area if line_density is None else line_density
    coil = build_coil(mesh, model.elements.nodes, model.nodes.mass, COILS[st.coil].code,
                      (PAYOUTS[st.payout].code, payout_table(dataclasses.asdict(st))),
                      (BUNDLES[st.bundle].code, st.bundle_release or 0.0), hold,
                      elem_mass=mu * model.elements.rest_len)
    return dataclasses.replace(model, coil=coil)


def _check_arm(case, mesh: Mesh):
    """[perturbation] arm names an arm of the scene (when a key uses it)."""
    p = case.perturbation
    if (p.tip_mass_scale != 1.0 or p.delay > 0) and not p.arm < mesh.n_arms:
        raise InputError(case.source, "perturbation.arm", f"arm {p.arm} does not exist: the "
                         f"scene has {mesh.n_arms} arms (0 to {mesh.n_arms - 1})")


def _scale_tip(model: Model, mesh: Mesh, arm: int, scale: float) -> Model:
    """The model with arm ``arm``'s tip (corner) point mass times ``scale``."""
    tips = np.asarray(mesh.node_sets["tips"], np.int64)
    tip = tips[mesh.node_arm[tips] == arm] if len(mesh.node_arm) else tips[arm:arm + 1]
    mass = model.nodes.mass.copy()
    mass[tip] += (scale - 1.0) * mesh.node_point_mass[tip]
    inv = np.where(model.nodes.inv_mass > 0, 1.0 / mass, 0.0)
    return dataclasses.replace(model, nodes=Nodes(mass, inv, model.nodes.contact))


def deployed(case):
    """The deployed (flat) web or straight tethers of a case: (mesh, Structure of
    :mod:`spinweb_fe.linear.steady`).

    The fold is replaced by ``flat`` (webs) or ``straight`` (tethers) and the stowage by
    none, so that the mesh and model are the case's flat reference with its hub ties.
    """
    # imported here: linear/ needs scipy.sparse, 0.15-0.25 s of start-up that a run does not use
    from spinweb_fe.linear.steady import structure_from_model

    pattern = "flat" if case.scene == "web" else "straight"
    stowage = dataclasses.replace(case.stowage, **{k: None for k in
                                                   case.stowage.__dataclass_fields__})
    flat = dataclasses.replace(case, fold=dataclasses.replace(case.fold, pattern=pattern),
                               stowage=stowage)
    mesh = build_mesh(flat)
    model = model_from_case(flat, mesh)
    if not (np.all(np.isfinite(model.nodes.mass)) and np.all(np.isfinite(model.elements.ea))):
        raise InputError(case.source, "cable", "node masses or E A are not finite")
    return mesh, structure_from_model(model)


def spin_rate(case, given=None) -> float:
    """The spin rate [rad/s]: ``given``, else ``initial.omega``, else (a run that starts at
    rest) the largest rate of a prescribed-rate law such as the spin ramp.

    Raises
    ------
    InputError
        If the rate is zero (or not finite).
    """
    if given is not None:
        if not (math.isfinite(float(given)) and float(given) != 0.0):
            raise InputError("--omega", "", f"must be finite and nonzero, got {given}: {NO_SPIN}")
        return float(given)
    omega = case.initial.omega
    control = control_from_case(case)
    if omega == 0.0 and control.law.prescribes_rate:
        times = [*control.law.breaks(control.params), case.time.end]
        omega = max((control.law.rate(control.params, t)[0] for t in times), key=abs)
    if omega == 0.0:
        raise InputError(case.source, "initial.omega", f"is 0 and no spin rate is prescribed: "
                         f"{NO_SPIN}; pass --omega")
    return float(omega)


def control_from_case(case) -> Control:
    """The case's [control] table as a Control (the loader has checked the law's keys)."""
    c = case.control
    law_keys = {k: getattr(c, k) for k in c.__dataclass_fields__ if k != "law"}
    return make_control(c.law, {k: v for k, v in law_keys.items() if v is not None})


def prepare(case) -> Scene:
    """Mesh, model, control, initial state and dt of a case (no output)."""
    mesh = build_mesh(case)
    model = model_from_case(case, mesh)
    control = control_from_case(case)
    omega0 = case.initial.omega
    if control.law.prescribes_rate:
        _, w_law = control.torque_or_rate(0.0, omega0)
        if abs(w_law - omega0) > 1e-12 * max(1.0, abs(omega0)):
            raise InputError(case.source, "initial.omega",
                             f"must equal the prescribed hub rate at t = 0 ({w_law:g} rad/s) "
                             f"for control.law = '{control.law.name}'")
    _check_model(case, model)
    dt = choose_dt(model, case.time.cfl, case.time.dt, case.output.history_dt)

    def start(m):
        state = initial_state(m, omega0, case.initial.spin, case.perturbation.hub_tilt_rate)
        if case.initial.state == "steady":
            steady_start(case, m, state, dt)
        return state
    model, state = perturbed(case, model, start, _perturbation_field(case, mesh, model))
    n_steps = case.time.end / dt
    if not n_steps <= MAX_STEPS:
        raise InputError(case.source, "time.end", f"needs {n_steps:.3g} steps of {dt:.3g} s, "
                         f"more than the limit {MAX_STEPS:.0e} (check time.dt and the cable)")
    return Scene(mesh, model, control, state, dt)


def steady_start(case, model: Model, state: State, dt: float):
    """The state at the steady spinning equilibrium of the deployed scene (linear.steady),
    turning at initial.omega as the central differences turn it: the equilibrium solved at
    2 sin(omega dt / 2) / dt and the velocities sin(omega dt) / dt about the axis, so that
    x_n = R(n omega dt) x_0 is the scheme's own solution (the strains stay to round-off)."""
    # imported here: linear/ needs scipy.sparse, start-up time a run without it does not use
    from spinweb_fe.linear.steady import solve_steady, structure_from_model

    omega = case.initial.omega
    phi = omega * dt
    try:
        st = solve_steady(structure_from_model(model), 2.0 * math.sin(0.5 * phi) / dt)
    except RunError as exc:
        raise InputError(case.source, "initial.state", f"'steady': {exc}") from None
    pos, vel = state.node_pos, state.node_vel
    pos[:, :2] = st.position[:, :2]
    rate = math.sin(phi) / dt
    vel[:, 0] = -rate * pos[:, 1]
    vel[:, 1] = rate * pos[:, 0]
    vel[:, 2] = 0.0


def _perturbation_field(case, mesh: Mesh, model: Model):
    """The shape w (n,) of a ``random`` or ``mode`` perturbation (None: tilt, or none)."""
    p = case.perturbation
    code = SHAPES[p.shape].code
    if code == TILT or (p.z_amplitude == 0 and p.vz_amplitude == 0):
        return None
    if code == RANDOM:
        return random_field(mesh.node_ref, model.hub.tied_idx, p.seed)
    try:
        return mode_field(deployed(case)[1], spin_rate(case))
    except RunError as exc:
        raise InputError(case.source, "perturbation.shape", f"'mode': {exc}") from None


def _check_model(case, model):
    """Derived values that valid-looking extremes (1e-300, 1e300) can break: InputError."""
    src = case.source
    mass = model.nodes.mass
    el = model.elements
    if not (np.all(np.isfinite(mass)) and np.all(mass[el.nodes] > 0)):
        raise InputError(src, "cable.density", "gives node masses that are zero or not finite "
                         "(check cable.density and cable.area)")
    if not np.all(np.isfinite(el.ea)) or not np.all(np.isfinite(el.cdamp)):
        raise InputError(src, "cable.youngs_modulus", "E * A (or the damper) is not finite")
    if not 0 < model.dt_critical < math.inf:
        raise InputError(src, "cable", f"the critical time step is {model.dt_critical:g} s "
                         "(check cable.youngs_modulus and cable.density)")
    if not 0 < model.hub.j_eff < math.inf:
        raise InputError(src, "hub.inertia",
                         f"the hub's effective inertia is {model.hub.j_eff:g} kg m^2")
