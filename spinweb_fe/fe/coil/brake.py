"""The brake's kernels (``[stowage] payout = "brake"``, fe.coil.payout): where the line at each
arm's departure point D goes in a step. A return mapping: the line sticks while its tension
at D is at or below the force (or its pull lies along the hub), else it slips to where the
tension equals the force, within limits that keep the slip physical (the line's stretch and
travel, its momentum balance across D) and the brake dissipative (its work never above
-SLIP_DUE times the friction's N x_rel); docs/solver.md. :func:`device_target` is the reel's
or the brake's target, which the step's device phase (fe.hub.axis, fe.hub.body) calls.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.coil.levels import law_value
from spinweb_fe.fe.coil.payout import (REEL, _frac, _hub_velocity3, _world, device_point,
                                  rest_ref)

#: the brake's return mapping: at most this many tension evaluations per arm and step
SLIP_ITERATIONS = 40
#: the brake's line runs through D at most this many times as fast as its taut material
#: leaves D
SLIP_SPEED = 2.0
#: a brake's slip is limited so that its work stays at most -SLIP_DUE times the friction's
#: N x (x the line's slip relative to D) summed over its slips: 1 would be the exact
#: friction, which the step's handover estimate (O(dt) pairing terms left out) hits too
#: often while the line loads up (tension at D 2.8 % above the force on the tethers)
SLIP_DUE = 0.9


@njit(inline="always")
def brake_target(coil, cs, k, lev, elems, mv, pose, force, dt):
    """The line coordinate at D after the brake's step: the line slips while it pulls away
    from the hub at D (the pull of the front level's elements has an outward part, along
    D's radial from the hub axis of ``pose``) and its tension (the outer nodes at ``pos``, D
    where the line's coordinate puts it on the coil) exceeds ``force`` [N], to where the
    tension equals it (a return mapping: Newton on the tension from the stuck state, kept
    inside a bracket of the slip and bisecting where it would leave it; it stops at the
    front level's coordinate). A line that lies along the hub or wraps on it
    stays: the coil holds it, as the free payout's does."""
    s_old, s_f = cs.s_dev[k], coil.level_coord[lev]
    x_d = cs.dev_x[k]
    c = pose.centre
    ax = np.array([pose.rot[0, 2], pose.rot[1, 2], pose.rot[2, 2]])
    r = x_d - c
    r = r - (r[0] * ax[0] + r[1] * ax[1] + r[2] * ax[2]) * ax  # D's radial
    pos, vel = mv.pos, mv.vel
    vd0, vd1, vd2 = _hub_velocity3(pose, x_d[0], x_d[1], x_d[2])
    level = s_old - s_f
    x, lo, hi = 0.0, 0.0, level  # the slip and its bracket: tension above, below
    n0, cap, v_max, stretch, mu = 0.0, level, 0.0, 0.0, 0.0
    for it in range(SLIP_ITERATIONS):
        if it > 0:
            x_d = _world(pose, device_point(coil, k, lev, s_old - x))
        n, slope, out = 0.0, 0.0, 0.0
        for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
            e, b = coil.test_elem[q], coil.test_to[q]
            u = pos[b] - x_d
            d = np.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
            s_to = coil.test_to_coord[q]
            ell = elems.rest_len[e] * _frac(s_to, s_f, s_old - x)
            if d > ell and s_old - x > s_f:
                k_e = elems.ea[e] * elems.inv_rest[e]
                n += k_e * (d - ell)
                slope += k_e * elems.rest_len[e] / (s_to - s_f)
                out += k_e * (d - ell) / d * (u[0] * r[0] + u[1] * r[1] + u[2] * r[2])
                if it == 0:  # how fast the taut line's material leaves D
                    span = s_to - s_f
                    mu += coil.test_half[q] * elems.rest_len[e] / (span * span)
                    v_away = ((vel[b, 0] - vd0) * u[0] + (vel[b, 1] - vd1) * u[1]
                              + (vel[b, 2] - vd2) * u[2]) / d
                    v_max = max(v_max, v_away)
                    stretch = max(stretch, d - ell)
        if it == 0:
            if out <= 0.0 or n <= force:  # along the hub or below the force: stuck
                break
            n0 = n
            # the line slips through D by at most its largest stretch (what the brake
            # relieves) and SLIP_SPEED times the step's travel of its taut material away
            # from D: a return mapping of many elements (a web's gathered level) would
            # otherwise jump a whole level in a step and hand the passing mass that speed
            cap = min(level, stretch + SLIP_SPEED * v_max * dt)
            # and no faster than the line's momentum balance across D lets it: the material
            # passing D at u carries away mu u^2 of the tension's excess over the force (mu
            # [kg/m]: the mass that passes per metre of the arm's coordinate, as seen by the
            # elements' line speeds)
            if mu > 0.0:
                cap = min(cap, dt * np.sqrt((n0 - force) / mu))
            hi = cap
            if cap <= 0.0:
                break
        if abs(n - force) <= 1e-12 * force:
            break
        if n > force:
            lo = x
        else:
            hi = x
        # Newton on the rest lengths' part of the slope, kept inside the bracket (D's own
        # motion along the coil also changes the stretch: where the line wraps on the hub
        # a bare Newton step overshoots into the slack)
        step = (n - force) / slope if slope > 0.0 else hi - x
        x_new = x + step
        if not (lo < x_new < hi):
            x_new = 0.5 * (lo + hi)
        if hi - lo <= 1e-12 * (s_old - s_f + 1.0):
            # above the force over the whole level: it all passes (the next level's
            # elements take over) if the slip relieves the line; where it does not (the
            # line lies along the coil, D's slide lengthens it as fast as it pays out) the
            # coil holds it. Else the last slip with the tension above the force.
            if hi == level:
                x = hi if n < n0 else 0.0
            elif hi == cap:  # above the force up to the speed limit
                x = cap
            else:
                x = lo
            break
        x = x_new
    if x > 0.0:
        x = _dissipative(coil, cs, k, lev, elems, mv, pose, force, x, dt)
    x = min(x, s_old - s_f)
    return s_old - x


@njit(cache=True)
def _dissipative(coil, cs, k, lev, elems, mv, pose, force, x, dt):
    """The slip x limited so that the brake has, over its slips so far, taken at least
    the friction's energy: N times the line's slip relative to D (the slip less D's slide
    along the pull, ``cs.dev_friction``); the step's handover (``slip_energy``) would
    otherwise let material pass D at a speed the strain it relieves cannot pay for.
    Bisection on the largest x that keeps the sum; the friction's energy summed."""
    x0 = cs.dev_x[k]
    p0, p1, p2 = 0.0, 0.0, 0.0  # the pull's direction at D
    for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
        b = coil.test_to[q]
        u0, u1, u2 = mv.pos[b, 0] - x0[0], mv.pos[b, 1] - x0[1], mv.pos[b, 2] - x0[2]
        d = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2) + 1e-300
        w = elems.ea[coil.test_elem[q]] * elems.inv_rest[coil.test_elem[q]] / d
        p0, p1, p2 = p0 + w * u0, p1 + w * u1, p2 + w * u2
    size = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2) + 1e-300
    p0, p1, p2 = p0 / size, p1 / size, p2 / size
    room = -(cs.dev_work[k] + cs.dev_friction[k])
    s_old, s_f = cs.s_dev[k], coil.level_coord[lev]
    lo, hi, y = 0.0, x, x
    fr = 0.0
    for it in range(SLIP_ITERATIONS + 1):
        x1 = _world(pose, device_point(coil, k, lev, max(s_old - y, s_f)))
        fr_y = SLIP_DUE * force * max(y + (x1[0] - x0[0]) * p0 + (x1[1] - x0[1]) * p1
                                      + (x1[2] - x0[2]) * p2, 0.0)
        if slip_energy(coil, cs, k, lev, elems, mv, pose, y, dt) + fr_y <= room:
            lo, fr = y, fr_y
            if it == 0:
                break
        else:
            hi = y
        if hi - lo <= 1e-9 * x:
            break
        y = 0.5 * (lo + hi)
    cs.dev_friction[k] += fr
    return lo


@njit(cache=True)
def slip_energy(coil, cs, k, lev, elems, mv, pose, x, dt):
    """The energy [J] arm k's line would gain if it slipped by x (arm coordinate) through D
    in this step, as :func:`move_line` hands the material over: the strain energy of the
    front level's elements (D moved with the line along the coil, each element's rest
    length phi L0) and the kinetic energy of the material that passes, from the hub's
    velocity where the device holds it to the line's at D (D's own velocity and the line's
    speed along the element; the hub's reaction to first order), merged with the outer
    node's momentum. The brake's work in that step is this up to the leapfrog's pairing
    terms (O(dt))."""
    s_old, s_f = cs.s_dev[k], coil.level_coord[lev]
    s = max(s_old - x, s_f)
    x0 = cs.dev_x[k]
    x1 = _world(pose, device_point(coil, k, lev, s))
    vh0, vh1, vh2 = _hub_velocity3(pose, x0[0], x0[1], x0[2])
    vd0, vd1, vd2 = vh0 + (x1[0] - x0[0]) / dt, vh1 + (x1[1] - x0[1]) / dt, \
        vh2 + (x1[2] - x0[2]) / dt
    x_m = _world(pose, rest_ref(coil, k, lev))
    vm0, vm1, vm2 = _hub_velocity3(pose, x_m[0], x_m[1], x_m[2])
    pos, vel, mass = mv.pos, mv.vel, mv.mass
    gain = 0.0
    for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
        e, b = coil.test_elem[q], coil.test_to[q]
        rest, s_to = elems.rest_len[e], coil.test_to_coord[q]
        f0, f1 = _frac(s_to, s_f, s_old), _frac(s_to, s_f, s)
        u0, u1, u2 = pos[b, 0] - x0[0], pos[b, 1] - x0[1], pos[b, 2] - x0[2]
        d0 = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        w0, w1, w2 = pos[b, 0] - x1[0], pos[b, 1] - x1[1], pos[b, 2] - x1[2]
        d1 = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        a0, a1 = max(d0 - rest * f0, 0.0), max(d1 - rest * f1, 0.0)
        gain += 0.5 * elems.ea[e] * elems.inv_rest[e] * (a1 * a1 - a0 * a0)
        dm = (f1 - f0) * coil.test_half[q]
        if dm <= 0.0:
            continue
        c = (f1 - f0) * rest / dt / d0 if d0 > 0.0 else 0.0
        v0, v1, v2 = vd0 + c * u0, vd1 + c * u1, vd2 + c * u2  # the line's at D
        m_b = mass[b]
        gain += 0.5 * dm * ((v0 - vm0) ** 2 + (v1 - vm1) ** 2 + (v2 - vm2) ** 2) \
            - 0.5 * dm * m_b / (m_b + dm) * ((v0 - vel[b, 0]) ** 2 + (v1 - vel[b, 1]) ** 2
                                             + (v2 - vel[b, 2]) ** 2)
    return gain


@njit(inline="always")
def device_target(coil, cs, k, lev, elems, mv, pose, t, dt):
    """Where arm k's line at D goes in this step (its arm coordinate, never back): the
    reel's law, or the brake's return mapping at its force at time t (``pose``: the hub's,
    see :func:`locate_devices`)."""
    if coil.payout_code == REEL:
        return min(cs.s_dev[k], coil.arm_end[k] - law_value(coil.law_t, coil.law_v, t))
    return brake_target(coil, cs, k, lev, elems, mv, pose,
                        law_value(coil.law_t, coil.law_v, t), dt)
