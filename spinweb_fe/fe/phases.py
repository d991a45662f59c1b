"""The phases of the step that differ by the hub's kind, each a small dispatcher that
``fe.step.advance`` calls once per step: ``axis`` (fe.hub.axis.Axis) for a hub on a fixed
axis, ``body`` (fe.hub.rigid.Body) for a free one, the other None. They are inlined at
numba's IR level (``inline="always"``), so that numba prunes the branch of the absent hub
after inlining them into ``advance``; none is a compile of its own.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.coil.levels import any_held, held_moment, place_held, release_fronts
from spinweb_fe.fe.coil.devices import axis_devices, body_devices
from spinweb_fe.fe.contact.failsafe import contact_resolve
from spinweb_fe.fe.contact.touch import REACTIONS
from spinweb_fe.fe.hub.axis import (axis_field, axis_field_work, axis_kick, axis_nodes,
                                    axis_reaction, axis_row, axis_vector_row, place_rigid)
from spinweb_fe.fe.hub.body import (body_drift, body_kick, body_nodes, body_release, body_row,
                                    body_state, twist)
from spinweb_fe.fe.hub.rigid import place_body
from spinweb_fe.fe.vectors import plane_stats


@njit(inline="always")
def field_loads(axis, env, t, nodes, hub, coil, cs, bundles, mv, force, tidal, field, holding):
    """The gravity gradient's loads at x_n on a scene with a fixed axis (fe.hub.axis.axis_field;
    a free hub takes the field in its own phases). The step calls it only for a scene with
    the field."""
    if axis is not None:
        axis_field(env, t, nodes, hub.tied_idx, coil, cs, bundles, mv, force, tidal, field,
                   holding)


@njit(inline="always")
def field_work(axis, env, field, tidal, mv, kick, dt):
    """The gravity gradient's work over the step on a scene with a fixed axis [J] (a free
    hub's is counted in its node pass). The step calls it only for a scene with the
    field."""
    w = 0.0
    if axis is not None:
        w = axis_field_work(field, tidal, mv, kick, dt)
    return w


@njit(inline="always")
def held_loads(axis, coil, cs, pos, force, tau):
    """The moment about a fixed axis of the forces on its held coil at x_n, and of a reel's
    or brake's line at D (fe.coil.payout), added to ``tau`` [N m]; a free hub counts its held
    coil in its own loads. Called only while some arm is held: the coil's arrays are
    handed over only then (each array a call or an inlined phase receives costs a
    reference count, per step)."""
    if axis is not None:
        tau += held_moment(coil.arm_ptr, cs.front, coil.level_ptr, coil.level_nodes, pos,
                           force)
        if coil.device:
            tau += cs.dev_moment[2]
    return tau


@njit(inline="always")
def hub_loads(axis, body, hub, coil, cs, env, rs, law, pos, force, tau, hs, t, dt):
    """Loads on the hub at x_n and its kick over the step: fe.hub.axis.AxisKick (fixed axis:
    ``tau`` the moment of the held coil, :func:`held_loads`) or fe.hub.body.BodyKick (free
    hub)."""
    if axis is not None:
        kick = axis_kick(hub.tied_idx, law, pos, force, tau, hs.rate[0], hs.inertia[0], t, dt)
    if body is not None:
        kick = body_kick(hub, coil, cs, env, rs, law, pos, force, t, dt)
    return kick


@njit(inline="always")
def move_nodes(axis, body, nodes, hub, mv, work, env, rs, kick, t, dt, sums, record,
               threads):
    """Kick, hub contact and drift of every free node in one pass. Returns (the kick with
    the hub's rate after the contacts, contact dissipation [J], gravity-gradient work [J])."""
    if axis is not None:
        kick, diss = axis_nodes(nodes, hub, mv, kick, work, dt, sums, record, threads)
        wgrav = 0.0
    if body is not None:
        kick, diss, wgrav = body_nodes(nodes, hub, mv, work.force, env, t, rs, kick, dt,
                                       record, sums)
    return kick, diss, wgrav


@njit(inline="always")
def hub_drift(axis, body, rs, kick, theta, dt):
    """The hub's drift over the step; returns theta_{n+1} [rad]."""
    if axis is not None:
        theta = theta + dt * kick.rate_new
    if body is not None:
        theta = body_drift(rs, kick, dt, theta)
    return theta


@njit(inline="always")
def place_bound(axis, body, hub, coil, cs, rs, pos, vel, theta, omega):
    """The tied nodes move with the hub at theta_{n+1} (a free hub's held coil too)."""
    if axis is not None:
        place_rigid(pos, vel, hub.tied_idx, hub.tied_ref, theta, omega)
    if body is not None:
        place_body(hub, coil, cs, rs, pos, vel)


@njit(inline="always")
def place_coil(axis, coil, cs, pos, vel, theta, omega):
    """The held coil moves with a fixed axis at theta_{n+1} (only while some arm is held)."""
    if axis is not None:
        place_held(coil.arm_ptr, cs.front, coil.level_ptr, coil.level_nodes, coil.level_ref,
                   pos, vel, theta, omega)


@njit(inline="always")
def release(axis, body, elems, nodes, hub, coil, cs, rs, mv, j_eff, t, broken):
    """Release the front levels the arms pull off at time t (fe.coil.levels.release_fronts);
    returns the fixed axis's effective inertia without them [kg m^2] (a free body
    reassembles itself)."""
    if axis is not None:
        j_eff = release_fronts(coil, cs, elems, nodes, mv.pos, mv.mass, mv.inv_mass, j_eff, t,
                               broken)
    if body is not None:
        body_release(body, elems, nodes, hub, coil, cs, rs, mv, t, broken)
    return j_eff


@njit(inline="always")
def device_phase(axis, body, devices, elems, nodes, hub, coil, cs, rs, mv, hs, t, dt):
    """The reels and brakes at the end of a step (fe.coil.payout; nothing without them)."""
    if axis is not None:
        axis_devices(devices, cs, elems, nodes, hub, mv, hs, t, dt)
    if body is not None:
        body_devices(devices, body, cs, elems, nodes, hub, rs, mv, hs, t, dt)


@njit(inline="always")
def hub_now(axis, body, rs, kick, j_eff):
    """(rate omega_{n+1/2} about the hub axis [rad/s], effective inertia [kg m^2]) after the
    step."""
    if axis is not None:
        out = (kick.rate_new, j_eff)
    if body is not None:
        out = body_state(rs)
    return out


@njit(inline="always")
def reacted(axis, body, hub, coil, cs, rs, pos, vel, hs, dw, dt):
    """After the hub took the reaction of the contact's impulses (:func:`settle`): a
    fixed axis turns by dt times its rate's change ``dw``, a free body has turned itself;
    the tied and held nodes are placed again. Returns the hub's angle [rad]."""
    if axis is not None:
        theta = hs.angle[0] + dt * dw
    if body is not None:
        theta = twist(rs.quaternion, hs.angle[0])
        hs.rate[0], hs.inertia[0] = body_state(rs)
    place_bound(axis, body, hub, coil, cs, rs, pos, vel, theta, hs.rate[0])
    if any_held(coil.arm_ptr, cs.front):
        place_coil(axis, coil, cs, pos, vel, theta, hs.rate[0])
    return theta


@njit(inline="always")
def settle(axis, body, hub, coil, cs, rs, contact, pos, vel, inv_mass, hs, dt, threads):
    """The contact's fail-safe at the step's end (fe.contact.penalty.contact_resolve). When its
    impulses pushed on the hub, the hub takes the reaction and places its tied and held
    nodes again (:func:`reacted`), and the pairs those nodes have are tested again, at most
    fe.contact.touch.REACTIONS passes in all; in the last the reaction changes the hub's velocities
    only, not its pose, so that nothing moves after the pass that tested it (the passes can
    go on pushing a cable pinched between two of the hub's elements). Returns (fresh,
    clean) for fe.contact.touch.audit_step: the swept boxes stand; nothing crossed.
    ``threads``: the step's (fe.contact.failsafe.resolve_crossings)."""
    fresh, clean = True, True
    for k in range(REACTIONS):
        place = k < REACTIONS - 1
        n, left = 0, 0
        if axis is not None:  # (two ifs: an else would compile the free hub's on an axis)
            n, left = contact_resolve(contact, pos, vel, inv_mass, dt, hs.rate, hs.inertia,
                                      None, hs.angle[0], k > 0, place, threads)
        if body is not None:
            n, left = contact_resolve(contact, pos, vel, inv_mass, dt, None, None, rs,
                                      hs.angle[0], k > 0, place, threads)
        took = contact.hub0.took[0]
        fresh = fresh and n == 0 and not took
        clean = fresh and left == 0
        if not took:
            break
        turned = contact.hub0.dw[0] if place else 0.0  # (a free body turned itself, or not)
        hs.angle[0] = reacted(axis, body, hub, coil, cs, rs, pos, vel, hs, turned, dt)
    return fresh, clean


@njit(inline="always")
def hub_record(axis, body, kick, env, t, hub, coil, cs, nodes, pos, force, vrow, vs):
    """The vector row's distances from the hub plane at x_n and, on a fixed axis, the torque
    the axis exerts on the hub (fe.hub.axis.axis_reaction)."""
    if axis is not None:
        plane_stats(pos, nodes.inv_mass, np.zeros(3), np.array([0.0, 0.0, 1.0]), vrow, vs)
        axis_reaction(env, t, hub, coil, cs, pos, force, vrow, vs)
    if body is not None:
        plane_stats(pos, nodes.inv_mass, kick.hull[0], kick.hull[1], vrow, vs)


@njit(inline="always")
def hub_row(axis, body, hub, coil, cs, nodes, rs, kick, sums, pos, theta, vec, k, vs):
    """The hub's part of row k: (mean rate about its axis [rad/s], kinetic energy [J],
    angular momentum about +z [N m s]) of the scalar row, and its part of the vector row
    ``vec[k]`` (when recorded; slots ``vs``)."""
    if axis is not None:
        out = axis_row(kick, sums)
        if vec is not None:
            axis_vector_row(hub, coil, cs, nodes, pos, theta, out[0], kick.j_eff, vec[k], vs)
    if body is not None:
        out = body_row(rs, kick, sums, vec[k], vs)
    return out
