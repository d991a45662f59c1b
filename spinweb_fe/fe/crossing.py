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
candidates, valid while no node has moved more than skin / 2 from where it was at the
build (two nodes then close by at most the skin).
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
    d1 = w[1] - w[0]
    d2 = w[3] - w[2]
    r = w[0] - w[2]
    a = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
    c = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
    d = d1[0] * r[0] + d1[1] * r[1] + d1[2] * r[2]
    e = d2[0] * r[0] + d2[1] * r[1] + d2[2] * r[2]
    den = a * c - b * b
    if den <= 1e-14 * a * c:
        return False
    s = (b * e - c * d) / den
    u = (a * e - b * d) / den
    return 0.0 <= s < 1.0 and 0.0 <= u < 1.0


@njit(cache=True)
def pair_crossings(a0, a1, b0, b1, c0, c1, d0, d1, times, signs):
    """Crossings of element AB (ends a, b) and CD during a step: each point from its
    position at the step's start (``*0``) to its end (``*1``). Writes the step fractions
    t in (0, 1] of up to 3 crossings into ``times`` and the sign of V after each into
    ``signs``; returns how many."""
    w = np.empty((4, 3))
    # V(t) = k0 + k1 t + k2 t^2 + k3 t^3 from four samples (exact for a cubic)
    v0 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 0.0, w)
    v1 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 1.0 / 3.0, w)
    v2 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 2.0 / 3.0, w)
    v3 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 1.0, w)
    k1 = -5.5 * v0 + 9.0 * v1 - 4.5 * v2 + v3
    k2 = 9.0 * v0 - 22.5 * v1 + 18.0 * v2 - 4.5 * v3
    k3 = -4.5 * v0 + 13.5 * v1 - 13.5 * v2 + 4.5 * v3
    # the pieces: [0, 1] cut at the roots of V' = k1 + 2 k2 t + 3 k3 t^2 inside it
    cuts = np.empty(4)
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


@njit(cache=True)
def grid_entries(lo, hi, active, cell, origin, count):
    """(keys, owners, n): every ``active`` box (rows of ``lo``, ``hi``) in each cell of the
    uniform grid of size ``cell`` from ``origin`` that it touches, as n (cell key, box)
    entries (``count``: room for at least that many)."""
    big = np.int64(GRID_SPAN)
    keys = np.empty(count, np.int64)
    owners = np.empty(count, np.int64)
    n_ent = 0
    for e in range(lo.shape[0]):
        if not active[e]:
            continue
        i0 = np.int64((lo[e, 0] - origin[0]) / cell)
        j0 = np.int64((lo[e, 1] - origin[1]) / cell)
        k0 = np.int64((lo[e, 2] - origin[2]) / cell)
        i1 = np.int64((hi[e, 0] - origin[0]) / cell)
        j1 = np.int64((hi[e, 1] - origin[1]) / cell)
        k1 = np.int64((hi[e, 2] - origin[2]) / cell)
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                for k in range(k0, k1 + 1):
                    keys[n_ent] = (i * big + j) * big + k
                    owners[n_ent] = e
                    n_ent += 1
    return keys, owners, n_ent


@njit(cache=True)
def candidate_pairs(pos, elem_nodes, active, skin):
    """(P, 2) int64 element pairs (e < f, no common node, both ``active``) whose boxes,
    widened by ``skin`` [m], overlap: the broad phase, through a uniform hash grid."""
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
    # least the box's size), as (cell key, element) entries sorted by key
    keys, owners, n_ent = grid_entries(lo, hi, active, cell, origin, 8 * m)
    order = np.argsort(keys[:n_ent], kind="mergesort")
    out = np.empty((16, 2), np.int64)
    n_out = 0
    s = 0
    while s < n_ent:
        t = s
        key = keys[order[s]]
        while t < n_ent and keys[order[t]] == key:
            t += 1
        for p in range(s, t):
            e = owners[order[p]]
            for q in range(p + 1, t):
                f = owners[order[q]]
                if e == f:
                    continue
                ea, eb = elem_nodes[e, 0], elem_nodes[e, 1]
                fa, fb = elem_nodes[f, 0], elem_nodes[f, 1]
                if ea == fa or ea == fb or eb == fa or eb == fb:
                    continue
                if (lo[e, 0] > hi[f, 0] or lo[f, 0] > hi[e, 0] or lo[e, 1] > hi[f, 1]
                        or lo[f, 1] > hi[e, 1] or lo[e, 2] > hi[f, 2] or lo[f, 2] > hi[e, 2]):
                    continue
                if n_out == out.shape[0]:
                    grown = np.empty((2 * out.shape[0], 2), np.int64)
                    grown[:n_out] = out[:n_out]
                    out = grown
                out[n_out, 0] = min(e, f)
                out[n_out, 1] = max(e, f)
                n_out += 1
        s = t
    if n_out == 0:
        return out[:0]
    # a pair that shares several cells is listed once
    code = out[:n_out, 0] * np.int64(m) + out[:n_out, 1]
    code = np.unique(code)
    pairs = np.empty((len(code), 2), np.int64)
    for i in range(len(code)):
        pairs[i, 0] = code[i] // m
        pairs[i, 1] = code[i] % m
    return pairs


@njit(cache=True)
def step_crossings(pairs, elem_nodes, pos0, pos1, out_t, out_e, out_f, out_s):
    """Every crossing of the candidate ``pairs`` while the nodes move from ``pos0`` to
    ``pos1`` (one step); writes its step fraction, elements and sign into the ``out_*``
    arrays (as many as they hold) and returns the count (possibly more than they hold)."""
    times = np.empty(3)
    signs = np.empty(3, np.int64)
    n = 0
    for p in range(pairs.shape[0]):
        e, f = pairs[p, 0], pairs[p, 1]
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        c, d = elem_nodes[f, 0], elem_nodes[f, 1]
        if apart(pos0, pos1, a, b, c, d):
            continue
        k = pair_crossings(pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c],
                           pos0[d], pos1[d], times, signs)
        for i in range(k):
            if n < out_t.shape[0]:
                out_t[n] = times[i]
                out_e[n] = e
                out_f[n] = f
                out_s[n] = signs[i]
            n += 1
    return n


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


@njit(cache=True)
def closest_points(p0, p1, q0, q1):
    """(s, t, distance): the parameters of the closest points of segments p0p1 and q0q1
    (clamped to both segments; parallel segments handled) and their distance [m]."""
    d1 = p1 - p0
    d2 = q1 - q0
    w = p0 - q0
    a = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    e = d2[0] * d2[0] + d2[1] * d2[1] + d2[2] * d2[2]
    f = d2[0] * w[0] + d2[1] * w[1] + d2[2] * w[2]
    c = d1[0] * w[0] + d1[1] * w[1] + d1[2] * w[2]
    b = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
    den = a * e - b * b
    s = min(max((b * f - c * e) / den, 0.0), 1.0) if den > 1e-14 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t, s = 0.0, min(max(-c / a, 0.0), 1.0)
    elif t > 1.0:
        t, s = 1.0, min(max((b - c) / a, 0.0), 1.0)
    x = w + s * d1 - t * d2
    return s, t, np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2])


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
        out[p] = segment_distance(pos[elem_nodes[e, 0]], pos[elem_nodes[e, 1]],
                                  pos[elem_nodes[f, 0]], pos[elem_nodes[f, 1]])
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
