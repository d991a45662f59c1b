"""numba kernels of the explicit central-difference solver.

Central differences with half-step velocities (Kratos / LS-DYNA style):

    f_n        = internal forces at x_n (damping with v_{n-1/2})
    v_{n+1/2}  = v_{n-1/2} + dt f_n / m                       (free nodes)
    omega_{n+1/2} = omega_{n-1/2} + dt (M_n + tau_n) / J_eff  (hub, or prescribed)
    contact    : radial impulse so that x_{n+1} stays outside the hub (+ Coulomb friction)
    x_{n+1}    = x_n + dt v_{n+1/2};  theta_{n+1} = theta_n + dt omega_{n+1/2}
    tied nodes : x = R(theta_{n+1}) x_hub

Every kernel and the helpers it calls live in this module (``cache=True`` does not see
edits to jitted helpers in other files). Constants come in as arguments.
"""

from __future__ import annotations

import numpy as np
from numba import njit

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
    """
    se = 0.0
    tmax = 0.0
    pdamp = 0.0
    for e in range(elem_nodes.shape[0]):
        i = elem_nodes[e, 0]
        j = elem_nodes[e, 1]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        ln = np.sqrt(dx * dx + dy * dy + dz * dz)
        l0 = rest[e]
        if ln <= l0:  # slack (or gathered, zero length): tension-only branch
            tension[e] = 0.0
            continue
        strain = (ln - l0) / l0  # engineering strain on the stored rest length
        inv = 1.0 / ln
        ux = dx * inv
        uy = dy * inv
        uz = dz * inv
        n_el = ea[e] * strain  # N = EA eps
        n_tot = n_el
        if cdamp[e] > 0.0:
            # elongation rate dL/dt = u . (v_j - v_i); damper N_d = c dL/dt, tension only
            ldot = (ux * (vel[j, 0] - vel[i, 0]) + uy * (vel[j, 1] - vel[i, 1])
                    + uz * (vel[j, 2] - vel[i, 2]))
            n_tot = n_el + cdamp[e] * ldot
            if n_tot < 0.0:
                n_tot = 0.0
            pdamp += (n_tot - n_el) * ldot
        tension[e] = n_tot
        if n_tot > tmax:
            tmax = n_tot
        if want_energy:
            se += 0.5 * ea[e] * strain * strain * l0  # U = EA eps^2 L0 / 2
        fx = n_tot * ux
        fy = n_tot * uy
        fz = n_tot * uz
        force[i, 0] += fx
        force[i, 1] += fy
        force[i, 2] += fz
        force[j, 0] -= fx
        force[j, 1] -= fy
        force[j, 2] -= fz
    return se, tmax, pdamp


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
def apply_contact(pos, vel, force, node_mass, contact_idx, r0, mu, j_eff, omega, dw_force, dt):
    """Kinematic cable-hub contact: radial impulse along x_n so that |x_{n+1}| >= r0 (in plane).

    Friction (Coulomb, coefficient mu) adds a tangential impulse bounded by mu times the
    normal impulse; its reaction turns the hub. ``dw_force`` is the hub rate increment of
    this step's torques. Returns (new omega, dissipated energy [J]).

    The dissipated energy is the kinetic energy the impulse removes, less the part that the
    step's own force put into the removed velocity (dt f . dv / 2): a node resting on the hub
    under a steady load then dissipates nothing, as in the continuous problem, and
    KE + SE + dissipation stays balanced to the scheme's order.
    """
    diss = 0.0
    for k in range(contact_idx.shape[0]):
        i = contact_idx[k]
        px = pos[i, 0] + dt * vel[i, 0]
        py = pos[i, 1] + dt * vel[i, 1]
        if px * px + py * py >= r0 * r0:
            continue
        rn = np.sqrt(pos[i, 0] ** 2 + pos[i, 1] ** 2)
        if rn == 0.0:
            continue
        ex = pos[i, 0] / rn  # radial unit at x_n: no moment about the axis
        ey = pos[i, 1] / rn
        pr = px * ex + py * ey
        disc = pr * pr - (px * px + py * py) + r0 * r0
        s = -pr + np.sqrt(max(disc, 0.0))  # |p + s e| = r0, s >= 0
        m = node_mass[i]
        e_before = 0.5 * m * (vel[i, 0] ** 2 + vel[i, 1] ** 2)
        vx0 = vel[i, 0]
        vy0 = vel[i, 1]
        # never push outwards: the impulse at most stops the inward motion along e
        dvn = min(s / dt, max(-(vel[i, 0] * ex + vel[i, 1] * ey), 0.0))
        if dvn <= 0.0:
            continue
        vel[i, 0] += dvn * ex
        vel[i, 1] += dvn * ey
        if mu > 0.0:
            # tangential slip relative to the hub surface; stick impulse includes the hub's response
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
        # minus the work of this step's force on the removed velocity: dt f/m . dv m / 2
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


@njit(cache=True)
def integrate_free(pos, vel, force, inv_mass, node_mass, dt, want_record):
    """v += dt f/m for free nodes (inv_mass > 0). On record steps returns kinetic energies
    before/after and the angular momentum sum m (x_n x v_{n+1/2})_z."""
    ke0 = 0.0
    ke1 = 0.0
    for i in range(pos.shape[0]):
        im = inv_mass[i]
        if im == 0.0:
            continue
        if want_record:
            ke0 += node_mass[i] * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
        vel[i, 0] += dt * force[i, 0] * im
        vel[i, 1] += dt * force[i, 1] * im
        vel[i, 2] += dt * force[i, 2] * im
        if want_record:
            ke1 += node_mass[i] * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
    return 0.5 * ke0, 0.5 * ke1


@njit(cache=True)
def angular_momentum_free(pos, vel, inv_mass, node_mass):
    lz = 0.0
    for i in range(pos.shape[0]):
        if inv_mass[i] > 0.0:
            lz += node_mass[i] * (pos[i, 0] * vel[i, 1] - pos[i, 1] * vel[i, 0])
    return lz


@njit(cache=True)
def integrate_positions(pos, vel, inv_mass, dt):
    for i in range(pos.shape[0]):
        if inv_mass[i] > 0.0:
            pos[i, 0] += dt * vel[i, 0]
            pos[i, 1] += dt * vel[i, 1]
            pos[i, 2] += dt * vel[i, 2]


@njit(cache=True)
def advance(pos, vel, hub, force, tension, inv_mass, node_mass, elem_nodes, rest, ea, cdamp,
            tied_idx, tied_ref, contact_idx, r0, mu, j_eff, law, law_params, dt, nsteps,
            rec_every, probe_idx, rec, rec_probe_pos, rec_probe_vel):
    """Run ``nsteps`` central-difference steps; record history rows every ``rec_every`` steps.

    Row k of ``rec`` holds REC_COLUMNS at integer step n (energies as the mean of the two
    half-step values, accumulated work/dissipation up to t_n). ``rec_probe_pos/vel`` get the
    positions x_n and velocities (v_{n-1/2} + v_{n+1/2}) / 2 of the probe nodes (arm tips
    and spines, see spinweb_fe.arms).
    Returns (status, rows): status 0 ok, 1 non-finite state detected.
    """
    nrec = 0
    ntip = probe_idx.shape[0]
    vtip = np.zeros((ntip, 3))
    for _ in range(nsteps):
        step = int(hub[H_STEP])
        record = step % rec_every == 0
        t = step * dt
        force[:, :] = 0.0
        se, tmax, pdamp = eval_elements(pos, vel, elem_nodes, rest, ea, cdamp, force, tension,
                                        record)
        tau = hub_torque_of(pos, force, tied_idx)
        w_old = hub[H_OMEGA]
        prescribed, value = eval_control(law, law_params, t, w_old)
        if prescribed:  # hub rate imposed at the half step; the torque it takes is reported
            _, w_new = eval_control(law, law_params, t + 0.5 * dt, w_old)
            torque = j_eff * (w_new - w_old) / dt - tau
        else:  # J_eff omega' = M + tau (tied-node reactions)
            torque = value
            w_new = w_old + dt * (torque + tau) / j_eff
        if record:
            lz0 = angular_momentum_free(pos, vel, inv_mass, node_mass)
            for k in range(ntip):
                for d in range(3):
                    vtip[k, d] = vel[probe_idx[k], d]
        ke0, ke1 = integrate_free(pos, vel, force, inv_mass, node_mass, dt, record)
        w_new, dcontact = apply_contact(pos, vel, force, node_mass, contact_idx, r0, mu, j_eff,
                                        w_new, w_new - w_old, dt)
        dwork = torque * dt * 0.5 * (w_new + w_old)  # exact discrete work on the hub
        ddamp = pdamp * dt
        if record:
            ke1 = 0.0
            for i in range(pos.shape[0]):
                if inv_mass[i] > 0.0:
                    ke1 += node_mass[i] * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
            ke1 *= 0.5
            lz1 = angular_momentum_free(pos, vel, inv_mass, node_mass)
            ke = 0.5 * (ke0 + ke1) + 0.25 * j_eff * (w_old * w_old + w_new * w_new)
            if not (np.isfinite(ke) and np.isfinite(se)):
                return 1, nrec
            rec[nrec, 0] = t
            rec[nrec, 1] = hub[H_THETA]
            rec[nrec, 2] = 0.5 * (w_old + w_new)
            rec[nrec, 3] = torque
            rec[nrec, 4] = ke
            rec[nrec, 5] = se
            rec[nrec, 6] = hub[H_WORK] + 0.5 * dwork
            rec[nrec, 7] = hub[H_DAMP] + 0.5 * ddamp
            rec[nrec, 8] = hub[H_CONTACT] + 0.5 * dcontact
            rec[nrec, 9] = 0.5 * (lz0 + lz1) + j_eff * 0.5 * (w_old + w_new)
            rec[nrec, 10] = tmax
            for k in range(ntip):
                for d in range(3):
                    rec_probe_pos[nrec, k, d] = pos[probe_idx[k], d]
                    rec_probe_vel[nrec, k, d] = 0.5 * (vtip[k, d] + vel[probe_idx[k], d])
            nrec += 1
        integrate_positions(pos, vel, inv_mass, dt)
        hub[H_THETA] += dt * w_new
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
