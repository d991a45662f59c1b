"""The State: everything that changes during a run, as named arrays the kernels update in
place. Scalars are 1-element arrays so that numba can write them."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from spinweb_fe.fe.coil.devices import axis_pose, body_pose
from spinweb_fe.fe.hub.axis import place_rigid
from spinweb_fe.fe.coil.levels import CoilState, coil_start, held_inertia, level_masses, place_held
from spinweb_fe.fe.layout import STEP_TERMS
from spinweb_fe.fe.coil.payout import locate_devices, start_devices
from spinweb_fe.fe.hub.rigid import RigidState, place_body, rigid_start
from spinweb_fe.fe.rupture import StrengthState, no_strength, strength_start


class HubState(NamedTuple):
    """Hub motion about its fixed axis (+z); for a free hub (``State.rigid``) the same
    quantities about its body axis.

    Attributes
    ----------
    angle : (1,) float64 [rad]
        theta_n, counter-clockwise positive (free hub: its turn about its own axis,
        2 atan2(q_z, q_w), continued in time).
    rate : (1,) float64 [rad/s]
        omega_{n-1/2} (omega_0 before the run starts; free hub: the body-axis rate).
    inertia : (1,) float64 [kg m^2]
        Effective inertia now: the hub, the tied nodes and the held coil, sum m r^2 (free
        hub: the body's moment about its axis).
    """

    angle: np.ndarray
    rate: np.ndarray
    inertia: np.ndarray


#: checkpoints before the energy table (fe.layout) held each term as ``totals/<name>``
_OLD_TOTALS = {"torque_work": "torque_work", "damping_dissipation": "damping_dissipation",
               "contact_dissipation": "contact_dissipation",
               "gravity_gradient_work": "gravity_work"}


def no_totals() -> np.ndarray:
    """The energy terms at the start: (len(fe.layout.STEP_TERMS),) zeros [J]."""
    return np.zeros(len(STEP_TERMS))


class State(NamedTuple):
    """Positions, half-step velocities, active masses, hub and coil state, totals, step.

    Attributes
    ----------
    node_pos : (n, 3) float64 [m]
        x_n.
    node_vel : (n, 3) float64 [m/s]
        v_{n-1/2} (v_0 before the run starts, see ``run.loop.start``).
    node_mass, node_inv_mass : (n,) float64 [kg], [1/kg]
        The masses the node update uses now: the model's for a free node, 0 for a node that
        moves with the hub (tied, held) or with its bundle, a bundle's mass on its spine node.
    hub : HubState
    coil : spinweb_fe.fe.coil.levels.CoilState
    totals : (len(fe.layout.STEP_TERMS),) float64 [J]
        Each energy term of the step (fe.layout.STEP_TERMS) accumulated up to t_n.
    step : (1,) int64
        n.
    time : (1,) float64 [s]
        t_n = n dt.
    strength : spinweb_fe.fe.rupture.StrengthState
        Broken elements, the strain peak since the last row, the rupture dissipation.
    rigid : spinweb_fe.fe.hub.rigid.RigidState or None
        The free hub's body (None for a hub on a fixed axis).
    """

    node_pos: np.ndarray
    node_vel: np.ndarray
    node_mass: np.ndarray
    node_inv_mass: np.ndarray
    hub: HubState
    coil: CoilState
    totals: np.ndarray
    step: np.ndarray
    time: np.ndarray
    strength: StrengthState
    rigid: RigidState | None

    def copy(self) -> "State":
        """A deep copy (every array copied)."""
        return from_arrays({k: v.copy() for k, v in to_arrays(self).items()})


def to_arrays(state: State) -> dict:
    """Flat {name: array} view of a State (names like 'hub/rate'), for checkpoints."""
    out = {}
    for name, value in zip(State._fields, state):
        if value is None:
            continue
        if isinstance(value, tuple):
            out.update({f"{name}/{k}": v for k, v in zip(value._fields, value)})
        else:
            out[name] = value
    return out


def from_arrays(arrays: dict) -> State:
    """Inverse of :func:`to_arrays` (KeyError names a missing field). Arrays without the
    strength fields (written before they existed, by scenes without a strength check) get
    those of no check, a coil without the payout devices' fields zeros there; energy terms written one by one (before fe.layout) are gathered;
    a rigid body of empty arrays (a fixed axis, before it was None) is None."""
    nested = {"hub": HubState, "coil": CoilState, "strength": StrengthState,
              "rigid": RigidState}
    kw = {}
    for name in State._fields:
        if name == "strength" and not any(k.startswith("strength/") for k in arrays):
            kw[name] = strength_start(no_strength())
        elif name == "rigid":
            rigid = RigidState(*(arrays.get(f"rigid/{k}", np.zeros(0))
                                 for k in RigidState._fields))
            kw[name] = rigid if rigid.position.size else None
        elif name == "coil":
            n_arms = len(arrays["coil/front"])
            zero = {"dev_ref": np.zeros((n_arms, 3)), "dev_x": np.zeros((n_arms, 3)),
                    "dev_moment": np.zeros(3)}
            kw[name] = CoilState(*(arrays.get(f"coil/{k}", zero.get(k, np.zeros(n_arms)))
                                   for k in CoilState._fields))
        elif name == "totals" and "totals" not in arrays:
            kw[name] = np.array([float(np.asarray(arrays.get(f"totals/{_OLD_TOTALS[t.name]}",
                                                             [0.0])).ravel()[0])
                                 for t in STEP_TERMS])
        elif name in nested:
            kw[name] = nested[name](*(arrays[f"{name}/{k}"] for k in nested[name]._fields))
        else:
            kw[name] = arrays[name]
    kw["step"] = np.asarray(kw["step"], dtype=np.int64)
    return State(**kw)


def initial_state(model, omega: float, spin: str = "all", tilt_rate: float = 0.0) -> State:
    """Initial positions from the mesh; rigid spin omega [rad/s] of hub and web ('all') or of
    the hub and what moves with it only ('hub'). A coiled model's coil is held (only its
    tip level free) or loose, as its ``coil_code`` says. A free hub (``model.free_hub``) also turns at ``tilt_rate``
    [rad/s] about its x axis, with the nodes that move with it. Velocities are v_0 (see
    ``run.loop.start``)."""
    pos = np.array(model.mesh.node_pos, dtype=np.float64)
    vel = np.zeros_like(pos)
    if spin == "all":
        vel[:, 0] = -omega * pos[:, 1]
        vel[:, 1] = omega * pos[:, 0]
    hub, coil = model.hub, model.coil
    place_rigid(pos, vel, hub.tied_idx, hub.tied_ref, 0.0, omega)
    cs = coil_start(coil)
    mass, inv = model.nodes.mass.copy(), model.nodes.inv_mass.copy()
    spans = [np.arange(coil.level_ptr[coil.arm_ptr[k] + f], coil.level_ptr[coil.arm_ptr[k + 1]])
            for k, f in enumerate(cs.front)]
    held_nodes = coil.level_nodes[np.concatenate(spans)] if spans else np.zeros(0, np.int64)
    mass[held_nodes] = 0.0
    inv[held_nodes] = 0.0
    for k, f in enumerate(cs.front):  # the free levels, bundled or not
        level_masses(coil.level_ptr, coil.level_nodes, coil.level_mass, model.nodes.mass,
                     model.nodes.inv_mass, mass, inv, coil.arm_ptr[k], coil.arm_ptr[k] + f,
                     bool(cs.bundled[k]))
    place_held(coil.arm_ptr, cs.front, coil.level_ptr, coil.level_nodes, coil.level_ref, pos,
               vel, 0.0, omega)
    inertia = hub.j_eff + held_inertia(coil.arm_ptr, cs.front, coil.level_ptr,
                                       coil.level_nodes, coil.level_ref, model.nodes.mass)
    if coil.device:  # a reel or a brake holds each arm's line at its tip
        inertia += start_devices(coil, cs, model.nodes, mass, inv)
        locate_devices(coil, cs, axis_pose(0.0, omega))
    rigid = None
    if model.free_hub:
        rigid = rigid_start(model, cs, omega, tilt_rate)
        place_body(hub, coil, cs, rigid, pos, vel)
        if coil.device:
            locate_devices(coil, cs, body_pose(rigid))
        inertia = float(rigid.inertia[2, 2])
    return State(pos, vel, mass, inv, HubState(np.zeros(1), np.array([float(omega)]),
                                               np.array([inertia])), cs,
                 no_totals(),
                 np.zeros(1, np.int64), np.zeros(1), strength_start(model.strength), rigid)
