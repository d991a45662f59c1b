"""Model (fixed arrays), State (what changes) and the time-step choice.

Model never changes during a run; State holds positions, half-step velocities and the
hub / accumulator vector; Control (spinweb_fe.control) holds the torque law.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from meshgen.mesh import Mesh, lumped_mass
from spinweb_fe import kernels


@dataclass(frozen=True, eq=False)
class Model:
    """Fixed arrays of a run (SI units).

    Attributes
    ----------
    mesh : Mesh
        The mesh the model was built from (reference positions, sets, arm data).
    node_mass : (n,) float64 [kg]
        Lumped cable mass plus point masses (tied nodes included; the hub is not).
    node_inv_mass : (n,) float64 [1/kg]
        1/m for free nodes, 0 for nodes tied to the hub (moved kinematically).
    elem_nodes : (m, 2) int64
    elem_rest_len : (m,) float64 [m]
    elem_ea : (m,) float64 [N]
        Axial stiffness E*A.
    elem_cdamp : (m,) float64 [N s/m]
        Axial damper coefficient zeta * A * sqrt(E rho) (critical for the element mode).
    tied_idx : (k,) int64
        Nodes tied to the hub; ``tied_ref`` (k, 3) [m] their hub-frame positions.
    node_contact : (n,) bool
        Nodes checked for cable-hub contact (all False when the scene has no hub contact).
    hub_radius, hub_inertia, hub_friction : float
        r0 [m], J_hub [kg m^2], Coulomb coefficient.
    j_eff : float [kg m^2]
        Hub inertia plus the tied nodes' m r^2.
    tip_idx : (n_arms,) int64
        The tip (corner) node of each arm.
    wave_speed : float [m/s]
        sqrt(E / rho).
    dt_critical : float [s]
        min L0/c, reduced for damping by sqrt(1 + zeta^2) - zeta.
    """

    mesh: Mesh
    node_mass: np.ndarray
    node_inv_mass: np.ndarray
    elem_nodes: np.ndarray
    elem_rest_len: np.ndarray
    elem_ea: np.ndarray
    elem_cdamp: np.ndarray
    tied_idx: np.ndarray
    tied_ref: np.ndarray
    node_contact: np.ndarray
    hub_radius: float
    hub_inertia: float
    hub_friction: float
    j_eff: float
    tip_idx: np.ndarray
    wave_speed: float
    dt_critical: float

    @property
    def n_nodes(self):
        return len(self.node_mass)

    @property
    def n_elems(self):
        return len(self.elem_nodes)


def build_model(mesh: Mesh, youngs_modulus, density, area, damping_ratio=0.0,
                hub_radius=None, hub_inertia=1.0, hub_friction=0.0, contact=True) -> Model:
    """Assemble a Model from a Mesh and material / hub data (SI units).

    Parameters
    ----------
    contact : bool
        Check cable-hub contact for the free nodes (False, or hub_radius 0, skips it).
    """
    r0 = mesh.hub_radius if hub_radius is None else hub_radius
    rho_line = density * area
    node_mass = lumped_mass(mesh, rho_line)
    tied = np.asarray(mesh.node_sets["hub_tied"], dtype=np.int64)
    inv = np.where(node_mass > 0, 1.0 / np.where(node_mass > 0, node_mass, 1.0), 0.0)
    inv[tied] = 0.0
    tied_ref = np.ascontiguousarray(mesh.node_pos[tied], dtype=np.float64)
    j_eff = hub_inertia + float(np.sum(node_mass[tied] * (tied_ref[:, 0] ** 2 + tied_ref[:, 1] ** 2)))
    node_contact = (inv > 0) & bool(contact and r0 > 0)
    m = mesh.n_elems
    c = math.sqrt(youngs_modulus / density)
    zeta = damping_ratio
    positive = mesh.elem_rest_len[mesh.elem_rest_len > 0]
    dt_crit = float(positive.min() / c) * (math.sqrt(1 + zeta * zeta) - zeta) if m else math.inf
    return Model(
        mesh=mesh, node_mass=node_mass, node_inv_mass=inv,
        elem_nodes=np.ascontiguousarray(mesh.elem_nodes),
        elem_rest_len=np.ascontiguousarray(mesh.elem_rest_len),
        elem_ea=np.full(m, youngs_modulus * area),
        elem_cdamp=np.full(m, zeta * area * math.sqrt(youngs_modulus * density)),
        tied_idx=tied, tied_ref=tied_ref, node_contact=node_contact,
        hub_radius=float(r0), hub_inertia=float(hub_inertia), hub_friction=float(hub_friction),
        j_eff=float(j_eff), tip_idx=np.asarray(mesh.node_sets["tips"], dtype=np.int64),
        wave_speed=c, dt_critical=dt_crit)


def model_from_case(case, mesh: Mesh) -> Model:
    """Model for a validated case and its mesh."""
    cab, hub = case.cable, case.hub
    return build_model(mesh, cab.youngs_modulus, cab.density, cab.area, cab.damping_ratio,
                       hub_radius=hub.radius, hub_inertia=hub.inertia, hub_friction=hub.friction)


@dataclass(eq=False)
class State:
    """Everything that changes: positions x_n (n,3) [m], half-step velocities v_{n-1/2} (n,3)
    [m/s], and ``hub`` (kernels.HUB_STATE_SIZE,): angle, rate, time, torque work, damping and
    contact dissipation, step count, last torque."""

    pos: np.ndarray
    vel: np.ndarray
    hub: np.ndarray

    @property
    def time(self):
        return float(self.hub[kernels.H_TIME])

    @property
    def step(self):
        return int(self.hub[kernels.H_STEP])


def initial_state(model: Model, omega: float, spin: str = "all") -> State:
    """Initial positions from the mesh; rigid spin omega [rad/s] of hub and web ('all') or of
    the hub and tied nodes only ('hub'). Velocities are v_0 (see ``start``)."""
    pos = np.array(model.mesh.node_pos, dtype=np.float64)
    vel = np.zeros_like(pos)
    if spin == "all":
        vel[:, 0] = -omega * pos[:, 1]
        vel[:, 1] = omega * pos[:, 0]
    hub = np.zeros(kernels.HUB_STATE_SIZE)
    hub[kernels.H_OMEGA] = omega
    kernels.place_tied(pos, vel, model.tied_idx, model.tied_ref, 0.0, omega)
    return State(pos, vel, hub)


def choose_dt(model: Model, cfl: float, dt_cap=None, history_dt=None) -> float:
    """cfl * dt_critical, capped by ``dt_cap``, then shortened so that history_dt is a whole
    number of steps (history rows fall exactly on multiples of history_dt)."""
    dt = cfl * model.dt_critical
    if dt_cap:
        dt = min(dt, dt_cap)
    if history_dt:
        dt = history_dt / math.ceil(history_dt / dt * (1 - 1e-12))
    return dt
