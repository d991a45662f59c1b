"""numba kernels of the explicit central-difference solver.

Central differences with half-step velocities (Kratos / LS-DYNA style):

    f_n        = internal forces at x_n (damping with v_{n-1/2})
    v_{n+1/2}  = v_{n-1/2} + dt f_n / m                       (free nodes)
    omega_{n+1/2} = omega_{n-1/2} + dt (M_n + tau_n) / J_eff  (hub, or prescribed)
    contact    : radial impulse so that x_{n+1} stays outside the hub (+ Coulomb friction)
    x_{n+1}    = x_n + dt v_{n+1/2};  theta_{n+1} = theta_n + dt omega_{n+1/2}
    tied nodes : x = R(theta_{n+1}) x_hub

Every kernel and the helpers it calls live in this module (``cache=True`` does not see
edits to jitted helpers in other files). Constants come in as arguments. The hot loop uses
``error_model="numpy"`` so that divisions carry no Python zero-division check (a branch per
element); its divisor is never zero.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

# layout of the hub / accumulator state vector ``hub`` (float64 array)
H_THETA, H_OMEGA, H_TIME, H_WORK, H_DAMP, H_CONTACT, H_STEP, H_TORQUE = range(8)
HUB_STATE_SIZE = 8
# columns of the per-record scalar table written by ``advance``
REC_COLUMNS = ("time", "hub_angle", "hub_omega", "hub_torque", "kinetic_energy",
               "strain_energy", "torque_work", "damping_dissipation", "contact_dissipation",
               "angular_momentum", "max_tension")
# control law codes (see spinweb_fe.control)
LAW_FREE, LAW_FEEDBACK, LAW_RAMP, LAW_CONSTANT = 0, 1, 2, 3


@njit(cache=True)
def eval_elements(pos, vel, elem_nodes, rest, ea, cdamp, force, tension, want_energy):
    """Tension-only truss forces. Adds element forces into ``force`` (n,3), writes ``tension``.

    Returns (strain_energy [J] if want_energy else 0, max tension [N], damping power [W]).
    The same element law as the step loop (``accumulate_elements``), for frames and tests.
    """
    inv_rest = 1.0 / rest
    damped = False
    for e in range(cdamp.shape[0]):
        damped = damped or cdamp[e] > 0.0
    return accumulate_elements(pos, vel, elem_nodes, inv_rest, ea, cdamp, damped, force, 0,
                               elem_nodes.shape[0], want_energy, tension)


@njit(cache=True)
def eval_control(law, params, t, omega):
    """Control law -> (prescribed, value): torque [N m], or the prescribed hub rate [rad/s]."""
    if law == LAW_FEEDBACK:  # M = M0 (1 - omega/omega0)
        return False, params[0] * (1.0 - omega / params[1])
    if law == LAW_RAMP:  # omega = omega_max t / ramp_time, then omega_max
        if t < params[1]:
            return True, params[0] * t / params[1]
        return True, params[0]
    if law == LAW_CONSTANT:
        return False, params[0]
    return False, 0.0


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
def apply_contact(pos, vel, force, node_mass, contact_idx, r0, mu, j_eff, omega, dw_force, dt):
    """Contact (see ``contact_node``) for a list of nodes. Returns (omega, dissipated energy)."""
    diss = 0.0
    for k in range(contact_idx.shape[0]):
        i = contact_idx[k]
        omega, d = contact_node(i, pos, vel, force, node_mass[i], r0, mu, j_eff, omega,
                                dw_force, dt)
        diss += d
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
def accumulate_elements(pos, vel, elem_nodes, inv_rest, ea, cdamp, damped, force, lo, hi,
                        record, tension):
    """Hot loop: tension-only element forces of elements lo..hi-1 added into ``force`` (n,3);
    element tensions written into ``tension`` unless it is empty.

    Same physics as ``eval_elements``, arranged for speed: 1/L0 is stored, and the
    tension-only rule is a branch-free max on the strain (a web spinning unstretched sits on
    the slack/taut kink, where a real branch is mispredicted about half the time: measured
    11 ns against 5.8 ns per element). Zero-length elements give zero force (the length gets
    1e-150 added under the root). Returns (strain energy [J], max tension [N]) on record
    steps, and the damping power [W].
    """
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


@njit(cache=True, parallel=True)
def accumulate_threads(pos, vel, elem_nodes, inv_rest, ea, cdamp, damped, forces, bounds, record,
                       out):
    """Element pass on several threads: chunk c (elements bounds[c]..bounds[c+1]-1) adds into
    its own buffer forces[c]; out[c] = (strain energy, max tension, damping power)."""
    for c in prange(forces.shape[0]):
        se, tm, pd = accumulate_elements(pos, vel, elem_nodes, inv_rest, ea, cdamp, damped,
                                         forces[c], bounds[c], bounds[c + 1], record,
                                         np.empty(0))
        out[c, 0] = se
        out[c, 1] = tm
        out[c, 2] = pd


@njit(cache=True)
def integrate_nodes(pos, vel, force, inv_mass, node_mass, contact, r0, mu, j_eff, omega,
                    dw_force, dt, lo, hi, record, out):
    """Fused node pass over nodes lo..hi-1: v += dt f/m, cable-hub contact, x += dt v, and
    f = 0 for the next step. Tied nodes (inv_mass 0) are skipped. On record steps ``out[:4]``
    receives the kinetic energy and angular momentum sums before and after the update.
    Returns (omega, contact dissipation [J])."""
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
def integrate_threads(pos, vel, forces, inv_mass, node_mass, contact, r0, j_eff, omega, dw_force,
                      dt, nbounds, record, out):
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
        _, diss = integrate_nodes(pos, vel, forces[0], inv_mass, node_mass, contact, r0, 0.0,
                                  j_eff, omega, dw_force, dt, lo, hi, record, out[b])
        out[b, 4] = diss


@njit(cache=True)
def split(n, parts):
    """Bounds (parts + 1,) of ``parts`` near-equal contiguous ranges of 0..n-1."""
    b = np.empty(parts + 1, np.int64)
    for k in range(parts + 1):
        b[k] = (n * k) // parts
    return b


@njit(cache=True)
def advance(pos, vel, hub, force, tension, inv_mass, node_mass, elem_nodes, rest, ea, cdamp,
            tied_idx, tied_ref, contact, r0, mu, j_eff, law, law_params, dt, nsteps,
            rec_every, probe_idx, rec, rec_probe_pos, rec_probe_vel):
    """Run ``nsteps`` central-difference steps; record history rows every ``rec_every`` steps.

    ``force`` (nt, n, 3) holds one force buffer per thread (nt = 1: serial) and must be zero
    on entry (the node pass leaves it zeroed); ``tension`` is scratch of length m (it holds
    1/L0); ``contact`` (n,) bool marks the nodes checked against the hub.
    Row k of ``rec`` holds REC_COLUMNS at integer step n (energies as the mean of the two
    half-step values, accumulated work/dissipation up to t_n). ``rec_probe_pos/vel`` get the
    positions x_n and velocities (v_{n-1/2} + v_{n+1/2}) / 2 of the probe nodes (arm tips
    and spines, see spinweb_fe.arms). Threads give the same result for a given thread count
    (fixed chunks, fixed reduction order). Returns (status, rows): status 0 ok, 1 non-finite.
    """
    nt = force.shape[0]
    n = pos.shape[0]
    m_el = elem_nodes.shape[0]
    ebounds = split(m_el, nt)
    nbounds = split(n, nt)
    eout = np.zeros((nt, 3))
    nout = np.zeros((nt, 5))
    sums = np.zeros(5)
    no_tension = np.empty(0)
    nrec = 0
    nprobe = probe_idx.shape[0]
    vprobe = np.zeros((nprobe, 3))
    inv_rest = tension
    damped = False
    for e in range(m_el):
        inv_rest[e] = 1.0 / rest[e]
        damped = damped or cdamp[e] > 0.0
    for _ in range(nsteps):
        step = int(hub[H_STEP])
        record = step % rec_every == 0
        t = step * dt
        if nt == 1:
            se, tmax, pdamp = accumulate_elements(pos, vel, elem_nodes, inv_rest, ea, cdamp,
                                                  damped, force[0], 0, m_el, record, no_tension)
        else:
            accumulate_threads(pos, vel, elem_nodes, inv_rest, ea, cdamp, damped, force,
                               ebounds, record, eout)
            se = eout[:, 0].sum()
            tmax = eout[:, 1].max()
            pdamp = eout[:, 2].sum()
        tau = hub_torque_buffers(pos, force, tied_idx)
        w_old = hub[H_OMEGA]
        prescribed, value = eval_control(law, law_params, t, w_old)
        if prescribed:  # hub rate imposed at the half step; the torque it takes is reported
            _, w_new = eval_control(law, law_params, t + 0.5 * dt, w_old)
            torque = j_eff * (w_new - w_old) / dt - tau
        else:  # J_eff omega' = M + tau (tied-node reactions)
            torque = value
            w_new = w_old + dt * (torque + tau) / j_eff
        if record:
            for k in range(nprobe):
                for d in range(3):
                    vprobe[k, d] = vel[probe_idx[k], d]
                    rec_probe_pos[nrec, k, d] = pos[probe_idx[k], d]
        theta = hub[H_THETA]
        if nt > 1 and mu == 0.0:
            integrate_threads(pos, vel, force, inv_mass, node_mass, contact, r0, j_eff, w_new,
                              w_new - w_old, dt, nbounds, record, nout)
            for k in range(5):
                sums[k] = nout[:, k].sum()
            dcontact = sums[4]
        else:
            for c in range(1, nt):
                force[0] += force[c]
                force[c] = 0.0
            w_new, dcontact = integrate_nodes(pos, vel, force[0], inv_mass, node_mass, contact,
                                              r0, mu, j_eff, w_new, w_new - w_old, dt, 0, n,
                                              record, sums)
        dwork = torque * dt * 0.5 * (w_new + w_old)  # exact discrete work on the hub
        ddamp = pdamp * dt
        if record:
            ke = 0.5 * (sums[0] + sums[1]) + 0.25 * j_eff * (w_old * w_old + w_new * w_new)
            if not (np.isfinite(ke) and np.isfinite(se)):
                return 1, nrec
            rec[nrec, 0] = t
            rec[nrec, 1] = theta
            rec[nrec, 2] = 0.5 * (w_old + w_new)
            rec[nrec, 3] = torque
            rec[nrec, 4] = ke
            rec[nrec, 5] = se
            rec[nrec, 6] = hub[H_WORK] + 0.5 * dwork
            rec[nrec, 7] = hub[H_DAMP] + 0.5 * ddamp
            rec[nrec, 8] = hub[H_CONTACT] + 0.5 * dcontact
            rec[nrec, 9] = 0.5 * (sums[2] + sums[3]) + j_eff * 0.5 * (w_old + w_new)
            rec[nrec, 10] = tmax
            for k in range(nprobe):
                for d in range(3):
                    rec_probe_vel[nrec, k, d] = 0.5 * (vprobe[k, d] + vel[probe_idx[k], d])
            nrec += 1
        hub[H_THETA] = theta + dt * w_new
        hub[H_OMEGA] = w_new
        hub[H_TORQUE] = torque
        hub[H_WORK] += dwork
        hub[H_DAMP] += ddamp
        hub[H_CONTACT] += dcontact
        hub[H_STEP] = step + 1
        hub[H_TIME] = (step + 1) * dt
        place_tied(pos, vel, tied_idx, tied_ref, hub[H_THETA], w_new)
    return 0, nrec


@njit(cache=True)
def start_half_step(pos, vel, hub, force, tension, inv_mass, elem_nodes, rest, ea, cdamp,
                    tied_idx, law, law_params, j_eff, dt):
    """Turn initial velocities v_0, omega_0 into v_{-1/2}, omega_{-1/2} = v_0 - dt/2 a_0."""
    force[:, :] = 0.0
    eval_elements(pos, vel, elem_nodes, rest, ea, cdamp, force, tension, False)
    for i in range(pos.shape[0]):
        for d in range(3):
            vel[i, d] -= 0.5 * dt * force[i, d] * inv_mass[i]
    tau = hub_torque_of(pos, force, tied_idx)
    prescribed, value = eval_control(law, law_params, 0.0, hub[H_OMEGA])
    if prescribed:
        _, hub[H_OMEGA] = eval_control(law, law_params, -0.5 * dt, hub[H_OMEGA])
    else:
        hub[H_OMEGA] -= 0.5 * dt * (value + tau) / j_eff
