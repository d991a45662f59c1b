"""Impact zones: the contact's last resort in a step whose crossings the fail-safe's pair
impulses (fe.contact.penalty.resolve_crossings) did not remove within their rounds.

In a column of stacked layers an impulse that parts one pair drives one of its elements
into the next layer, and the rounds run out with crossings left (the study of
docs/contact.md: every crossing the contact left in its runs came from such steps). After
Provot's and Harmon, Vouga, Tamstorf and Grinspun's "robust treatment of simultaneous
collisions", the free nodes of the pairs still crossing are gathered into zones (a pair
joins the zones of its four nodes), and each zone moves over the step as a rigid body:
every node gets v = V + w x (y - X), with the zone's mass M, centre of mass X, momentum
M V, angular momentum L about X and inertia tensor I about X (w = I^+ L, the
pseudo-inverse: a zone on a straight line has no moment about it and no angular momentum
along it), y = x_{n+1} - dt v_{n+1/2} (x_n for a node that moved freely). So a zone keeps
its linear and angular momentum (to round-off; the hub's reaction and the energy booking
of fe.contact.impulses see the velocities' change as any impulse's), and its nodes move by one
affine map x_n -> x_n + tau dt (V + w x (x_n - X)), invertible for every tau in [0, 1]:
two elements of one zone that did not touch at x_n cannot pass through each other during
the step. Elements of a zone can still meet elements outside it; those pairs are tested
again, and zones grow (merge) until no pair crosses or the rounds run out. A zone with a
node held on or tied to the hub (inverse mass 0) moves with the hub: its free nodes take
the hub's motion over the step, x_{n+1} = A y + c (``hub``: A, c from the hub's pose at
the two ends of the step, :func:`axis_map`, :func:`body_map`), the map that carried the
hub's own nodes; the momentum they gain or lose is the hub's reaction (fe.contact.impulses). Without
the map (a call outside a run) such a zone stays as it is, and its crossings are counted.
Such a zone's free nodes stay stuck to the hub for the rest of the step (``follow``): the
hub's reaction to the step's impulses moves them with it (fe.contact.impulses.body_reaction,
axis_reaction: the inelastic impact of the nodes on the hub, momenta kept), so that a node
carried along touching a hub element is not left behind on its far side when the hub places
its nodes again.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.fe.contact.crossing import moved_crosses
from spinweb_fe.fe.hub.rigid import hub_centre, jacobi3, rotation

#: passes of zone building at most per step
ZONE_ROUNDS = 20


class Adjacency(NamedTuple):
    """For each node the listed pairs with an element that has it (``idx[ptr[i]:ptr[i +
    1]]``, by a counting sort), filled when first needed (``ready``); ``stamp`` (P,) and
    ``clock`` (1,): the marks :func:`pairs_of` sets, each call a new one."""

    ptr: np.ndarray
    idx: np.ndarray
    stamp: np.ndarray
    clock: np.ndarray
    ready: np.ndarray


@njit(cache=True)
def no_adjacency(n_nodes, n_pairs):
    """An :class:`Adjacency` for ``n_nodes`` nodes and ``n_pairs`` pairs, not filled yet."""
    return Adjacency(np.zeros(n_nodes + 1, np.int64), np.empty(4 * n_pairs, np.int64),
                     np.full(n_pairs, -1, np.int64), np.zeros(1, np.int64),
                     np.zeros(1, np.bool_))


@njit(cache=True)
def ensure_adjacency(adj, pairs, elem_nodes):
    """Fill ``adj`` for ``pairs`` if it is not yet (a list's adjacency is built once, when a
    pass after the first needs it: stacked columns list 1e5-1e6 pairs)."""
    if adj.ready[0]:
        return
    n = adj.ptr.shape[0] - 1
    ptr = adj.ptr
    ptr[:] = 0
    for p in range(pairs.shape[0]):
        for side in range(2):
            e = pairs[p, side]
            ptr[elem_nodes[e, 0] + 1] += 1
            ptr[elem_nodes[e, 1] + 1] += 1
    for i in range(n):
        ptr[i + 1] += ptr[i]
    fill = ptr[:-1].copy()
    for p in range(pairs.shape[0]):
        for side in range(2):
            e = pairs[p, side]
            for i in (elem_nodes[e, 0], elem_nodes[e, 1]):
                adj.idx[fill[i]] = p
                fill[i] += 1
    adj.ready[0] = True


@njit(cache=True)
def pair_adjacency(pairs, elem_nodes, n):
    """The :class:`Adjacency` of ``pairs`` for ``n`` nodes, filled. Later passes of the
    fail-safe and of the zones test only the pairs of the nodes the last pass moved, not the
    whole list (a pass over all of a stacked web's pairs costs milliseconds)."""
    adj = no_adjacency(n, pairs.shape[0])
    ensure_adjacency(adj, pairs, elem_nodes)
    return adj


@njit(cache=True)
def pairs_of(adj, moved):
    """The pairs (sorted) with a node in ``moved`` (n,) bool, each once (``adj`` filled).
    The marked pairs in the list's order: a read of the stamps when they are more than a
    32nd of the list (a sequential pass, 2.7-4 ns a pair reached, where numba's sort of the
    pairs took 13-46 ns a pair for 5 000-17 000 of 30 000, the sort growing with k log k),
    else a sort of the few."""
    adj.clock[0] += 1
    tick = adj.clock[0]
    ptr, idx, stamp = adj.ptr, adj.idx, adj.stamp
    count = 0
    for i in range(moved.shape[0]):
        if moved[i]:
            count += ptr[i + 1] - ptr[i]
    out = np.empty(count, np.int64)
    k = 0
    for i in range(moved.shape[0]):
        if not moved[i]:
            continue
        for q in range(ptr[i], ptr[i + 1]):
            p = idx[q]
            if stamp[p] != tick:
                stamp[p] = tick
                out[k] = p
                k += 1
    if 32 * k < stamp.shape[0]:
        return np.sort(out[:k])
    j = 0
    for p in range(stamp.shape[0]):
        if stamp[p] == tick:
            out[j] = p
            j += 1
    return out[:k]


@njit(cache=True)
def _root(parent, i):
    """The zone of node i (union-find with path halving)."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True)
def _join(parent, a, b):
    ra, rb = _root(parent, a), _root(parent, b)
    if ra != rb:
        if ra < rb:
            parent[rb] = ra
        else:
            parent[ra] = rb


@njit(cache=True)
def rigid_zone(members, pos1, vel, inv_mass, dt):
    """The nodes ``members`` (all free) move as one rigid body over the step (module
    docstring): their v_{n+1/2} and x_{n+1} change, the zone's momentum and angular momentum
    stay."""
    M = 0.0
    X = np.zeros(3)
    P = np.zeros(3)
    y = np.empty((members.shape[0], 3))
    for k in range(members.shape[0]):
        i = members[k]
        m = 1.0 / inv_mass[i]
        M += m
        for d in range(3):
            y[k, d] = pos1[i, d] - dt * vel[i, d]
            X[d] += m * y[k, d]
            P[d] += m * vel[i, d]
    X /= M
    L = np.zeros(3)
    inertia = np.zeros((3, 3))
    for k in range(members.shape[0]):
        i = members[k]
        m = 1.0 / inv_mass[i]
        r0, r1, r2 = y[k, 0] - X[0], y[k, 1] - X[1], y[k, 2] - X[2]
        v0, v1, v2 = vel[i, 0], vel[i, 1], vel[i, 2]
        L[0] += m * (r1 * v2 - r2 * v1)
        L[1] += m * (r2 * v0 - r0 * v2)
        L[2] += m * (r0 * v1 - r1 * v0)
        rr = r0 * r0 + r1 * r1 + r2 * r2
        r = (r0, r1, r2)
        for a in range(3):
            inertia[a, a] += m * rr
            for b in range(3):
                inertia[a, b] -= m * r[a] * r[b]
    lam, axes = jacobi3(inertia)
    top = max(lam[0], max(lam[1], lam[2]))
    w = np.zeros(3)
    for k in range(3):
        if lam[k] > 1e-12 * top:
            c = (axes[0, k] * L[0] + axes[1, k] * L[1] + axes[2, k] * L[2]) / lam[k]
            for d in range(3):
                w[d] += c * axes[d, k]
    V = P / M
    for k in range(members.shape[0]):
        i = members[k]
        r0, r1, r2 = y[k, 0] - X[0], y[k, 1] - X[1], y[k, 2] - X[2]
        nv = (V[0] + w[1] * r2 - w[2] * r1, V[1] + w[2] * r0 - w[0] * r2,
              V[2] + w[0] * r1 - w[1] * r0)
        for d in range(3):
            pos1[i, d] += dt * (nv[d] - vel[i, d])
            vel[i, d] = nv[d]


@njit(cache=True)
def axis_map(dtheta):
    """(4, 3): the turn by ``dtheta`` [rad] about the fixed z axis as x -> A x + c (rows
    0-2: A, row 3: c = 0)."""
    out = np.zeros((4, 3))
    c, s = np.cos(dtheta), np.sin(dtheta)
    out[0, 0], out[0, 1], out[1, 0], out[1, 1], out[2, 2] = c, -s, s, c, 1.0
    return out


@njit(cache=True)
def body_map(rs, centre0, q0):
    """(4, 3): a free hub's motion since its hub centre was ``centre0`` [m] and its attitude
    ``q0`` (fe.contact.impulses.body_snapshot) to its pose now, x -> A x + c with A = R R0^T, c =
    C - A C0. (No None case: a branch returning None would type the map Optional, and every
    callee of the free hub's fail-safe would compile a second time for it.)"""
    R = rotation(rs.quaternion)
    R0 = rotation(q0)
    out = np.zeros((4, 3))
    for a in range(3):
        for b in range(3):
            out[a, b] = R[a, 0] * R0[b, 0] + R[a, 1] * R0[b, 1] + R[a, 2] * R0[b, 2]
    C = hub_centre(rs, R)
    for a in range(3):
        out[3, a] = C[a] - (out[a, 0] * centre0[0] + out[a, 1] * centre0[1]
                            + out[a, 2] * centre0[2])
    return out


@njit(cache=True)
def hub_zone(members, pos1, vel, inv_mass, dt, hub, follow):
    """The free nodes of ``members`` move with the hub over the step: x_{n+1} = A y + c
    (``hub``, module docstring), v_{n+1/2} = (x_{n+1} - y) / dt; they are marked in
    ``follow`` (n,) bool."""
    for i in members:
        if inv_mass[i] == 0.0:
            continue
        follow[i] = True
        y0, y1, y2 = pos1[i, 0] - dt * vel[i, 0], pos1[i, 1] - dt * vel[i, 1], \
            pos1[i, 2] - dt * vel[i, 2]
        for d in range(3):
            x = hub[d, 0] * y0 + hub[d, 1] * y1 + hub[d, 2] * y2 + hub[3, d]
            vel[i, d] = (x - (y0, y1, y2)[d]) / dt
            pos1[i, d] = x


@njit(cache=True)
def impact_zones(pairs, elem_nodes, pos0, pos1, vel, inv_mass, dt, rounds=ZONE_ROUNDS,
                 hub=None, moved=None, adj=None, follow=None):
    """Zones of the pairs still crossing over the step from ``pos0`` to ``pos1`` (module
    docstring), moved rigidly, grown until no listed pair crosses (at most ``rounds``
    passes; ``hub`` (4, 3): the hub's map over the step for the zones with a node of the
    hub, None: those stay; ``moved`` (n,) bool: the nodes whose pairs may cross, those the
    fail-safe's last pass moved, None: all; ``adj``: :func:`pair_adjacency`'s, None: built
    here; ``follow`` (n,) bool: the free nodes of zones moved with the hub get marked).
    Returns (zones moved in the last pass that moved any, crossings left: those of
    the last test)."""
    n = pos0.shape[0]
    parent = np.arange(n)
    zoned = np.zeros(n, np.bool_)
    if moved is None:
        moved = np.ones(n, np.bool_)
    if adj is None:
        adj = pair_adjacency(pairs, elem_nodes, n)
    ensure_adjacency(adj, pairs, elem_nodes)
    if follow is None:
        follow = np.zeros(n, np.bool_)
    times = np.empty(3)
    signs = np.empty(3, np.int64)
    scratch, cuts = np.empty((4, 3)), np.empty(4)
    left, zones = 0, 0
    for rnd in range(rounds + 1):
        left = 0
        for p in pairs_of(adj, moved):
            e, g = pairs[p, 0], pairs[p, 1]
            a, b = elem_nodes[e, 0], elem_nodes[e, 1]
            c, d = elem_nodes[g, 0], elem_nodes[g, 1]
            if not moved_crosses(pos0, pos1, moved, a, b, c, d, times, signs, scratch, cuts):
                continue
            left += 1
            for i in (a, b, c, d):
                zoned[i] = True
            _join(parent, a, b)
            _join(parent, a, c)
            _join(parent, a, d)
        if left == 0 or rnd == rounds:
            break
        # the zones' members, grouped by root; a zone with a node that is not free stays
        members = np.nonzero(zoned)[0]
        roots = np.empty(members.shape[0], np.int64)
        for k in range(members.shape[0]):
            roots[k] = _root(parent, members[k])
        order = np.argsort(roots, kind="mergesort")
        members, roots = members[order], roots[order]
        moved[:] = False
        zones = 0
        start = 0
        while start < members.shape[0]:
            stop = start
            free = True
            while stop < members.shape[0] and roots[stop] == roots[start]:
                free = free and inv_mass[members[stop]] > 0.0
                stop += 1
            group = members[start:stop]
            done = free
            if free:
                rigid_zone(group, pos1, vel, inv_mass, dt)
            elif hub is not None:  # pruned by numba when None
                hub_zone(group, pos1, vel, inv_mass, dt, hub, follow)
                done = True
            if done:
                for i in group:
                    moved[i] = True
                zones += 1
            start = stop
        if zones == 0:
            break
    return zones, left
