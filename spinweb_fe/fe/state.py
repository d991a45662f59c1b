"""The State: everything that changes during a run, as named arrays the kernels update in
place. Scalars are 1-element arrays so that numba can write them."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from spinweb_fe.fe.step import place_tied


class HubState(NamedTuple):
    """Hub motion about its fixed axis (+z).

    Attributes
    ----------
    angle : (1,) float64 [rad]
        theta_n, counter-clockwise positive.
    rate : (1,) float64 [rad/s]
        omega_{n-1/2} (omega_0 before the run starts).
    """

    angle: np.ndarray
    rate: np.ndarray


class Totals(NamedTuple):
    """Energy accumulated up to t_n [J] (each a (1,) float64)."""

    torque_work: np.ndarray
    damping_dissipation: np.ndarray
    contact_dissipation: np.ndarray


class State(NamedTuple):
    """Positions, half-step velocities, hub state, accumulated totals and the step count.

    Attributes
    ----------
    node_pos : (n, 3) float64 [m]
        x_n.
    node_vel : (n, 3) float64 [m/s]
        v_{n-1/2} (v_0 before the run starts, see ``run.loop.start``).
    hub : HubState
    totals : Totals
    step : (1,) int64
        n.
    time : (1,) float64 [s]
        t_n = n dt.
    """

    node_pos: np.ndarray
    node_vel: np.ndarray
    hub: HubState
    totals: Totals
    step: np.ndarray
    time: np.ndarray

    def copy(self) -> "State":
        """A deep copy (every array copied)."""
        return from_arrays({k: v.copy() for k, v in to_arrays(self).items()})


def to_arrays(state: State) -> dict:
    """Flat {name: array} view of a State (names like 'hub/rate'), for checkpoints."""
    out = {}
    for name, value in zip(State._fields, state):
        if isinstance(value, tuple):
            out.update({f"{name}/{k}": v for k, v in zip(value._fields, value)})
        else:
            out[name] = value
    return out


def from_arrays(arrays: dict) -> State:
    """Inverse of :func:`to_arrays` (KeyError names a missing field)."""
    return State(
        node_pos=arrays["node_pos"], node_vel=arrays["node_vel"],
        hub=HubState(*(arrays[f"hub/{k}"] for k in HubState._fields)),
        totals=Totals(*(arrays[f"totals/{k}"] for k in Totals._fields)),
        step=np.asarray(arrays["step"], dtype=np.int64), time=arrays["time"])


def initial_state(model, omega: float, spin: str = "all") -> State:
    """Initial positions from the mesh; rigid spin omega [rad/s] of hub and web ('all') or of
    the hub and tied nodes only ('hub'). Velocities are v_0 (see ``run.loop.start``)."""
    pos = np.array(model.mesh.node_pos, dtype=np.float64)
    vel = np.zeros_like(pos)
    if spin == "all":
        vel[:, 0] = -omega * pos[:, 1]
        vel[:, 1] = omega * pos[:, 0]
    place_tied(pos, vel, model.hub.tied_idx, model.hub.tied_ref, 0.0, omega)
    return State(pos, vel, HubState(np.zeros(1), np.array([float(omega)])),
                 Totals(np.zeros(1), np.zeros(1), np.zeros(1)), np.zeros(1, np.int64),
                 np.zeros(1))
