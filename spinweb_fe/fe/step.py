"""The explicit central-difference step: ``advance`` and every numba kernel it calls.

Central differences with half-step velocities (Kratos / LS-DYNA style):

    f_n        = internal forces at x_n (damping with v_{n-1/2}): element force vectors,
                 then their sum per node (fe.forces)
    v_{n+1/2}  = v_{n-1/2} + dt f_n / m                       (free nodes)
    omega_{n+1/2} = omega_{n-1/2} + dt (M_n + tau_n) / J_eff  (hub, or prescribed)
    contact    : radial impulse so that x_{n+1} stays outside the hub (+ Coulomb friction)
    x_{n+1}    = x_n + dt v_{n+1/2};  theta_{n+1} = theta_n + dt omega_{n+1/2}
    tied nodes : x = R(theta_{n+1}) x_hub

    held coil  : x = R(theta_{n+1}) x_hub; then the peel fronts and bundles (fe.coil)

The kernels take the named data of :mod:`spinweb_fe.fe.model` (``Model.kernel``: elements,
links, nodes, hub, coil), :mod:`spinweb_fe.fe.state` (``State``), the law (``KernelLaw``) and
``Recording`` below. The features they call live in their own files of ``fe/`` (contact, hub,
coil, control, rupture, forces): the numba cache of every ``fe`` kernel is stamped with the whole folder
(:mod:`spinweb_fe.fe.cache`), so an edit of a helper recompiles its callers. Constants come
in as arguments, never as module globals. The element pass uses ``error_model="numpy"`` so
that divisions carry no Python zero-division check (a branch per element); its divisor is
never zero.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from spinweb_fe.fe.coil import (any_held, front_row, gather_bundles, held_moment, open_bundles,
                                payout_allowed, place_held, release_fronts, scatter_bundles)
from spinweb_fe.fe.contact import contact_node
from spinweb_fe.fe.control import eval_control
from spinweb_fe.fe.forces import element_forces, node_forces
from spinweb_fe.fe.hub import hub_step, moment_of, place_rigid
from spinweb_fe.fe.rupture import record_strength, strength_pass
from spinweb_fe.fe.vectors import fixed_hub_row, node_momenta, plane_stats

#: columns of the per-record scalar table that ``advance`` writes (see
#: spinweb_fe.record.history for units and meaning)
REC_COLUMNS = ("time", "hub_angle", "hub_omega", "hub_torque", "kinetic_energy",
               "strain_energy", "torque_work", "damping_dissipation", "contact_dissipation",
               "angular_momentum", "max_tension")


class Recording(NamedTuple):
    """Where ``advance`` records history rows (one every ``every`` steps).

    Attributes
    ----------
    every : int
        Steps between two rows.
    probes : (p,) int64
        Nodes whose positions and velocities are recorded (arm tips and spines).
    table : (rows, len(REC_COLUMNS)) float64
        Scalar columns of each row.
    probe_pos, probe_vel : (rows, p, 3) float64 [m], [m/s]
        Probe positions x_n and mean velocities (v_{n-1/2} + v_{n+1/2}) / 2.
    arm_table : (rows, n_arms, 5) float64
        Per arm: front and next outer level coordinates [m], pinned on the rim (1/0), held
        back by the payout law (1/0), allowed payout [m] (see record_arms).
    strength_table : (rows, 5) float64
        Scenes with a failure strain: the row of fe.rupture.STRENGTH_COLUMNS ((rows, 0)
        otherwise).
    """

    every: int
    probes: np.ndarray
    table: np.ndarray
    probe_pos: np.ndarray
    probe_vel: np.ndarray
    arm_table: np.ndarray
    strength_table: np.ndarray


class NodeMotion(NamedTuple):
    """The node arrays of the State that the node pass updates or reads (a flat tuple, as
    the parallel kernels take it)."""

    pos: np.ndarray
    vel: np.ndarray
    mass: np.ndarray
    inv_mass: np.ndarray


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
    """Node pass over nodes lo..hi-1 on a record step or with a hub (:func:`node_pass` takes
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


@njit(cache=True, no_cpython_wrapper=True)
def checks_strength(strength):
    """Whether the kernel's ``strength`` checks any element (None: no, at compile time)."""
    if strength is None:
        return False
    return strength.fail.shape[0] > 0


@njit(cache=True)
def element_pass(elems, links, strength, ss, pos, vel, work, record, dt, threads=None):
    """The internal forces at x_n into ``work.force`` (n, 3) (overwritten): every element's force
    vector (fe.forces, or the strength pass of fe.rupture for a scene with a failure strain;
    ``ss`` its state, ``dt`` the step), then their sum per node. Returns (strain energy, max
    tension, damping power).

    ``strength`` None (no strength check) and ``threads`` None (one thread) are decided by
    numba from the argument types, before it types the branches: a scene compiles only the
    passes it can take (the strength and thread kernels cost seconds of compile time)."""
    if strength is not None and strength.fail.shape[0] > 0:  # pruned by numba when None
        se, tmax, pdamp = strength_pass(elems, strength, ss, pos, vel, work, record, dt,
                                        threads)
    else:
        se, tmax, pdamp = element_forces(elems, links, pos, vel, work, record, threads)
    node_forces(links, work, threads)
    return se, tmax, pdamp


@njit(cache=True)
def node_pass(nodes, hub, mv, j_eff, work, w_old, w_new, dt, sums, record, threads=None):
    """Velocity and position update of every free node: one straight loop when there is
    nothing to sum and no hub to touch, else in node blocks (``nout`` (blocks, 5): their
    partial sums); on several threads when contact is frictionless. ``sums[:5]`` receives
    the kinetic energy and angular momentum sums (record steps) and the contact dissipation,
    added in block order. Returns (omega_{n+1/2} after friction, contact dissipation [J])."""
    force, nout, inside = work.force, work.nout, work.inside
    n = force.shape[0]
    if not (record or hub.radius > 0.0):  # nothing to sum, no contact: one straight loop
        if threads is None:
            kick_drift(mv, force, dt, 0, n)
        else:
            kick_drift_threads(mv, force, dt, threads)
        sums[4] = 0.0
        return w_new, 0.0
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
    return w, sums[4]


@njit(cache=True, no_cpython_wrapper=True)
def probe_positions(rec, k, pos, vel, vprobe):
    """Probe positions x_n into row k, before the node pass; v_{n-1/2} kept in ``vprobe``."""
    probes = rec.probes
    for p in range(probes.shape[0]):
        for d in range(3):
            vprobe[p, d] = vel[probes[p], d]
            rec.probe_pos[k, p, d] = pos[probes[p], d]


@njit(cache=True, no_cpython_wrapper=True)
def probe_velocities(rec, k, vel, vprobe):
    """Probe velocities of row k after the node pass: the mean of v_{n-1/2} and v_{n+1/2}."""
    probes = rec.probes
    for p in range(probes.shape[0]):
        for d in range(3):
            rec.probe_vel[k, p, d] = 0.5 * (vprobe[p, d] + vel[probes[p], d])


@njit(cache=True, no_cpython_wrapper=True)
def write_row(row, t, theta, w_old, w_new, torque, j_eff, sums, se, tmax, totals, incr):
    """One history row at step n (REC_COLUMNS): energies as the mean of the two half-step
    values, accumulated work and dissipation up to t_n (``incr``: this step's increments)."""
    row[0] = t
    row[1] = theta
    row[2] = 0.5 * (w_old + w_new)
    row[3] = torque
    row[4] = 0.5 * (sums[0] + sums[1]) + 0.25 * j_eff * (w_old * w_old + w_new * w_new)
    row[5] = se
    row[6] = totals.torque_work[0] + 0.5 * incr[0]
    row[7] = totals.damping_dissipation[0] + 0.5 * incr[1]
    row[8] = totals.contact_dissipation[0] + 0.5 * incr[2]
    row[9] = 0.5 * (sums[2] + sums[3]) + j_eff * 0.5 * (w_old + w_new)
    row[10] = tmax


@njit(cache=True, no_cpython_wrapper=True)
def record_arms(coil, cs, table, t):
    """Per arm at a record step (see fe.coil.front_row): the front's and the next outer
    level's arm coordinates, pinned on the rim (1/0), held back by the payout law (1/0),
    and the paid-out length the law allows (NaN: free payout)."""
    allowed = payout_allowed(coil, t)
    for k in range(table.shape[0]):
        table[k, 0], table[k, 1], table[k, 2], table[k, 3] = front_row(coil, cs, k, t)
        table[k, 4] = allowed if np.isfinite(allowed) else np.nan


@njit(cache=True, nogil=True)
def advance(model, law, state, work, rec, dt, nsteps, vec=None, threads=None):
    """Run ``nsteps`` central-difference steps; record a history row every ``rec.every`` steps.

    ``model`` is the kernel view of the Model (``Model.kernel``); ``work`` the scratch of the
    force passes (:func:`spinweb_fe.fe.forces.make_work`). Row k of ``rec.table`` holds
    REC_COLUMNS at integer step n,
    ``rec.probe_pos/vel`` the probe positions x_n and mean velocities, ``rec.arm_table`` the
    arm data of :func:`record_arms`, and ``vec`` (rows, fe.vectors.VEC_WIDTH), if given, the
    momentum vectors, the hub's pose and the distances from the hub plane (a run that can
    leave the plane; without it numba compiles none of that). ``threads``: None for one
    thread (numba compiles no thread kernel), else the number of threads, which run the
    workspace's chunks; every thread count gives the same bits (fixed blocks, fixed
    reduction order). Returns (status, rows): 0 ok, 1 non-finite.
    """
    elems, nodes, hub, coil = model.elements, model.nodes, model.hub, model.coil
    strength = model.strength
    has_strength = checks_strength(strength)
    pos = state.node_pos
    vel = state.node_vel
    force = work.force
    sums = np.zeros(5)
    incr = np.zeros(3)
    vprobe = np.zeros((rec.probes.shape[0], 3))
    totals = state.totals
    has_coil = coil.level_nodes.shape[0] > 0
    # the state's arrays taken out once: every use of a tuple's field inside the loop, and
    # every tuple handed to a compiled function, costs NRT reference counts (an atomic add
    # per array), which made 40 % of a 200-element step
    links, bundles, cs, ss = model.links, model.bundles, state.coil, state.strength
    mass, inv_mass, broken = state.node_mass, state.node_inv_mass, ss.broken
    mv = NodeMotion(pos, vel, mass, inv_mass)
    hub_angle, hub_rate, hub_inertia = state.hub.angle, state.hub.rate, state.hub.inertia
    step_no, time_now = state.step, state.time
    torque_work = totals.torque_work
    damping_dissipation = totals.damping_dissipation
    contact_dissipation = totals.contact_dissipation
    arm_ptr, front = coil.arm_ptr, cs.front
    nrec = np.int64(0)  # not the literal 0: a literal argument compiles callees twice
    for _ in range(nsteps):
        step = step_no[0]
        holding = any_held(arm_ptr, front)
        record = step % rec.every == 0
        t = step * dt
        se, tmax, pdamp = element_pass(elems, links, strength, ss, pos, vel, work, record, dt,
                                       threads)
        tau = moment_of(pos, force, hub.tied_idx)
        if holding:
            tau += held_moment(coil, cs, pos, force)
        if has_coil:
            gather_bundles(bundles, cs, force)
        w_old = hub_rate[0]
        j_eff = hub_inertia[0]
        torque, w_new = hub_step(law, j_eff, tau, w_old, t, dt)
        if record:
            probe_positions(rec, nrec, pos, vel, vprobe)
            record_arms(coil, cs, rec.arm_table[nrec], t)
            if has_strength:
                record_strength(ss, rec.strength_table[nrec])
            if vec is not None:
                vec[nrec] = 0.0
                node_momenta(pos, vel, mass, inv_mass, vec[nrec], 0.5)
                plane_stats(pos, nodes.inv_mass, np.zeros(3), np.array([0.0, 0.0, 1.0]),
                            vec[nrec])
        theta = hub_angle[0]
        w_new, dcontact = node_pass(nodes, hub, mv, j_eff, work, w_old, w_new, dt, sums,
                                    record, threads)
        if has_coil:
            scatter_bundles(bundles, cs, pos, vel)
        incr[0] = torque * dt * 0.5 * (w_new + w_old)  # exact discrete work on the hub
        incr[1] = pdamp * dt
        incr[2] = dcontact
        if record:
            write_row(rec.table[nrec], t, theta, w_old, w_new, torque, j_eff, sums, se, tmax,
                      totals, incr)
            if vec is not None:
                node_momenta(pos, vel, mass, inv_mass, vec[nrec], 0.5)
                fixed_hub_row(hub, coil, cs, nodes, pos, theta, 0.5 * (w_old + w_new),
                              j_eff, vec[nrec])
            if not (np.isfinite(rec.table[nrec, 4]) and np.isfinite(se)):
                return 1, nrec
            probe_velocities(rec, nrec, vel, vprobe)
            nrec += 1
        hub_angle[0] = theta + dt * w_new
        hub_rate[0] = w_new
        torque_work[0] += incr[0]
        damping_dissipation[0] += incr[1]
        contact_dissipation[0] += incr[2]
        step_no[0] = step + 1
        time_now[0] = (step + 1) * dt
        place_rigid(pos, vel, hub.tied_idx, hub.tied_ref, hub_angle[0], w_new)
        if holding:  # the held nodes move with the hub; then the fronts the arms pull off
            place_held(coil, cs, pos, vel, hub_angle[0], w_new)
            hub_inertia[0] = release_fronts(coil, cs, elems, nodes, pos, mass, inv_mass,
                                            hub_inertia[0], (step + 1) * dt, broken)
        if has_coil:  # and the bundles that are due open
            open_bundles(bundles, cs, nodes, mass, inv_mass, (step + 1) * dt)
    return 0, nrec


def start_half_step(model, law, state, force, dt):
    """Turn initial velocities v_0, omega_0 into v_{-1/2}, omega_{-1/2} = v_0 - dt/2 a_0;
    ``force`` (n, 3): the internal forces at x_0 (fe.forces.internal_forces).

    Python, not a kernel: it runs once, and a kernel taking the whole model and state costs
    about a second of cold compile for their unboxing alone. The compiled helpers it calls
    are the step loop's own; the arithmetic is the same, in the same order (bit for bit)."""
    hub, coil = model.hub, model.coil
    pos = state.node_pos
    vel = state.node_vel
    if model.bundles is not None:
        gather_bundles(model.bundles, state.coil, force)
    vel -= 0.5 * dt * force * state.node_inv_mass[:, None]
    tau = moment_of(pos, force, hub.tied_idx) + held_moment(coil, state.coil, pos, force)
    rate = state.hub.rate
    prescribed, value = eval_control(law, 0.0, rate[0])
    if prescribed:
        _, rate[0] = eval_control(law, -0.5 * dt, rate[0])
    else:
        rate[0] -= 0.5 * dt * (value + tau) / state.hub.inertia[0]
    if model.bundles is not None:
        scatter_bundles(model.bundles, state.coil, pos, vel)
