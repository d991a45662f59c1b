"""Crossings of cable elements (issue #26): the continuous narrow phase that finds every
time two straight elements pass through each other during a step, and the elements'
closest points (the broad phase that lists the pairs to test: fe.contact.broad).

Over a step each node moves on a straight line (x(t) = x_n + t (x_{n+1} -
x_n), t in [0, 1]), so the signed volume V(t) = (B - A) . ((C - A) x (D - A)) of two
elements AB and CD is a cubic in t. Two segments can only pass through each other where
the four points are coplanar, V = 0; they do where, in addition, the two lines meet inside
both segments. The step is cut at the roots of V' (where V turns) into pieces on which V is
monotone; a piece whose ends have V of different signs (V >= 0 counting as positive, the
same in every step, so that a root on a step boundary is counted in exactly one step)
holds one root, found by bisection to round-off, and the lines' closest points there
decide. The direction of a crossing is the sign of V after it. Nothing depends on the
speed: a crossing at any speed within the step is found (the tests go to 200 m/s).

Conservative where V cannot tell. V is a volume: two elements that stay parallel to
within round-off, or four points that stay coplanar, keep V at round-off of its terms over
the whole step, and a touch without passing through (V turning at zero) has no sign
change: the test above would miss both. Given a least separation ``sep`` [m] (in a run,
:data:`SEP` times the scene's largest coordinate: :func:`separation`), the test counts a
pair as crossing where it comes within ``sep`` while V is within round-off (at a root of
V whose lines are nearly parallel, at a turning point of V, or anywhere in a step where V
stays at round-off, found by conservative advancement on the pair's distance), and a
meeting point within round-off outside an end (the element beside it may miss it by the
same round-off). A false alarm at distance ``sep`` is possible; a miss is not
(tests/test_crossing_conservative.py plants such pairs in every orientation at scales
from 1e-3 to 1e3 m).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.contact.broad import boxes_apart, swept_boxes
from spinweb_fe.fe.contact.distance import _closest

#: bisection steps of a root of V in a monotone piece of the step (2^-60: round-off)
ROOT_ITERATIONS = 60
#: the least separation the conservative test resolves, relative to the largest coordinate
#: of the scene: pairs closer than this where V cannot tell the sides apart count as
#: crossing (1e-9: 10^7 round-offs of a coordinate, 0.1 um on the paper's 100 m web)
SEP = 1e-9


@njit(cache=True)
def separation(pos0, pos1):
    """The conservative test's least separation [m] for a step from ``pos0`` to ``pos1``:
    :data:`SEP` times the largest coordinate magnitude (at least 1e-300)."""
    big = 1e-300
    for i in range(pos0.shape[0]):
        for k in range(3):
            big = max(big, max(abs(pos0[i, k]), abs(pos1[i, k])))
    return SEP * big


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


@njit(inline="always")
def _gram(w):
    """The Gram terms of the lines of segments w[0] w[1] and w[2] w[3]: (a, b, c, d, e) =
    (d1.d1, d1.d2, d2.d2, d1.r, d2.r), d1 and d2 the segments, r = w[0] - w[2]."""
    d10, d11, d12 = w[1, 0] - w[0, 0], w[1, 1] - w[0, 1], w[1, 2] - w[0, 2]
    d20, d21, d22 = w[3, 0] - w[2, 0], w[3, 1] - w[2, 1], w[3, 2] - w[2, 2]
    r0, r1, r2 = w[0, 0] - w[2, 0], w[0, 1] - w[2, 1], w[0, 2] - w[2, 2]
    return (d10 * d10 + d11 * d11 + d12 * d12, d10 * d20 + d11 * d21 + d12 * d22,
            d20 * d20 + d21 * d21 + d22 * d22, d10 * r0 + d11 * r1 + d12 * r2,
            d20 * r0 + d21 * r1 + d22 * r2)


@njit(cache=True)
def _lines_meet(w):
    """The lines of segments w[0] w[1] and w[2] w[3] (coplanar) meet inside both: the
    parameters of their closest points in [0, 1) x [0, 1) (half-open: a crossing exactly
    through a shared end is counted by one of the two elements). Parallel lines: no."""
    a, b, c, d, e = _gram(w)
    den = a * c - b * b
    if den <= 1e-14 * a * c:
        return False
    s = (b * e - c * d) / den
    u = (a * e - b * d) / den
    return 0.0 <= s < 1.0 and 0.0 <= u < 1.0


@njit(cache=True)
def _gap_at(w):
    """The least distance [m] of segments w[0] w[1] and w[2] w[3]."""
    return _closest(w[0, 0], w[0, 1], w[0, 2], w[1, 0], w[1, 1], w[1, 2], w[2, 0], w[2, 1],
                    w[2, 2], w[3, 0], w[3, 1], w[3, 2])[2]


@njit(cache=True)
def _meets(w, sep):
    """The segments of ``w`` (at a time where V = 0, or |V| within round-off) meet: their
    lines meet inside both (:func:`_lines_meet`), or, where that test cannot tell (nearly
    parallel lines, a meeting point within round-off outside an end), they come within
    ``sep`` [m] of each other. The exact end s = 1 (or u = 1) stays the neighbour's
    (half-open), so a crossing exactly through a node two elements share counts once."""
    if _lines_meet(w):
        return True
    if sep <= 0.0:
        return False
    a, b, c, d, e = _gram(w)
    den = a * c - b * b
    if den > 1e-14 * a * c:
        s = (b * e - c * d) / den
        u = (a * e - b * d) / den
        if s == 1.0 or u == 1.0:  # exactly at an end: the other element's crossing
            return False
    return _gap_at(w) <= sep


@njit(cache=True)
def _gap_dir(w, n):
    """The least distance [m] of segments w[0] w[1] and w[2] w[3], and into ``n`` (3,) the
    unit vector from the second's closest point to the first's (zeros where they meet)."""
    s, u, d = _closest(w[0, 0], w[0, 1], w[0, 2], w[1, 0], w[1, 1], w[1, 2], w[2, 0], w[2, 1],
                       w[2, 2], w[3, 0], w[3, 1], w[3, 2])
    for k in range(3):
        x = (w[0, k] + s * (w[1, k] - w[0, k])) - (w[2, k] + u * (w[3, k] - w[2, k]))
        n[k] = x / d if d > 0.0 else 0.0
    return d


@njit(inline="always")
def _proj(p0, p1, t0, t1, n):
    """The projections on ``n`` of a node at step fractions t0 and t1 (lo, hi)."""
    x0 = 0.0
    x1 = 0.0
    for k in range(3):
        x0 += (p0[k] + t0 * (p1[k] - p0[k])) * n[k]
        x1 += (p0[k] + t1 * (p1[k] - p0[k])) * n[k]
    return min(x0, x1), max(x0, x1)


@njit(cache=True)
def _slab_gap(a0, a1, b0, b1, c0, c1, d0, d1, t0, t1, n):
    """A lower bound of the pair's distance over [t0, t1]: the gap along the unit vector
    ``n`` between the projections of the two elements' nodes at t0 and t1 (each element
    sweeps the convex hull of its ends at the interval's ends: straight-line motion)."""
    lo1, hi1 = _proj(a0, a1, t0, t1, n)
    lo, hi = _proj(b0, b1, t0, t1, n)
    lo1, hi1 = min(lo1, lo), max(hi1, hi)
    lo2, hi2 = _proj(c0, c1, t0, t1, n)
    lo, hi = _proj(d0, d1, t0, t1, n)
    lo2, hi2 = min(lo2, lo), max(hi2, hi)
    return max(lo2 - hi1, lo1 - hi2, 0.0)


@njit(cache=True)
def _flat_touch(a0, a1, b0, b1, c0, c1, d0, d1, sep, w):
    """Where V stays at round-off over the whole step (the four points coplanar, or the
    elements parallel: V tells nothing), whether the segments come within ``sep`` [m]
    during the step, by conservative advancement: on an interval [t0, t1] their distance
    is at least the larger of min(D(t0), D(t1)) - R (t1 - t0) / 2 (R the largest relative
    displacement of a node of one against a node of the other over the step) and the gap
    between the nodes' projections at t0 and t1 on the direction of the closest points at
    either end (parallel elements sliding along each other keep that gap). Intervals
    that cannot be ruled out are halved until one comes within ``sep`` or is shorter than
    ``sep`` / R (then counted: within 1.5 ``sep``). Returns the step fraction of the
    touch, or -1 for none."""
    rel = 0.0
    for p0, p1 in ((a0, a1), (b0, b1)):
        for q0, q1 in ((c0, c1), (d0, d1)):
            x = 0.0
            for k in range(3):
                x += ((p1[k] - p0[k]) - (q1[k] - q0[k])) ** 2
            rel = max(rel, np.sqrt(x))
    size = 62
    ts = np.empty((size, 2))
    ds = np.empty((size, 2))
    ns = np.empty((size, 2, 3))
    _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 0.0, w)
    ds[0, 0] = _gap_dir(w, ns[0, 0])
    _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 1.0, w)
    ds[0, 1] = _gap_dir(w, ns[0, 1])
    if ds[0, 0] <= sep:
        return 0.0
    if ds[0, 1] <= sep:
        return 1.0
    ts[0, 0], ts[0, 1] = 0.0, 1.0
    n = 1
    nm = np.empty(3)
    for _ in range(4096):
        if n == 0:
            return -1.0
        n -= 1
        t0, t1 = ts[n, 0], ts[n, 1]
        bound = min(ds[n, 0], ds[n, 1]) - 0.5 * rel * (t1 - t0)
        for j in range(2):
            bound = max(bound, _slab_gap(a0, a1, b0, b1, c0, c1, d0, d1, t0, t1, ns[n, j]))
        if bound > sep:
            continue
        if 0.5 * rel * (t1 - t0) <= 0.5 * sep or n >= size - 2:
            return t0 if ds[n, 0] <= ds[n, 1] else t1
        tm = 0.5 * (t0 + t1)
        _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, tm, w)
        gm = _gap_dir(w, nm)
        if gm <= sep:
            return tm
        ts[n + 1, 0], ts[n + 1, 1] = t0, tm
        ds[n + 1, 0], ds[n + 1, 1] = ds[n, 0], gm
        ns[n + 1, 0], ns[n + 1, 1] = ns[n, 0], nm
        ts[n, 0] = tm
        ds[n, 0] = gm
        ns[n, 0] = nm
        n += 2
    return 0.0


@njit(cache=True)
def pair_crossings(a0, a1, b0, b1, c0, c1, d0, d1, times, signs, w=None, cuts=None,
                   sep=0.0):
    """Crossings of element AB (ends a, b) and CD during a step: each point from its
    position at the step's start (``*0``) to its end (``*1``). Writes the step fractions
    t in (0, 1] of up to 3 crossings into ``times`` and the sign of V after each into
    ``signs``; returns how many. ``w`` (4, 3) and ``cuts`` (4,): scratch, if given (a
    loop over pairs makes them once).

    ``sep`` [m] > 0 makes the test conservative where V cannot tell (module text): a pair
    that comes within ``sep`` of each other where V is at round-off (a touch at a turning
    point of V, nearly parallel elements, V flat over the step) or meets within round-off
    outside an end counts as crossing there (a false alarm at round-off distance rather
    than a miss)."""
    if w is None:
        w = np.empty((4, 3))
    if cuts is None:
        cuts = np.empty(4)
    # V(t) = k0 + k1 t + k2 t^2 + k3 t^3 from four samples (exact for a cubic)
    v0 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 0.0, w)
    v1 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 1.0 / 3.0, w)
    v2 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 2.0 / 3.0, w)
    v3 = _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 1.0, w)
    tol = 0.0  # |V| within round-off of its terms: V cannot tell the sides apart
    if sep > 0.0:
        tol = _round_off(a0, a1, b0, b1, c0, c1, d0, d1)
        if max(max(abs(v0), abs(v1)), max(abs(v2), abs(v3))) <= tol:
            t = _flat_touch(a0, a1, b0, b1, c0, c1, d0, d1, sep, w)
            if t < 0.0:
                return 0
            times[0] = max(t, 1e-300)
            signs[0] = 1 if v3 >= 0.0 else -1
            return 1
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
            if ta == 0.0 and abs(va) <= tol:  # touching at the start: the last step's end
                _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 0.0, w)
                if _gap_at(w) <= sep:
                    ta, va = tb, vb
                    continue
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
            if _meets(w, sep):
                times[found] = hi
                signs[found] = 1 if vb >= 0.0 else -1
                found += 1
        elif abs(vb) <= tol and found < 3:
            # V turns at round-off without changing sign, or ends the step there: the
            # elements may touch here (a touch at the step's start was the last step's end)
            if i == n_cut - 1:
                _volume_at(a0, a1, b0, b1, c0, c1, d0, d1, 1.0, w)
            if _gap_at(w) <= sep:
                times[found] = tb
                signs[found] = 1 if v3 >= 0.0 else -1
                found += 1
        ta, va = tb, vb
    return found


@njit(cache=True)
def _round_off(a0, a1, b0, b1, c0, c1, d0, d1):
    """A bound of the round-off in V [m^3] as :func:`_volume` computes it along the step:
    64 machine epsilons of the largest coordinate times the squared largest distance from
    A among the points."""
    big, ext = 0.0, 0.0
    for p0, p1 in ((a0, a1), (b0, b1), (c0, c1), (d0, d1)):
        for k in range(3):
            big = max(big, max(abs(p0[k]), abs(p1[k])))
            ext = max(ext, max(abs(p0[k] - a0[k]), abs(p1[k] - a1[k])))
    return 64.0 * 2.220446049250313e-16 * big * (3.0 * ext + 1e-300) ** 2


@njit(cache=True)
def boxed_crossings(pairs, elem_nodes, pos0, pos1, box, out_t, out_e, out_f, out_s,
                    sep=0.0):
    """:func:`step_crossings` with the elements' swept boxes given (``box``: rows of
    fe.contact.broad.swept_boxes for every element of ``pairs``)."""
    times = np.empty(3)
    signs = np.empty(3, np.int64)
    w, cuts = np.empty((4, 3)), np.empty(4)
    n = 0
    for p in range(pairs.shape[0]):
        e, f = pairs[p, 0], pairs[p, 1]
        if boxes_apart(box, e, f, sep):
            continue
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        c, d = elem_nodes[f, 0], elem_nodes[f, 1]
        k = pair_crossings(pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c],
                           pos0[d], pos1[d], times, signs, w, cuts, sep)
        n = log_crossings(out_t, out_e, out_f, out_s, n, times, signs, k, e, f)
    return n


@njit(inline="always")
def log_crossings(out_t, out_e, out_f, out_s, n, times, signs, k, e, f):
    """Append the ``k`` crossings of pair (e, f) (``times``, ``signs``) to the log from
    entry ``n`` while it has room; the count after them (it goes on past the room)."""
    for i in range(k):
        if n < out_t.shape[0]:
            out_t[n] = times[i]
            out_e[n] = e
            out_f[n] = f
            out_s[n] = signs[i]
        n += 1
    return n


@njit(cache=True)
def step_crossings(pairs, elem_nodes, pos0, pos1, out_t, out_e, out_f, out_s, sep=0.0):
    """Every crossing of the candidate ``pairs`` while the nodes move from ``pos0`` to
    ``pos1`` (one step); writes its step fraction, elements and sign into the ``out_*``
    arrays (as many as they hold) and returns the count (possibly more than they hold).
    ``sep`` [m]: the least separation of the conservative test (pair_crossings)."""
    box = np.empty((elem_nodes.shape[0], 6))
    swept_boxes(elem_nodes, np.ones(elem_nodes.shape[0], np.bool_), pos0, pos1, box)
    return boxed_crossings(pairs, elem_nodes, pos0, pos1, box, out_t, out_e, out_f, out_s,
                           sep)


@njit(inline="always")
def apart(pos0, pos1, a, b, c, d, gap=0.0):
    """True when the boxes that elements ab and cd sweep over the step are more than
    ``gap`` [m] apart along an axis (they cannot come closer: the narrow phase is
    skipped)."""
    for k in range(3):
        lo1 = min(pos0[a, k], pos1[a, k], pos0[b, k], pos1[b, k])
        hi1 = max(pos0[a, k], pos1[a, k], pos0[b, k], pos1[b, k])
        lo2 = min(pos0[c, k], pos1[c, k], pos0[d, k], pos1[d, k])
        hi2 = max(pos0[c, k], pos1[c, k], pos0[d, k], pos1[d, k])
        if lo1 > hi2 + gap or lo2 > hi1 + gap:
            return True
    return False


@njit(inline="always")
def moved_crosses(pos0, pos1, moved, a, b, c, d, times, signs, scratch, cuts):
    """Whether elements ab and cd, one of whose nodes is in ``moved``, cross over the step
    from ``pos0`` to ``pos1`` (a later pass of the contact's fail-safe: the swept boxes
    first, then the exact test; ``times``, ``signs`` as :func:`pair_crossings` fills them)."""
    if not (moved[a] or moved[b] or moved[c] or moved[d]) or apart(pos0, pos1, a, b, c, d):
        return False
    # (sep given, 0.0 as its default: the form of the loop's other calls, one compile)
    return pair_crossings(pos0[a], pos1[a], pos0[b], pos1[b], pos0[c], pos1[c], pos0[d],
                          pos1[d], times, signs, scratch, cuts, 0.0) > 0
