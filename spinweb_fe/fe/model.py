"""The Model: the fixed data of a run, grouped by entity as the step kernels take it.

Model never changes during a run; the State (:mod:`spinweb_fe.fe.state`) holds what
changes, the Control (:mod:`spinweb_fe.fe.control`) the hub law. ``Elements``, ``Nodes``
and ``Hub`` are NamedTuples of arrays and scalars that numba compiles and caches; a test
can build them by hand for a 3-node model and call one step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from meshgen.mesh import Mesh, lumped_mass
from spinweb_fe.fe.coil.levels import BUNDLES, Coil, no_coil
from spinweb_fe.fe.forces import Links, make_links
from spinweb_fe.fe.hub.axis import Axis
from spinweb_fe.fe.choice import Choice, Param, registry
from spinweb_fe.fe.hub.rigid import Body
from spinweb_fe.fe.rupture import Strength, no_strength
from spinweb_fe.fe.tidal import Environment, no_environment


NO_BUNDLES = BUNDLES["none"].code


def _nutates(tables):
    if tables["perturbation"]["hub_tilt_rate"] != 0:
        return "perturbation.hub_tilt_rate", ("needs hub.motion = 'free' (a hub on a fixed "
                                              "axis cannot nutate)")
    return None


#: how the hub moves: the step loop's hub kind (:attr:`Model.hub_kind`: fe.hub.axis or fe.hub.body)
MOTIONS = registry(
    Choice("fixed_axis", 0, "the hub turns about +z through the origin (fe.hub.axis); the axis "
                            "holds it in place and reacts the out-of-plane loads",
           check=_nutates, analytic="the analytical model's hub (Eq. 4)"),
    Choice("free", 1, "a rigid body of six degrees of freedom with its tied nodes and held "
                      "coil (fe.hub.body, fe.hub.rigid)",
           keys=(Param("principal_inertia", "kg m^2", "pos", "free hub: principal moments "
                       "[I_x, I_y, I_z] about the hub-frame axes (z the spin axis), instead of "
                       "inertia and inertia_transverse", kind="vector"),)),
)


class Elements(NamedTuple):
    """The cable elements (m of them).

    Attributes
    ----------
    nodes : (m, 2) int64
        End nodes i, j of each element.
    rest_len : (m,) float64 [m]
        Unstretched length L0 (from the flat web).
    inv_rest : (m,) float64 [1/m]
        1 / L0.
    ea : (m,) float64 [N]
        Axial stiffness E A.
    cdamp : (m,) float64 [N s/m]
        Axial damper coefficient zeta A sqrt(E rho) (critical for the element mode).
    damped : bool
        Whether any element has a damper (the undamped loop skips the damper terms).
    """

    nodes: np.ndarray
    rest_len: np.ndarray
    inv_rest: np.ndarray
    ea: np.ndarray
    cdamp: np.ndarray
    damped: bool


class Nodes(NamedTuple):
    """The nodes (n of them).

    Attributes
    ----------
    mass : (n,) float64 [kg]
        Lumped cable mass plus point masses (tied nodes included; the hub is not).
    inv_mass : (n,) float64 [1/kg]
        1/m for free nodes, 0 for nodes moved kinematically (tied to the hub).
    contact : (n,) bool
        Nodes checked for cable-hub contact (all False when the scene has no hub contact).
    """

    mass: np.ndarray
    inv_mass: np.ndarray
    contact: np.ndarray


class Hub(NamedTuple):
    """The rigid hub on a fixed axis (+z) and the nodes tied to it.

    Attributes
    ----------
    radius : float [m]
        r0 (0: no hub surface, no contact).
    friction : float
        Coulomb coefficient of cable-hub contact.
    inertia : float [kg m^2]
        J_hub about the axis.
    j_eff : float [kg m^2]
        J_hub plus the tied nodes' m r^2.
    transverse : float [kg m^2]
        The hub's own moment about an axis in its plane (axisymmetric: the tidal torque a
        fixed axis reacts).
    tied_idx : (k,) int64
        Nodes tied to the hub.
    tied_ref : (k, 3) float64 [m]
        Their hub-frame positions.
    """

    radius: float
    friction: float
    inertia: float
    j_eff: float
    transverse: float
    tied_idx: np.ndarray
    tied_ref: np.ndarray


class Kernel(NamedTuple):
    """What the step kernels see of a Model (``Model.kernel``; its hub kind apart,
    ``Model.hub_kind``)."""

    elements: Elements
    links: Links
    nodes: Nodes
    hub: Hub
    coil: Coil
    bundles: object  # the coil when it has bundles, else None (numba compiles none of them)
    devices: object  # the coil when it has reels or brakes (fe.coil.payout), else None
    strength: Strength
    env: Environment


@dataclass(frozen=True, eq=False)
class Model:
    """Fixed data of a run (SI units).

    Attributes
    ----------
    mesh : Mesh
        The mesh the model was built from (reference positions, sets, arm data).
    elements : Elements
    links : spinweb_fe.fe.forces.Links
        Which nodes each element joins and which elements each node has (the force passes'
        incidence, from ``elements.nodes``).
    nodes : Nodes
    hub : Hub
    coil : Coil
        The stowed coil's levels and release laws (no levels: nothing is held).
    tip_idx : (n_arms,) int64
        The tip (corner) node of each arm.
    wave_speed : float [m/s]
        Largest element wave speed sqrt(E A / mu) (sqrt(E / rho) for a uniform cable).
    dt_critical : float [s]
        min over the elements of L0 / sqrt(E A / mu), reduced for damping by
        sqrt(1 + zeta^2) - zeta.
    strength : Strength
        Failure strain per element and rupture (fe.rupture; empty: no strength check).
    body : Body or None
        The hub as a free rigid body (fe.hub.rigid; None: the hub turns about a fixed axis).
    env : Environment
        The gravity gradient (fe.tidal; mean motion 0: none).
    """

    mesh: Mesh
    elements: Elements
    links: Links
    nodes: Nodes
    hub: Hub
    coil: Coil
    tip_idx: np.ndarray
    wave_speed: float
    dt_critical: float
    strength: Strength = field(default_factory=no_strength)
    body: Body | None = None
    env: Environment = field(default_factory=no_environment)

    @property
    def kernel(self) -> Kernel:
        """The arrays of the step kernels, grouped by entity."""
        # the strength data even when empty (no failure strain: the element pass is chosen at
        # run time, fe.step.element_pass): the strength pass costs a scene without it a few
        # seconds of one cold compile, and a scene with and one without it share one loop
        # (every shipped case has a failure strain; the test suite's loops fell from 17 to 12)
        strength = self.strength
        bundles = self.coil if self.coil.bundle_code != NO_BUNDLES else None
        devices = self.coil if self.coil.device else None
        return Kernel(self.elements, self.links, self.nodes, self.hub, self.coil, bundles,
                      devices, strength, self.env)

    @property
    def hub_kind(self) -> tuple:
        """(axis, body): the hub as the step loop takes it, exactly one of them None:
        fe.hub.axis.Axis on a fixed axis, or the free hub's fe.hub.rigid.Body. The loop's phases are
        chosen by these types (fe.step)."""
        return (Axis(self.hub.j_eff), None) if self.body is None else (None, self.body)

    @property
    def free_hub(self) -> bool:
        """The hub is a free rigid body (fe.hub.body), not on a fixed axis (fe.hub.axis)."""
        return self.body is not None

    @property
    def n_nodes(self) -> int:
        return len(self.nodes.mass)

    @property
    def n_elems(self) -> int:
        return len(self.elements.nodes)


def make_hub(radius, friction, inertia, node_mass, tied_idx, tied_ref, transverse=None) -> Hub:
    """A Hub whose effective inertia counts the tied nodes (J_hub + sum m (x^2 + y^2));
    ``transverse`` [kg m^2] defaults to J_hub / 2 (a thin ring)."""
    tied_idx = np.asarray(tied_idx, dtype=np.int64)
    tied_ref = np.ascontiguousarray(tied_ref, dtype=np.float64).reshape(-1, 3)
    j_eff = inertia + float(np.sum(node_mass[tied_idx]
                                   * (tied_ref[:, 0] ** 2 + tied_ref[:, 1] ** 2)))
    transverse = 0.5 * inertia if transverse is None else transverse
    return Hub(float(radius), float(friction), float(inertia), float(j_eff), float(transverse),
               tied_idx, tied_ref)


def build_model(mesh: Mesh, youngs_modulus, density, area, damping_ratio=0.0,
                hub_radius=None, hub_inertia=1.0, hub_friction=0.0, contact=True,
                line_density=None, hub_transverse=None) -> Model:
    """Assemble a Model from a Mesh and material / hub data (SI units).

    Parameters
    ----------
    mesh : Mesh
    youngs_modulus, density, area : float [Pa], [kg/m^3], [m^2]
    damping_ratio : float
        Axial damping, fraction of critical.
    hub_radius : float or None [m]
        r0 (default the mesh's).
    hub_inertia : float [kg m^2]
    hub_friction : float
    hub_transverse : float or None [kg m^2]
        The hub's moment about an axis in its plane (default hub_inertia / 2).
    contact : bool
        Check cable-hub contact for the free nodes (False, or hub_radius 0, skips it).
    line_density : (m,) float64 or None [kg/m]
        Cable mass per length of each element (default density * area everywhere); each
        element's wave speed sqrt(E A / mu) and damper sqrt(E A mu) follow it.
    """
    r0 = mesh.hub_radius if hub_radius is None else hub_radius
    m = mesh.n_elems
    uniform = line_density is None
    mu = density * area if uniform else np.asarray(line_density, np.float64)
    node_mass = lumped_mass(mesh, mu)
    tied = np.asarray(mesh.node_sets["hub_tied"], dtype=np.int64)
    inv = np.where(node_mass > 0, 1.0 / np.where(node_mass > 0, node_mass, 1.0), 0.0)
    inv[tied] = 0.0
    hub = make_hub(r0, hub_friction, hub_inertia, node_mass, tied, mesh.node_pos[tied],
                   hub_transverse)
    zeta = damping_ratio
    rest = np.ascontiguousarray(mesh.elem_rest_len)
    if uniform:  # one cable: the closed forms, as before per-element data existed
        c = math.sqrt(youngs_modulus / density)
        positive = rest[rest > 0]
        dt_crit = float(positive.min() / c) if m else math.inf
        cdamp = np.full(m, zeta * area * math.sqrt(youngs_modulus * density))
    else:
        speed = np.sqrt(youngs_modulus * area / mu)
        c = float(speed.max()) if m else 0.0
        dt_crit = float(np.min(rest / speed)) if m else math.inf
        cdamp = zeta * np.sqrt(youngs_modulus * area * mu)
    dt_crit *= math.sqrt(1 + zeta * zeta) - zeta
    elements = Elements(np.ascontiguousarray(mesh.elem_nodes), rest, 1.0 / rest,
                        np.full(m, youngs_modulus * area), cdamp, bool(np.any(cdamp > 0.0)))
    nodes = Nodes(node_mass, inv, (inv > 0) & bool(contact and r0 > 0))
    return Model(mesh=mesh, elements=elements, links=make_links(elements.nodes, len(node_mass)),
                 nodes=nodes, hub=hub, coil=no_coil(mesh.n_arms),
                 tip_idx=np.asarray(mesh.node_sets["tips"], dtype=np.int64),
                 wave_speed=c, dt_critical=dt_crit)


def choose_dt(model: Model, cfl: float, dt_cap=None, history_dt=None) -> float:
    """cfl * dt_critical, capped by ``dt_cap``, then shortened so that history_dt is a whole
    number of steps (history rows fall exactly on multiples of history_dt)."""
    dt = cfl * model.dt_critical
    if dt_cap:
        dt = min(dt, dt_cap)
    if history_dt:
        dt = history_dt / math.ceil(history_dt / dt * (1 - 1e-12))
    return dt
