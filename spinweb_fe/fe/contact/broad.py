"""The broad phase of the crossing test and the cable contact: which element pairs can meet.

Every element's box, widened by ``skin`` on each side, goes into a uniform hash grid (cells
of the longest element plus twice the skin, sorted by cell: O(n log n)); the pairs of
elements without a common node whose widened boxes overlap are the candidates
(:func:`candidate_pairs`; each pair is taken in one cell, the one of the larger of its
boxes' low corners, and each element's partners come out in order by merging a run per
cell). A pair left out was more than twice the skin apart, so the list
holds every pair that can meet while no node has moved more than the skin from where it was
at the build (two elements then close by at most twice the skin). :func:`sift_pairs` then
leaves out the pairs that enter the list touching. Each step, the boxes the
elements swept (:func:`swept_boxes`) rule out most listed pairs before the exact test
(fe.contact.crossing).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.contact.distance import closest_nodes

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
def _cells(lo, hi, cell, origin):
    """(m, 6) int64: the first and last index per axis (i0, j0, k0, i1, j1, k1) of the grid
    cells box e (rows of ``lo``, ``hi``) touches."""
    span = np.empty((lo.shape[0], 6), np.int64)
    for e in range(lo.shape[0]):
        span[e, 0], span[e, 1], span[e, 2], span[e, 3], span[e, 4], span[e, 5] = \
            _cell_span(lo, hi, e, cell, origin)
    return span


@njit(cache=True)
def _grid(lo, hi, span, active, cell, origin, rigid):
    """The grid of the ``active`` boxes (with ``rigid`` those marked :data:`RIGID`, else the
    others) over their cells ``span`` (:func:`_cells`): (keys, start, owners), the occupied
    cells' keys ascending, cell u's boxes owners[start[u]:start[u + 1]], ascending within a
    cell (a stable sort of :func:`grid_entries`, made in the boxes' order)."""
    n = 0
    for e in range(span.shape[0]):
        if active[e] and (active[e] == RIGID) == rigid:
            n += ((span[e, 3] - span[e, 0] + 1) * (span[e, 4] - span[e, 1] + 1)
                  * (span[e, 5] - span[e, 2] + 1))
    keys, owners, _ = grid_entries(lo, hi, active, cell, origin, n, rigid)
    order = np.argsort(keys, kind="mergesort")
    keys, owners = keys[order], owners[order]
    cells = 0
    for q in range(n):
        cells += q == 0 or keys[q] != keys[q - 1]
    cell_keys = np.empty(cells, np.int64)
    start = np.empty(cells + 1, np.int64)
    u = 0
    for q in range(n):
        if q == 0 or keys[q] != keys[q - 1]:
            cell_keys[u] = keys[q]
            start[u] = q
            u += 1
    start[cells] = n
    return cell_keys, start, owners


@njit(cache=True)
def _partners(e, lo, hi, span, elem_nodes, grid, row, n_row, runs, n_runs):
    """Element e's partners of higher index in ``grid`` (:func:`_grid`): boxes overlapping,
    no common node, each found once, in the pair's own cell (the one holding the larger of
    the two boxes' low corners, which both boxes touch when they overlap). Appended to
    ``row`` from ``n_row``, one ascending run per cell, each run's start to ``runs`` from
    ``n_runs``; returns the new (n_row, n_runs)."""
    cell_keys, start, owners = grid
    big = np.int64(GRID_SPAN)
    ea, eb = elem_nodes[e, 0], elem_nodes[e, 1]
    for i in range(span[e, 0], span[e, 3] + 1):
        for j in range(span[e, 1], span[e, 4] + 1):
            for k in range(span[e, 2], span[e, 5] + 1):
                key = (i * big + j) * big + k
                u = np.searchsorted(cell_keys, key)
                if u == cell_keys.shape[0] or cell_keys[u] != key:
                    continue
                q, q1 = start[u], start[u + 1]
                while q < q1:  # the cell's first box above e (its boxes ascend)
                    mid = (q + q1) >> 1
                    if owners[mid] <= e:
                        q = mid + 1
                    else:
                        q1 = mid
                runs[n_runs] = n_row
                n_runs += 1
                for q in range(q, start[u + 1]):
                    f = owners[q]
                    if (max(span[e, 0], span[f, 0]) != i or max(span[e, 1], span[f, 1]) != j
                            or max(span[e, 2], span[f, 2]) != k):
                        continue  # the pair's own cell is another
                    fa, fb = elem_nodes[f, 0], elem_nodes[f, 1]
                    if ea == fa or ea == fb or eb == fa or eb == fb:
                        continue
                    if (lo[e, 0] > hi[f, 0] or lo[f, 0] > hi[e, 0] or lo[e, 1] > hi[f, 1]
                            or lo[f, 1] > hi[e, 1] or lo[e, 2] > hi[f, 2]
                            or lo[f, 2] > hi[e, 2]):
                        continue
                    row[n_row] = f
                    n_row += 1
    return n_row, n_runs


@njit(cache=True)
def candidate_pairs(pos, elem_nodes, active, skin):
    """(P, 2) int64 element pairs (e < f, no common node, both ``active``, not both
    :data:`RIGID`) whose boxes, widened by ``skin`` [m], overlap: the broad phase, through
    a uniform hash grid. Elements that move with the hub go into a grid of their own, which
    only the others search: two of them cannot cross while held, and a dense held coil
    would otherwise cost the broad phase its own pairs (on the paper's coiled web most of
    the rebuild's time). The list comes out sorted by code e * m + f."""
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
    # the cells each box touches (at most 2 per axis: the cell is at least the box's size,
    # 3 where the division rounds up), the free elements' grid and the rigid ones'
    # (typed flags and counts: a literal would compile a callee once per value)
    span = _cells(lo, hi, cell, origin)
    free = _grid(lo, hi, span, active, cell, origin, np.bool_(False))
    rigid = _grid(lo, hi, span, active, cell, origin, np.bool_(True))
    zero = np.int64(0)
    # each element's partners of higher index, a run per cell, merged into ascending order:
    # the list comes out sorted by code e * m + f
    row = np.empty(m, np.int64)
    runs = np.empty(2 * 27 + 1, np.int64)
    head = np.empty(2 * 27, np.int64)
    out = np.empty((max(16, 8 * m), 2), np.int64)
    n_out = 0
    for e in range(m):
        if not active[e]:
            continue
        n_row, n_runs = _partners(e, lo, hi, span, elem_nodes, free, row, zero, runs, zero)
        if active[e] != RIGID:
            n_row, n_runs = _partners(e, lo, hi, span, elem_nodes, rigid, row, n_row, runs,
                                      n_runs)
        if n_out + n_row > out.shape[0]:
            grown = np.empty((2 * (n_out + n_row), 2), np.int64)
            grown[:n_out] = out[:n_out]
            out = grown
        runs[n_runs] = n_row
        for r in range(n_runs):
            head[r] = runs[r]
        for _ in range(n_row):  # the least head of the runs, n_row times
            best, low = -1, np.int64(0)
            for r in range(n_runs):
                if head[r] < runs[r + 1] and (best < 0 or row[head[r]] < low):
                    best, low = r, row[head[r]]
            head[best] += 1
            out[n_out, 0] = e
            out[n_out, 1] = low
            n_out += 1
    return out[:n_out].copy()


@njit(cache=True)
def sift_pairs(pairs, elem_nodes, pos, old_codes, fresh, ignored, keep, touch):
    """The broad phase's list (``pairs``, sorted by code e * m + f) sifted for the audit and
    the contact: a pair that enters the list (its code not in the ascending ``old_codes``,
    every pair when ``fresh``) closer than ``touch`` [m] at ``pos`` is left out, and a pair
    left out before (its code in the ascending ``ignored``) stays out while it is within
    ``keep`` [m]. Returns (codes of every pair, the pairs kept, their codes, their
    distances [m] at ``pos``, the codes left out): one pass, with two merges."""
    n = pairs.shape[0]
    m = np.int64(elem_nodes.shape[0])
    codes = np.empty(n, np.int64)
    dist = np.empty(n)
    out = np.empty(n, np.bool_)
    i_old = i_ign = 0
    left = 0
    for p in range(n):
        e, f = pairs[p, 0], pairs[p, 1]
        code = e * m + f
        codes[p] = code
        dist[p] = closest_nodes(pos, elem_nodes[e, 0], elem_nodes[e, 1], elem_nodes[f, 0],
                                elem_nodes[f, 1])[2]
        while i_old < old_codes.shape[0] and old_codes[i_old] < code:
            i_old += 1
        entering = fresh or not (i_old < old_codes.shape[0] and old_codes[i_old] == code)
        while i_ign < ignored.shape[0] and ignored[i_ign] < code:
            i_ign += 1
        was_out = i_ign < ignored.shape[0] and ignored[i_ign] == code
        out[p] = (was_out and dist[p] <= keep) or (entering and dist[p] <= touch)
        left += out[p]
    kept = np.empty((n - left, 2), np.int64)
    kept_codes = np.empty(n - left, np.int64)
    kept_dist = np.empty(n - left)
    left_out = np.empty(left, np.int64)
    j = k = 0
    for p in range(n):
        if out[p]:
            left_out[k] = codes[p]
            k += 1
        else:
            kept[j, 0], kept[j, 1] = pairs[p, 0], pairs[p, 1]
            kept_codes[j], kept_dist[j] = codes[p], dist[p]
            j += 1
    return codes, kept, kept_codes, kept_dist, left_out


@njit(cache=True)
def carried(codes, fresh, old_codes, old):
    """(len(codes),) float: for each of the ascending ``codes``, its value in ``old`` (by
    the ascending ``old_codes``) where it was listed, else its value in ``fresh`` (a merge:
    a new list keeps what the pairs it shares with the one before had)."""
    out = fresh.copy()
    j = 0
    for i in range(codes.shape[0]):
        while j < old_codes.shape[0] and old_codes[j] < codes[i]:
            j += 1
        if j < old_codes.shape[0] and old_codes[j] == codes[i]:
            out[i] = old[j]
    return out


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
