"""The broad phase of the crossing test and the cable contact: which element pairs can meet.

Every element's box, widened by ``skin`` on each side, goes into a uniform hash grid (cells
of the longest element plus twice the skin, sorted by cell: O(n log n)); the pairs of
elements without a common node whose widened boxes overlap are the candidates
(:func:`candidate_pairs`). A pair left out was more than twice the skin apart, so the list
holds every pair that can meet while no node has moved more than the skin from where it was
at the build (two elements then close by at most twice the skin). Each step, the boxes the
elements swept (:func:`swept_boxes`) rule out most listed pairs before the exact test
(fe.contact.crossing).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: grid cells per axis of the hash grid's keys (2^21: three fit an int64)
GRID_SPAN = 2097152


#: ``active`` of the broad phase: an element that moves with the hub (held, tied)
RIGID = 2


@njit(inline="always")
def _cell_span(lo, hi, e, cell, origin):
    """The grid cells box e (rows of ``lo``, ``hi``) touches: (i0, j0, k0, i1, j1, k1),
    first and last index per axis, of the uniform grid of size ``cell`` from ``origin``."""
    return (np.int64((lo[e, 0] - origin[0]) / cell), np.int64((lo[e, 1] - origin[1]) / cell),
            np.int64((lo[e, 2] - origin[2]) / cell), np.int64((hi[e, 0] - origin[0]) / cell),
            np.int64((hi[e, 1] - origin[1]) / cell), np.int64((hi[e, 2] - origin[2]) / cell))


@njit(cache=True)
def grid_entries(lo, hi, active, cell, origin, count, rigid=False):
    """(keys, owners, n): every ``active`` box (rows of ``lo``, ``hi``; with ``rigid``, only
    those marked :data:`RIGID`, else only the others) in each cell of the uniform grid of
    size ``cell`` from ``origin`` that it touches, as n (cell key, box) entries (``count``:
    room for at least that many)."""
    big = np.int64(GRID_SPAN)
    keys = np.empty(count, np.int64)
    owners = np.empty(count, np.int64)
    n_ent = 0
    for e in range(lo.shape[0]):
        if not active[e] or (active[e] == RIGID) != rigid:
            continue
        i0, j0, k0, i1, j1, k1 = _cell_span(lo, hi, e, cell, origin)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                for k in range(k0, k1 + 1):
                    keys[n_ent] = (i * big + j) * big + k
                    owners[n_ent] = e
                    n_ent += 1
    return keys, owners, n_ent


@njit(cache=True)
def _cell_partners(e, lo, hi, elem_nodes, skeys, sowners, cell, origin, seen, row, n_row):
    """Element e's partners of higher index (boxes overlapping, no common node, each once:
    ``seen``) among the grid's entries (``skeys`` sorted, ``sowners``) of the cells e's box
    touches, appended to ``row`` from ``n_row``; returns the new count."""
    big = np.int64(GRID_SPAN)
    n_ent = skeys.shape[0]
    ea, eb = elem_nodes[e, 0], elem_nodes[e, 1]
    i0, j0, k0, i1, j1, k1 = _cell_span(lo, hi, e, cell, origin)
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            for k in range(k0, k1 + 1):
                key = (i * big + j) * big + k
                q = np.searchsorted(skeys, key)
                while q < n_ent and skeys[q] == key:
                    f = sowners[q]
                    q += 1
                    if f <= e or seen[f] == e:
                        continue
                    seen[f] = e
                    fa, fb = elem_nodes[f, 0], elem_nodes[f, 1]
                    if ea == fa or ea == fb or eb == fa or eb == fb:
                        continue
                    if (lo[e, 0] > hi[f, 0] or lo[f, 0] > hi[e, 0] or lo[e, 1] > hi[f, 1]
                            or lo[f, 1] > hi[e, 1] or lo[e, 2] > hi[f, 2]
                            or lo[f, 2] > hi[e, 2]):
                        continue
                    row[n_row] = f
                    n_row += 1
    return n_row


@njit(cache=True)
def candidate_pairs(pos, elem_nodes, active, skin):
    """(P, 2) int64 element pairs (e < f, no common node, both ``active``, not both
    :data:`RIGID`) whose boxes, widened by ``skin`` [m], overlap: the broad phase, through
    a uniform hash grid. Elements that move with the hub go into a grid of their own, which
    only the others search: two of them cannot cross while held, and a dense held coil
    would otherwise cost the broad phase its own pairs (on the paper's coiled web most of
    the rebuild's time)."""
    m = elem_nodes.shape[0]
    lo = np.empty((m, 3))
    hi = np.empty((m, 3))
    longest = 0.0
    for e in range(m):
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        for k in range(3):
            lo[e, k] = min(pos[a, k], pos[b, k]) - skin
            hi[e, k] = max(pos[a, k], pos[b, k]) + skin
            longest = max(longest, hi[e, k] - lo[e, k])
    cell = max(longest, 1e-9)
    origin = np.empty(3)
    for k in range(3):
        origin[k] = np.inf
    for e in range(m):
        for k in range(3):
            origin[k] = min(origin[k], lo[e, k])
    # every element into each cell its box touches (at most 2 per axis: the cell is at
    # least the box's size), as (cell key, element) entries sorted by key: the free
    # elements' grid and the rigid ones'
    keys, owners, n_ent = grid_entries(lo, hi, active, cell, origin, 8 * m)
    order = np.argsort(keys[:n_ent])
    free_keys, free_owners = keys[order], owners[order]
    keys, owners, n_ent = grid_entries(lo, hi, active, cell, origin, 8 * m, True)
    order = np.argsort(keys[:n_ent])
    rigid_keys, rigid_owners = keys[order], owners[order]
    # then each element's partners of higher index from the cells it touches, in
    # ascending order: the list comes out sorted by code e * m + f
    seen = np.full(m, -1, np.int64)
    row = np.empty(m, np.int64)
    out = np.empty((max(16, 8 * m), 2), np.int64)
    n_out = 0
    for e in range(m):
        if not active[e]:
            continue
        n_row = _cell_partners(e, lo, hi, elem_nodes, free_keys, free_owners, cell, origin,
                               seen, row, 0)
        if active[e] != RIGID:
            n_row = _cell_partners(e, lo, hi, elem_nodes, rigid_keys, rigid_owners, cell,
                                   origin, seen, row, n_row)
        if n_out + n_row > out.shape[0]:
            grown = np.empty((2 * (n_out + n_row), 2), np.int64)
            grown[:n_out] = out[:n_out]
            out = grown
        part = np.sort(row[:n_row])
        for r in range(n_row):
            out[n_out, 0] = e
            out[n_out, 1] = part[r]
            n_out += 1
    return out[:n_out].copy()


@njit(cache=True)
def swept_boxes(elem_nodes, active, pos0, pos1, box):
    """Into row e of ``box`` (m, 6) the box [lo x y z, hi x y z] [m] that ``active``
    element e sweeps while its nodes move from ``pos0`` to ``pos1`` (other rows stay)."""
    for e in range(elem_nodes.shape[0]):
        if not active[e]:
            continue
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        for k in range(3):
            box[e, k] = min(min(pos0[a, k], pos1[a, k]), min(pos0[b, k], pos1[b, k]))
            box[e, 3 + k] = max(max(pos0[a, k], pos1[a, k]), max(pos0[b, k], pos1[b, k]))


@njit(inline="always")
def boxes_apart(box, e, f, gap):
    """True when the boxes of elements e and f (rows of ``box``) are more than ``gap`` [m]
    apart along an axis (the hub's axis first: stacked layers part along it)."""
    return (box[e, 2] - gap > box[f, 5] or box[f, 2] - gap > box[e, 5]
            or box[e, 0] - gap > box[f, 3] or box[f, 0] - gap > box[e, 3]
            or box[e, 1] - gap > box[f, 4] or box[f, 1] - gap > box[e, 4])


@njit(cache=True)
def sorted_in(a, b):
    """(len(a),) bool: which entries of the ascending ``a`` occur in the ascending ``b``
    (a merge: O(len(a) + len(b)))."""
    out = np.zeros(a.shape[0], np.bool_)
    j = 0
    for i in range(a.shape[0]):
        while j < b.shape[0] and b[j] < a[i]:
            j += 1
        out[i] = j < b.shape[0] and b[j] == a[i]
    return out


@njit(cache=True)
def moved_since(ref, pos, c, s):
    """The largest distance [m] a node has moved from ``ref`` (its place at the broad
    phase's build, turned back by the hub's angle then) to ``pos`` turned back by the
    hub's angle now (c, s: its cosine and sine). Any
    rigid frame keeps distances, so the broad phase's skin bound holds in it; the hub's
    frame makes the spin's motion free."""
    worst = 0.0
    for i in range(pos.shape[0]):
        x = c * pos[i, 0] + s * pos[i, 1]
        y = -s * pos[i, 0] + c * pos[i, 1]
        dx, dy, dz = x - ref[i, 0], y - ref[i, 1], pos[i, 2] - ref[i, 2]
        worst = max(worst, dx * dx + dy * dy + dz * dz)
    return np.sqrt(worst)
