"""The hub on a fixed axis (+z through the origin): its phases of the step.

The hub turns at omega about +z with the effective inertia J_eff (the hub, its tied nodes and
the held coil); a torque law integrates

    J_eff omega' = M + tau,    tau = z-moment of the forces on the nodes that move with it,

and a prescribed-rate law imposes omega at the half step and reports the torque it takes.
Its node pass is the fast one: v += dt f / m, the cable-hub contact (fe.hub.contact) of the nodes
heading inside the rim, x += dt v, in one straight loop over node blocks that LLVM
vectorises, on several threads when the contact is frictionless (friction turns the hub node
by node). Every function here takes arrays and scalars, not whole tuples, where it runs
every step (numba counts a reference per array handed over: docs/performance.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from spinweb_fe.fe.coil.bundles import gather_bundles, scatter_bundles
from spinweb_fe.fe.coil.levels import held_moment
from spinweb_fe.fe.control import eval_control
from spinweb_fe.fe.hub.contact import contact_node
from spinweb_fe.fe.hub.rigid import body_loads, turn_node
from spinweb_fe.fe.tidal import axis_hub_tidal, node_tidal, tidal_power


class Axis(NamedTuple):
    """The hub on a fixed axis, as the step kernels see it (``Kernel.axis``; None for a free
    hub): ``j_eff`` [kg m^2], the hub's inertia plus its tied nodes' m r^2."""

    j_eff: float


class AxisKick(NamedTuple):
    """The fixed-axis hub over one step: control torque M_n [N m], omega_{n-1/2},
    omega_{n+1/2} [rad/s] and the effective inertia J_eff [kg m^2] now."""

    torque: float
    rate_old: float
    rate_new: float
    j_eff: float


class NodeMotion(NamedTuple):
    """The node arrays of the State that the node pass updates or reads (a flat tuple, as
    the parallel kernels take it)."""

    pos: np.ndarray
    vel: np.ndarray
    mass: np.ndarray
    inv_mass: np.ndarray


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
        turn_node(pos, vel, idx[k], ref[k], c, s, omega)


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


@njit(inline="always")
def axis_kick(tied_idx, law, pos, force, tau_held, w_old, j_eff, t, dt):
    """Loads on the hub at x_n (the moment of the forces on its tied nodes, plus
    ``tau_held``, that of the held coil and a device's line while some coil is held) and its
    rate over the step: an AxisKick."""
    tau = moment_of(pos, force, tied_idx)
    if tau_held != 0.0:
        tau += tau_held
    torque, w_new = hub_step(law, j_eff, tau, w_old, t, dt)
    return AxisKick(torque, w_old, w_new, j_eff)


@njit(inline="always")
def axis_field(env, t, nodes, tied_idx, coil, cs, bundles, mv, force, tidal, field, holding):
    """The gravity gradient at x_n on a scene whose hub turns on a fixed axis: m g(x) on
    every node (into ``tidal`` and added to ``force``; the nodes that move with the hub
    turn it by the moment about +z, the axis holds the rest), ``field[0]`` the power of the
    tidal forces on the free nodes [W] (a bundle's summed on its spine node), ``field[1]``
    their moment about +z on the nodes that move with the hub [N m]."""
    node_tidal(env, t, mv.pos, nodes.mass, force, tidal)
    tau = moment_of(mv.pos, tidal, tied_idx)
    if holding:
        tau += held_moment(coil.arm_ptr, cs.front, coil.level_ptr, coil.level_nodes, mv.pos,
                           tidal)
    gather_bundles(bundles, cs, tidal)
    field[0] = tidal_power(tidal, mv.vel, mv.inv_mass)
    field[1] = tau


@njit(inline="always")
def axis_field_work(field, tidal, mv, ak, dt):
    """The gravity gradient's work over the step [J]: dt (P_n + P_{n+1/2}) / 2 on the free
    nodes (P the tidal power with v_{n-1/2} and v_{n+1/2}) and its moment's work on the
    hub, dt tau (omega_{n-1/2} + omega_{n+1/2}) / 2, as the control torque's."""
    p1 = tidal_power(tidal, mv.vel, mv.inv_mass)
    return 0.5 * dt * (field[0] + p1) + field[1] * dt * 0.5 * (ak.rate_old + ak.rate_new)


@njit(cache=True)
def axis_reaction(env, t, hub, coil, cs, pos, force, row, vs):
    """The torque the fixed axis exerts on the hub about its centre, into the row's slots
    ``vs.axis_torque``: minus the x and y parts of the moment of the forces on the nodes
    that move with the hub and of the tidal torque on the hub itself (z: 0; the control
    torque is recorded apart)."""
    _, T = body_loads(hub, coil, cs, np.zeros(3), pos, force)
    if env.n > 0.0:
        T += axis_hub_tidal(env, t, hub)
    a = vs.axis_torque
    row[a] = -T[0]
    row[a + 1] = -T[1]
    row[a + 2] = 0.0


@njit(inline="always", error_model="numpy")
def drift(mv, dt, lo, hi):
    """x_{n+1} = x_n + dt v_{n+1/2} for the nodes of lo..hi-1 with active mass (a straight
    loop: the others add 0 dt v)."""
    pos, vel, inv_mass = mv.pos, mv.vel, mv.inv_mass
    for q in range(hi - lo):
        i = np.uint64(lo + q)
        h = dt if inv_mass[i] > 0.0 else 0.0
        pos[i, 0] += h * vel[i, 0]
        pos[i, 1] += h * vel[i, 1]
        pos[i, 2] += h * vel[i, 2]


@njit(inline="always", error_model="numpy")
def kick_drift(mv, force, dt, lo, hi):
    """v += dt f / m, then :func:`drift`, in one straight loop (no contact, no records)."""
    pos, vel, inv_mass = mv.pos, mv.vel, mv.inv_mass
    for q in range(hi - lo):
        i = np.uint64(lo + q)
        im = inv_mass[i]
        h = dt if im > 0.0 else 0.0  # a node without active mass stays where it is
        for d in range(3):
            v = vel[i, d] + dt * force[i, d] * im
            vel[i, d] = v
            pos[i, d] += h * v


@njit(inline="always", error_model="numpy")
def kick(mv, force, contact, inside, r0, dt, lo, hi, move):
    """v_{n+1/2} = v_{n-1/2} + dt f / m for nodes lo..hi-1 in a straight loop that LLVM
    vectorises (a node without active mass, 1/m = 0: tied, held, inside a bundle, adds
    nothing); ``inside[i]`` marks a contact node with active mass heading inside the hub
    cylinder (x_n + dt v_{n+1/2} within r0 of the axis). With ``move`` the same loop drifts
    every other node with active mass (:func:`drift`): the marked ones wait for their
    contact. Returns whether any node is marked."""
    pos, vel, inv_mass = mv.pos, mv.vel, mv.inv_mass
    hit = 0
    for q in range(hi - lo):
        i = np.uint64(lo + q)
        im = inv_mass[i]
        vx = vel[i, 0] + dt * force[i, 0] * im
        vy = vel[i, 1] + dt * force[i, 1] * im
        vz = vel[i, 2] + dt * force[i, 2] * im
        vel[i, 0] = vx
        vel[i, 1] = vy
        vel[i, 2] = vz
        px = pos[i, 0] + dt * vx
        py = pos[i, 1] + dt * vy
        into = (px * px + py * py < r0 * r0) and contact[i] and im > 0.0
        inside[i] = into
        h = dt if move and im > 0.0 and not into else 0.0
        pos[i, 0] += h * vx
        pos[i, 1] += h * vy
        pos[i, 2] += h * vz
        hit |= 1 if into else 0
    return hit > 0


@njit(inline="always")
def touch_hub(hub, mv, force, inside, omega, dw_force, j_eff, dt, lo, hi, move):
    """Cable-hub contact of the nodes of lo..hi-1 marked ``inside``, in node order (friction
    turns the hub node by node); with ``move`` each then takes its drift. Returns (omega,
    contact dissipation [J])."""
    pos, vel, node_mass = mv.pos, mv.vel, mv.mass
    diss = 0.0
    for i in range(lo, hi):
        if inside[i]:
            omega, d = contact_node(i, pos, vel, force, node_mass[i], hub.radius, hub.friction,
                                    j_eff, omega, dw_force, dt)
            diss += d
            if move:
                for k in range(3):
                    pos[i, k] += dt * vel[i, k]
    return omega, diss


@njit(cache=True, no_cpython_wrapper=True)
def spin_sums(mv, lo, hi):
    """(sum m |v|^2, sum m (x v_y - y v_x)) over the nodes of lo..hi-1 with active mass."""
    pos, vel, inv_mass, node_mass = mv.pos, mv.vel, mv.inv_mass, mv.mass
    ke = 0.0
    lz = 0.0
    for i in range(lo, hi):
        if inv_mass[i] > 0.0:
            m = node_mass[i]
            ke += m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
            lz += m * (pos[i, 0] * vel[i, 1] - pos[i, 1] * vel[i, 0])
    return ke, lz


@njit(cache=True, no_cpython_wrapper=True)
def integrate_nodes(nodes, hub, mv, force, inside, omega, dw_force, j_eff, dt, lo, hi, record,
                    out):
    """Node pass over nodes lo..hi-1 on a record step or with a hub (:func:`axis_nodes` takes
    the other steps in one straight loop): v += dt f/m, cable-hub contact, x += dt v.
    ``mv``: :class:`NodeMotion`; nodes with no active mass (tied, held, inside a bundle)
    stay; ``j_eff`` [kg m^2] is the hub's inertia now; ``inside`` (n,) bool: scratch for the
    nodes heading inside the hub. Contact is looked at only in a block where some node heads
    inside the hub. On record steps ``out[:4]`` receives the kinetic energy and angular
    momentum sums before and after the update. Returns (omega, contact dissipation [J])."""
    contact = nodes.contact
    r0 = hub.radius
    diss = 0.0
    if not record:  # one loop; the nodes heading inside get their contact, then move
        if kick(mv, force, contact, inside, r0, dt, lo, hi, True):
            omega, diss = touch_hub(hub, mv, force, inside, omega, dw_force, j_eff, dt, lo, hi,
                                    True)
        return omega, diss
    out[0], out[2] = spin_sums(mv, lo, hi)
    if kick(mv, force, contact, inside, r0, dt, lo, hi, False):  # v_{n+1/2}, no drift yet
        omega, diss = touch_hub(hub, mv, force, inside, omega, dw_force, j_eff, dt, lo, hi,
                                False)
    out[1], out[3] = spin_sums(mv, lo, hi)
    out[0] *= 0.5
    out[1] *= 0.5
    drift(mv, dt, lo, hi)  # x_{n+1} = x_n + dt v_{n+1/2}
    return omega, diss


@njit(cache=True, parallel=True)
def integrate_threads(nodes, hub, mv, force, inside, omega, dw_force, j_eff, dt, nout, chunks,
                      record):
    """:func:`integrate_nodes` on several threads (frictionless contact only: friction turns
    the hub node by node): node block b (``nout.shape[0]`` blocks of equal size) into
    nout[b] = (ke0, ke1, lz0, lz1, contact dissipation), the blocks in one contiguous chunk
    per thread."""
    n = force.shape[0]
    nb = nout.shape[0]
    size = -(-n // nb)
    for c in prange(chunks):
        for b in range(nb * c // chunks, nb * (c + 1) // chunks):
            _, nout[b, 4] = integrate_nodes(nodes, hub, mv, force, inside, omega, dw_force,
                                            j_eff, dt, b * size, min(n, (b + 1) * size),
                                            record, nout[b])


@njit(cache=True, parallel=True)
def kick_drift_threads(mv, force, dt, chunks):
    """:func:`kick_drift` of every node, one contiguous range of nodes per thread."""
    n = force.shape[0]
    for c in prange(chunks):
        kick_drift(mv, force, dt, n * c // chunks, n * (c + 1) // chunks)


@njit(cache=True)
def axis_nodes(nodes, hub, mv, ak, work, dt, sums, record, threads=None):
    """Velocity and position update of every free node against the hub of the AxisKick
    ``ak``: one straight loop when there is nothing to sum and no hub to touch, else in node
    blocks (``work.nout`` (blocks, 5): their partial sums); on several threads when contact
    is frictionless. ``sums[:5]`` receives the kinetic energy and angular momentum sums
    (record steps) and the contact dissipation, added in block order. Returns (the AxisKick
    with omega_{n+1/2} after friction, contact dissipation [J])."""
    force, nout, inside = work.force, work.nout, work.inside
    n = force.shape[0]
    w_old, w_new, j_eff = ak.rate_old, ak.rate_new, ak.j_eff
    if not (record or hub.radius > 0.0):  # nothing to sum, no contact: one straight loop
        if threads is None:
            kick_drift(mv, force, dt, 0, n)
        else:
            kick_drift_threads(mv, force, dt, threads)
        sums[4] = 0.0
        return ak, 0.0
    nb = nout.shape[0]
    size = -(-n // nb)
    w = w_new
    if threads is not None and hub.friction == 0.0:  # None: pruned by numba
        integrate_threads(nodes, hub, mv, force, inside, w_new, w_new - w_old, j_eff, dt, nout,
                          threads, record)
    else:
        for b in range(nb):
            w, nout[b, 4] = integrate_nodes(nodes, hub, mv, force, inside, w, w_new - w_old,
                                            j_eff, dt, b * size, min(n, (b + 1) * size),
                                            record, nout[b])
    for k in range(5):
        sums[k] = 0.0
        for b in range(nb):
            sums[k] += nout[b, k]
    return AxisKick(ak.torque, w_old, w, j_eff), sums[4]


@njit(inline="always")
def axis_row(ak, sums):
    """(mean hub rate, kinetic energy, angular momentum about +z) of a row: the nodes' sums
    of :func:`integrate_nodes` and the hub turning at the mean of its half-step rates."""
    w_old, w_new, j_eff = ak.rate_old, ak.rate_new, ak.j_eff
    ke = 0.5 * (sums[0] + sums[1]) + 0.25 * j_eff * (w_old * w_old + w_new * w_new)
    lz = 0.5 * (sums[2] + sums[3]) + j_eff * 0.5 * (w_old + w_new)
    return 0.5 * (w_old + w_new), ke, lz


@njit(cache=True)
def _add_spin(i, mass, pos, acc):
    """acc += m_i (-y, x, z x, z y) of node i (the sums of :func:`axis_vector_row`)."""
    m = mass[i]
    acc[0] -= m * pos[i, 1]
    acc[1] += m * pos[i, 0]
    acc[2] += m * pos[i, 2] * pos[i, 0]
    acc[3] += m * pos[i, 2] * pos[i, 1]


@njit(cache=True)
def axis_vector_row(hub, coil, cs, nodes, pos, theta, w, j_eff, row, vs):
    """The fixed-axis hub's part of a vector row (slots ``vs``): the tied and held nodes
    (model masses) turning at w about z, the hub's own spin, and its pose (at the origin,
    axis +z, angle theta)."""
    acc = np.zeros(4)  # sum m (-y, x, z x, z y) over the tied and held nodes
    for k in range(hub.tied_idx.shape[0]):
        _add_spin(hub.tied_idx[k], nodes.mass, pos, acc)
    for k in range(coil.arm_ptr.shape[0] - 1):
        for p in range(coil.level_ptr[coil.arm_ptr[k] + cs.front[k]],
                       coil.level_ptr[coil.arm_ptr[k + 1]]):
            _add_spin(coil.level_nodes[p], nodes.mass, pos, acc)
    px, py, sx, sy = acc[0], acc[1], acc[2], acc[3]
    p, lm = vs.linear_momentum, vs.angular_momentum_vector
    row[p] += w * px  # sum m w z x x
    row[p + 1] += w * py
    row[lm] -= w * sx  # sum m x x (w z x x) = w sum m ((x^2 + y^2) z - z (x, y, 0))
    row[lm + 1] -= w * sy
    row[lm + 2] += j_eff * w  # J_eff counts the tied and held m (x^2 + y^2)
    for d in range(3):
        row[vs.hub_position + d] = 0.0
        row[vs.hub_axis + d] = 0.0
        row[vs.hub_angular_velocity + d] = 0.0
    q = vs.hub_quaternion
    row[q] = np.cos(0.5 * theta)
    row[q + 1] = 0.0
    row[q + 2] = 0.0
    row[q + 3] = np.sin(0.5 * theta)
    row[vs.hub_axis + 2] = 1.0
    row[vs.hub_angular_velocity + 2] = w


def axis_start(model, law, state, force, dt):
    """v_{-1/2} = v_0 - dt/2 a_0 of the free nodes and omega_{-1/2} of the hub (a prescribed
    rate takes the law's rate at -dt/2); ``force`` (n, 3): the internal forces at x_0.

    Python, not a kernel: it runs once, and a kernel taking the whole model and state costs
    about a second of cold compile for their unboxing alone. The compiled helpers it calls
    are the step loop's own; the arithmetic is the same, in the same order (bit for bit)."""
    hub, coil, cs = model.hub, model.coil, state.coil
    pos = state.node_pos
    vel = state.node_vel
    if model.env.n > 0.0:  # the gravity gradient's forces (fe.hub.axis.axis_field)
        node_tidal(model.env, 0.0, pos, model.nodes.mass, force, np.zeros_like(force))
    if model.bundles is not None:
        gather_bundles(model.bundles, cs, force)
    vel -= 0.5 * dt * force * state.node_inv_mass[:, None]
    tau = (moment_of(pos, force, hub.tied_idx)
           + held_moment(coil.arm_ptr, cs.front, coil.level_ptr, coil.level_nodes, pos, force))
    rate = state.hub.rate
    prescribed, value = eval_control(law, 0.0, rate[0])
    if prescribed:
        _, rate[0] = eval_control(law, -0.5 * dt, rate[0])
    else:
        rate[0] -= 0.5 * dt * (value + tau) / state.hub.inertia[0]
    if model.bundles is not None:
        scatter_bundles(model.bundles, state.coil, pos, vel)
