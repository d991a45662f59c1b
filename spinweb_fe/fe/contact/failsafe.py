"""The cable contact's fail-safe (``[contact] cables = true``), after Bridson, Fedkiw and
Anderson's cloth collisions: at the end of each step, every candidate pair that would pass
through each other over the step gets equal and opposite impulses at its crossing points
(:func:`resolve_crossings`), the pairs a round leaves crossing move as impact zones
(fe.contact.zones), the friction's impulses come first, and the hub takes the reaction of
what its held and tied nodes could not (:func:`contact_resolve`, fe.contact.impulses). The
penalty of the step's start is fe.contact.penalty.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from spinweb_fe.fe.contact.bounds import (BLOCKS_PER_THREAD, THREAD_MIN_PAIRS, bound_after,
                                          bound_now, frame_turn, moved_pair_motion, pair_motion,
                                          step_motion)
from spinweb_fe.fe.contact.clock import (C_AGAIN, C_FRICTION, C_MOTION, C_REACTION, C_RESOLVE,
                                         C_ROUND0, C_ROUNDS, C_ZONES, N_AGAIN, N_EXACT0,
                                         N_IMPULSES, N_IMPULSES_AGAIN, N_LOOK0, N_REACTIONS,
                                         N_READ0, N_RESOLVE, N_ROUND_LOOKED, N_ROUND_PAIRS,
                                         N_ROUNDS, N_ZONES, cycles, lap)
from spinweb_fe.fe.contact.crossing import SEP, apart, pair_crossings
from spinweb_fe.fe.contact.distance import closest_points
from spinweb_fe.fe.contact.impulses import (axis_reaction, body_reaction, friction_impulses,
                                            impulse_work)
from spinweb_fe.fe.contact.penalty import AGAIN, FRICTION, IMPULSES, IN_CONTACT, LEFT, TAKEN
from spinweb_fe.fe.contact.zones import (ZONE_ROUNDS, axis_map, body_map, ensure_adjacency,
                                         impact_zones, no_adjacency, pairs_of)


@njit(cache=True, no_cpython_wrapper=True)
def contact_resolve(ck, pos, vel, inv_mass, dt, rate=None, inertia=None, body=None,
                    theta=0.0, again=False, place=True, threads=None):
    """The fail-safe over the step just taken from ``ck.pos0`` (the step's motion and the
    pairs' certificates first: fe.contact.bounds). Returns its impulses (0: the positions
    and the motion stand) and the crossings its last
    pass left (both 0: no pair of the list crossed in the step). The friction's impulses
    first (``ck.mu`` > 0). ``rate``, ``inertia`` ((1,) arrays, a fixed axis's rate
    omega_{n+1/2} and effective inertia): the hub takes the angular impulse about its axis
    that the impulses gave the free nodes, so that nodes held on or tied to it (which take
    no share of an impulse) push back through it (``ck.hub0.dw``: the rate's change).
    ``body`` (fe.hub.rigid.RigidState, a free hub): the body takes the impulse and the moment
    (fe.contact.impulses.body_reaction; ``ck.hub0.took`` when it did). The hub's motion over the
    step (the fixed axis's turn to ``theta`` [rad], or the body's) moves the free nodes of
    an impact zone that holds a node of the hub (fe.contact.zones). ``again``: a pass after the
    hub, having taken a reaction, placed its nodes again (fe.step.settle): only the pairs
    of the nodes it placed (inv_mass 0) and of the free nodes stuck to it this step (the
    zones', ``ck.follow``, which take the reaction with it) are tested, without the
    friction; when they are most of the web's nodes (the held coil) the whole list is read
    against its certificates for the motion as it then stands (the profile measured this
    pass at 22-29 ns a listed pair uncertified, 21-33 % of a contact step, for 0-0.1
    impulses a step). ``place`` False: the hub's reaction changes its velocities only, not its
    pose (fe.step.settle's last pass; fe.contact.impulses). ``threads``: as
    :func:`resolve_crossings` takes them. Timed into the profile (``ck.cert.clock``, ``tally``:
    fe.contact.clock)."""
    clock, tally = ck.cert.clock, ck.cert.tally
    start = cycles()
    ck.vel1[:] = vel
    h0 = ck.hub0
    h0.dw[0] = 0.0
    h0.took[0] = False
    rubbed = ck.mu > 0.0 and ck.stats[IN_CONTACT] > 0 and not again
    if rubbed:
        t0 = cycles()
        friction_impulses(ck.pairs, ck.elem_nodes, ck.hold, ck.pos0, pos, vel, inv_mass, dt,
                          ck.mu)
        ck.vel2[:] = vel
        lap(clock, C_FRICTION, t0)
    if body is not None:  # (this way round: numba prunes the body's branch on an axis)
        hub = body_map(body, h0.centre, h0.quaternion)
    else:
        hub = axis_map(theta - h0.angle[0])
    # an int64, not the global's literal type: the fail-safe's callees then have the types
    # a call from Python gives them (the unit tests share the loop's compile)
    zone_rounds = np.int64(ZONE_ROUNDS)
    if again:
        _, n, left = resolve_crossings(ck.pairs, ck.elem_nodes, ck.pos0, pos, vel, inv_mass,
                                       dt, ck.margin, (ck.rounds, zone_rounds), ck.cert, hub,
                                       (inv_mass == 0.0) | ck.follow, ck.follow, threads)
    else:
        ck.follow[:] = False
        t0 = cycles()
        step_motion(ck.cert.motion, ck.elem_nodes, ck.active, ck.pos0, pos)
        lap(clock, C_MOTION, t0)
        _, n, left = resolve_crossings(ck.pairs, ck.elem_nodes, ck.pos0, pos, vel, inv_mass,
                                       dt, ck.margin, (ck.rounds, zone_rounds), ck.cert, hub,
                                       None, ck.follow, threads)
    t0 = cycles()
    if rubbed or n > 0:
        # the energy the impulses took, as the leapfrog books a force at step n: J . (v_{n-1/2}
        # + v_{n+1/2}) / 2 per node (the impulses change v_{n+1/2} and x_{n+1} as a force
        # m dv / dt in the step's kick would), not the half-step kinetic energy's change,
        # which leaves out J . dt a_n / 2 (the cables' and the penalty's forces)
        work_hub = 0.0
        if rate is not None:
            dw = axis_reaction(pos, ck.vel1, vel, inv_mass, dt, inertia[0], ck.follow, place)
            # the hub's work, paired as the nodes' (omega_{n-1/2} + omega_{n+1/2}) / 2
            work_hub = inertia[0] * dw * (h0.rate[0] + rate[0] + dw) * 0.5
            rate[0] += dw
            h0.dw[0] = dw
            h0.took[0] = dw != 0.0
        if body is not None:
            work_hub = body_reaction(body, pos, ck.vel1, vel, inv_mass, h0.velocity,
                                     h0.omega, dt, ck.follow, place)
            h0.took[0] = True
        # (after the reaction, which the nodes stuck to the hub take too)
        total = -impulse_work(ck.vel1, vel, ck.vel0, inv_mass) - work_hub
        rub = -impulse_work(ck.vel1, ck.vel2, ck.vel0, inv_mass) if rubbed else 0.0
        ck.stats[FRICTION] += rub
        ck.stats[TAKEN] += total - rub
        if not again:
            lap(clock, C_REACTION, t0)
        tally[N_REACTIONS] += h0.took[0]
    ck.stats[IMPULSES] += n
    ck.stats[LEFT] += left
    if again:
        ck.stats[AGAIN] += n
        lap(clock, C_AGAIN, start)
        tally[N_AGAIN] += 1
        tally[N_IMPULSES_AGAIN] += n
    else:
        lap(clock, C_RESOLVE, start)
        tally[N_RESOLVE] += 1
        tally[N_IMPULSES] += n
    return n, left


@njit(cache=True, parallel=True)
def certified_candidates(pairs, elem_nodes, level, mo, sep, blocks):
    """The first pass's certificates (:func:`resolve_crossings`) on numba's threads: the pairs
    whose certificates cannot rule them out, in the list's order, and how many were looked
    at by their relative motion. A first pass moves no certificate (``level`` and ``mo``
    stand until its end; only its exact tests read the positions the impulses move), so
    the pass that then tests these pairs in order is the one-thread pass, bit for bit. The
    list is cut into ``blocks`` runs, each writing its pairs from its own start."""
    m = pairs.shape[0]
    size = (m + blocks - 1) // blocks
    found = np.empty(m, np.int64)
    counts = np.zeros((blocks, 2), np.int64)
    for c in prange(blocks):
        lo = min(m, c * size)
        k, looked = lo, 0
        for p in range(lo, min(m, lo + size)):
            e, g = pairs[p, 0], pairs[p, 1]
            if bound_after(level, mo, p, e, g) > sep:
                continue
            looked += 1
            a, b = elem_nodes[e, 0], elem_nodes[e, 1]
            if bound_now(level, mo, p, e, g) - pair_motion(mo, a, b, elem_nodes[g, 0],
                                                             elem_nodes[g, 1]) > sep:
                continue
            found[k] = p
            k += 1
        counts[c, 0], counts[c, 1] = k - lo, looked
    n = 0
    for c in range(blocks):
        lo = min(m, c * size)
        for i in range(counts[c, 0]):  # (forward: n <= lo)
            found[n + i] = found[lo + i]
        n += counts[c, 0]
    return found[:n].copy(), counts[:, 1].sum()


@njit(cache=True)
def resolve_crossings(pairs, elem_nodes, pos0, pos1, vel, inv_mass, dt, margin, rounds,
                      cert=None, hub=None, moved=None, follow=None, threads=None):
    """The fail-safe of the contact (after Bridson, Fedkiw and Anderson's cloth collisions):
    every candidate pair that would pass through each other over the step (from ``pos0``
    to ``pos1``, fe.contact.crossing's exact test) gets an impulse along the normal of the two
    elements at the crossing, equal and opposite at their crossing points, that changes
    their relative normal velocity so that they end the step ``margin`` [m] apart on the
    side they came from; the nodes' half-step velocities and end positions are updated
    (x_{n+1} by dt times the velocity's change). A node that does not move freely
    (inv_mass 0: held on or tied to the hub) takes no share (its side is infinitely heavy
    within the pass; the hub takes the reaction afterwards, :func:`contact_resolve`). The
    first pass tests every pair, later passes (``rounds``: at most ``rounds[0]`` passes in
    all, then at most ``rounds[1]`` of the impact zones) the pairs with a
    node an impulse moved; ``cert`` (fe.contact.bounds.Certified), if given, the pairs'
    certificates, the step's motion, the list's adjacency and its elements' activity:
    every pass tests only the pairs they cannot rule out, with the conservative test's
    least separation (a later pass: the swept boxes, then the pair's bound at the step's
    start less its four nodes' motion as the impulses left it,
    fe.contact.bounds.moved_pair_motion). If the rounds run out with crossings left, the
    pairs still crossing move as impact zones (fe.contact.zones: at most ``rounds[1]``
    passes; ``hub`` (4, 3), the hub's motion over the step, for the zones with a node of
    the hub). ``moved`` (n,) bool, if given: only these nodes moved since a
    pass found the rest of the list clear (the hub's nodes, placed again after it took a
    reaction): the first pass tests only their pairs. ``follow`` (n,) bool, if given: the
    free nodes of zones moved with the hub get marked. ``threads`` (None: one thread, no
    thread kernel compiled): the first pass's certificates of a list of at least
    fe.contact.bounds.THREAD_MIN_PAIRS pairs on that many threads
    (:func:`certified_candidates`: the same bits). Returns (kinetic energy the pair
    impulses took [J], pair impulses, crossings left)."""
    times = np.empty(3)
    signs = np.empty(3, np.int64)
    scratch, cuts = np.empty((4, 3)), np.empty(4)
    taken, impulses, left = 0.0, 0, 0
    first = 0 if moved is None else 1  # (a later pass's test from the start)
    if moved is None:
        moved = np.ones(pos0.shape[0], np.bool_)
    n_nodes = pos0.shape[0]
    todo = np.arange(pairs.shape[0])
    adj = no_adjacency(n_nodes, pairs.shape[0]) if cert is None else cert.adj
    sep = 0.0 if cert is None else SEP * cert.motion.scale[0]
    t0 = 0
    for rnd in range(first, rounds[0]):
        if cert is not None:
            t0 = cycles()
        now = np.zeros(n_nodes, np.bool_)
        left = 0
        certified = cert is not None and rnd == 0
        frame = (1.0, 0.0, 1.0, 0.0, 0.0, 0.0)
        if rnd >= 1:
            if 8 * np.count_nonzero(moved) < n_nodes:  # the pairs of the nodes the pass moved
                ensure_adjacency(adj, pairs, elem_nodes)
                todo = pairs_of(adj, moved)
            else:  # most nodes moved (the hub's, placed again): the whole list, certified
                todo = np.arange(pairs.shape[0])
                if cert is not None:  # (the certificates of the motion as it now stands)
                    step_motion(cert.motion, elem_nodes, cert.active, pos0, pos1)
                    certified = True
            if cert is not None:
                frame = frame_turn(cert.motion)
        read, looked, tested = 0, 0, 0
        ahead = False  # the first pass's certificates read on the threads
        if threads is not None and cert is not None:  # (pruned by numba when None)
            if certified and rnd == 0 and pairs.shape[0] >= THREAD_MIN_PAIRS:
                todo, looked = certified_candidates(pairs, elem_nodes, cert.level,
                                                    cert.motion, sep,
                                                    BLOCKS_PER_THREAD * threads)
                read = pairs.shape[0] - todo.shape[0]
                ahead = True
        for p in todo:
            read += 1
            e, g = pairs[p, 0], pairs[p, 1]
            # the certificate before the elements' nodes: most pairs end here, and their
            # four node indices are then never read (the same pairs pass either way)
            if certified and not ahead and bound_after(cert.level, cert.motion, p, e, g) > sep:
                continue
            a, b = elem_nodes[e, 0], elem_nodes[e, 1]
            c, d = elem_nodes[g, 0], elem_nodes[g, 1]
            if rnd >= 1 and not (moved[a] or moved[b] or moved[c] or moved[d]):
                continue
            if certified and not ahead:
                mo = cert.motion
                looked += 1
                if bound_now(cert.level, mo, p, e, g) - pair_motion(mo, a, b, c, d) > sep:
                    continue
            elif cert is not None and rnd >= 1:  # (the swept boxes first: no sqrt, no level)
                looked += 1
                if apart(pos0, pos1, a, b, c, d, sep) or bound_now(
                        cert.level, cert.motion, p, e, g) - moved_pair_motion(
                        cert.motion, pos0, pos1, a, b, c, d, frame) > sep:
                    continue
            tested += 1
            if apart(pos0, pos1, a, b, c, d, sep) or pair_crossings(
                    pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c], pos0[d], pos1[d],
                    times, signs, scratch, cuts, sep) == 0:
                continue
            left += 1
            tau = times[0]
            xa = pos0[a] + tau * (pos1[a] - pos0[a])
            xb = pos0[b] + tau * (pos1[b] - pos0[b])
            xc = pos0[c] + tau * (pos1[c] - pos0[c])
            xd = pos0[d] + tau * (pos1[d] - pos0[d])
            s, t, _ = closest_points(xa, xb, xc, xd)
            w = (1.0 - s) ** 2 * inv_mass[a] + s * s * inv_mass[b] \
                + (1.0 - t) ** 2 * inv_mass[c] + t * t * inv_mass[d]
            if w == 0.0:  # nothing free to push
                continue
            # the side the first element came from: the crossing points at the step's start
            gap0 = (1.0 - s) * pos0[a] + s * pos0[b] - (1.0 - t) * pos0[c] - t * pos0[d]
            d1, d2 = xb - xa, xd - xc
            n = np.cross(d1, d2)
            size = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
            scale = np.sqrt((d1[0] ** 2 + d1[1] ** 2 + d1[2] ** 2)
                            * (d2[0] ** 2 + d2[1] ** 2 + d2[2] ** 2))
            if size <= 1e-9 * scale:  # (nearly) parallel: the normal is the start's offset
                u = d1 / np.sqrt(d1[0] ** 2 + d1[1] ** 2 + d1[2] ** 2)
                n = gap0 - (gap0[0] * u[0] + gap0[1] * u[1] + gap0[2] * u[2]) * u
                size = np.sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2])
                if size == 0.0:
                    continue
            n /= size
            dist0 = gap0[0] * n[0] + gap0[1] * n[1] + gap0[2] * n[2]
            side = 1.0 if dist0 >= 0.0 else -1.0
            vrel = (1.0 - s) * vel[a] + s * vel[b] - (1.0 - t) * vel[c] - t * vel[d]
            vn = vrel[0] * n[0] + vrel[1] * n[1] + vrel[2] * n[2]
            j = ((side * margin - dist0) / dt - vn) / w
            ke0, ke1 = 0.0, 0.0
            for i, f in ((a, 1.0 - s), (b, s), (c, -(1.0 - t)), (d, -t)):
                if inv_mass[i] == 0.0:
                    continue
                ke0 += 0.5 * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2) / inv_mass[i]
                for k in range(3):
                    dv = f * j * inv_mass[i] * n[k]
                    vel[i, k] += dv
                    pos1[i, k] += dt * dv  # (not x_n + dt v: a node the hub placed or let go)
                ke1 += 0.5 * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2) / inv_mass[i]
                now[i] = True
            taken += ke0 - ke1
            impulses += 1
        moved = now
        if cert is not None and first == 0:  # (a pass after a reaction: contact_resolve's)
            if rnd == 0:
                lap(cert.clock, C_ROUND0, t0)
                cert.tally[N_READ0] += read
                cert.tally[N_LOOK0] += looked
                cert.tally[N_EXACT0] += tested
            else:
                lap(cert.clock, C_ROUNDS, t0)
                cert.tally[N_ROUNDS] += 1
                cert.tally[N_ROUND_PAIRS] += tested
                cert.tally[N_ROUND_LOOKED] += looked
        if left == 0:
            break
    if left > 0:  # the rounds ran out: the pairs still crossing move as rigid zones
        if cert is not None:
            t0 = cycles()
        _, left = impact_zones(pairs, elem_nodes, pos0, pos1, vel, inv_mass, dt,
                               rounds[1], hub, moved, adj, follow)
        if cert is not None and first == 0:
            lap(cert.clock, C_ZONES, t0)
            cert.tally[N_ZONES] += 1
    return taken, impulses, left
