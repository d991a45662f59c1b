"""The step of a scene whose hub is a free rigid body (``[hub] motion = "free"``).

The same central differences as :func:`spinweb_fe.fe.step.advance` (its element pass, the held
coil, the bundles, the records), with the hub, its tied nodes and its held coil as one rigid
body (:mod:`spinweb_fe.fe.rigid`) in the same leapfrog, the gravity gradient
(:mod:`spinweb_fe.fe.tidal`) and the cable-hub contact against the moving hub:

    f_n         = element forces at x_n (+ m g(x_n, t_n) with the gravity gradient)
    F, T        = forces on the body's nodes, their moment about its centre of mass X
                  (+ M g(X), 3 n^2 e x (I_s e)); control torque M about the body axis b3
    kick        : v += dt f / m (free nodes); V += dt F / M; Pi += dt (T + M b3)
                  (a prescribed rate: M such that b3 . I_s^{-1} Pi = omega_law(t + dt/2))
    contact     : impulses between free nodes and the hub cylinder (radius r0 about b3 in
                  the hub frame, unbounded along it), the reaction on the body
    drift       : x += dt v; X += dt V; free rotation of the body over dt with Pi fixed
    body nodes  : x = X + R (r - c), v = V + omega x (x - X); then releases, bundles

A separate kernel, so that a fixed-axis scene compiles and runs exactly what it did.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.coil import (any_held, gather_bundles, open_bundles, release_fronts,
                                scatter_bundles)
from spinweb_fe.fe.control import eval_control
from spinweb_fe.fe.rigid import (body_energy, body_loads, cross, detach, dot, free_rotation,
                                 hub_centre, inv_inertia, mul, place_body, rotation,
                                 spatial_inertia)
from spinweb_fe.fe.rupture import record_strength
from spinweb_fe.fe.step import (NodeMotion, checks_strength, element_pass, probe_positions,
                                probe_velocities, record_arms)
from spinweb_fe.fe.tidal import body_tidal, tidal_accel, vertical
from spinweb_fe.fe.vectors import I_GRAVITY, I_HUB, node_momenta, plane_stats


@njit(cache=True)
def contact_free(i, pos, vel, f, m, r0, hull, rs, R, V, Pi, Fb, Tb, dt):
    """Kinematic contact of free node i with the free hub: a normal impulse along the node's
    radial in the hub frame, just large enough that x_{n+1} lands on the rim relative to the
    hub (and at most stopping its approach), shared with the body through their effective
    mass; the body takes the equal and opposite impulse at the node (momentum exact). Returns
    the energy it removes [J] from node and body, less this step's force work on the removed
    velocities (``f`` the node's force, ``Fb``, ``Tb`` the body's), as the fixed-axis contact."""
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
    qx, qy, qz = qx - hq * b1[0], qy - hq * b1[1], qz - hq * b1[2]
    pr = qx * e[0] + qy * e[1] + qz * e[2]
    disc = pr * pr - (qx * qx + qy * qy + qz * qz) + r0 * r0
    s = -pr + np.sqrt(max(disc, 0.0))  # |q + s e| = r0, s >= 0
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
    work = (f[0] * dv[0] + f[1] * dv[1] + f[2] * dv[2] + Fb[0] * dV[0] + Fb[1] * dV[1]
            + Fb[2] * dV[2] + Tb[0] * dw[0] + Tb[1] * dw[1] + Tb[2] * dw[2])
    return before - after + 0.5 * dt * work


@njit(cache=True)
def integrate_free(nodes, hub, mv, force, env, t, hull, rs, R, V, Pi, Fb, Tb, dt, record,
                   out):
    """Node pass of the free-hub step over every node: v += dt (f + m g) / m, contact with
    the hub, x += dt v. ``out[:2]`` receives the kinetic energy before and after on
    record steps. Returns (contact dissipation [J], gravity-gradient work on the nodes [J])."""
    pos, vel, inv_mass, node_mass = mv.pos, mv.vel, mv.inv_mass, mv.mass
    contact = nodes.contact
    r0 = hub.radius
    use_contact = r0 > 0.0
    tidal = env.n > 0.0
    e = vertical(env, t)
    n2 = env.n * env.n
    c1, b1 = hull[2], hull[3]
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
                    diss += contact_free(i, pos, vel, f, m, r0, hull, rs, R, V, Pi, Fb, Tb,
                                         dt)
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
    return diss, 0.5 * dt * work


@njit(cache=True)
def body_kick(hub, coil, cs, env, rs, law, pos, force, t, dt, R):
    """The body's loads and control at step n: (F, T + M b3, M [N m], omega before, its
    component omega_3 about b3, V_{n+1/2}, Pi_{n+1/2}, tidal force, tidal torque); V and
    Pi before contact. (The model's and state's parts, not the whole tuples: numba counts a
    reference for every array a call hands over.)"""
    F, T = body_loads(hub, coil, cs, rs, pos, force)
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
    return F, T + torque * b3, torque, w_old, w3_old, V, Pi, Fg, Tg


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
def write_free_row(row, vrow, t, theta, w3, torque, ke, se, tmax, totals, incr):
    """One history row (fe.step.REC_COLUMNS) of the free-hub step: ``w3`` the mean body-axis
    rate, ``ke`` the kinetic energy (mean of the half steps), the angular momentum about +z
    from the vector row."""
    row[0] = t
    row[1] = theta
    row[2] = w3
    row[3] = torque
    row[4] = ke
    row[5] = se
    row[6] = totals.torque_work[0] + 0.5 * incr[0]
    row[7] = totals.damping_dissipation[0] + 0.5 * incr[1]
    row[8] = totals.contact_dissipation[0] + 0.5 * incr[2]
    row[9] = vrow[5]
    row[10] = tmax
    vrow[I_GRAVITY] = totals.gravity_work[0] + 0.5 * incr[3]


@njit(cache=True)
def body_row(vrow, rs, R, hull, V0, V1, P0, P1, w0, w1):
    """The body's part of a vector row: its momenta (mean of the half steps) and pose."""
    M = rs.mass[0]
    X = rs.position
    vm = 0.5 * (V0 + V1)
    lm = M * cross(X, vm) + 0.5 * (P0 + P1)
    q = rs.quaternion
    for d in range(3):
        vrow[d] += M * vm[d]
        vrow[3 + d] += lm[d]
        vrow[I_HUB + d] = hull[0, d]
        vrow[13 + d] = R[d, 2]
        vrow[16 + d] = 0.5 * (w0[d] + w1[d])
    for d in range(4):
        vrow[9 + d] = q[d]


@njit(cache=True)
def twist(q, prev):
    """The hub's turn about its own axis, 2 atan2(q_z, q_w), continued from ``prev`` [rad]."""
    a = 2.0 * np.arctan2(q[3], q[0])
    d = a - prev
    return prev + d - 2.0 * np.pi * np.floor(d / (2.0 * np.pi) + 0.5)


@njit(cache=True, nogil=True)
def advance_free(model, law, state, work, rec, vec, dt, nsteps, threads=None):
    """``nsteps`` steps of a free-hub scene; rows as :func:`spinweb_fe.fe.step.advance` (its
    workspace and threads for the force passes; the node pass runs on one thread), the
    vector table ``vec`` (rows, fe.vectors.VEC_WIDTH) always. Returns (status, rows)."""
    elems, nodes, hub, coil = model.elements, model.nodes, model.hub, model.coil
    strength = model.strength
    has_strength = checks_strength(strength)
    pos, vel = state.node_pos, state.node_vel
    force = work.force
    rs, totals = state.rigid, state.totals
    sums = np.zeros(2)
    incr = np.zeros(4)
    vprobe = np.zeros((rec.probes.shape[0], 3))
    has_coil = coil.level_nodes.shape[0] > 0
    # the model's and state's arrays taken out once (see fe.step.advance: every tuple handed
    # to a compiled function costs a reference count per array)
    links, bundles, env, body = model.links, model.bundles, model.env, model.body
    cs, ss = state.coil, state.strength
    mass, inv_mass, broken = state.node_mass, state.node_inv_mass, ss.broken
    mv = NodeMotion(pos, vel, mass, inv_mass)
    hub_angle, hub_rate, hub_inertia = state.hub.angle, state.hub.rate, state.hub.inertia
    step_no, time_now = state.step, state.time
    torque_work, gravity_work = totals.torque_work, totals.gravity_work
    damping_dissipation = totals.damping_dissipation
    contact_dissipation = totals.contact_dissipation
    arm_ptr, front = coil.arm_ptr, cs.front
    nrec = np.int64(0)  # not the literal 0: a literal argument compiles callees twice
    for _ in range(nsteps):
        step = step_no[0]
        record = step % rec.every == 0
        t = step * dt
        se, tmax, pdamp = element_pass(elems, links, strength, ss, pos, vel, work, record, dt,
                                       threads)
        if has_coil:
            gather_bundles(bundles, cs, force)
        R = rotation(rs.quaternion)
        Fb, Tb, torque, w_old, w3_old, V, Pi, Fg, Tg = body_kick(hub, coil, cs, env, rs, law,
                                                                 pos, force, t, dt, R)
        hull = hull_of(rs, R, w_old, dt)
        if record:
            probe_positions(rec, nrec, pos, vel, vprobe)
            record_arms(coil, cs, rec.arm_table[nrec], t)
            if has_strength:
                record_strength(ss, rec.strength_table[nrec])
            vec[nrec] = 0.0
            node_momenta(pos, vel, mass, inv_mass, vec[nrec], 0.5)
            plane_stats(pos, nodes.inv_mass, hull[0], hull[1], vec[nrec])
        dcontact, wg = integrate_free(nodes, hub, mv, force, env, t, hull, rs, R, V, Pi, Fb, Tb,
                                      dt, record, sums)
        if has_coil:
            scatter_bundles(bundles, cs, pos, vel)
        w_new = inv_inertia(rs, R, Pi)
        w3_new = dot(R[:, 2], w_new)
        incr[0] = torque * dt * 0.5 * (w3_old + w3_new)  # work of M about b3
        incr[1] = pdamp * dt
        incr[2] = dcontact
        incr[3] = wg + 0.5 * dt * (dot(Fg, rs.velocity + V) + dot(Tg, w_old + w_new))
        theta = hub_angle[0]
        if record:
            node_momenta(pos, vel, mass, inv_mass, vec[nrec], 0.5)
            body_row(vec[nrec], rs, R, hull, rs.velocity, V, rs.momentum, Pi, w_old, w_new)
            ke = 0.5 * (sums[0] + sums[1] + body_energy(rs, R, rs.velocity, rs.momentum)
                        + body_energy(rs, R, V, Pi))
            write_free_row(rec.table[nrec], vec[nrec], t, theta, 0.5 * (w3_old + w3_new),
                           torque, ke, se, tmax, totals, incr)
            if not (np.isfinite(rec.table[nrec, 4]) and np.isfinite(se)):
                return 1, nrec
            probe_velocities(rec, nrec, vel, vprobe)
            nrec += 1
        rs.velocity[:] = V  # the drift: X += dt V, the free rotation with Pi fixed
        rs.momentum[:] = Pi
        rs.position[:] = rs.position + dt * V
        free_rotation(rs, dt)
        torque_work[0] += incr[0]
        damping_dissipation[0] += incr[1]
        contact_dissipation[0] += incr[2]
        gravity_work[0] += incr[3]
        step_no[0] = step + 1
        time_now[0] = (step + 1) * dt
        hub_angle[0] = twist(rs.quaternion, theta)
        # the body's nodes placed; releases of held levels (the body detaches them), bundles
        place_body(hub, coil, cs, rs, pos, vel)
        t_next = (step + 1) * dt
        if any_held(arm_ptr, front):
            before = front.sum()
            release_fronts(coil, cs, elems, nodes, pos, mass, inv_mass, 0.0, t_next, broken)
            if front.sum() != before:
                detach(body, nodes, hub, coil, cs, rs)
        if has_coil:
            open_bundles(bundles, cs, nodes, mass, inv_mass, t_next)
        R1 = rotation(rs.quaternion)
        b3 = R1[:, 2].copy()
        hub_rate[0] = dot(b3, inv_inertia(rs, R1, rs.momentum))
        hub_inertia[0] = dot(b3, mul(spatial_inertia(rs, R1), b3))
    return 0, nrec


@njit(cache=True)
def start_free(model, law, state, force, dt):
    """v_{-1/2} = v_0 - dt/2 a_0 for the free nodes and the body (V, Pi); a prescribed rate
    takes the law's body-axis rate at -dt/2."""
    coil, env = model.coil, model.env
    pos, vel = state.node_pos, state.node_vel
    rs = state.rigid
    if coil.level_nodes.shape[0] > 0:
        gather_bundles(model.bundles, state.coil, force)
    R = rotation(rs.quaternion)
    F, T = body_loads(model.hub, coil, state.coil, rs, pos, force)
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
