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
s is the sign that :func:`spinweb_fe.fe.crossing.pair_crossings` reports (the same V,
symmetric in the two elements), and Lk changes by s eps_P eps_Q, eps = +1 when the
loop runs the element in its stored node order, -1 against it. An
interior element borders two cells, which run it in opposite directions, so one crossing
changes the linking numbers of up to four cell pairs, by +-1 each (tests/test_linking.py).

In a run: :class:`LinkingMonitor` (with ``[audit] crossings``), its group /linking
(:func:`write_group`); the broad phase is :mod:`spinweb_fe.record.loop_boxes`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.record.loop_boxes import box_pairs
from spinweb_fe.record.recorders import Recorder


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


#: the linking check's columns, one value per check: units, dtype, meaning
COLUMNS = {
    "time": ("s", np.float64, "time of the check"),
    "linked": ("1", np.int64, "cell pairs with a nonzero linking number"),
    "changed": ("1", np.int64, "cell pairs whose linking number changed since the previous "
                               "check (0 at the first)"),
    "worst": ("1", np.float64, "largest distance of a computed linking number from an "
                               "integer"),
    "suspect": ("1", np.int64, "pairs farther than the tolerance from an integer (cells "
                               "that meet: a check caught mid-crossing); they keep their "
                               "previous value"),
}


def _cell_elements(loops: Loops, elem_nodes) -> np.ndarray:
    """(ptr[-1],) int64: the element from each loop node to the next (cells run along
    elements, so each is one)."""
    e = np.asarray(elem_nodes, np.int64)
    n = int(max(e.max(initial=-1), loops.nodes.max(initial=-1))) + 1
    nxt = np.arange(len(loops.nodes)) + 1
    nxt[loops.ptr[1:] - 1] = loops.ptr[:-1]
    a, b = loops.nodes, loops.nodes[nxt]
    key = np.minimum(a, b) * n + np.maximum(a, b)
    ekey = np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1])
    order = np.argsort(ekey, kind="stable")
    return order[np.searchsorted(ekey[order], key)]


def _among(rows, alive):
    """The rows (K, 3) (i, j, Lk) of pairs of cells that are both ``alive`` (L,) bool."""
    return rows[alive[rows[:, 0]] & alive[rows[:, 1]]]


def _values(rows, keys, n):
    """Lk of the pairs ``keys`` (codes i n + j, sorted) in ``rows`` (K, 3), 0 if absent."""
    out = np.zeros(len(keys), np.int64)
    out[np.searchsorted(keys, rows[:, 0] * n + rows[:, 1])] = rows[:, 2]
    return out


class LinkingMonitor(Recorder):
    """The linking check of a run (``[audit] crossings = true``, beside the crossing
    audit): the linking numbers of the web's cells, checked at the run's states.

    A check: :func:`linked_pairs` of the cells (:func:`cell_loops`) that have no broken
    element, at the check's positions. A pair farther than ``tol`` from an integer (a
    suspect: its cells meet, a check caught mid-crossing) keeps the value it had; a cell
    that loses an element to rupture is no loop any more and leaves the check, its pairs
    with it (not counted as changes). The first check's links are the reference; each
    check records the :data:`COLUMNS`.

    Which states: the run's first (``state``, when the run does not continue a
    checkpoint's memory), every frame (``output.frame_dt``; the loop gives one at the
    last step) and the last step (the loop's checkpoint event at the end, which it
    calls with or without checkpoint files): a run without frames is checked at its
    start and at its end. A state is checked once.

    Parameters
    ----------
    mesh : meshgen.mesh.Mesh
    state : spinweb_fe.fe.state.State or None
        The run's first state.
    tol : float
        How far from an integer a linking number may be (:func:`linked_pairs`).
    """

    name = "linking"

    def __init__(self, mesh, state=None, tol: float = 1e-6):
        self.loops = cell_loops(mesh)
        self.tol = float(tol)
        self.edge_elem = _cell_elements(self.loops, mesh.elem_nodes)
        self.edge_cell = np.repeat(np.arange(self.loops.n_loops), np.diff(self.loops.ptr))
        self.log = {k: [] for k in COLUMNS}
        self.reference = self.current = np.zeros((0, 3), np.int64)
        self.last_step = -1
        self.alive = np.ones(self.loops.n_loops, bool)  # at the last check
        self.dt, self.end_step = 1.0, None
        self._first = None if state is None else (
            int(state.step[0]), state.node_pos.copy(), _broken(state))

    def start(self, info):
        self.dt, self.end_step = info.dt, info.n_total
        if self._first is not None and not self.log["time"]:
            self.check(*self._first)
        self._first = None

    def frame(self, frame):
        self.check(round(frame.time / self.dt), frame.pos, frame.broken)

    def checkpoint(self, state, memory):
        if self.end_step is not None and int(state.step[0]) >= self.end_step:
            self.check(int(state.step[0]), state.node_pos, _broken(state))

    def check(self, step: int, pos, broken=None) -> None:
        """Check the positions ``pos`` (n, 3) [m] of step ``step`` (time step * dt), with
        the elements ``broken`` (m,) bool (None: none); a step already checked is not."""
        if step == self.last_step:
            return
        n = self.loops.n_loops
        alive = np.ones(n, bool)
        loops = self.loops
        if broken is not None and np.any(broken):
            alive[self.edge_cell[np.asarray(broken)[self.edge_elem]]] = False
            sizes = np.diff(loops.ptr)[alive]
            loops = Loops(np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                          loops.nodes[alive[self.edge_cell]])
        live = np.flatnonzero(alive)
        res = linked_pairs(pos, loops, self.tol)
        prev = _among(self.current, alive)
        suspect = live[res.suspect]
        held = np.isin(prev[:, 0] * n + prev[:, 1], suspect[:, 0] * n + suspect[:, 1])
        now = np.vstack([np.column_stack([live[res.links[:, :2]], res.links[:, 2]]),
                         prev[held]]).astype(np.int64)
        now = now[np.lexsort((now[:, 1], now[:, 0]))]
        keys = np.union1d(prev[:, 0] * n + prev[:, 1], now[:, 0] * n + now[:, 1])
        changed = int(np.count_nonzero(_values(prev, keys, n) != _values(now, keys, n)))
        if not self.log["time"]:
            self.reference, changed = now, 0
        for k, v in (("time", step * self.dt), ("linked", len(now)), ("changed", changed),
                     ("worst", res.worst), ("suspect", len(suspect))):
            self.log[k].append(v)
        self.current, self.last_step, self.alive = now, int(step), alive

    def table(self) -> dict:
        """The checks as arrays (name -> (C,) array, the :data:`COLUMNS`)."""
        return {k: np.asarray(v, COLUMNS[k][1]) for k, v in self.log.items()}

    def summary(self) -> dict:
        """``changed_total``, ``first_change_time`` [s] (NaN: none), ``net_changed`` (pairs
        whose Lk at the last check differs from the first's), ``linked`` (at the last)."""
        table = self.table()
        t, changed = table["time"], table["changed"]
        n = self.loops.n_loops
        ref = _among(self.reference, self.alive)
        keys = np.union1d(ref[:, 0] * n + ref[:, 1],
                          self.current[:, 0] * n + self.current[:, 1])
        net = _values(ref, keys, n) != _values(self.current, keys, n)
        return {"changed_total": int(changed.sum()), "net_changed": int(np.count_nonzero(net)),
                "first_change_time": float(t[changed > 0][0]) if np.any(changed) else math.nan,
                "linked": len(self.current)}

    def memory(self) -> dict:
        return {**self.table(), "reference": self.reference, "current": self.current,
                "last_step": np.array([self.last_step], np.int64), "alive": self.alive}

    def restore(self, memory: dict) -> None:
        for k in self.log:
            self.log[k] = np.asarray(memory[k]).tolist()
        self.reference = np.asarray(memory["reference"], np.int64).reshape(-1, 3)
        self.current = np.asarray(memory["current"], np.int64).reshape(-1, 3)
        self.last_step = int(memory["last_step"][0])
        self.alive = np.asarray(memory["alive"], bool)
        self._first = None


def _broken(state):
    """The state's broken elements (m,) bool, or None without rupture."""
    broken = state.strength.broken
    return broken.copy() if len(broken) else None


def write_group(h5, monitor: LinkingMonitor):
    """The /linking group: the :data:`COLUMNS` with their units, ``links`` (K, 3) (i, j,
    Lk) at the last check and ``reference`` at the first (cells: /linking/cells, ptr and
    nodes), attributes ``loops``, ``dropped``, ``tol``, ``changed_total``,
    ``net_changed``, ``first_change_time`` [s] (NaN: no change)."""
    if "linking" in h5:
        del h5["linking"]
    g = h5.create_group("linking")
    for name, arr in monitor.table().items():
        ds = g.create_dataset(name, data=arr)
        ds.attrs["units"], ds.attrs["description"] = COLUMNS[name][0], COLUMNS[name][2]
    for name, rows, what in (("links", monitor.current, "at the last check"),
                             ("reference", monitor.reference, "at the first check")):
        ds = g.create_dataset(name, data=rows.reshape(-1, 3))
        ds.attrs["units"] = "1"
        ds.attrs["description"] = f"(i, j, Lk) of the linked cell pairs {what}"
    cells = g.create_group("cells")
    cells.create_dataset("ptr", data=monitor.loops.ptr)
    cells.create_dataset("nodes", data=monitor.loops.nodes)
    cells.attrs["description"] = "cell i: nodes[ptr[i]:ptr[i+1]] (indices into /mesh/points)"
    summary = monitor.summary()
    g.attrs["loops"] = monitor.loops.n_loops
    g.attrs["dropped"] = int(np.count_nonzero(~monitor.alive))
    g.attrs["tol"] = monitor.tol
    for k in ("changed_total", "net_changed", "first_change_time"):
        g.attrs[k] = summary[k]
    g.attrs["units"] = "first_change_time: s"
