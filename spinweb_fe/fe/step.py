"""The explicit central-difference step: ``advance`` and every numba kernel it calls.

Central differences with half-step velocities (Kratos / LS-DYNA style):

    f_n        = internal forces at x_n (damping with v_{n-1/2})
    v_{n+1/2}  = v_{n-1/2} + dt f_n / m                       (free nodes)
    omega_{n+1/2} = omega_{n-1/2} + dt (M_n + tau_n) / J_eff  (hub, or prescribed)
    contact    : radial impulse so that x_{n+1} stays outside the hub (+ Coulomb friction)
    x_{n+1}    = x_n + dt v_{n+1/2};  theta_{n+1} = theta_n + dt omega_{n+1/2}
    tied nodes : x = R(theta_{n+1}) x_hub

The kernels take the named data of :mod:`spinweb_fe.fe.model` (``Elements``, ``Nodes``,
``Hub``, ``Law``), :mod:`spinweb_fe.fe.state` (``State``) and ``Recording`` below. Every
kernel and the helpers it calls live in this module (``cache=True`` does not see edits to
jitted helpers in other files); constants come in as arguments, never as module globals.
The element pass uses ``error_model="numpy"`` so that divisions carry no Python
zero-division check (a branch per element); its divisor is never zero.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

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
    """

    every: int
    probes: np.ndarray
    table: np.ndarray
    probe_pos: np.ndarray
    probe_vel: np.ndarray


@njit(cache=True)
def eval_control(law, t, omega):
    """Control law -> (prescribed, value): torque [N m], or the prescribed hub rate [rad/s].

    ``law.code`` selects the branch (the registry of spinweb_fe.fe.control names them).
    """
    p = law.params
    if law.code == 1:  # torque_feedback: M = M0 (1 - omega/omega0)
        return False, p[0] * (1.0 - omega / p[1])
    if law.code == 2:  # spin_ramp: omega = omega_max t / ramp_time, then omega_max
        if t < p[1]:
            return True, p[0] * t / p[1]
        return True, p[0]
    if law.code == 3:  # constant_torque
        return False, p[0]
    return False, 0.0  # free


@njit(cache=True)
def hub_torque_of(pos, force, tied_idx):
    """z-moment of the element forces acting on the tied nodes, sum (x f_y - y f_x)."""
    tau = 0.0
    for k in range(tied_idx.shape[0]):
        i = tied_idx[k]
        tau += pos[i, 0] * force[i, 1] - pos[i, 1] * force[i, 0]
    return tau


@njit(cache=True)
def hub_torque_buffers(pos, forces, tied_idx):
    """hub_torque_of summed over the per-thread force buffers (nt, n, 3)."""
    tau = 0.0
    for c in range(forces.shape[0]):
        tau += hub_torque_of(pos, forces[c], tied_idx)
    return tau


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


@njit(cache=True)
def place_tied(pos, vel, tied_idx, tied_ref, theta, omega):
    """Tied nodes move with the hub: x = R(theta) x_hub, v = omega z x x."""
    c = np.cos(theta)
    s = np.sin(theta)
    for k in range(tied_idx.shape[0]):
        i = tied_idx[k]
        x = c * tied_ref[k, 0] - s * tied_ref[k, 1]
        y = s * tied_ref[k, 0] + c * tied_ref[k, 1]
        pos[i, 0] = x
        pos[i, 1] = y
        pos[i, 2] = tied_ref[k, 2]
        vel[i, 0] = -omega * y
        vel[i, 1] = omega * x
        vel[i, 2] = 0.0


@njit(cache=True, error_model="numpy")
def accumulate_elements(elems, pos, vel, force, lo, hi, record, tension):
    """Hot loop: tension-only element forces of elements lo..hi-1 added into ``force`` (n,3);
    element tensions written into ``tension`` unless it is empty.

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
    for e in range(lo, hi):
        i = elem_nodes[e, 0]
        j = elem_nodes[e, 1]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        ln = np.sqrt(dx * dx + dy * dy + dz * dz + 1e-300)
        inv = 1.0 / ln
        strain = max(ln * inv_rest[e] - 1.0, 0.0)  # tension only: N = EA max(eps, 0)
        n_el = ea[e] * strain
        n_tot = n_el
        if damped:  # N_d = c dL/dt while taut, total tension never negative
            ldot = inv * (dx * (vel[j, 0] - vel[i, 0]) + dy * (vel[j, 1] - vel[i, 1])
                          + dz * (vel[j, 2] - vel[i, 2]))
            taut = 1.0 if strain > 0.0 else 0.0
            n_tot = max(n_el + taut * cdamp[e] * ldot, 0.0)
            pdamp += (n_tot - n_el) * ldot
        if record:
            se += 0.5 * n_el * strain / inv_rest[e]  # U = EA eps^2 L0 / 2
            tmax = max(tmax, n_tot)
        if write_tension:
            tension[e] = n_tot
        c = n_tot * inv
        fx = c * dx
        fy = c * dy
        fz = c * dz
        force[i, 0] += fx
        force[i, 1] += fy
        force[i, 2] += fz
        force[j, 0] -= fx
        force[j, 1] -= fy
        force[j, 2] -= fz
    return se, tmax, pdamp


@njit(cache=True)
def eval_elements(elems, pos, vel, force, tension, want_energy):
    """Tension-only truss forces of every element added into ``force`` (n,3); tensions into
    ``tension`` (m,). Returns (strain energy [J] if want_energy else 0, max tension [N],
    damping power [W]). The step loop's element law, for frames and tests."""
    return accumulate_elements(elems, pos, vel, force, 0, elems.nodes.shape[0], want_energy,
                               tension)


@njit(cache=True, parallel=True)
def accumulate_threads(elems, pos, vel, forces, bounds, record, out):
    """Element pass on several threads: chunk c (elements bounds[c]..bounds[c+1]-1) adds into
    its own buffer forces[c]; out[c] = (strain energy, max tension, damping power)."""
    for c in prange(forces.shape[0]):
        se, tm, pd = accumulate_elements(elems, pos, vel, forces[c], bounds[c], bounds[c + 1],
                                         record, np.empty(0))
        out[c, 0] = se
        out[c, 1] = tm
        out[c, 2] = pd


@njit(cache=True)
def integrate_nodes(nodes, hub, pos, vel, force, omega, dw_force, dt, lo, hi, record, out):
    """Fused node pass over nodes lo..hi-1: v += dt f/m, cable-hub contact, x += dt v, and
    f = 0 for the next step. Tied nodes (inv_mass 0) are skipped. On record steps ``out[:4]``
    receives the kinetic energy and angular momentum sums before and after the update.
    Returns (omega, contact dissipation [J])."""
    inv_mass = nodes.inv_mass
    node_mass = nodes.mass
    contact = nodes.contact
    r0 = hub.radius
    mu = hub.friction
    j_eff = hub.j_eff
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
def integrate_threads(nodes, hub, pos, vel, forces, omega, dw_force, dt, nbounds, record, out):
    """Node pass on several threads (frictionless contact only: friction turns the hub node by
    node). Block b sums the thread buffers into forces[0] for its nodes, then integrates them;
    out[b] = (ke0, ke1, lz0, lz1, contact dissipation)."""
    for b in prange(nbounds.shape[0] - 1):
        lo = nbounds[b]
        hi = nbounds[b + 1]
        for c in range(1, forces.shape[0]):
            for i in range(lo, hi):
                for d in range(3):
                    forces[0, i, d] += forces[c, i, d]
                    forces[c, i, d] = 0.0
        _, diss = integrate_nodes(nodes, hub, pos, vel, forces[0], omega, dw_force, dt, lo, hi,
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
def element_pass(elems, pos, vel, force, ebounds, eout, record, no_tension):
    """Element forces of this step into the force buffers: one thread (force (1, n, 3)) or
    several (one buffer per thread). Returns (strain energy, max tension, damping power)."""
    if force.shape[0] == 1:
        return accumulate_elements(elems, pos, vel, force[0], 0, elems.nodes.shape[0], record,
                                   no_tension)
    accumulate_threads(elems, pos, vel, force, ebounds, record, eout)
    return eout[:, 0].sum(), eout[:, 1].max(), eout[:, 2].sum()


@njit(cache=True)
def hub_step(law, j_eff, tau, w_old, t, dt):
    """Hub rate over the step: (torque M_n [N m], omega_{n+1/2}).

    A prescribed law imposes the rate at the half step and reports the torque it takes;
    a torque law integrates J_eff omega' = M + tau (tau: the tied-node reactions)."""
    prescribed, value = eval_control(law, t, w_old)
    if prescribed:
        _, w_new = eval_control(law, t + 0.5 * dt, w_old)
        return j_eff * (w_new - w_old) / dt - tau, w_new
    return value, w_old + dt * (value + tau) / j_eff


@njit(cache=True)
def node_pass(nodes, hub, pos, vel, force, w_old, w_new, dt, nbounds, nout, sums, record):
    """Velocity and position update of every free node (one thread, or several when contact
    is frictionless). ``sums[:4]`` receives the kinetic energy and angular momentum sums.
    Returns (omega_{n+1/2} after friction, contact dissipation [J])."""
    nt = force.shape[0]
    if nt > 1 and hub.friction == 0.0:
        integrate_threads(nodes, hub, pos, vel, force, w_new, w_new - w_old, dt, nbounds,
                          record, nout)
        for k in range(5):
            sums[k] = nout[:, k].sum()
        return w_new, sums[4]
    for c in range(1, nt):
        force[0] += force[c]
        force[c] = 0.0
    return integrate_nodes(nodes, hub, pos, vel, force[0], w_new, w_new - w_old, dt, 0,
                           pos.shape[0], record, sums)


@njit(cache=True)
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


@njit(cache=True)
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


@njit(cache=True)
def advance(elems, nodes, hub, law, state, force, rec, dt, nsteps):
    """Run ``nsteps`` central-difference steps; record a history row every ``rec.every`` steps.

    ``force`` (nt, n, 3) holds one force buffer per thread (nt = 1: serial) and must be zero
    on entry (the node pass leaves it zeroed). Row k of ``rec.table`` holds REC_COLUMNS at
    integer step n; ``rec.probe_pos/vel`` the probe positions x_n and mean velocities.
    Threads give the same result for a given thread count (fixed chunks, fixed reduction
    order). Returns (status, rows): status 0 ok, 1 non-finite.
    """
    nt = force.shape[0]
    pos = state.node_pos
    vel = state.node_vel
    ebounds = split(elems.nodes.shape[0], nt)
    nbounds = split(pos.shape[0], nt)
    eout = np.zeros((nt, 3))
    nout = np.zeros((nt, 5))
    sums = np.zeros(5)
    incr = np.zeros(3)
    vprobe = np.zeros((rec.probes.shape[0], 3))
    no_tension = np.empty(0)
    totals = state.totals
    nrec = 0
    for _ in range(nsteps):
        step = state.step[0]
        record = step % rec.every == 0
        t = step * dt
        se, tmax, pdamp = element_pass(elems, pos, vel, force, ebounds, eout, record,
                                        no_tension)
        tau = hub_torque_buffers(pos, force, hub.tied_idx)
        w_old = state.hub.rate[0]
        torque, w_new = hub_step(law, hub.j_eff, tau, w_old, t, dt)
        if record:
            record_probes(rec, nrec, pos, vel, vprobe, True)
        theta = state.hub.angle[0]
        w_new, dcontact = node_pass(nodes, hub, pos, vel, force, w_old, w_new, dt, nbounds,
                                    nout, sums, record)
        incr[0] = torque * dt * 0.5 * (w_new + w_old)  # exact discrete work on the hub
        incr[1] = pdamp * dt
        incr[2] = dcontact
        if record:
            write_row(rec.table[nrec], t, theta, w_old, w_new, torque, hub.j_eff, sums, se, tmax,
                      totals, incr)
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
        place_tied(pos, vel, hub.tied_idx, hub.tied_ref, state.hub.angle[0], w_new)
    return 0, nrec


@njit(cache=True)
def start_half_step(elems, nodes, hub, law, state, dt):
    """Turn initial velocities v_0, omega_0 into v_{-1/2}, omega_{-1/2} = v_0 - dt/2 a_0."""
    pos = state.node_pos
    vel = state.node_vel
    force = np.zeros(pos.shape)
    eval_elements(elems, pos, vel, force, np.zeros(elems.nodes.shape[0]), False)
    for i in range(pos.shape[0]):
        for d in range(3):
            vel[i, d] -= 0.5 * dt * force[i, d] * nodes.inv_mass[i]
    tau = hub_torque_of(pos, force, hub.tied_idx)
    prescribed, value = eval_control(law, 0.0, state.hub.rate[0])
    if prescribed:
        _, state.hub.rate[0] = eval_control(law, -0.5 * dt, state.hub.rate[0])
    else:
        state.hub.rate[0] -= 0.5 * dt * (value + tau) / hub.j_eff
