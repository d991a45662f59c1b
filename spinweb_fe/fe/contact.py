"""Cable-hub contact: a kinematic constraint on the hub cylinder, frictionless or Coulomb."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def contact_node(i, pos, vel, force, m, r0, mu, j_eff, omega, dw_force, dt):
    """Kinematic cable-hub contact of node i: radial impulse along x_n so that |x_{n+1}| >= r0.

    The impulse acts along the radial of x_n (no moment about the axis) and at most stops the
    inward motion (it never pushes outwards). Friction (Coulomb, coefficient mu) adds a
    tangential impulse bounded by mu times the normal impulse; its reaction turns the hub.
    ``dw_force`` is the hub rate increment of this step's torques. Returns (omega, dissipated
    energy [J]): the kinetic energy the impulse removes, less the part this step's force put
    into the removed velocity (dt f . dv / 2), so that a node resting on the hub under a steady
    load dissipates nothing, as in the continuous problem.
    """
    px = pos[i, 0] + dt * vel[i, 0]
    py = pos[i, 1] + dt * vel[i, 1]
    if px * px + py * py >= r0 * r0:
        return omega, 0.0
    rn = np.sqrt(pos[i, 0] ** 2 + pos[i, 1] ** 2)
    if rn == 0.0:
        return omega, 0.0
    ex = pos[i, 0] / rn
    ey = pos[i, 1] / rn
    pr = px * ex + py * ey
    disc = pr * pr - (px * px + py * py) + r0 * r0
    s = -pr + np.sqrt(max(disc, 0.0))  # |p + s e| = r0, s >= 0
    vx0 = vel[i, 0]
    vy0 = vel[i, 1]
    dvn = min(s / dt, max(-(vx0 * ex + vy0 * ey), 0.0))
    if dvn <= 0.0:
        return omega, 0.0
    e_before = 0.5 * m * (vx0 * vx0 + vy0 * vy0)
    vel[i, 0] += dvn * ex
    vel[i, 1] += dvn * ey
    diss = 0.0
    if mu > 0.0:
        # slip relative to the hub surface; the stick impulse includes the hub's response
        vrel = (-ey * vel[i, 0] + ex * vel[i, 1]) - omega * rn
        p_stick = -vrel / (1.0 / m + rn * rn / j_eff)
        p_max = mu * m * dvn
        p = min(max(p_stick, -p_max), p_max)
        w0 = omega
        vel[i, 0] += -ey * p / m
        vel[i, 1] += ex * p / m
        omega -= p * rn / j_eff  # equal and opposite moment on the hub
        diss += 0.5 * j_eff * (w0 * w0 - omega * omega) + 0.5 * j_eff * dw_force * (omega - w0)
    diss += e_before - 0.5 * m * (vel[i, 0] ** 2 + vel[i, 1] ** 2)
    diss += 0.5 * dt * (force[i, 0] * (vel[i, 0] - vx0) + force[i, 1] * (vel[i, 1] - vy0))
    return omega, diss
