"""The contact's impulses at a step's end besides the fail-safe's crossings
(fe.contact.penalty): Coulomb friction between touching cables, and the bookkeeping of every
impulse: its work paired as the leapfrog pairs a force, and the angular impulse about the
axis that a fixed hub takes as their reaction, or the impulse and moment a free hub takes
(docs/solver.md, cable-cable contact)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.fe.hub.rigid import (cross, dot, hub_centre, inv_inertia, mul, mul_t, normalise,
                                rotation, spatial_inertia, turn)


@njit(cache=True)
def friction_impulses(pairs, elem_nodes, hold, pos0, pos1, vel, inv_mass, dt, mu):
    """Coulomb friction of the pairs in contact at the step's start (``hold``: normal force
    [N], s, t; module docstring): a tangential impulse at their closest points against the
    relative sliding velocity of ``vel`` (v_{n+1/2}), at most mu F dt and at most what
    stops the sliding; the end positions follow (x_{n+1} = x_n + dt v_{n+1/2}). Returns the
    half-step kinetic energy it took [J] (>= 0; the step books the impulses' work with
    :func:`impulse_work` instead)."""
    taken = 0.0
    for p in range(pairs.shape[0]):
        fn = hold[p, 0]
        if fn <= 0.0:
            continue
        s, t = hold[p, 1], hold[p, 2]
        e, g = pairs[p, 0], pairs[p, 1]
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        c, d = elem_nodes[g, 0], elem_nodes[g, 1]
        # the push's direction, p - q at x_n
        n0 = (1.0 - s) * pos0[a, 0] + s * pos0[b, 0] - (1.0 - t) * pos0[c, 0] - t * pos0[d, 0]
        n1 = (1.0 - s) * pos0[a, 1] + s * pos0[b, 1] - (1.0 - t) * pos0[c, 1] - t * pos0[d, 1]
        n2 = (1.0 - s) * pos0[a, 2] + s * pos0[b, 2] - (1.0 - t) * pos0[c, 2] - t * pos0[d, 2]
        size = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if size == 0.0:
            continue
        n0, n1, n2 = n0 / size, n1 / size, n2 / size
        r0 = (1.0 - s) * vel[a, 0] + s * vel[b, 0] - (1.0 - t) * vel[c, 0] - t * vel[d, 0]
        r1 = (1.0 - s) * vel[a, 1] + s * vel[b, 1] - (1.0 - t) * vel[c, 1] - t * vel[d, 1]
        r2 = (1.0 - s) * vel[a, 2] + s * vel[b, 2] - (1.0 - t) * vel[c, 2] - t * vel[d, 2]
        vn = r0 * n0 + r1 * n1 + r2 * n2
        r0, r1, r2 = r0 - vn * n0, r1 - vn * n1, r2 - vn * n2
        slide = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        if slide == 0.0:
            continue
        w = (1.0 - s) ** 2 * inv_mass[a] + s * s * inv_mass[b] \
            + (1.0 - t) ** 2 * inv_mass[c] + t * t * inv_mass[d]
        j = min(mu * fn * dt, slide / w)
        u0, u1, u2 = r0 / slide, r1 / slide, r2 / slide
        for i, f in ((a, 1.0 - s), (b, s), (c, -(1.0 - t)), (d, -t)):
            if inv_mass[i] == 0.0:
                continue
            m = 1.0 / inv_mass[i]
            ke0 = 0.5 * m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
            h = -f * j * inv_mass[i]
            vel[i, 0] += h * u0
            vel[i, 1] += h * u1
            vel[i, 2] += h * u2
            pos1[i, 0] += dt * h * u0
            pos1[i, 1] += dt * h * u1
            pos1[i, 2] += dt * h * u2
            taken += ke0 - 0.5 * m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
    return taken


@njit(cache=True)
def impulse_work(before, after, start, inv_mass):
    """sum m (after - before) . (start + after) / 2 over the free nodes [J]: the work of the
    impulses that changed v_{n+1/2} from ``before`` to ``after``, paired with v_{n-1/2}
    (``start``) as the leapfrog pairs a force's work."""
    w = 0.0
    for i in range(before.shape[0]):
        if inv_mass[i] == 0.0:
            continue
        acc = 0.0
        for k in range(3):
            dv = after[i, k] - before[i, k]
            if dv != 0.0:
                acc += dv * (start[i, k] + after[i, k])
        w += 0.5 * acc / inv_mass[i]
    return w


@njit(cache=True)
def node_impulse(pos, before, after, inv_mass, dt):
    """(J, H): sum m (after - before) [N s] and sum m y x (after - before) [N m s] over the
    free nodes, y = x_{n+1} - dt v_{n+1/2} at the end positions ``pos`` (x_n for a node
    that moved freely): the linear and angular impulse (about the origin) that changed
    their v_{n+1/2} (and x_{n+1} by dt times that; the angular momentum the step keeps is
    sum m x_{n+1} x v_{n+1/2}, which changes by y x m dv). A fixed axis takes H's z part."""
    J = np.zeros(3)
    H = np.zeros(3)
    for i in range(before.shape[0]):
        if inv_mass[i] == 0.0:
            continue
        d0, d1, d2 = after[i, 0] - before[i, 0], after[i, 1] - before[i, 1], \
            after[i, 2] - before[i, 2]
        if d0 == 0.0 and d1 == 0.0 and d2 == 0.0:
            continue
        y0, y1, y2 = pos[i, 0] - dt * after[i, 0], pos[i, 1] - dt * after[i, 1], \
            pos[i, 2] - dt * after[i, 2]
        im = inv_mass[i]
        J[0] += d0 / im
        J[1] += d1 / im
        J[2] += d2 / im
        H[0] += (y1 * d2 - y2 * d1) / im
        H[1] += (y2 * d0 - y0 * d2) / im
        H[2] += (y0 * d1 - y1 * d0) / im
    return J, H


@njit(inline="always")
def _skew(out, r0, r1, r2, m, sign):
    """out += sign m [r]x (the matrix of r x .)."""
    out[0, 1] -= sign * m * r2
    out[0, 2] += sign * m * r1
    out[1, 0] += sign * m * r2
    out[1, 2] -= sign * m * r0
    out[2, 0] -= sign * m * r1
    out[2, 1] += sign * m * r0


@njit(cache=True)
def axis_reaction(pos, before, after, inv_mass, dt, inertia, follow, place=True):
    """A fixed axis (effective inertia ``inertia`` [kg m^2]) takes the angular impulse
    about z of the impulses that changed the free nodes' v_{n+1/2} from ``before`` to
    ``after`` (``pos``: their x_{n+1}, :func:`node_impulse`), together with the free nodes
    that move with it this step (``follow``, fe.contact.zones: stuck to the hub, they turn with it,
    v += dw z x x_{n+1}, x_{n+1} by dt times that): the rate's change dw [rad/s] keeps the
    axial angular momentum of hub and nodes. ``place`` False: the hub will not turn by dt
    dw in this step (fe.step.settle's last pass), so the stuck nodes take only the velocity
    (their x_{n+1} stays, and so their moment arm). Returns dw."""
    H = node_impulse(pos, before, after, inv_mass, dt)[1][2]
    if not np.any(follow):
        return -H / inertia
    jeff = inertia
    for i in range(pos.shape[0]):
        if follow[i] and inv_mass[i] > 0.0:
            y0, y1 = pos[i, 0], pos[i, 1]
            if place:
                y0, y1 = y0 - dt * after[i, 0], y1 - dt * after[i, 1]
            jeff += (y0 * pos[i, 0] + y1 * pos[i, 1]) / inv_mass[i]
    dw = -H / jeff
    for i in range(pos.shape[0]):
        if follow[i] and inv_mass[i] > 0.0:
            d0, d1 = -dw * pos[i, 1], dw * pos[i, 0]
            after[i, 0] += d0
            after[i, 1] += d1
            if place:
                pos[i, 0] += dt * d0
                pos[i, 1] += dt * d1
    return dw


@njit(cache=True)
def _stuck(rs, pos, after, inv_mass, dt, follow, J, H, base, Iw, place):
    """(dV, dw): the free body's velocity and angular velocity change that keep the linear
    and angular momentum of the body and the free nodes stuck to it (``follow``; each
    moving by dV + dw x (x_{n+1} - X)) after the impulses (J, H) (:func:`body_reaction`):
    one 6 x 6 solve (the inelastic impact of the nodes on the body; ``place`` False: the
    nodes' x_{n+1} stay, their moment arm with them)."""
    M = rs.mass[0]
    X = rs.position
    A = np.zeros((6, 6))
    rhs = np.empty(6)
    for d in range(3):
        A[d, d] = M
        rhs[d], rhs[3 + d] = -J[d], -H[d]
        for e in range(3):
            A[3 + d, 3 + e] = Iw[d, e]
    top = np.zeros((3, 3))
    low = np.zeros((3, 3))
    _skew(low, base[0], base[1], base[2], M, 1.0)
    for i in range(pos.shape[0]):
        if not (follow[i] and inv_mass[i] > 0.0):
            continue
        m = 1.0 / inv_mass[i]
        r = pos[i] - X
        y = pos[i] - dt * after[i] if place else pos[i].copy()
        for d in range(3):
            A[d, d] += m
        _skew(top, r[0], r[1], r[2], m, -1.0)  # sum m dw x r = -sum m [r]x dw
        _skew(low, y[0], y[1], y[2], m, 1.0)
        yr = y[0] * r[0] + y[1] * r[1] + y[2] * r[2]
        for d in range(3):  # y x (dw x r) = (y . r) dw - r (y . dw)
            A[3 + d, 3 + d] += m * yr
            for e in range(3):
                A[3 + d, 3 + e] -= m * r[d] * y[e]
    A[0:3, 3:6] = top
    A[3:6, 0:3] = low
    sol = np.linalg.solve(A, rhs)
    return sol[0:3].copy(), sol[3:6].copy()


@njit(cache=True)
def body_reaction(rs, pos, before, after, inv_mass, v0, w0, dt, follow=None, place=True):
    """A free hub (fe.hub.rigid.RigidState ``rs``, after its drift) takes the reaction of the
    impulses that changed the free nodes' v_{n+1/2} from ``before`` to ``after`` (``pos``:
    their x_{n+1}, see :func:`node_impulse`): V_{n+1/2} by -J / M and X_{n+1} by dt times
    that (as a node's impulse moves its x_{n+1}), Pi_{n+1/2} such that the step's angular
    momentum M X x V + Pi + sum m x_n x v_{n+1/2} is unchanged, and its attitude turned by
    dt times the change of its angular velocity (as a fixed axis turns by dt dw). The free
    nodes marked in ``follow`` (stuck to the hub this step, fe.contact.zones) take the body's
    change with it, v += dV + dw x (x_{n+1} - X) and x_{n+1} by dt times that, and the
    change keeps the momenta of body and nodes together (:func:`_stuck`). ``place`` False
    (fe.step.settle's last pass): the reaction changes the velocities only, X_{n+1}, the
    attitude and the stuck nodes' x_{n+1} stay (so M X x V + Pi + sum m x_{n+1} x v is kept,
    the moment arms those of x_{n+1}), and nothing the hub carries moves after the pass
    that tested it. ``v0``, ``w0``: V_{n-1/2} [m/s] and its angular velocity [rad/s] at the
    step's start. Returns the work of the reaction on the body [J], paired as the leapfrog
    pairs a force's (with the half-step values before and after)."""
    J, H = node_impulse(pos, before, after, inv_mass, dt)
    M = rs.mass[0]
    X, V, Pi = rs.position, rs.velocity, rs.momentum
    # M (X + dt dV) x (V + dV) - M X x V = (X - dt V) x (M dV): the body's drift started there
    base = X - dt * V if place else X.copy()
    R = rotation(rs.quaternion)
    w_old = inv_inertia(rs, R, Pi)
    stuck = follow is not None and np.any(follow)
    if stuck:
        Iw = spatial_inertia(rs, R)
        dV, dw = _stuck(rs, pos, after, inv_mass, dt, follow, J, H, base, Iw, place)
        dPi = mul(Iw, dw)
        dP = M * dV
        for i in range(pos.shape[0]):
            if follow[i] and inv_mass[i] > 0.0:
                dv = dV + cross(dw, pos[i] - X)
                for d in range(3):
                    after[i, d] += dv[d]
                    if place:
                        pos[i, d] += dt * dv[d]
    else:
        dV = -J / M
        dP = -J
        dPi = cross(base, J) - H
    for d in range(3):
        V[d] += dV[d]
        if place:
            X[d] += dt * dV[d]
        Pi[d] += dPi[d]
    w_new = inv_inertia(rs, R, Pi)
    dw = w_new - w_old
    size = np.sqrt(dot(dw, dw))
    if place and size > 0.0:
        turn(rs.quaternion, mul_t(R, dw) / size, dt * size)
        normalise(rs.quaternion)
    return (dot(dP, v0 + V) + dot(dPi, w0 + w_new)) * 0.5


class HubStart(NamedTuple):
    """The hub at a step's start, and the reaction the contact's fail-safe gave it at the
    step's end (fe.contact.penalty.contact_resolve; each field an array the kernels write).

    rate, angle (1,) [rad/s], [rad]: a fixed axis's omega_{n-1/2} and theta_n; dw (1,)
    [rad/s]: the change of a fixed axis's rate the reaction made; took (1,) bool: the hub
    took a reaction (a fixed axis: dw not 0); velocity (3,) [m/s], omega (3,) [rad/s],
    centre (3,) [m], quaternion (4,): a free hub's V_{n-1/2}, angular velocity, hub centre
    and attitude (w, x, y, z) at the step's start (:func:`body_snapshot`).
    """

    rate: np.ndarray
    angle: np.ndarray
    dw: np.ndarray
    took: np.ndarray
    velocity: np.ndarray
    omega: np.ndarray
    centre: np.ndarray
    quaternion: np.ndarray


def hub_start() -> HubStart:
    """A :class:`HubStart` of zeros."""
    return HubStart(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1, np.bool_), np.zeros(3),
                    np.zeros(3), np.zeros(3), np.zeros(4))


@njit(cache=True)
def body_snapshot(rs, start):
    """A free hub's V [m/s], angular velocity I_s^{-1} Pi [rad/s] (those of
    :func:`body_reaction`), hub centre [m] and attitude quaternion now, into ``start`` (a
    :class:`HubStart`; None, a fixed axis: nothing)."""
    if rs is None:
        return
    R = rotation(rs.quaternion)
    start.velocity[:] = rs.velocity
    start.omega[:] = inv_inertia(rs, R, rs.momentum)
    start.centre[:] = hub_centre(rs, R)
    start.quaternion[:] = rs.quaternion
