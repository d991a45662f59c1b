"""Linking numbers of the web's closed loops (issue #26, item 3): a topological invariant
of a frame that only a crossing of two cable elements can change.

The loops are the web's mesh cells: the bounded faces of its flat reference
(``Mesh.node_ref``, a plane straight-line graph), each a cycle of node indices,
counter-clockwise seen from +z in the flat web (:func:`cell_loops`). The mesh stores no
cells; they are found once from the elements.

Formula. The Gauss linking integral of closed polygons P and Q,

    Lk(P, Q) = 1/(4 pi) sum_i sum_j  int int (x - y) . (dx x dy) / |x - y|^3,

is, for one straight segment x in [p1, p2] of P and one y in [p3, p4] of Q, the solid
angle under which the parallelogram of differences y - x = (p3 - p1) + t (p4 - p3) -
s (p2 - p1), s, t in [0, 1] (corners p3 - p1, p3 - p2, p4 - p2, p4 - p1), is seen from the
origin, signed by V = (p2 - p1) . ((p3 - p1) x (p4 - p1)): the integrand is the
pull-back of the unit sphere's area by (s, t) -> (y - x) / |y - x|, whose Jacobian has
the sign of V everywhere (Banchoff 1976; Klenin & Langowski 2000 write the same solid
angle as four arcsines). Here it is the sum of the two triangles (p3 - p1, p3 - p2,
p4 - p2) and (p3 - p1, p4 - p2, p4 - p1), each by Van Oosterom and Strackee's
tan(Omega / 2) = a . (b x c) / (|a||b||c| + (a.b)|c| + (a.c)|b| + (b.c)|a|), their
half-angles added as one complex product and one atan2 (exact: the parallelogram lies in
an open hemisphere, so the sum's half-angle is within (-pi, pi)). For disjoint loops the
sum is an integer to round-off: 1e-17 to 1e-14 in the paper web's frames, growing as two
loops come close, about 3e-17 L / d for segments of size L a distance d apart (3e-8 at
d = 1e-9 L), so that the default tolerance 1e-6 flags loops within some 1e-11 L.

Degenerate cases. V = 0 (coplanar or parallel segments) contributes exactly 0, so
coplanar loops give exactly 0 -- also when they overlap in their plane, where the linking
number is undefined (a planar run, the star-folded web's coincident layers): there the
invariant is blind, as the crossing detector is (its V stays 0). Segments that meet (the
loops are not disjoint) make the integrand singular and Lk undefined: two segments that
cross in a point are coplanar (V = 0, their pair counts 0), so a frame caught exactly at
a crossing gives the mean of the values before and after, a half-integer; a node common
to both loops gives some finite, meaningless value. :func:`linked_pairs` computes no
pair that shares a node and reports a result off an integer as a suspect.

A crossing. When a segment AB of P passes through a segment CD of Q, V of the pair
changes sign, from -s to s, and its solid angle goes from nearly -2 pi s to nearly 2 pi s
(the parallelogram of differences sweeps over the origin), while every other pair's
changes continuously: Lk(P, Q) changes by exactly s. With the elements taken as stored,
s is the sign that :func:`spinweb_fe.fe.contact.crossing.pair_crossings` reports (the same V,
symmetric in the two elements), and Lk changes by s eps_P eps_Q, eps = +1 when the
loop runs the element in its stored node order, -1 against it. An
interior element borders two cells, which run it in opposite directions, so one crossing
changes the linking numbers of up to four cell pairs, by +-1 each (tests/test_linking.py).

In a run: :class:`spinweb_fe.record.linking_check.LinkingMonitor` (with ``[audit]
crossings``), its group /linking; the broad phase is :mod:`spinweb_fe.record.loop_boxes`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.record.loop_boxes import box_pairs


class Loops(NamedTuple):
    """Closed loops of nodes, CSR: loop i is ``nodes[ptr[i]:ptr[i+1]]``, closed back to
    its first node.

    Attributes
    ----------
    ptr : (L+1,) int64
    nodes : (ptr[-1],) int64
        Node indices, each loop in its orientation.
    """

    ptr: np.ndarray
    nodes: np.ndarray

    @property
    def n_loops(self) -> int:
        return len(self.ptr) - 1

    def loop(self, i: int) -> np.ndarray:
        """(k,) int64 node indices of loop i."""
        return self.nodes[self.ptr[i]:self.ptr[i + 1]]


class Links(NamedTuple):
    """Linking numbers of one frame (:func:`linked_pairs`).

    Attributes
    ----------
    links : (K, 3) int64
        Rows (i, j, Lk), i < j, of the pairs with Lk != 0, in (i, j) order.
    worst : float
        The largest |Lk - round(Lk)| over every pair computed (0 if none).
    suspect : (B, 2) int64
        Pairs whose Lk was farther than ``tol`` from an integer: loops that touch or
        cross in this frame (or a tolerance too tight); not in ``links``.
    candidates : int
        Node-disjoint pairs whose boxes overlap: the pairs computed.
    """

    links: np.ndarray
    worst: float
    suspect: np.ndarray
    candidates: int


def loops_from(cycles) -> Loops:
    """:class:`Loops` of a sequence of node index cycles (each at least 3 nodes)."""
    cycles = [np.asarray(c, np.int64).ravel() for c in cycles]
    ptr = np.zeros(len(cycles) + 1, np.int64)
    ptr[1:] = np.cumsum([len(c) for c in cycles])
    nodes = np.concatenate(cycles) if cycles else np.zeros(0, np.int64)
    return Loops(ptr, nodes)


def cell_loops(mesh) -> Loops:
    """The web's cells: the bounded faces of its flat reference ``mesh.node_ref`` (x, y).

    Each face is traced with its inside on the left (at each node the next element is the
    first one clockwise from the one it came in by), so every cell runs counter-clockwise
    seen from +z in the flat web and an interior element is run once each way by the two
    cells it borders. The outer face (negative area) and faces of no area (the walk along
    a tree, e.g. tethers) are left out. A central cut-out's rim is a bounded face too and
    is listed like a cell: it is a closed loop of cables as well.

    Parameters
    ----------
    mesh : meshgen.mesh.Mesh
        With a plane reference (every web of meshgen; z is ignored) and no two elements
        crossing in it.

    Returns
    -------
    Loops
        In the order of each cell's first half-edge (element order).
    """
    xy = np.asarray(mesh.node_ref, np.float64)[:, :2]
    e = np.asarray(mesh.elem_nodes, np.int64)
    if len(e) == 0:
        return loops_from([])
    tail = np.concatenate([e[:, 0], e[:, 1]])   # half-edge h: tail -> head;
    head = np.concatenate([e[:, 1], e[:, 0]])   # its twin is (h + m) mod 2m
    m2 = len(tail)
    d = xy[head] - xy[tail]
    order = np.lexsort((np.arctan2(d[:, 1], d[:, 0]), tail))  # by tail, then angle (ccw)
    rank = np.empty(m2, np.int64)
    rank[order] = np.arange(m2)
    first = np.searchsorted(tail[order], np.arange(len(xy)), side="left")
    # next(h) = the half-edge out of head(h) just clockwise of the twin of h
    twin = (np.arange(m2) + m2 // 2) % m2
    r = rank[twin]
    start = first[head]
    prev = np.where(r == start, r + np.bincount(tail, minlength=len(xy))[head] - 1, r - 1)
    nxt = order[prev].tolist()
    face = [-1] * m2
    walks = []
    for h in range(m2):
        if face[h] >= 0:
            continue
        walk = []
        while face[h] < 0:
            face[h] = len(walks)
            walk.append(h)
            h = nxt[h]
        walks.append(walk)
    # twice the signed area of each face (shoelace over its half-edges)
    p, q = xy[tail], xy[head]
    area = np.bincount(face, weights=p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1])
    area_tol = 1e-12 * float(np.ptp(xy[:, 0]) * np.ptp(xy[:, 1]) if len(xy) else 0.0)
    cycles = [tail[w] for w, a in zip(walks, area) if a > area_tol]
    return loops_from(cycles)


@njit(cache=True)
def _differences(pos, a, b, diff, norm):
    """diff[i * m + j] = pos[b[j]] - pos[a[i]] and its length, m = len(b)."""
    m = len(b)
    for i in range(len(a)):
        for j in range(m):
            r = 0.0
            for k in range(3):
                diff[i * m + j, k] = pos[b[j], k] - pos[a[i], k]
                r += diff[i * m + j, k] ** 2
            norm[i * m + j] = math.sqrt(r)


@njit(cache=True)
def _parallelogram_angle(diff, norm, p13, p23, p24, p14):
    """Signed solid angle [sr] under which the parallelogram of differences with corners
    diff[p13] = p3 - p1, diff[p23], diff[p24], diff[p14] is seen from the origin: the
    Gauss integral of segments p1 -> p2 and p3 -> p4."""
    a0, a1, a2 = diff[p13, 0], diff[p13, 1], diff[p13, 2]
    b0, b1, b2 = diff[p23, 0], diff[p23, 1], diff[p23, 2]
    c0, c1, c2 = diff[p24, 0], diff[p24, 1], diff[p24, 2]
    d0, d1, d2 = diff[p14, 0], diff[p14, 1], diff[p14, 2]
    # V = (p2 - p1) . ((p3 - p1) x (p4 - p1)) = (a - b) . (a x d): 0 for coplanar segments
    vol = ((a0 - b0) * (a1 * d2 - a2 * d1) + (a1 - b1) * (a2 * d0 - a0 * d2)
           + (a2 - b2) * (a0 * d1 - a1 * d0))
    if vol == 0.0:
        return 0.0
    la, lb, lc, ld = norm[p13], norm[p23], norm[p24], norm[p14]
    ab, ac = a0 * b0 + a1 * b1 + a2 * b2, a0 * c0 + a1 * c1 + a2 * c2
    ad = a0 * d0 + a1 * d1 + a2 * d2
    bc, cd = b0 * c0 + b1 * c1 + b2 * c2, c0 * d0 + c1 * d1 + c2 * d2
    # Van Oosterom-Strackee: triangle (a, b, c) and triangle (a, c, d)
    y1 = a0 * (b1 * c2 - b2 * c1) + a1 * (b2 * c0 - b0 * c2) + a2 * (b0 * c1 - b1 * c0)
    x1 = la * lb * lc + ab * lc + ac * lb + bc * la
    y2 = a0 * (c1 * d2 - c2 * d1) + a1 * (c2 * d0 - c0 * d2) + a2 * (c0 * d1 - c1 * d0)
    x2 = la * lc * ld + ac * ld + ad * lc + cd * la
    # the two half-angles added: arg((x1 + i y1)(x2 + i y2))
    return 2.0 * math.atan2(x1 * y2 + x2 * y1, x1 * x2 - y1 * y2)


@njit(cache=True)
def _loop_angle(pos, a, b, diff, norm):
    """Sum of the segment pairs' solid angles [sr] of closed loops ``a`` and ``b`` (node
    index arrays into ``pos``): 4 pi Lk. ``diff`` (>= n m, 3) and ``norm`` are scratch."""
    n, m = len(a), len(b)
    _differences(pos, a, b, diff, norm)
    total = 0.0
    for i in range(n):
        i2 = (i + 1) % n
        for j in range(m):
            j2 = (j + 1) % m
            total += _parallelogram_angle(diff, norm, i * m + j, i2 * m + j, i2 * m + j2,
                                          i * m + j2)
    return total


def segment_linking(p1, p2, p3, p4) -> float:
    """The Gauss integral of straight segments p1 -> p2 and p3 -> p4, over 4 pi: each
    segment pair's share of a linking number (module docstring). (3,) points [m]."""
    pos = np.ascontiguousarray(np.array([p1, p2, p3, p4], np.float64))
    diff, norm = np.empty((4, 3)), np.empty(4)
    _differences(pos, np.array([0, 1]), np.array([2, 3]), diff, norm)
    return _parallelogram_angle(diff, norm, 0, 2, 3, 1) / (4.0 * math.pi)


def linking_number(P, Q) -> float:
    """Gauss linking number of closed polygons P (n,3) and Q (m,3) [m] (each closed back
    to its first point), as a float: an integer to round-off for disjoint loops, exactly 0
    for coplanar ones, not an integer in general for loops that meet (module docstring).
    Lk(P, Q) = Lk(Q, P); reversing one loop changes its sign; +1 when Q passes through P
    along P's right-hand normal (P counter-clockwise about +z, Q through it upwards)."""
    P = np.asarray(P, np.float64).reshape(-1, 3)
    Q = np.asarray(Q, np.float64).reshape(-1, 3)
    pos = np.ascontiguousarray(np.vstack([P, Q]))
    a = np.arange(len(P), dtype=np.int64)
    b = np.arange(len(P), len(P) + len(Q), dtype=np.int64)
    return _loop_angle(pos, a, b, np.empty((len(a) * len(b), 3)),
                       np.empty(len(a) * len(b))) / (4.0 * math.pi)


@njit(cache=True)
def _pairs_linking(pos, ptr, nodes, pairs):
    """(P,) float Lk of each loop pair."""
    lk = np.empty(pairs.shape[0])
    longest = 0
    for i in range(len(ptr) - 1):
        longest = max(longest, ptr[i + 1] - ptr[i])
    diff = np.empty((longest * longest, 3))
    norm = np.empty(longest * longest)
    for p in range(pairs.shape[0]):
        i, j = pairs[p, 0], pairs[p, 1]
        lk[p] = _loop_angle(pos, nodes[ptr[i]:ptr[i + 1]], nodes[ptr[j]:ptr[j + 1]], diff,
                            norm) / (4.0 * math.pi)
    return lk


def linked_pairs(positions, loops: Loops, tol: float = 1e-6) -> Links:
    """Linking numbers of the frame's loop pairs; those that are not 0.

    Only pairs of loops with no node in common and whose axis-aligned boxes overlap are
    computed (:func:`box_pairs`): loops that share a node meet, and have no linking number;
    boxes that do not overlap are separated by a plane (each in one closed half-space),
    and disjoint loops on the two sides of a plane are not linked (move one away along
    the plane's normal: they never meet), so their Lk is 0.

    Parameters
    ----------
    positions : (n, 3) float64 [m]
        Node positions of the frame.
    loops : Loops
        From :func:`cell_loops` or :func:`loops_from`.
    tol : float
        How far from an integer a computed Lk may be.

    Returns
    -------
    Links
        The pairs with a nonzero integer Lk, the worst distance from an integer, the pairs
        beyond ``tol`` (suspects: the loops meet in this frame) and the candidate count.
    """
    pos = np.ascontiguousarray(positions, dtype=np.float64)
    pairs = box_pairs(pos, loops)
    lk = _pairs_linking(pos, loops.ptr, loops.nodes, pairs)
    near = np.rint(lk)
    off = np.abs(lk - near)
    good = off <= tol
    keep = good & (near != 0)
    links = np.column_stack([pairs[keep], near[keep].astype(np.int64)]).reshape(-1, 3)
    return Links(links=links, worst=float(off.max()) if len(off) else 0.0,
                 suspect=pairs[~good].reshape(-1, 2), candidates=len(pairs))
