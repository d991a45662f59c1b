"""The explicit central-difference step: ``advance``, the one loop of every scene, and its
phases.

Central differences with half-step velocities (Kratos / LS-DYNA style), for a hub on a fixed
axis (:mod:`spinweb_fe.fe.hub.axis`) or a free rigid hub (:mod:`spinweb_fe.fe.hub.body`):

    forces     f_n = internal forces at x_n (damping with v_{n-1/2}): element force
               vectors, then their sum per node (fe.forces; fe.rupture with a strength check)
    hub loads  the forces on the nodes that move with the hub (tied, held) and the control
               law; the hub's kick: omega_{n+1/2} (fixed axis) or V, Pi_{n+1/2} (free)
    nodes      v_{n+1/2} = v_{n-1/2} + dt f_n / m, the cable-hub contact (fe.hub.contact) of
               the nodes heading inside the rim, x_{n+1} = x_n + dt v_{n+1/2}: one pass
    hub drift  theta_{n+1} = theta_n + dt omega_{n+1/2}, or the free body's drift
    place      tied and held nodes move with the hub
    release    the peel fronts the arms pull off (fe.coil.levels), the bundles that are due
    record     a history row every ``rec.every`` steps (fe.layout's tables)

Each phase is one call here, named once; which hub it runs is chosen by argument type:
``advance`` takes the hub as two arguments, ``axis`` (fe.hub.axis.Axis, None for a free hub) and
``body`` (fe.hub.rigid.Body, None on a fixed axis), and numba prunes a branch on an argument that
is None before typing it, so a scene compiles and runs the phases of its own hub only (as
the strength pass and the threads are chosen). The phases that differ by hub are inlined at
numba's IR level (``inline="always"``): their pairs of branches are pruned in ``advance``
after inlining, and none of them costs a compile of its own. Constants come in as arguments
(the layouts' slots in ``Recording.slots``), never as module globals.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.fe.coil.bundles import gather_bundles, open_bundles, scatter_bundles
from spinweb_fe.fe.coil.levels import any_held, front_row, payout_allowed
from spinweb_fe.fe.coil.payout import device_forces
from spinweb_fe.fe.contact.penalty import add_penalty
from spinweb_fe.fe.contact.touch import SERVICE, touch_begin, touch_end, touch_row
from spinweb_fe.fe.forces import element_forces, node_forces
from spinweb_fe.fe.hub.axis import NodeMotion, axis_start
from spinweb_fe.fe.hub.body import body_start
from spinweb_fe.fe.phases import (device_phase, field_loads, field_work, held_loads,
                                  hub_drift, hub_loads, hub_now, hub_record, hub_row,
                                  move_nodes, place_bound, place_coil, release, settle)
from spinweb_fe.fe.rupture import record_strength, strength_pass
from spinweb_fe.fe.vectors import node_momenta


class Recording(NamedTuple):
    """Where ``advance`` records history rows (one every ``every`` steps).

    Attributes
    ----------
    every : int
        Steps between two rows.
    probes : (p,) int64
        Nodes whose positions and velocities are recorded (arm tips and spines).
    table : (rows, fe.layout.ROW_WIDTH) float64
        The scalar row (fe.layout.ROW, then the step's energy terms).
    probe_pos, probe_vel : (rows, p, 3) float64 [m], [m/s]
        Probe positions x_n and mean velocities (v_{n-1/2} + v_{n+1/2}) / 2.
    arm_table : (rows, n_arms, len(fe.layout.ARM)) float64
        Per arm of a held coil: the row of fe.layout.ARM (see :func:`record_arms`).
    strength_table : (rows, len(fe.layout.STRENGTH)) float64
        Scenes with a failure strain: the row of fe.layout.STRENGTH ((rows, 0) otherwise).
    slots : fe.layout.Slots
        The column indices of every layout.
    """

    every: int
    probes: np.ndarray
    table: np.ndarray
    probe_pos: np.ndarray
    probe_vel: np.ndarray
    arm_table: np.ndarray
    strength_table: np.ndarray
    slots: tuple


@njit(cache=True, no_cpython_wrapper=True)
def checks_strength(strength):
    """Whether the kernel's ``strength`` checks any element (empty or None: no)."""
    if strength is None:
        return False
    return strength.fail.shape[0] > 0


@njit(cache=True)
def element_pass(elems, links, strength, ss, pos, vel, work, record, dt, threads=None,
                 devices=None, cs=None):
    """The internal forces at x_n into ``work.force`` (n, 3) (overwritten): every element's force
    vector (fe.forces, or the strength pass of fe.rupture for a scene with a failure strain;
    ``ss`` its state, ``dt`` the step), the elements a reel or brake holds at its departure
    point as it holds them (fe.coil.payout; ``devices`` the coil, None without one, ``cs`` its
    state), then their sum per node. Returns (strain energy, max tension, damping power).

    ``strength`` (fe.rupture.Strength) with no element (no failure strain) takes the plain
    element pass, chosen at run time (the model's kernel always hands the strength data, so
    that scenes with and without it share one compiled loop); None, from a direct caller,
    compiles no strength pass. ``threads`` None (one thread) is decided by numba from the
    argument type, before it types the branches: no thread kernel is compiled for it."""
    if strength is not None and strength.fail.shape[0] > 0:  # pruned by numba when None
        se, tmax, pdamp = strength_pass(elems, strength, ss, pos, vel, work, record, dt,
                                        threads)
    else:
        se, tmax, pdamp = element_forces(elems, links, pos, vel, work, record, threads)
    if devices is not None:  # pruned by numba when None
        dse, dpow, dmax = device_forces(devices, cs, elems, pos, vel, work, record, ss.broken)
        se += dse
        pdamp += dpow
        tmax = max(tmax, dmax)
    node_forces(links, work, threads)
    return se, tmax, pdamp


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
def record_arms(coil, cs, table, t, sa):
    """Per arm at a record step (see fe.coil.levels.front_row), into the slots ``sa`` of
    fe.layout.ARM: the front's (a reel's or brake's line at D) and the next outer level's arm
    coordinates, pinned on the rim (1/0), held back by the payout law (1/0), the paid-out
    length the law allows (NaN: none), and a reel's or brake's tension at D and work."""
    allowed = payout_allowed(coil, t)
    for k in range(table.shape[0]):
        row = table[k]
        row[sa.front], row[sa.next], row[sa.rim], row[sa.held_back] = front_row(coil, cs, k, t)
        row[sa.allowed] = allowed if np.isfinite(allowed) else np.nan
        row[sa.brake_tension] = cs.dev_tension[k]
        row[sa.brake_work] = cs.dev_work[k]


@njit(cache=True, no_cpython_wrapper=True)
def write_row(row, sr, t, theta, w, torque, ke, se, lz, tmax, totals, incr):
    """One scalar row at step n (slots ``sr`` of fe.layout.ROW): energies as the mean of the
    two half-step values, each energy term accumulated up to t_n (``incr``: this step's
    increments)."""
    row[sr.time] = t
    row[sr.hub_angle] = theta
    row[sr.hub_omega] = w
    row[sr.hub_torque] = torque
    row[sr.kinetic_energy] = ke
    row[sr.strain_energy] = se
    row[sr.angular_momentum] = lz
    row[sr.max_tension] = tmax
    for j in range(totals.shape[0]):
        row[sr.energy + j] = totals[j] + 0.5 * incr[j]


@njit(cache=True, nogil=True)
def advance(model, axis, body, law, state, work, rec, dt, nsteps, vec=None, threads=None,
            audit=None, contact=None, tidal=None):
    """Run ``nsteps`` central-difference steps; record a history row every ``rec.every`` steps.

    ``model`` is the kernel view of the Model (``Model.kernel``), ``axis`` and ``body`` its
    hub (``Model.hub_kind``: one of them None); ``work`` the scratch of the
    force passes (:func:`spinweb_fe.fe.forces.make_work`). Row k of ``rec.table`` holds
    fe.layout.ROW and the energy terms at integer step n, ``rec.probe_pos/vel`` the probe
    positions x_n and mean velocities, ``rec.arm_table`` the arm rows of
    :func:`record_arms`, and ``vec`` (rows, fe.layout.VEC_WIDTH), if given, the momentum
    vectors, the hub's pose and the distances from the hub plane (a run that can leave the
    plane, and every free hub; without it numba compiles none of that). ``threads``: None
    for one thread (numba compiles no thread kernel), else the number of threads, which run
    the workspace's chunks; every thread count gives the same bits (fixed blocks, fixed
    reduction order). ``audit`` (fe.contact.touch.AuditKernel) and ``contact``
    (fe.contact.touch.ContactKernel), if given, the crossing audit and the cable-cable contact
    (fe.contact.touch: numba compiles none of it without them). ``tidal`` (n, 3): the gravity
    gradient's node forces on a fixed axis (fe.hub.axis.axis_field; None: a scene without the
    field, or a free hub, and numba compiles none of it). Returns (status, rows): 0 ok, 1
    non-finite, fe.contact.touch.SERVICE: stopped after a step for the audit's list.
    """
    elems, nodes, hub, coil = model.elements, model.nodes, model.hub, model.coil
    env, strength = model.env, model.strength
    has_strength = checks_strength(strength)
    pos, vel, force = state.node_pos, state.node_vel, work.force
    totals = state.totals
    field = np.zeros(2)
    sums = np.zeros(5)
    incr = np.zeros(totals.shape[0])
    vprobe = np.zeros((rec.probes.shape[0], 3))
    has_coil = coil.level_nodes.shape[0] > 0
    # the state's arrays taken out once: every use of a tuple's field inside the loop, and
    # every tuple handed to a compiled function, costs NRT reference counts (an atomic add
    # per array), which made 40 % of a 200-element step
    links, bundles, cs, ss, rs, hs = model.links, model.bundles, state.coil, state.strength, \
        state.rigid, state.hub
    devices = model.devices
    mass, inv_mass, broken = state.node_mass, state.node_inv_mass, ss.broken
    mv = NodeMotion(pos, vel, mass, inv_mass)
    hub_angle, hub_rate, hub_inertia = hs.angle, hs.rate, hs.inertia
    step_no, time_now = state.step, state.time
    arm_ptr, front = coil.arm_ptr, cs.front
    sl = rec.slots
    term = sl.term
    nrec = np.int64(0)  # not the literal 0: a literal argument compiles callees twice
    for _ in range(nsteps):
        step = step_no[0]
        record = step % rec.every == 0
        t = step * dt
        holding = any_held(arm_ptr, front)
        # (two ifs, not if/else: numba prunes a branch only on an argument that is None, so
        # an else of `axis is not None` would compile the free hub's calls on a fixed axis)
        if axis is not None:
            touch_begin(audit, contact, pos, vel, inv_mass, dt, hub_rate, None, hub_angle[0])
        if body is not None:
            touch_begin(audit, contact, pos, vel, inv_mass, dt, None, rs, hub_angle[0])
        # forces at x_n
        se, tmax, pdamp = element_pass(elems, links, strength, ss, pos, vel, work, record, dt,
                                       threads, devices, cs)
        if tidal is not None:  # the field on a fixed axis (pruned by numba when None)
            field_loads(axis, env, t, nodes, hub, coil, cs, bundles, mv, force, tidal, field,
                        holding)
        if contact is not None:  # the cable contact's penalty
            add_penalty(contact, force)
        if has_coil:
            gather_bundles(bundles, cs, force)
        # loads on the hub and its kick
        tau = 0.0
        if holding:
            tau = held_loads(axis, coil, cs, pos, force, tau)
        kick = hub_loads(axis, body, hub, coil, cs, env, rs, law, pos, force, tau, hs, t, dt)
        if record:  # the row's positions x_n and v_{n-1/2}
            probe_positions(rec, nrec, pos, vel, vprobe)
            record_arms(coil, cs, rec.arm_table[nrec], t, sl.arm)
            if has_strength:
                record_strength(ss, rec.strength_table[nrec], sl.strength)
            if vec is not None:
                vec[nrec] = 0.0
                node_momenta(pos, vel, mass, inv_mass, vec[nrec], 0.5, sl.vec)
                hub_record(axis, body, kick, env, t, hub, coil, cs, nodes, pos, force,
                           vec[nrec], sl.vec)
        # kick, constraints and contact, drift of the free nodes
        kick, dcontact, wgrav = move_nodes(axis, body, nodes, hub, mv, work, env, rs, kick, t,
                                           dt, sums, record, threads)
        if has_coil:
            scatter_bundles(bundles, cs, pos, vel)
        incr[term.torque_work] = kick.torque * dt * 0.5 * (kick.rate_old + kick.rate_new)
        incr[term.damping_dissipation] = pdamp * dt
        incr[term.contact_dissipation] = dcontact
        wfield = 0.0
        if tidal is not None:
            wfield = field_work(axis, env, field, tidal, mv, kick, dt)
        incr[term.gravity_gradient_work] = wgrav + wfield
        theta = hub_angle[0]
        if record:  # the row of step n: mean velocities, energies, momenta
            if vec is not None:
                node_momenta(pos, vel, mass, inv_mass, vec[nrec], 0.5, sl.vec)
            w, ke, lz = hub_row(axis, body, hub, coil, cs, nodes, rs, kick, sums, pos, theta,
                                vec, nrec, sl.vec)
            write_row(rec.table[nrec], sl.row, t, theta, w, kick.torque, ke, se, lz, tmax,
                      totals, incr)
            if not (np.isfinite(ke) and np.isfinite(se)):
                return 1, nrec
            probe_velocities(rec, nrec, vel, vprobe)
            touch_row(audit, contact, nrec)
            nrec += 1
        # the hub's drift
        hub_angle[0] = hub_drift(axis, body, rs, kick, theta, dt)
        for j in range(incr.shape[0]):
            totals[j] += incr[j]
        step_no[0] = step + 1
        time_now[0] = (step + 1) * dt
        # tied and held nodes with the hub; the fronts the arms pull off; bundles due
        place_bound(axis, body, hub, coil, cs, rs, pos, vel, hub_angle[0], kick.rate_new)
        if holding:
            place_coil(axis, coil, cs, pos, vel, hub_angle[0], kick.rate_new)
        j_eff = hub_inertia[0]
        if holding:
            j_eff = release(axis, body, elems, nodes, hub, coil, cs, rs, mv, j_eff,
                            (step + 1) * dt, broken)
        if has_coil:
            open_bundles(bundles, cs, nodes, mass, inv_mass, (step + 1) * dt)
        hub_rate[0], hub_inertia[0] = hub_now(axis, body, rs, kick, j_eff)
        if holding:  # the reels and brakes let their lines out
            device_phase(axis, body, devices, elems, nodes, hub, coil, cs, rs, mv, hs,
                         (step + 1) * dt, dt)
        # (not the literals: with them the audit's step compiles again for a run without contact)
        fresh, clean = np.bool_(False), np.bool_(False)
        if contact is not None:
            fresh, clean = settle(axis, body, hub, coil, cs, rs, contact, pos, vel, inv_mass,
                                  hs, dt, threads)
        if touch_end(audit, pos, t, dt, front, fresh, clean, threads):
            return SERVICE, nrec
    return 0, nrec


def start_half_step(model, body, law, state, force, dt):
    """Turn initial velocities v_0, omega_0 into v_{-1/2}, omega_{-1/2} = v_0 - dt/2 a_0
    (and the free body's V, Pi); ``model``, ``law``: the kernel views, ``body`` the free
    hub's (None on a fixed axis); ``force`` (n, 3): the internal forces at x_0
    (fe.forces.internal_forces)."""
    if body is None:
        axis_start(model, law, state, force, dt)
    else:
        body_start(model, law, state, force, dt)
