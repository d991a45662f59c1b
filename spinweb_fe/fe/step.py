"""The explicit central-difference step: ``advance`` and every numba kernel it calls.

Central differences with half-step velocities (Kratos / LS-DYNA style):

    f_n        = internal forces at x_n (damping with v_{n-1/2})
    v_{n+1/2}  = v_{n-1/2} + dt f_n / m                       (free nodes)
    omega_{n+1/2} = omega_{n-1/2} + dt (M_n + tau_n) / J_eff  (hub, or prescribed)
    contact    : radial impulse so that x_{n+1} stays outside the hub (+ Coulomb friction)
    x_{n+1}    = x_n + dt v_{n+1/2};  theta_{n+1} = theta_n + dt omega_{n+1/2}
    tied nodes : x = R(theta_{n+1}) x_hub

    held coil  : x = R(theta_{n+1}) x_hub; then the peel fronts and bundles (fe.coil)

The kernels take the named data of :mod:`spinweb_fe.fe.model` (``Model.kernel``: elements,
nodes, hub, coil), :mod:`spinweb_fe.fe.state` (``State``), the law (``KernelLaw``) and
``Recording`` below. The features they call live in their own files of ``fe/`` (contact, hub,
coil, control, rupture): the numba cache of every ``fe`` kernel is stamped with the whole folder
(:mod:`spinweb_fe.fe.cache`), so an edit of a helper recompiles its callers. Constants come
in as arguments, never as module globals. The element pass uses ``error_model="numpy"`` so
that divisions carry no Python zero-division check (a branch per element); its divisor is
never zero.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from spinweb_fe.fe.coil import (front_row, gather_bundles, held_moment, open_bundles,
                                payout_allowed, place_held, release_fronts, scatter_bundles)
from spinweb_fe.fe.contact import contact_node
from spinweb_fe.fe.control import eval_control
from spinweb_fe.fe.hub import hub_step, moment_of, place_rigid
from spinweb_fe.fe.law import add_pair, damped_tension, lengthening, stretch
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


@njit(cache=True, error_model="numpy")
def accumulate_elements(elems, pos, vel, force, lo, hi, record, tension, elist=None):
    """Hot loop: tension-only element forces of elements lo..hi-1 (or of elist[lo:hi], an
    element list) added into ``force`` (n,3); element tensions written into ``tension``
    unless it is empty (the list is decided by numba from its type: without it the loop is
    the plain one).

    1/L0 is stored, and the tension-only rule is a branch-free max on the strain (a web
    spinning unstretched sits on the slack/taut kink, where a real branch is mispredicted
    about half the time: measured 11 ns against 5.8 ns per element). Zero-length elements
    give zero force (the length gets 1e-300 added under the root). Returns (strain energy
    [J], max tension [N]) on record steps, and the damping power [W].
    """
    elem_nodes = elems.nodes
    inv_rest = elems.inv_rest
    ea = elems.ea
    cdamp = elems.cdamp
    damped = elems.damped
    se = 0.0
    tmax = 0.0
    pdamp = 0.0
    write_tension = tension.shape[0] > 0
    for k in range(lo, hi):
        if elist is None:
            e = k
        else:
            e = elist[k]
        i = elem_nodes[e, 0]
        j = elem_nodes[e, 1]
        dx, dy, dz, inv, strain = stretch(pos, i, j, inv_rest[e])  # N = EA max(eps, 0)
        n_el = ea[e] * strain
        n_tot = n_el
        if damped:  # N_d = c dL/dt while taut, total tension never negative
            ldot = lengthening(vel, i, j, dx, dy, dz, inv)
            n_tot = damped_tension(n_el, strain, cdamp[e], ldot)
            pdamp += (n_tot - n_el) * ldot
        if record:
            se += 0.5 * n_el * strain / inv_rest[e]  # U = EA eps^2 L0 / 2
            tmax = max(tmax, n_tot)
        if write_tension:
            tension[e] = n_tot
        add_pair(force, i, j, n_tot * inv, dx, dy, dz)
    return se, tmax, pdamp


@njit(cache=True)
def eval_elements(elems, pos, vel, force, tension, want_energy):
    """Tension-only truss forces of every element added into ``force`` (n,3); tensions into
    ``tension`` (m,). Returns (strain energy [J] if want_energy else 0, max tension [N],
    damping power [W]). The step loop's element law, for frames and tests."""
    return accumulate_elements(elems, pos, vel, force, 0, elems.nodes.shape[0], want_energy,
                               tension)


@njit(cache=True, parallel=True)
def accumulate_threads(elems, pos, vel, forces, bounds, record, out, elist):
    """Element pass on several threads: chunk c (elements bounds[c]..bounds[c+1]-1, or
    elist[bounds[c]:bounds[c+1]] with an element list) adds into its own buffer forces[c];
    out[c] = (strain energy, max tension, damping power)."""
    for c in prange(forces.shape[0]):
        se, tm, pd = accumulate_elements(elems, pos, vel, forces[c], bounds[c], bounds[c + 1],
                                         record, np.empty(0), elist)
        out[c, 0] = se
        out[c, 1] = tm
        out[c, 2] = pd


class NodeMotion(NamedTuple):
    """The node arrays of the State that the node pass updates or reads (a flat tuple, as
    the parallel kernels take it)."""

    pos: np.ndarray
    vel: np.ndarray
    mass: np.ndarray
    inv_mass: np.ndarray


@njit(cache=True)
def integrate_nodes(nodes, hub, mv, force, omega, dw_force, j_eff, dt, lo, hi, record, out):
    """Fused node pass over nodes lo..hi-1: v += dt f/m, cable-hub contact, x += dt v, and
    f = 0 for the next step. ``mv``: :class:`NodeMotion`; nodes with no active mass (tied,
    held, inside a bundle) are skipped; ``j_eff`` [kg m^2] is the hub's inertia now. On
    record steps ``out[:4]`` receives the kinetic energy and angular momentum sums before
    and after the update. Returns (omega, contact dissipation [J])."""
    pos = mv.pos
    vel = mv.vel
    inv_mass = mv.inv_mass
    node_mass = mv.mass
    contact = nodes.contact
    r0 = hub.radius
    mu = hub.friction
    ke0 = 0.0
    ke1 = 0.0
    lz0 = 0.0
    lz1 = 0.0
    diss = 0.0
    use_contact = r0 > 0.0
    for i in range(lo, hi):
        im = inv_mass[i]
        if im > 0.0:
            m = node_mass[i]
            if record:
                ke0 += m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
                lz0 += m * (pos[i, 0] * vel[i, 1] - pos[i, 1] * vel[i, 0])
            vel[i, 0] += dt * force[i, 0] * im  # v_{n+1/2} = v_{n-1/2} + dt f / m
            vel[i, 1] += dt * force[i, 1] * im
            vel[i, 2] += dt * force[i, 2] * im
            if use_contact and contact[i]:
                px = pos[i, 0] + dt * vel[i, 0]  # predicted position: only nodes heading
                py = pos[i, 1] + dt * vel[i, 1]  # inside the hub cylinder need the call
                if px * px + py * py < r0 * r0:
                    omega, d = contact_node(i, pos, vel, force, m, r0, mu, j_eff, omega,
                                            dw_force, dt)
                    diss += d
            if record:
                ke1 += m * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
                lz1 += m * (pos[i, 0] * vel[i, 1] - pos[i, 1] * vel[i, 0])
            pos[i, 0] += dt * vel[i, 0]  # x_{n+1} = x_n + dt v_{n+1/2}
            pos[i, 1] += dt * vel[i, 1]
            pos[i, 2] += dt * vel[i, 2]
        force[i, 0] = 0.0
        force[i, 1] = 0.0
        force[i, 2] = 0.0
    if record:
        out[0] = 0.5 * ke0
        out[1] = 0.5 * ke1
        out[2] = lz0
        out[3] = lz1
    return omega, diss


@njit(cache=True, parallel=True)
def integrate_threads(nodes, hub, mv, forces, omega, dw_force, j_eff, dt, nbounds, record, out):
    """Node pass on several threads (frictionless contact only: friction turns the hub node by
    node). ``nbounds`` (3, nt + 1): row 0 the node blocks (one per buffer), rows 1 and 2 the
    range of nodes [lo, hi) where buffer c can hold forces (fe.threads). Block b
    adds the other buffers into its own buffer b for its nodes, within those ranges
    (elsewhere they are zero), then integrates its nodes from buffer b; out[b] = (ke0, ke1,
    lz0, lz1, contact dissipation). With two buffers the sums are those of a fold into
    buffer 0 (a + b = b + a)."""
    for b in prange(nbounds.shape[1] - 1):
        lo = nbounds[0, b]
        hi = nbounds[0, b + 1]
        for c in range(forces.shape[0]):
            if c == b:
                continue
            for i in range(max(lo, nbounds[1, c]), min(hi, nbounds[2, c])):
                for d in range(3):
                    forces[b, i, d] += forces[c, i, d]
                    forces[c, i, d] = 0.0
        _, diss = integrate_nodes(nodes, hub, mv, forces[b], omega, dw_force, j_eff, dt, lo, hi,
                                  record, out[b])
        out[b, 4] = diss


@njit(cache=True)
def split(n, parts):
    """Bounds (parts + 1,) of ``parts`` near-equal contiguous ranges of 0..n-1."""
    b = np.empty(parts + 1, np.int64)
    for k in range(parts + 1):
        b[k] = (n * k) // parts
    return b


@njit(cache=True)
def element_pass(elems, strength, ss, pos, vel, force, ebounds, eout, record, no_tension, dt,
                 lists=None):
    """Element forces of this step into the force buffers: one thread (force (1, n, 3)) or
    several (one buffer per thread, ``ebounds`` their element ranges). A scene with a failure
    strain takes the strength pass (fe.rupture; ``ss`` its state, ``eout`` (nt, 8), ``dt``
    the step). Returns (strain energy, max tension, damping power).

    ``strength`` None (no strength check) and ``ebounds`` None (one thread) are decided by
    numba from the argument types, before it types the branches: a scene compiles only the
    passes it can take (the strength and thread kernels cost seconds of compile time)."""
    if strength is not None:
        if strength.fail.shape[0] > 0:
            return strength_pass(elems, strength, ss, pos, vel, force, ebounds, eout, record,
                                 no_tension, dt)
    if ebounds is None or force.shape[0] == 1:
        return accumulate_elements(elems, pos, vel, force[0], 0, elems.nodes.shape[0], record,
                                   no_tension)
    if lists is None:
        accumulate_threads(elems, pos, vel, force, ebounds, record, eout, None)
    else:  # the elements grouped by node block (fe.threads)
        accumulate_threads(elems, pos, vel, force, lists[0], record, eout, lists[1])
    return eout[:, 0].sum(), eout[:, 1].max(), eout[:, 2].sum()


@njit(cache=True, no_cpython_wrapper=True)
def checks_strength(strength):
    """Whether the kernel's ``strength`` checks any element (None: no, at compile time)."""
    if strength is None:
        return False
    return strength.fail.shape[0] > 0


@njit(cache=True)
def node_pass(nodes, hub, state, force, w_old, w_new, dt, nbounds, nout, sums, record):
    """Velocity and position update of every free node (one thread, or several when contact
    is frictionless). ``sums[:4]`` receives the kinetic energy and angular momentum sums.
    Returns (omega_{n+1/2} after friction, contact dissipation [J])."""
    nt = force.shape[0]
    mv = NodeMotion(state.node_pos, state.node_vel, state.node_mass, state.node_inv_mass)
    j_eff = state.hub.inertia[0]
    if nbounds is not None and nt > 1 and hub.friction == 0.0:  # None: pruned by numba
        integrate_threads(nodes, hub, mv, force, w_new, w_new - w_old, j_eff, dt, nbounds,
                          record, nout)
        for k in range(5):
            sums[k] = nout[:, k].sum()
        return w_new, sums[4]
    fold_buffers(force)
    return integrate_nodes(nodes, hub, mv, force[0], w_new, w_new - w_old, j_eff, dt, 0,
                           mv.pos.shape[0], record, sums)


@njit(cache=True, no_cpython_wrapper=True)
def fold_buffers(force):
    """force[0] += force[c], force[c] = 0 for every other thread's buffer c, in order (an
    explicit loop: numba's array expression for it costs seconds of compile time building
    its shape-mismatch message)."""
    for c in range(1, force.shape[0]):
        for i in range(force.shape[1]):
            for d in range(3):
                force[0, i, d] += force[c, i, d]
                force[c, i, d] = 0.0


@njit(cache=True, no_cpython_wrapper=True)
def record_probes(rec, k, pos, vel, vprobe, before):
    """Probe positions x_n and velocities into row k: ``before`` the node pass keeps
    v_{n-1/2} in ``vprobe``; after it the row gets the mean with v_{n+1/2}."""
    probes = rec.probes
    for p in range(probes.shape[0]):
        for d in range(3):
            if before:
                vprobe[p, d] = vel[probes[p], d]
                rec.probe_pos[k, p, d] = pos[probes[p], d]
            else:
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


@njit(cache=True, no_cpython_wrapper=True)
def coil_step(coil, elems, nodes, state, t_next):
    """After a step: release the fronts that the free parts pull off the hub (broken
    elements pull nothing), then open the bundles that are due."""
    cs = state.coil
    state.hub.inertia[0] = release_fronts(coil, cs, elems, nodes, state.node_pos,
                                          state.node_mass, state.node_inv_mass,
                                          state.hub.inertia[0], t_next, state.strength.broken)
    if coil.bundle_code > 0:
        open_bundles(coil, cs, nodes, state.node_mass, state.node_inv_mass, t_next)


@njit(cache=True)
def advance(model, law, state, force, rec, dt, nsteps, vec=None, ebounds=None, nbounds=None,
            lists=None):
    """Run ``nsteps`` central-difference steps; record a history row every ``rec.every`` steps.

    ``model`` is the kernel view of the Model (``Model.kernel``). ``force`` (nt, n, 3) holds
    one force buffer per thread (nt = 1: serial) and must be zero on entry (the node pass
    leaves it zeroed). Row k of ``rec.table`` holds REC_COLUMNS at integer step n,
    ``rec.probe_pos/vel`` the probe positions x_n and mean velocities, ``rec.arm_table`` the
    arm data of :func:`record_arms`, and ``vec`` (rows, fe.vectors.VEC_WIDTH), if given, the
    momentum vectors, the hub's pose and the distances from the hub plane (a run that can
    leave the plane; without it numba compiles none of that). Several threads (nt > 1) need
    ``ebounds``, ``nbounds`` and ``lists``, the element and node ranges of each
    (fe.threads.thread_ranges); without them (one thread) numba compiles no thread kernel.
    Threads give the same result for a given thread count (fixed chunks, fixed reduction
    order). Returns (status, rows): 0 ok, 1 non-finite.
    """
    elems, nodes, hub, coil = model.elements, model.nodes, model.hub, model.coil
    strength = model.strength
    has_strength = checks_strength(strength)
    nt = force.shape[0]
    pos = state.node_pos
    vel = state.node_vel
    eout = np.zeros((nt, 8))
    nout = np.zeros((nt, 5))
    sums = np.zeros(5)
    incr = np.zeros(3)
    vprobe = np.zeros((rec.probes.shape[0], 3))
    no_tension = np.empty(0)
    totals = state.totals
    has_coil = coil.level_nodes.shape[0] > 0
    nrec = 0
    for _ in range(nsteps):
        step = state.step[0]
        record = step % rec.every == 0
        t = step * dt
        se, tmax, pdamp = element_pass(elems, strength, state.strength, pos, vel, force,
                                       ebounds, eout, record, no_tension, dt, lists)
        tau = moment_of(pos, force, hub.tied_idx)
        if has_coil:
            tau += held_moment(coil, state.coil, pos, force)
            gather_bundles(coil, state.coil, force)
        w_old = state.hub.rate[0]
        j_eff = state.hub.inertia[0]
        torque, w_new = hub_step(law, j_eff, tau, w_old, t, dt)
        if record:
            record_probes(rec, nrec, pos, vel, vprobe, True)
            record_arms(coil, state.coil, rec.arm_table[nrec], t)
            if has_strength:
                record_strength(state.strength, rec.strength_table[nrec])
            if vec is not None:
                vec[nrec] = 0.0
                node_momenta(pos, vel, state.node_mass, state.node_inv_mass, vec[nrec], 0.5)
                plane_stats(pos, nodes.inv_mass, np.zeros(3), np.array([0.0, 0.0, 1.0]),
                            vec[nrec])
        theta = state.hub.angle[0]
        w_new, dcontact = node_pass(nodes, hub, state, force, w_old, w_new, dt, nbounds, nout,
                                    sums, record)
        if has_coil:
            scatter_bundles(coil, state.coil, pos, vel)
        incr[0] = torque * dt * 0.5 * (w_new + w_old)  # exact discrete work on the hub
        incr[1] = pdamp * dt
        incr[2] = dcontact
        if record:
            write_row(rec.table[nrec], t, theta, w_old, w_new, torque, j_eff, sums, se, tmax,
                      totals, incr)
            if vec is not None:
                node_momenta(pos, vel, state.node_mass, state.node_inv_mass, vec[nrec], 0.5)
                fixed_hub_row(hub, coil, state.coil, nodes, pos, theta, 0.5 * (w_old + w_new),
                              j_eff, vec[nrec])
            if not (np.isfinite(rec.table[nrec, 4]) and np.isfinite(se)):
                return 1, nrec
            record_probes(rec, nrec, pos, vel, vprobe, False)
            nrec += 1
        state.hub.angle[0] = theta + dt * w_new
        state.hub.rate[0] = w_new
        totals.torque_work[0] += incr[0]
        totals.damping_dissipation[0] += incr[1]
        totals.contact_dissipation[0] += incr[2]
        state.step[0] = step + 1
        state.time[0] = (step + 1) * dt
        place_rigid(pos, vel, hub.tied_idx, hub.tied_ref, state.hub.angle[0], w_new)
        if has_coil:
            place_held(coil, state.coil, pos, vel, state.hub.angle[0], w_new)
            coil_step(coil, elems, nodes, state, (step + 1) * dt)
    return 0, nrec


@njit(cache=True)
def start_half_step(model, law, state, dt):
    """Turn initial velocities v_0, omega_0 into v_{-1/2}, omega_{-1/2} = v_0 - dt/2 a_0."""
    elems, hub, coil = model.elements, model.hub, model.coil
    pos = state.node_pos
    vel = state.node_vel
    force = np.zeros((1, pos.shape[0], 3))
    eval_elements(elems, pos, vel, force[0], np.zeros(elems.nodes.shape[0]), False)
    if coil.level_nodes.shape[0] > 0:
        gather_bundles(coil, state.coil, force)
    for i in range(pos.shape[0]):
        for d in range(3):
            vel[i, d] -= 0.5 * dt * force[0, i, d] * state.node_inv_mass[i]
    tau = moment_of(pos, force, hub.tied_idx) + held_moment(coil, state.coil, pos, force)
    prescribed, value = eval_control(law, 0.0, state.hub.rate[0])
    if prescribed:
        _, state.hub.rate[0] = eval_control(law, -0.5 * dt, state.hub.rate[0])
    else:
        state.hub.rate[0] -= 0.5 * dt * (value + tau) / state.hub.inertia[0]
    if coil.level_nodes.shape[0] > 0:
        scatter_bundles(coil, state.coil, pos, vel)
