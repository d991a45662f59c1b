"""The free hub (``[hub] motion = "free"``): its phases of the step.

The hub, its tied nodes and its held coil are one rigid body (:mod:`spinweb_fe.fe.hub.rigid`) in
the same leapfrog as the cables, with the gravity gradient (:mod:`spinweb_fe.fe.tidal`) and the
cable-hub contact against the moving hub:

    f_n         = element forces at x_n (+ m g(x_n, t_n) with the gravity gradient)
    F, T        = forces on the body's nodes, their moment about its centre of mass X
                  (+ M g(X), 3 n^2 e x (I_s e)); control torque M about the body axis b3
    kick        : v += dt f / m (free nodes); V += dt F / M; Pi += dt (T + M b3)
                  (a prescribed rate: M such that b3 . I_s^{-1} Pi = omega_law(t + dt/2))
    contact     : impulses between free nodes and the hub cylinder (radius r0 about b3 in
                  the hub frame, unbounded along it), the reaction on the body
    drift       : x += dt v; X += dt V; free rotation of the body over dt with Pi fixed
    body nodes  : x = X + R (r - c), v = V + omega x (x - X); then releases, bundles
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.fe.coil.bundles import gather_bundles, scatter_bundles
from spinweb_fe.fe.coil.levels import release_fronts
from spinweb_fe.fe.control import eval_control
from spinweb_fe.fe.hub.contact import contact_free
from spinweb_fe.fe.hub.rigid import (body_energy, body_loads, cross, detach, dot, free_rotation,
                                     hub_centre, inv_inertia, mul, rotation, spatial_inertia)
from spinweb_fe.fe.tidal import body_tidal, tidal_accel, vertical


class BodyKick(NamedTuple):
    """The free hub over one step (from :func:`body_kick`; ``w_new``, ``rate_new`` after
    the node pass).

    Attributes
    ----------
    R : (3, 3) float64
        Attitude at t_n.
    F, T : (3,) float64 [N], [N m]
        Force on the body and torque about its centre of mass, control included.
    torque : float [N m]
        Control torque about the body axis b3.
    w_old : (3,) float64 [rad/s]
        Angular velocity at the half step before.
    rate_old : float [rad/s]
        Its component about b3.
    V, Pi : (3,) float64 [m/s], [N m s]
        V_{n+1/2}, Pi_{n+1/2} (the contact impulses change them in place).
    Fg, Tg : (3,) float64 [N], [N m]
        Tidal force and torque on the body.
    hull : (4, 3) float64
        Hub centre and unit axis at x_n, and their predictions at t + dt.
    w_new : (3,) float64 [rad/s]
        Angular velocity at the half step after.
    rate_new : float [rad/s]
        Its component about b3.
    """

    R: np.ndarray
    F: np.ndarray
    T: np.ndarray
    torque: float
    w_old: np.ndarray
    rate_old: float
    V: np.ndarray
    Pi: np.ndarray
    Fg: np.ndarray
    Tg: np.ndarray
    hull: np.ndarray
    w_new: np.ndarray
    rate_new: float


@njit(cache=True)
def hull_of(rs, R, w, dt):
    """(4, 3) ``hull`` of the node pass: the hub centre and unit axis at x_n, and their
    predictions at t + dt (the centre moved by dt times its velocity, the axis turned by
    dt omega)."""
    hull = np.empty((4, 3))
    c = hub_centre(rs, R)
    b = R[:, 2].copy()
    hull[0] = c
    hull[1] = b
    hull[2] = c + dt * (rs.velocity + cross(w, c - rs.position))
    b1 = b + dt * cross(w, b)
    hull[3] = b1 / np.sqrt(dot(b1, b1))
    return hull


@njit(cache=True)
def body_kick(hub, coil, cs, env, rs, law, pos, force, t, dt):
    """The body's loads and control at step n and its kick: a BodyKick with V_{n+1/2} and
    Pi_{n+1/2} before contact. (The model's and state's parts, not the whole tuples: numba
    counts a reference for every array a call hands over.)"""
    R = rotation(rs.quaternion)
    F, T = body_loads(hub, coil, cs, rs.position, pos, force)
    if coil.device:  # a reel's or brake's line pulls at D (fe.coil.payout)
        T += cs.dev_moment
    Fg = np.zeros(3)
    Tg = np.zeros(3)
    if env.n > 0.0:
        Fg, Tg = body_tidal(env, t, rs.mass[0], rs.position, spatial_inertia(rs, R))
        F += Fg
        T += Tg
    b3 = R[:, 2].copy()
    w_old = inv_inertia(rs, R, rs.momentum)
    w3_old = dot(b3, w_old)
    prescribed, value = eval_control(law, t, w3_old)
    Pi = rs.momentum + dt * T
    torque = value
    if prescribed:  # the torque about b3 that gives the law's rate at the half step
        _, target = eval_control(law, t + 0.5 * dt, w3_old)
        torque = ((target - dot(b3, inv_inertia(rs, R, Pi)))
                  / (dt * dot(b3, inv_inertia(rs, R, b3))))
    Pi += dt * torque * b3
    V = rs.velocity + dt * F / rs.mass[0]
    return BodyKick(R, F, T + torque * b3, torque, w_old, w3_old, V, Pi, Fg, Tg,
                    hull_of(rs, R, w_old, dt), w_old, w3_old)


@njit(cache=True)
def body_nodes(nodes, hub, mv, force, env, t, rs, bk, dt, record, out):
    """Node pass against the free hub of the BodyKick ``bk``: v += dt (f + m g) / m,
    contact with the hub, x += dt v, over every node in node order (each contact impulse
    changes the body the next one meets: one thread). ``out[:2]`` receives the kinetic
    energy before and after on record steps. Returns (the BodyKick with the rates after the
    contacts, contact dissipation [J], gravity-gradient work on nodes and body [J])."""
    pos, vel, inv_mass, node_mass = mv.pos, mv.vel, mv.inv_mass, mv.mass
    contact = nodes.contact
    r0, mu = hub.radius, hub.friction
    use_contact = r0 > 0.0
    tidal = env.n > 0.0
    e = vertical(env, t)
    n2 = env.n * env.n
    c1, b1 = bk.hull[2], bk.hull[3]
    ke0 = 0.0
    ke1 = 0.0
    diss = 0.0
    work = 0.0
    f = np.zeros(3)
    for i in range(pos.shape[0]):
        im = inv_mass[i]
        if im > 0.0:
            m = node_mass[i]
            vx, vy, vz = vel[i, 0], vel[i, 1], vel[i, 2]
            if record:
                ke0 += m * (vx * vx + vy * vy + vz * vz)
            f[0], f[1], f[2] = force[i, 0], force[i, 1], force[i, 2]
            gx = gy = gz = 0.0
            if tidal:
                gx, gy, gz = tidal_accel(n2, e, pos[i, 0], pos[i, 1], pos[i, 2])
                f[0] += m * gx
                f[1] += m * gy
                f[2] += m * gz
            vel[i, 0] += dt * f[0] * im  # v_{n+1/2} = v_{n-1/2} + dt f / m
            vel[i, 1] += dt * f[1] * im
            vel[i, 2] += dt * f[2] * im
            if use_contact and contact[i]:
                qx = pos[i, 0] + dt * vel[i, 0] - c1[0]  # predicted, relative to the hub
                qy = pos[i, 1] + dt * vel[i, 1] - c1[1]
                qz = pos[i, 2] + dt * vel[i, 2] - c1[2]
                h = qx * b1[0] + qy * b1[1] + qz * b1[2]
                if qx * qx + qy * qy + qz * qz - h * h < r0 * r0:
                    diss += contact_free(i, pos, vel, f, m, r0, mu, rs, bk, dt)
            if tidal:  # dt m g . (v_{n-1/2} + v_{n+1/2}) / 2
                work += m * (gx * (vx + vel[i, 0]) + gy * (vy + vel[i, 1])
                             + gz * (vz + vel[i, 2]))
            if record:
                ke1 += m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
            pos[i, 0] += dt * vel[i, 0]  # x_{n+1} = x_n + dt v_{n+1/2}
            pos[i, 1] += dt * vel[i, 1]
            pos[i, 2] += dt * vel[i, 2]
    if record:
        out[0] = 0.5 * ke0
        out[1] = 0.5 * ke1
    w_new = inv_inertia(rs, bk.R, bk.Pi)
    w3_new = dot(bk.R[:, 2], w_new)
    wg = 0.5 * dt * work + 0.5 * dt * (dot(bk.Fg, rs.velocity + bk.V)
                                       + dot(bk.Tg, bk.w_old + w_new))
    after = BodyKick(bk.R, bk.F, bk.T, bk.torque, bk.w_old, bk.rate_old, bk.V, bk.Pi, bk.Fg,
                     bk.Tg, bk.hull, w_new, w3_new)
    return after, diss, wg


@njit(cache=True)
def body_row(rs, bk, sums, vrow, vs):
    """The body's part of a vector row (slots ``vs``; its momenta as the mean of the half
    steps, its pose) and (mean body-axis rate, kinetic energy, angular momentum about +z)
    of the scalar row (``sums[:2]``: the nodes' kinetic energy before and after)."""
    M = rs.mass[0]
    X = rs.position
    vm = 0.5 * (rs.velocity + bk.V)
    lm = M * cross(X, vm) + 0.5 * (rs.momentum + bk.Pi)
    q = rs.quaternion
    for d in range(3):
        vrow[vs.linear_momentum + d] += M * vm[d]
        vrow[vs.angular_momentum_vector + d] += lm[d]
        vrow[vs.hub_position + d] = bk.hull[0, d]
        vrow[vs.hub_axis + d] = bk.R[d, 2]
        vrow[vs.hub_angular_velocity + d] = 0.5 * (bk.w_old[d] + bk.w_new[d])
    for d in range(4):
        vrow[vs.hub_quaternion + d] = q[d]
    ke = 0.5 * (sums[0] + sums[1] + body_energy(rs, bk.R, rs.velocity, rs.momentum)
                + body_energy(rs, bk.R, bk.V, bk.Pi))
    return 0.5 * (bk.rate_old + bk.rate_new), ke, vrow[vs.angular_momentum_vector + 2]


@njit(cache=True)
def twist(q, prev):
    """The hub's turn about its own axis, 2 atan2(q_z, q_w), continued from ``prev`` [rad]."""
    a = 2.0 * np.arctan2(q[3], q[0])
    d = a - prev
    return prev + d - 2.0 * np.pi * np.floor(d / (2.0 * np.pi) + 0.5)


@njit(cache=True)
def body_drift(rs, bk, dt, theta):
    """The body's drift: V, Pi of the half step, X += dt V, the free rotation with Pi fixed.
    Returns its turn about its own axis [rad], continued from ``theta``."""
    rs.velocity[:] = bk.V
    rs.momentum[:] = bk.Pi
    rs.position[:] = rs.position + dt * bk.V
    free_rotation(rs, dt)
    return twist(rs.quaternion, theta)


@njit(cache=True)
def body_release(body, elems, nodes, hub, coil, cs, rs, mv, t, broken):
    """Releases of held levels at time t (fe.coil.levels.release_fronts, outward from the hub's
    axis where it is now) and, when some went, the body without them (fe.hub.rigid.detach:
    every point keeps its velocity)."""
    front = cs.front
    before = front.sum()
    R = rotation(rs.quaternion)
    frame = np.empty((2, 3))
    frame[0] = hub_centre(rs, R)
    frame[1] = R[:, 2]
    release_fronts(coil, cs, elems, nodes, mv.pos, mv.mass, mv.inv_mass, 0.0, t, broken,
                   frame)
    if front.sum() != before:
        detach(body, nodes, hub, coil, cs, rs)


@njit(cache=True)
def body_state(rs):
    """(body-axis rate, moment of inertia about the axis) of the body now."""
    R1 = rotation(rs.quaternion)
    b3 = R1[:, 2].copy()
    return dot(b3, inv_inertia(rs, R1, rs.momentum)), dot(b3, mul(spatial_inertia(rs, R1), b3))


@njit(cache=True)
def body_start(model, law, state, force, dt):
    """v_{-1/2} = v_0 - dt/2 a_0 for the free nodes and the body (V, Pi); a prescribed rate
    takes the law's body-axis rate at -dt/2."""
    coil, env = model.coil, model.env
    pos, vel = state.node_pos, state.node_vel
    rs = state.rigid
    if coil.level_nodes.shape[0] > 0:
        gather_bundles(model.bundles, state.coil, force)
    R = rotation(rs.quaternion)
    F, T = body_loads(model.hub, coil, state.coil, rs.position, pos, force)
    e = vertical(env, 0.0)
    n2 = env.n * env.n
    for i in range(pos.shape[0]):
        im = state.node_inv_mass[i]
        g = tidal_accel(n2, e, pos[i, 0], pos[i, 1], pos[i, 2])
        for d in range(3):
            vel[i, d] -= 0.5 * dt * (force[i, d] * im + (g[d] if im > 0.0 else 0.0))
    if env.n > 0.0:
        Fg, Tg = body_tidal(env, 0.0, rs.mass[0], rs.position, spatial_inertia(rs, R))
        F += Fg
        T += Tg
    b3 = R[:, 2].copy()
    w3 = dot(b3, inv_inertia(rs, R, rs.momentum))
    prescribed, value = eval_control(law, 0.0, w3)
    rs.velocity[:] = rs.velocity - 0.5 * dt * F / rs.mass[0]
    rs.momentum[:] = rs.momentum - 0.5 * dt * T
    if prescribed:
        _, target = eval_control(law, -0.5 * dt, w3)
        mu = ((target - dot(b3, inv_inertia(rs, R, rs.momentum)))
              / dot(b3, inv_inertia(rs, R, b3)))
        rs.momentum[:] = rs.momentum + mu * b3
    else:
        rs.momentum[:] = rs.momentum - 0.5 * dt * value * b3
    if coil.level_nodes.shape[0] > 0:
        scatter_bundles(model.bundles, state.coil, pos, vel)
    state.hub.rate[0] = dot(b3, inv_inertia(rs, R, rs.momentum))
