"""The payout devices' phase at the end of a step on either hub (``payout = "rate" |
"brake"``, fe.coil.payout): each arm's line moves to its device's target, the hub sheds the
mass that passes D and takes the device's reaction (a fixed axis: the moment about it; a
free body: the impulse and the moment that conserve momentum and angular momentum), the
held and tied nodes follow, and each arm's device work is the change of the energy its
update makes (fe.coil.line). The hub's pose as the devices see it: :func:`axis_pose`,
:func:`body_pose`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.coil.brake import device_target
from spinweb_fe.fe.coil.levels import place_held, place_levels
from spinweb_fe.fe.coil.line import line_energy, line_pairing
from spinweb_fe.fe.coil.payout import Pose, locate_devices, move_line, no_reaction, rest_ref
from spinweb_fe.fe.hub.axis import place_rigid
from spinweb_fe.fe.hub.body import body_state
from spinweb_fe.fe.hub.rigid import (body_energy, cross, detach, hub_centre, inv_inertia,
                                     place_body, rotation)


@njit(cache=True)
def axis_pose(theta, omega):
    """The fe.coil.payout.Pose of a hub on the fixed axis at theta turning at omega: R =
    Rz(theta), the centres at the origin, no velocity there."""
    R = np.zeros((3, 3))
    c, s = np.cos(theta), np.sin(theta)
    R[0, 0], R[0, 1], R[1, 0], R[1, 1], R[2, 2] = c, -s, s, c, 1.0
    w = np.zeros(3)
    w[2] = omega
    return Pose(R, np.zeros(3), np.zeros(3), np.zeros(3), w)


@njit(inline="always")
def arm_target(coil, cs, k, elems, mv, pose, t, dt):
    """Arm k's level at its front and where its line at D goes in this step (its arm
    coordinate); level -1 when the arm's device does nothing now: every level gone, a coil
    not yet free of its hold, or a target that does not move the line on (its speed then
    0)."""
    lev = coil.arm_ptr[k] + cs.front[k]
    if lev >= coil.arm_ptr[k + 1] or (cs.front[k] == 0 and t < coil.arm_hold[k]):
        return -1, 0.0
    if cs.front[k] == 0:
        return lev, cs.s_dev[k]
    s_new = device_target(coil, cs, k, lev, elems, mv, pose, t, dt)
    if s_new >= cs.s_dev[k]:
        cs.dev_speed[k] = 0.0
        return -1, 0.0
    return lev, s_new


@njit(cache=True)
def axis_devices(coil, cs, elems, nodes, hub, mv, hs, t, dt):
    """The reels or brakes of a scene on a fixed axis at the end of a step (fe.coil.payout): each
    arm's line moves to the device's target, the hub sheds the mass that passes and takes
    the reaction's moment about the axis (its rate and inertia in ``hs`` change), the held
    and tied nodes follow; each arm's device work is the change of the energy its update
    makes (``coil`` None: nothing, at compile time)."""
    if coil is None:
        return
    w, j = hs.rate[0], hs.inertia[0]
    pose = axis_pose(hs.angle[0], w)
    locate_devices(coil, cs, pose)
    out = no_reaction()
    steps = np.empty((coil.test_elem.shape[0] + 1, 3))
    moved = False
    for k in range(coil.arm_ptr.shape[0] - 1):
        lev, s_new = arm_target(coil, cs, k, elems, mv, pose, t, dt)
        if lev < 0:
            continue
        # the held nodes the energies count turn with the hub's rate now (every held node
        # and the tied ones follow once, after the last arm)
        place_levels(coil.arm_ptr, cs.front, coil.level_ptr, coil.level_nodes, coil.level_ref,
                     mv.pos, mv.vel, hs.angle[0], w, k, lev, lev)
        e0 = line_energy(coil, cs, k, elems, mv, lev, lev) + 0.5 * j * w * w
        steps[0, 0] = -1.0
        e0 += 0.5 * line_pairing(coil, cs, k, elems, mv, pose, lev, dt, steps)
        r = rest_ref(coil, k, lev)
        rest0 = cs.dev_rest[k] * (r[0] ** 2 + r[1] ** 2)
        out.impulse[:] = 0.0
        out.moment[:] = 0.0
        out.inertia[:] = 0.0
        move_line(coil, cs, k, elems, nodes, mv, pose, s_new, dt, out)
        lev1 = coil.arm_ptr[k] + cs.front[k]
        if lev1 < coil.arm_ptr[k + 1]:
            r = rest_ref(coil, k, lev1)
            j += cs.dev_rest[k] * (r[0] ** 2 + r[1] ** 2)
        j -= rest0 + out.inertia[0]
        w += out.moment[2] / j  # the moment of the device's reaction about the axis
        pose.omega[2] = w
        moved = True
        place_levels(coil.arm_ptr, cs.front, coil.level_ptr, coil.level_nodes, coil.level_ref,
                     mv.pos, mv.vel, hs.angle[0], w, k, lev, lev1)
        e1 = (line_energy(coil, cs, k, elems, mv, lev, lev1) + 0.5 * j * w * w
              + 0.5 * line_pairing(coil, cs, k, elems, mv, pose, lev, dt, steps))
        cs.dev_work[k] += e1 - e0
    if moved:
        place_rigid(mv.pos, mv.vel, hub.tied_idx, hub.tied_ref, hs.angle[0], w)
        place_held(coil.arm_ptr, cs.front, coil.level_ptr, coil.level_nodes, coil.level_ref,
                   mv.pos, mv.vel, hs.angle[0], w)
    hs.rate[0], hs.inertia[0] = w, j


@njit(cache=True)
def body_pose(rs):
    """The fe.coil.payout.Pose of the free body now: its attitude, the hub centre, the centre of
    mass, its velocity and angular velocity (copies)."""
    R = rotation(rs.quaternion)
    return Pose(R, hub_centre(rs, R), rs.position.copy(), rs.velocity.copy(),
                inv_inertia(rs, R, rs.momentum))


@njit(cache=True)
def body_devices(coil, body, cs, elems, nodes, hub, rs, mv, hs, t, dt):
    """The reels or brakes of a scene with a free hub at the end of a step (fe.coil.payout):
    each arm's line moves to its device's target, the body sheds the mass that passes
    (fe.hub.rigid.detach: every point keeps its velocity) and takes the device's reaction (the
    impulse and the moment that conserve momentum and angular momentum); each arm's
    device work is the change of the energy its update makes (``coil`` None: nothing)."""
    if coil is None:
        return
    pose = body_pose(rs)
    locate_devices(coil, cs, pose)
    out = no_reaction()
    steps = np.empty((coil.test_elem.shape[0] + 1, 3))
    for k in range(coil.arm_ptr.shape[0] - 1):
        lev, s_new = arm_target(coil, cs, k, elems, mv, pose, t, dt)
        if lev < 0:
            continue
        R = pose.rot.copy()
        steps[0, 0] = -1.0
        e0 = (line_energy(coil, cs, k, elems, mv, lev, lev)
              + body_energy(rs, R, rs.velocity, rs.momentum)
              + 0.5 * line_pairing(coil, cs, k, elems, mv, pose, lev, dt, steps))
        out.impulse[:] = 0.0
        out.moment[:] = 0.0
        out.inertia[:] = 0.0
        move_line(coil, cs, k, elems, nodes, mv, pose, s_new, dt, out)
        detach(body, nodes, hub, coil, cs, rs)
        J = out.impulse
        rs.velocity[:] = rs.velocity - J / rs.mass[0]
        rs.momentum[:] = rs.momentum + out.moment + cross(rs.position, J)
        pose = body_pose(rs)
        place_body(hub, coil, cs, rs, mv.pos, mv.vel)
        e1 = (line_energy(coil, cs, k, elems, mv, lev, coil.arm_ptr[k] + cs.front[k])
              + body_energy(rs, R, rs.velocity, rs.momentum)
              + 0.5 * line_pairing(coil, cs, k, elems, mv, pose, lev, dt, steps))
        cs.dev_work[k] += e1 - e0
    hs.rate[0], hs.inertia[0] = body_state(rs)
