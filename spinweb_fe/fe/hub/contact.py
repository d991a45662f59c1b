"""Cable-hub contact: a kinematic constraint on the hub cylinder, for both hub kinds.

A free node whose predicted position x_n + dt v_{n+1/2} lies inside the hub cylinder (radius
r0 about the hub axis, unbounded along it) takes a normal impulse along its radial at x_n,
just large enough that it lands on the rim (and at most stopping its approach: it never
pushes outwards). On a fixed axis (:func:`contact_node`) the normal impulse has no moment
about the axis and the hub does not move; Coulomb friction adds a tangential impulse bounded
by mu times the normal one, whose reaction turns the hub. On a free hub
(:func:`contact_free`) the body takes the equal and opposite impulse at the node (momentum
exact), shared through their effective mass.

Each returns the kinetic energy the impulses remove, less the part this step's forces put
into the removed velocities (dt f . dv / 2), so that a node resting on the hub under a steady
load dissipates nothing, as in the continuous problem.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.hub.rigid import body_energy, cross, inv_inertia


@njit(inline="always")
def rim_depth(qx, qy, qz, ex, ey, ez, r0):
    """s >= 0 with |q + s e| = r0: how far along the unit radial e the predicted position q
    (relative to the axis, in the hub plane) must move to land on the rim."""
    pr = qx * ex + qy * ey + qz * ez
    disc = pr * pr - (qx * qx + qy * qy + qz * qz) + r0 * r0
    return -pr + np.sqrt(max(disc, 0.0))


@njit(cache=True)
def contact_node(i, pos, vel, force, m, r0, mu, j_eff, omega, dw_force, dt):
    """Kinematic contact of node i with the hub on a fixed axis (+z): radial impulse along
    x_n so that |x_{n+1}| >= r0, Coulomb friction of coefficient ``mu`` against the hub
    surface turning at ``omega`` (``dw_force``: the hub rate increment of this step's
    torques). Returns (omega after the friction's reaction, dissipated energy [J])."""
    px = pos[i, 0] + dt * vel[i, 0]
    py = pos[i, 1] + dt * vel[i, 1]
    if px * px + py * py >= r0 * r0:
        return omega, 0.0
    rn = np.sqrt(pos[i, 0] ** 2 + pos[i, 1] ** 2)
    if rn == 0.0:
        return omega, 0.0
    ex = pos[i, 0] / rn
    ey = pos[i, 1] / rn
    s = rim_depth(px, py, 0.0, ex, ey, 0.0, r0)
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


@njit(cache=True)
def slip(i, vel, m, M, p_max, rs, R, V, Pi, rho, e, dv, dV, dw):
    """Coulomb friction of node i on the free hub after its normal impulse: the slip u_t
    (the node's velocity relative to the hub surface, less its part along the normal e) is
    stopped by the impulse |u_t| / (1/m + 1/M + k . I_s^{-1} k), k = rho x t, t = u_t /
    |u_t|, or slowed by ``p_max``; node and body (V, Pi) take it, and the velocity changes
    are added to ``dv``, ``dV``, ``dw``."""
    w = inv_inertia(rs, R, Pi)
    vs = V + cross(w, rho)
    u = np.array([vel[i, 0] - vs[0], vel[i, 1] - vs[1], vel[i, 2] - vs[2]])
    un = u[0] * e[0] + u[1] * e[1] + u[2] * e[2]
    ut = u - un * e
    size = np.sqrt(ut[0] ** 2 + ut[1] ** 2 + ut[2] ** 2)
    if size == 0.0:
        return
    t = ut / size
    k = cross(rho, t)
    ik = inv_inertia(rs, R, k)
    pt = min(size / (1.0 / m + 1.0 / M + k[0] * ik[0] + k[1] * ik[1] + k[2] * ik[2]), p_max)
    for d in range(3):  # the node takes -pt t, the body +pt t at rho
        vel[i, d] -= pt / m * t[d]
        V[d] += pt / M * t[d]
        Pi[d] += pt * k[d]
        dv[d] -= pt / m * t[d]
        dV[d] += pt / M * t[d]
        dw[d] += pt * ik[d]


@njit(cache=True)
def contact_free(i, pos, vel, f, m, r0, mu, rs, bk, dt):
    """Kinematic contact of free node i with the free hub of the BodyKick ``bk`` (its
    V_{n+1/2}, Pi_{n+1/2} changed in place): the normal impulse along the node's radial in
    the hub frame, shared with the body through their effective mass, then (``mu`` > 0)
    Coulomb friction against the slip over the hub surface: the tangential impulse that
    stops the slip, through the effective mass along it, at most mu times the normal one;
    the body takes every impulse's reaction at the node. Returns the energy they remove
    [J] from node and body, less this step's force work on the removed velocities (``f``
    the node's force, ``bk.F``, ``bk.T`` the body's)."""
    hull, R, V, Pi = bk.hull, bk.R, bk.V, bk.Pi
    c0, b0, c1, b1 = hull[0], hull[1], hull[2], hull[3]
    dx = pos[i, 0] - c0[0]
    dy = pos[i, 1] - c0[1]
    dz = pos[i, 2] - c0[2]
    h = dx * b0[0] + dy * b0[1] + dz * b0[2]
    ex, ey, ez = dx - h * b0[0], dy - h * b0[1], dz - h * b0[2]
    rn = np.sqrt(ex * ex + ey * ey + ez * ez)
    if rn == 0.0:
        return 0.0
    e = np.array([ex / rn, ey / rn, ez / rn])
    qx = pos[i, 0] + dt * vel[i, 0] - c1[0]
    qy = pos[i, 1] + dt * vel[i, 1] - c1[1]
    qz = pos[i, 2] + dt * vel[i, 2] - c1[2]
    hq = qx * b1[0] + qy * b1[1] + qz * b1[2]
    s = rim_depth(qx - hq * b1[0], qy - hq * b1[1], qz - hq * b1[2], e[0], e[1], e[2], r0)
    rho = np.array([pos[i, 0], pos[i, 1], pos[i, 2]]) - rs.position
    w = inv_inertia(rs, R, Pi)
    vs = V + cross(w, rho)  # the hub surface under the node
    un = (vel[i, 0] - vs[0]) * e[0] + (vel[i, 1] - vs[1]) * e[1] + (vel[i, 2] - vs[2]) * e[2]
    dvn = min(s / dt, max(-un, 0.0))
    if dvn <= 0.0:
        return 0.0
    k = cross(rho, e)
    ik = inv_inertia(rs, R, k)
    M = rs.mass[0]
    p = dvn / (1.0 / m + 1.0 / M + k[0] * ik[0] + k[1] * ik[1] + k[2] * ik[2])
    before = 0.5 * m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2) \
        + body_energy(rs, R, V, Pi)
    dv = (p / m) * e
    dV = -(p / M) * e
    for d in range(3):
        vel[i, d] += dv[d]
        V[d] += dV[d]
        Pi[d] -= p * k[d]
    after = 0.5 * m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2) \
        + body_energy(rs, R, V, Pi)
    dw = -p * ik
    if mu > 0.0:
        slip(i, vel, m, M, mu * p, rs, R, V, Pi, rho, e, dv, dV, dw)
        after = 0.5 * m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2) \
            + body_energy(rs, R, V, Pi)
    Fb, Tb = bk.F, bk.T
    work = (f[0] * dv[0] + f[1] * dv[1] + f[2] * dv[2] + Fb[0] * dV[0] + Fb[1] * dV[1]
            + Fb[2] * dV[2] + Tb[0] * dw[0] + Tb[1] * dw[1] + Tb[2] * dw[2])
    return before - after + 0.5 * dt * work
