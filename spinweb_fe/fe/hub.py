"""The rigid hub on a fixed axis: its rate over a step, and the nodes that move with it."""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.control import eval_control


@njit(cache=True)
def moment_of(pos, force, idx):
    """z-moment sum (x f_y - y f_x) of the forces ``force`` (n, 3) on nodes ``idx``."""
    tau = 0.0
    for k in range(idx.shape[0]):
        i = idx[k]
        tau += pos[i, 0] * force[i, 1] - pos[i, 1] * force[i, 0]
    return tau


@njit(cache=True)
def place_rigid(pos, vel, idx, ref, theta, omega):
    """Nodes ``idx`` move with the hub: x = R(theta) x_hub (``ref``), v = omega z x x."""
    if idx.shape[0] == 0:
        return
    c = np.cos(theta)
    s = np.sin(theta)
    for k in range(idx.shape[0]):
        i = idx[k]
        x = c * ref[k, 0] - s * ref[k, 1]
        y = s * ref[k, 0] + c * ref[k, 1]
        pos[i, 0] = x
        pos[i, 1] = y
        pos[i, 2] = ref[k, 2]
        vel[i, 0] = -omega * y
        vel[i, 1] = omega * x
        vel[i, 2] = 0.0


@njit(cache=True, no_cpython_wrapper=True)
def hub_step(law, j_eff, tau, w_old, t, dt):
    """Hub rate over the step: (torque M_n [N m], omega_{n+1/2}).

    A prescribed law imposes the rate at the half step and reports the torque it takes;
    a torque law integrates J_eff omega' = M + tau (tau: the reactions of the nodes that
    move with the hub)."""
    prescribed, value = eval_control(law, t, w_old)
    if prescribed:
        _, w_new = eval_control(law, t + 0.5 * dt, w_old)
        return j_eff * (w_new - w_old) / dt - tau, w_new
    return value, w_old + dt * (value + tau) / j_eff
