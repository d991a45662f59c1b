"""The free hub: a rigid body of six degrees of freedom (hub, tied nodes and held coil).

The body is the hub (its mass and its own inertia tensor about its centre, in the hub frame)
together with the nodes that move with it: the tied nodes and the held coil (their model
masses at their hub-frame positions ``r``). Its state (:class:`RigidState`) is the centre of
mass X (inertial), its velocity V at the half step, the attitude q (a unit quaternion, hub
frame -> inertial) and the angular momentum about the centre of mass Pi (inertial) at the
half step; its mass, centre of mass in the hub frame and inertia tensor change only when held
nodes are released (:func:`detach`). A node of the body sits at x = X + R (r - c).

One step (fe.step with the phases of fe.hub.body) is the central-difference step of the cables with the body in the
same leapfrog: a kick V += dt F / M, Pi += dt T with the loads at x_n, then the drift X += dt
V and the free rotation of the body with Pi fixed over dt. The free rotation is the
symplectic splitting of Dullweber, Leimkuhler and McLachlan (1997): the kinetic energy
T = sum m_k^2 / (2 I_k) over the principal axes is split into three exactly solvable
rotations about one principal axis each, composed symmetrically (axis a for dt/2, b for dt/2,
the axis nearest the spin axis for dt, b, a). Each part turns the body about a body axis and
counter-rotates the body components of Pi, so the inertial Pi never changes in the drift:
angular momentum is conserved to round-off; the energy error is O(dt^2) and bounded (the
scheme is symplectic and time-reversible). The quaternion is renormalised after each drift.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit


class Body(NamedTuple):
    """The hub as a rigid body (fixed during a run).

    Attributes
    ----------
    mass : float [kg]
        Hub mass.
    inertia : (3, 3) float64 [kg m^2]
        The hub's own inertia tensor about its centre, hub frame (z: the spin axis).
    """

    mass: float
    inertia: np.ndarray


class RigidState(NamedTuple):
    """The free body's state (``State.rigid``; None when the hub turns about a fixed axis).

    Attributes
    ----------
    position : (3,) float64 [m]
        Centre of mass X_n of hub, tied and held nodes, inertial.
    velocity : (3,) float64 [m/s]
        V_{n-1/2}.
    quaternion : (4,) float64
        Attitude q_n (w, x, y, z), hub frame -> inertial.
    momentum : (3,) float64 [N m s]
        Angular momentum about the centre of mass Pi_{n-1/2}, inertial.
    mass : (1,) float64 [kg]
        Mass of the body now.
    com : (3,) float64 [m]
        Centre of mass in the hub frame.
    inertia : (3, 3) float64 [kg m^2]
        Inertia tensor about the centre of mass, hub frame.
    axes : (3, 3) float64
        Principal axes of ``inertia`` (columns, hub frame).
    moments : (3,) float64 [kg m^2]
        Principal moments.
    """

    position: np.ndarray
    velocity: np.ndarray
    quaternion: np.ndarray
    momentum: np.ndarray
    mass: np.ndarray
    com: np.ndarray
    inertia: np.ndarray
    axes: np.ndarray
    moments: np.ndarray


def make_body(mass: float, principal) -> Body:
    """A free hub of ``mass`` [kg] and principal moments (I_x, I_y, I_z) [kg m^2] about
    the hub-frame axes (z the spin axis)."""
    return Body(float(mass), np.diag(np.asarray(principal, np.float64)))


@njit(cache=True)
def rotation(q):
    """(3, 3) rotation matrix of the unit quaternion q = (w, x, y, z)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    R = np.empty((3, 3))
    R[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[0, 1] = 2.0 * (x * y - w * z)
    R[0, 2] = 2.0 * (x * z + w * y)
    R[1, 0] = 2.0 * (x * y + w * z)
    R[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[1, 2] = 2.0 * (y * z - w * x)
    R[2, 0] = 2.0 * (x * z - w * y)
    R[2, 1] = 2.0 * (y * z + w * x)
    R[2, 2] = 1.0 - 2.0 * (x * x + y * y)
    return R


@njit(cache=True)
def turn(q, a, theta):
    """q <- q (x) (cos theta/2, sin theta/2 a): a turn by theta about the hub-frame unit
    axis a (in place)."""
    c = np.cos(0.5 * theta)
    s = np.sin(0.5 * theta)
    bx, by, bz = s * a[0], s * a[1], s * a[2]
    w, x, y, z = q[0], q[1], q[2], q[3]
    q[0] = w * c - x * bx - y * by - z * bz
    q[1] = w * bx + x * c + y * bz - z * by
    q[2] = w * by - x * bz + y * c + z * bx
    q[3] = w * bz + x * by - y * bx + z * c


@njit(cache=True)
def normalise(q):
    """q <- q / |q| (the attitude quaternion, in place, after a turn)."""
    qn = np.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2 + q[3] ** 2)
    for k in range(4):
        q[k] /= qn


@njit(cache=True)
def cross(a, b):
    """a x b of two 3-vectors."""
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit(cache=True)
def dot(a, b):
    """a . b of two 3-vectors."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def mul(A, u):
    """A u (3x3 times a 3-vector)."""
    out = np.empty(3)
    for d in range(3):
        out[d] = A[d, 0] * u[0] + A[d, 1] * u[1] + A[d, 2] * u[2]
    return out


@njit(cache=True)
def mul_t(A, u):
    """A^T u (3x3 transposed times a 3-vector)."""
    out = np.empty(3)
    for d in range(3):
        out[d] = A[0, d] * u[0] + A[1, d] * u[1] + A[2, d] * u[2]
    return out


@njit(cache=True)
def inv_inertia(rs, R, u):
    """I_s^{-1} u [rad/s per N m s]: the inverse of the body's inertia tensor about its
    centre of mass, in the inertial frame at attitude R (I_s = R P diag(I) P^T R^T)."""
    P = rs.axes
    b = mul_t(R, u)
    out = np.zeros(3)
    for k in range(3):
        c = (P[0, k] * b[0] + P[1, k] * b[1] + P[2, k] * b[2]) / rs.moments[k]
        for d in range(3):
            out[d] += c * P[d, k]
    return mul(R, out)


@njit(cache=True)
def spatial_inertia(rs, R):
    """(3, 3) inertia tensor about the centre of mass in the inertial frame [kg m^2]."""
    out = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            s = 0.0
            for i in range(3):
                for j in range(3):
                    s += R[a, i] * rs.inertia[i, j] * R[b, j]
            out[a, b] = s
    return out


@njit(cache=True)
def hub_centre(rs, R):
    """The hub centre X - R c [m], inertial."""
    return rs.position - mul(R, rs.com)


@njit(cache=True)
def jacobi3(A):
    """Eigenvalues (3,) and eigenvectors (columns, (3, 3)) of a symmetric 3x3 matrix by
    cyclic Jacobi rotations (deterministic, converged to round-off)."""
    a = A.copy()
    v = np.eye(3)
    for _ in range(50):
        off = a[0, 1] ** 2 + a[0, 2] ** 2 + a[1, 2] ** 2
        if off <= 1e-32 * (a[0, 0] ** 2 + a[1, 1] ** 2 + a[2, 2] ** 2):
            break
        for p, r in ((0, 1), (0, 2), (1, 2)):
            if a[p, r] == 0.0:
                continue
            th = 0.5 * (a[r, r] - a[p, p]) / a[p, r]
            t = np.sign(th) / (abs(th) + np.sqrt(th * th + 1.0)) if th != 0.0 else 1.0
            c = 1.0 / np.sqrt(t * t + 1.0)
            s = t * c
            for k in range(3):  # a <- J^T a J, v <- v J
                akp, akr = a[k, p], a[k, r]
                a[k, p] = c * akp - s * akr
                a[k, r] = s * akp + c * akr
            for k in range(3):
                apk, ark = a[p, k], a[r, k]
                a[p, k] = c * apk - s * ark
                a[r, k] = s * apk + c * ark
            for k in range(3):
                vkp, vkr = v[k, p], v[k, r]
                v[k, p] = c * vkp - s * vkr
                v[k, r] = s * vkp + c * vkr
    return np.array([a[0, 0], a[1, 1], a[2, 2]]), v


@njit(cache=True)
def _add_point(m, r, first, inertia):
    """Add a point mass m at hub-frame r: first moment and inertia about the hub centre."""
    rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    for a in range(3):
        first[a] += m * r[a]
        for b in range(3):
            inertia[a, b] += m * ((rr if a == b else 0.0) - r[a] * r[b])


@njit(cache=True)
def assemble(body, nodes, hub, coil, cs, rs):
    """Mass, centre of mass, inertia tensor about it and principal axes of the body: the
    hub, the tied nodes, the held coil levels (behind each arm's front) and the mass a
    payout device holds at its departure point (fe.coil.payout), into ``rs``."""
    mass = body.mass
    first = np.zeros(3)
    inertia = body.inertia.copy()
    for k in range(hub.tied_idx.shape[0]):
        i = hub.tied_idx[k]
        mass += nodes.mass[i]
        _add_point(nodes.mass[i], hub.tied_ref[k], first, inertia)
    for k in range(coil.arm_ptr.shape[0] - 1):
        for p in range(coil.level_ptr[coil.arm_ptr[k] + cs.front[k]],
                       coil.level_ptr[coil.arm_ptr[k + 1]]):
            i = coil.level_nodes[p]
            mass += nodes.mass[i]
            _add_point(nodes.mass[i], coil.level_ref[p], first, inertia)
        lev = coil.arm_ptr[k] + cs.front[k]
        if cs.dev_rest[k] > 0.0:  # held by a device at the next outer level's place
            mass += cs.dev_rest[k]
            _add_point(cs.dev_rest[k], coil.level_ref[coil.level_ptr[lev - 1]], first, inertia)
    c = first / mass
    cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2]
    for a in range(3):  # parallel axes: about the centre of mass
        for b in range(3):
            inertia[a, b] -= mass * ((cc if a == b else 0.0) - c[a] * c[b])
    rs.mass[0] = mass
    rs.com[:] = c
    rs.inertia[:, :] = inertia
    moments, axes = jacobi3(inertia)
    rs.moments[:] = moments
    rs.axes[:, :] = axes


@njit(cache=True)
def place_body(hub, coil, cs, rs, pos, vel):
    """Tied and held nodes move with the body: x = X + R (r - c), v = V + omega x (x - X),
    omega = I_s^{-1} Pi (at the body's current attitude and half-step momentum)."""
    R = rotation(rs.quaternion)
    w = inv_inertia(rs, R, rs.momentum)
    X, V, c = rs.position, rs.velocity, rs.com
    # arrays taken out of their tuples before the loops, rows passed by index: a field or a
    # row view taken per node costs numba reference counts per node (most of a step of the
    # free-hub tethers)
    tied_idx, tied_ref = hub.tied_idx, hub.tied_ref
    arm_ptr, level_ptr, front = coil.arm_ptr, coil.level_ptr, cs.front
    level_nodes, level_ref = coil.level_nodes, coil.level_ref
    for k in range(tied_idx.shape[0]):
        _place(tied_idx[k], tied_ref, k, R, X, V, c, w, pos, vel)
    for k in range(arm_ptr.shape[0] - 1):
        for p in range(level_ptr[arm_ptr[k] + front[k]], level_ptr[arm_ptr[k + 1]]):
            _place(level_nodes[p], level_ref, p, R, X, V, c, w, pos, vel)


@njit(inline="always")
def _place(i, refs, row, R, X, V, c, w, pos, vel):
    """Node i at its body-frame position refs[row]."""
    r0, r1, r2 = refs[row, 0] - c[0], refs[row, 1] - c[1], refs[row, 2] - c[2]
    for a in range(3):
        pos[i, a] = X[a] + R[a, 0] * r0 + R[a, 1] * r1 + R[a, 2] * r2
    dx = pos[i, 0] - X[0]
    dy = pos[i, 1] - X[1]
    dz = pos[i, 2] - X[2]
    vel[i, 0] = V[0] + w[1] * dz - w[2] * dy
    vel[i, 1] = V[1] + w[2] * dx - w[0] * dz
    vel[i, 2] = V[2] + w[0] * dy - w[1] * dx


@njit(cache=True)
def body_loads(hub, coil, cs, X, pos, force):
    """(F, T): the sum of the forces on the tied and held nodes and their moment about the
    point X (3,) [m] (the body's centre of mass; force: one (n, 3) buffer)."""
    F = np.zeros(3)
    T = np.zeros(3)
    tied_idx = hub.tied_idx  # taken out before the loops (see place_body)
    arm_ptr, level_ptr, front, level_nodes = coil.arm_ptr, coil.level_ptr, cs.front, \
        coil.level_nodes
    for k in range(tied_idx.shape[0]):
        _load(tied_idx[k], X, pos, force, F, T)
    for k in range(arm_ptr.shape[0] - 1):
        for p in range(level_ptr[arm_ptr[k] + front[k]], level_ptr[arm_ptr[k + 1]]):
            _load(level_nodes[p], X, pos, force, F, T)
    return F, T


@njit(inline="always")
def _load(i, X, pos, force, F, T):
    fx, fy, fz = force[i, 0], force[i, 1], force[i, 2]
    dx, dy, dz = pos[i, 0] - X[0], pos[i, 1] - X[1], pos[i, 2] - X[2]
    F[0] += fx
    F[1] += fy
    F[2] += fz
    T[0] += dy * fz - dz * fy
    T[1] += dz * fx - dx * fz
    T[2] += dx * fy - dy * fx


@njit(cache=True)
def free_rotation(rs, dt):
    """Turn the body over dt with its angular momentum Pi fixed (the symmetric splitting of
    the module docstring); Pi is untouched, q is renormalised."""
    q = rs.quaternion
    P = rs.axes
    b = mul_t(rotation(q), rs.momentum)
    m = np.empty(3)  # body components along the principal axes
    for k in range(3):
        m[k] = P[0, k] * b[0] + P[1, k] * b[1] + P[2, k] * b[2]
    spin = 0  # the principal axis nearest the hub axis turns in the middle, for dt
    for k in range(1, 3):
        if abs(P[2, k]) > abs(P[2, spin]):
            spin = k
    a, c = (spin + 1) % 3, (spin + 2) % 3
    for k, h in ((a, 0.5), (c, 0.5), (spin, 1.0), (c, 0.5), (a, 0.5)):
        theta = h * dt * m[k] / rs.moments[k]  # exact flow of m_k^2 / (2 I_k)
        i, j = (k + 1) % 3, (k + 2) % 3
        ct, st = np.cos(theta), np.sin(theta)
        mi, mj = m[i], m[j]
        m[i] = ct * mi + st * mj
        m[j] = -st * mi + ct * mj
        turn(q, P[:, k].copy(), theta)
    normalise(q)


@njit(cache=True)
def detach(body, nodes, hub, coil, cs, rs):
    """After a release of held nodes (their velocities already those of the body): the
    body's new mass, centre of mass, inertia and principal axes, and its V and Pi such that
    every point keeps its velocity (so momentum and energy are continuous to round-off)."""
    R = rotation(rs.quaternion)
    w = inv_inertia(rs, R, rs.momentum)
    X_old = rs.position.copy()
    centre = hub_centre(rs, R)
    assemble(body, nodes, hub, coil, cs, rs)
    X = centre + mul(R, rs.com)
    rs.position[:] = X
    rs.velocity[:] = rs.velocity + cross(w, X - X_old)  # the body's velocity at the new X
    rs.momentum[:] = mul(spatial_inertia(rs, R), w)


@njit(cache=True)
def body_energy(rs, R, V, Pi):
    """Kinetic energy M V^2 / 2 + Pi . I_s^{-1} Pi / 2 [J] at attitude R."""
    w = inv_inertia(rs, R, Pi)
    return 0.5 * rs.mass[0] * (V[0] ** 2 + V[1] ** 2 + V[2] ** 2) \
        + 0.5 * (Pi[0] * w[0] + Pi[1] * w[1] + Pi[2] * w[2])


def rigid_start(model, cs, omega: float, tilt_rate: float = 0.0) -> RigidState:
    """The body at rest in translation, hub frame = inertial, turning at (tilt_rate, 0,
    omega) [rad/s] about the hub-frame axes (x: the transverse rate, z: the spin)."""
    rs = RigidState(np.zeros(3), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3),
                    np.zeros(1), np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3))
    assemble(model.body, model.nodes, model.hub, model.coil, cs, rs)
    w = np.array([float(tilt_rate), 0.0, float(omega)])
    rs.position[:] = rs.com  # the hub centre at the origin
    rs.velocity[:] = np.cross(w, rs.com)  # the hub centre at rest
    rs.momentum[:] = rs.inertia @ w
    return rs


@njit(inline="always")
def turn_node(pos, vel, i, ref, c, s, omega):
    """Node ``i`` moves with a hub turned by the angle whose cosine and sine are ``c``,
    ``s``, spinning at ``omega`` [rad/s] about z: x = R x_hub (``ref`` (3,)), v = omega z x x."""
    x = c * ref[0] - s * ref[1]
    y = s * ref[0] + c * ref[1]
    pos[i, 0] = x
    pos[i, 1] = y
    pos[i, 2] = ref[2]
    vel[i, 0] = -omega * y
    vel[i, 1] = omega * x
    vel[i, 2] = 0.0
