"""Crossings of cable elements (issue #26): a broad phase that lists the element pairs
that can meet within a skin, and a continuous narrow phase that finds every time two
straight elements pass through each other during a step.

Narrow phase. Over a step each node moves on a straight line (x(t) = x_n + t (x_{n+1} -
x_n), t in [0, 1]), so the signed volume V(t) = (B - A) . ((C - A) x (D - A)) of two
elements AB and CD is a cubic in t. Two segments can only pass through each other where
the four points are coplanar, V = 0; they do where, in addition, the two lines meet inside
both segments. The step is cut at the roots of V' (where V turns) into pieces on which V is
monotone; a piece whose ends have V of different signs (V >= 0 counting as positive, the
same in every step, so that a root on a step boundary is counted in exactly one step)
holds one root, found by bisection to round-off, and the lines' closest points there
decide. The direction of a crossing is the sign of V after it. Nothing depends on the
speed: a crossing at any speed within the step is found (the tests go to 200 m/s).

Broad phase. Every element's box, widened by ``skin`` on each side, goes into a uniform
hash grid (cells of the longest element plus twice the skin, sorted by cell: O(n log n));
the pairs of elements without a common node whose widened boxes overlap are the
candidates. A pair left out was more than twice the skin apart, so the list holds every
pair that can meet while no node has moved more than the skin from where it was at the
build (two elements then close by at most twice the skin).
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: bisection steps of a root of V in a monotone piece of the step (2^-60: round-off)
ROOT_ITERATIONS = 60


@njit(inline="always")
def _volume(a, b, c, d):
    """(b - a) . ((c - a) x (d - a)) of four (3,) points."""
    u0, u1, u2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    v0, v1, v2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    w0, w1, w2 = d[0] - a[0], d[1] - a[1], d[2] - a[2]
    return u0 * (v1 * w2 - v2 * w1) + u1 * (v2 * w0 - v0 * w2) + u2 * (v0 * w1 - v1 * w0)


@njit(inline="always")
def _at(p0, p1, t, out):
    for k in range(3):
        out[k] = p0[k] + t * (p1[k] - p0[k])


@njit(cache=True)
def _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, t, w):
    _at(a0, a1, t, w[0])
    _at(b0, b1, t, w[1])
    _at(c0, c1, t, w[2])
    _at(d0, d1, t, w[3])
    return _volume(w[0], w[1], w[2], w[3])


@njit(cache=True)
def _lines_meet(w):
    """The lines of segments w[0] w[1] and w[2] w[3] (coplanar) meet inside both: the
    parameters of their closest points in [0, 1) x [0, 1) (half-open: a crossing exactly
    through a shared end is counted by one of the two elements). Parallel lines: no."""
    d10, d11, d12 = w[1, 0] - w[0, 0], w[1, 1] - w[0, 1], w[1, 2] - w[0, 2]
    d20, d21, d22 = w[3, 0] - w[2, 0], w[3, 1] - w[2, 1], w[3, 2] - w[2, 2]
    r0, r1, r2 = w[0, 0] - w[2, 0], w[0, 1] - w[2, 1], w[0, 2] - w[2, 2]
    a = d10 * d10 + d11 * d11 + d12 * d12
    b = d10 * d20 + d11 * d21 + d12 * d22
    c = d20 * d20 + d21 * d21 + d22 * d22
    d = d10 * r0 + d11 * r1 + d12 * r2
    e = d20 * r0 + d21 * r1 + d22 * r2
    den = a * c - b * b
    if den <= 1e-14 * a * c:
        return False
    s = (b * e - c * d) / den
    u = (a * e - b * d) / den
    return 0.0 <= s < 1.0 and 0.0 <= u < 1.0


@njit(cache=True)
def pair_crossings(a0, a1, b0, b1, c0, c1, d0, d1, times, signs, w=None, cuts=None):
    """Crossings of element AB (ends a, b) and CD during a step: each point from its
    position at the step's start (``*0``) to its end (``*1``). Writes the step fractions
    t in (0, 1] of up to 3 crossings into ``times`` and the sign of V after each into
    ``signs``; returns how many. ``w`` (4, 3) and ``cuts`` (4,): scratch, if given (a
    loop over pairs makes them once)."""
    if w is None:
        w = np.empty((4, 3))
    if cuts is None:
        cuts = np.empty(4)
    # V(t) = k0 + k1 t + k2 t^2 + k3 t^3 from four samples (exact for a cubic)
    v0 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 0.0, w)
    v1 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 1.0 / 3.0, w)
    v2 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 2.0 / 3.0, w)
    v3 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 1.0, w)
    k1 = -5.5 * v0 + 9.0 * v1 - 4.5 * v2 + v3
    k2 = 9.0 * v0 - 22.5 * v1 + 18.0 * v2 - 4.5 * v3
    k3 = -4.5 * v0 + 13.5 * v1 - 13.5 * v2 + 4.5 * v3
    # the pieces: [0, 1] cut at the roots of V' = k1 + 2 k2 t + 3 k3 t^2 inside it
    n_cut = 0
    cuts[n_cut] = 0.0
    n_cut += 1
    qa, qb, qc = 3.0 * k3, 2.0 * k2, k1
    scale = abs(qa) + abs(qb) + abs(qc)
    if scale > 0.0:
        if abs(qa) <= 1e-14 * scale:
            if qb != 0.0:
                r = -qc / qb
                if 0.0 < r < 1.0:
                    cuts[n_cut] = r
                    n_cut += 1
        else:
            disc = qb * qb - 4.0 * qa * qc
            if disc > 0.0:
                sq = np.sqrt(disc)
                q = -0.5 * (qb + (sq if qb >= 0.0 else -sq))
                r1 = q / qa
                r2 = qc / q if q != 0.0 else r1
                lo, hi = min(r1, r2), max(r1, r2)
                if 0.0 < lo < 1.0:
                    cuts[n_cut] = lo
                    n_cut += 1
                if 0.0 < hi < 1.0 and hi != lo:
                    cuts[n_cut] = hi
                    n_cut += 1
    cuts[n_cut] = 1.0
    n_cut += 1
    found = 0
    ta = cuts[0]
    va = v0
    for i in range(1, n_cut):
        tb = cuts[i]
        vb = v3 if i == n_cut - 1 else _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, tb, w)
        if (va >= 0.0) != (vb >= 0.0):
            lo, hi, vlo = ta, tb, va
            for _ in range(ROOT_ITERATIONS):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                vm = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, mid, w)
                if (vm >= 0.0) == (vlo >= 0.0):
                    lo, vlo = mid, vm
                else:
                    hi = mid
            _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, hi, w)
            if _lines_meet(w):
                times[found] = hi
                signs[found] = 1 if vb >= 0.0 else -1
                found += 1
        ta, va = tb, vb
    return found


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
def boxed_crossings(pairs, elem_nodes, pos0, pos1, box, out_t, out_e, out_f, out_s):
    """:func:`step_crossings` with the elements' swept boxes given (``box``: rows of
    :func:`swept_boxes` for every element of ``pairs``)."""
    times = np.empty(3)
    signs = np.empty(3, np.int64)
    w, cuts = np.empty((4, 3)), np.empty(4)
    n = 0
    for p in range(pairs.shape[0]):
        e, f = pairs[p, 0], pairs[p, 1]
        if boxes_apart(box, e, f, 0.0):
            continue
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        c, d = elem_nodes[f, 0], elem_nodes[f, 1]
        k = pair_crossings(pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c],
                           pos0[d], pos1[d], times, signs, w, cuts)
        for i in range(k):
            if n < out_t.shape[0]:
                out_t[n] = times[i]
                out_e[n] = e
                out_f[n] = f
                out_s[n] = signs[i]
            n += 1
    return n


@njit(cache=True)
def step_crossings(pairs, elem_nodes, pos0, pos1, out_t, out_e, out_f, out_s):
    """Every crossing of the candidate ``pairs`` while the nodes move from ``pos0`` to
    ``pos1`` (one step); writes its step fraction, elements and sign into the ``out_*``
    arrays (as many as they hold) and returns the count (possibly more than they hold)."""
    box = np.empty((elem_nodes.shape[0], 6))
    swept_boxes(elem_nodes, np.ones(elem_nodes.shape[0], np.bool_), pos0, pos1, box)
    return boxed_crossings(pairs, elem_nodes, pos0, pos1, box, out_t, out_e, out_f, out_s)


@njit(inline="always")
def apart(pos0, pos1, a, b, c, d):
    """True when the boxes that elements ab and cd sweep over the step are disjoint (they
    cannot meet: the narrow phase is skipped)."""
    for k in range(3):
        lo1 = min(pos0[a, k], pos1[a, k], pos0[b, k], pos1[b, k])
        hi1 = max(pos0[a, k], pos1[a, k], pos0[b, k], pos1[b, k])
        lo2 = min(pos0[c, k], pos1[c, k], pos0[d, k], pos1[d, k])
        hi2 = max(pos0[c, k], pos1[c, k], pos0[d, k], pos1[d, k])
        if lo1 > hi2 or lo2 > hi1:
            return True
    return False


@njit(inline="always")
def _closest(p00, p01, p02, p10, p11, p12, q00, q01, q02, q10, q11, q12):
    """closest_points on the twelve coordinates (scalars: no array is made, as this runs
    for every close pair of every step)."""
    d10, d11, d12 = p10 - p00, p11 - p01, p12 - p02
    d20, d21, d22 = q10 - q00, q11 - q01, q12 - q02
    w0, w1, w2 = p00 - q00, p01 - q01, p02 - q02
    a = d10 * d10 + d11 * d11 + d12 * d12
    e = d20 * d20 + d21 * d21 + d22 * d22
    f = d20 * w0 + d21 * w1 + d22 * w2
    c = d10 * w0 + d11 * w1 + d12 * w2
    b = d10 * d20 + d11 * d21 + d12 * d22
    if a <= 0.0 or e <= 0.0:  # an element of no length (a folded web's degenerate one)
        if a <= 0.0 and e <= 0.0:
            s, t = 0.0, 0.0
        elif a <= 0.0:
            s, t = 0.0, min(max(f / e, 0.0), 1.0)
        else:
            s, t = min(max(-c / a, 0.0), 1.0), 0.0
    else:
        den = a * e - b * b
        s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 1e-14 * a * e else 0.0
        t = (b * s + f) / e
        if t < 0.0:
            t, s = 0.0, min(max(-c / a, 0.0), 1.0)
        elif t > 1.0:
            t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    x0 = w0 + s * d10 - t * d20
    x1 = w1 + s * d11 - t * d21
    x2 = w2 + s * d12 - t * d22
    return s, t, np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)


@njit(cache=True)
def closest_points(p0, p1, q0, q1):
    """(s, t, distance): the parameters of the closest points of segments p0p1 and q0q1
    (clamped to both segments; parallel segments handled) and their distance [m]."""
    return _closest(p0[0], p0[1], p0[2], p1[0], p1[1], p1[2], q0[0], q0[1], q0[2], q1[0],
                    q1[1], q1[2])


@njit(inline="always")
def closest_nodes(pos, a, b, c, d):
    """closest_points of the segments of nodes a b and c d (rows of ``pos``)."""
    return _closest(pos[a, 0], pos[a, 1], pos[a, 2], pos[b, 0], pos[b, 1], pos[b, 2],
                    pos[c, 0], pos[c, 1], pos[c, 2], pos[d, 0], pos[d, 1], pos[d, 2])


@njit(cache=True)
def segment_distance(p, q, r, s):
    """The least distance [m] between the segments pq and rs."""
    return closest_points(p, q, r, s)[2]


@njit(cache=True)
def pair_distances(pairs, elem_nodes, pos):
    """(P,) the least distance [m] of each element pair at ``pos``."""
    out = np.empty(pairs.shape[0])
    for p in range(pairs.shape[0]):
        e, f = pairs[p, 0], pairs[p, 1]
        out[p] = closest_nodes(pos, elem_nodes[e, 0], elem_nodes[e, 1], elem_nodes[f, 0],
                               elem_nodes[f, 1])[2]
    return out


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


@njit(inline="always")
def moved_crosses(pos0, pos1, moved, a, b, c, d, times, signs, scratch, cuts):
    """Whether elements ab and cd, one of whose nodes is in ``moved``, cross over the step
    from ``pos0`` to ``pos1`` (a later pass of the contact's fail-safe: the swept boxes
    first, then the exact test; ``times``, ``signs`` as :func:`pair_crossings` fills them)."""
    if not (moved[a] or moved[b] or moved[c] or moved[d]) or apart(pos0, pos1, a, b, c, d):
        return False
    return pair_crossings(pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c], pos0[d],
                          pos1[d], times, signs, scratch, cuts) > 0
