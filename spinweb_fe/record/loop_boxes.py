"""The broad phase of the linking check (record/linking.py): the pairs of closed loops that
share no node and whose axis-aligned boxes overlap, from a uniform hash grid.

``loops`` is a :class:`spinweb_fe.record.linking.Loops` (CSR ``ptr``, ``nodes``); this
module reads only those two arrays and its ``n_loops``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.contact.broad import GRID_SPAN, grid_entries

#: the broad phase widens its grid cells until a loop's box sits in at most this many
#: cells on average (a few giant loops would otherwise fill the grid)
MAX_CELLS_PER_LOOP = 16


@njit(cache=True)
def _loop_boxes(pos, ptr, nodes):
    """(L, 3) lower and upper corners of each loop's axis-aligned box [m]."""
    n_loops = len(ptr) - 1
    lo = np.empty((n_loops, 3))
    hi = np.empty((n_loops, 3))
    for i in range(n_loops):
        for k in range(3):
            lo[i, k] = np.inf
            hi[i, k] = -np.inf
        for p in range(ptr[i], ptr[i + 1]):
            for k in range(3):
                lo[i, k] = min(lo[i, k], pos[nodes[p], k])
                hi[i, k] = max(hi[i, k], pos[nodes[p], k])
    return lo, hi


@njit(cache=True)
def _grid(lo, hi, cell):
    """The grid's origin and how many (loop, grid cell) entries cells of size ``cell``
    make (each box goes into every cell it touches)."""
    origin = np.empty(3)
    for k in range(3):
        origin[k] = lo[:, k].min()
    count = 0
    for i in range(lo.shape[0]):
        c = 1
        for k in range(3):
            c *= int((hi[i, k] - origin[k]) / cell) - int((lo[i, k] - origin[k]) / cell) + 1
        count += c
    return origin, count


@njit(cache=True)
def _share_node(nodes, a0, a1, b0, b1):
    for p in range(a0, a1):
        for q in range(b0, b1):
            if nodes[p] == nodes[q]:
                return True
    return False


@njit(cache=True)
def _scan_cells(keys, owners, lo, hi, ptr, nodes, cell, origin, out):
    """Loop pairs i < j without a common node whose boxes overlap (on every axis lo_a <
    hi_b and lo_b < hi_a), from the grid entries sorted by key (``keys``, ``owners``),
    into ``out`` (room for every pair of entries in a cell); how many. A pair is taken in
    the grid cell of the lower corner of its boxes' intersection only."""
    big = np.int64(GRID_SPAN)
    n_ent = len(keys)
    n_out = 0
    s = 0
    while s < n_ent:
        key = keys[s]
        t = s
        while t < n_ent and keys[t] == key:
            t += 1
        for p in range(s, t):
            a = owners[p]
            for q in range(p + 1, t):
                b = owners[q]
                corner = np.int64(0)
                inside = True
                for k in range(3):
                    if not (lo[a, k] < hi[b, k] and lo[b, k] < hi[a, k]):
                        inside = False  # the plane x_k = hi of one box separates them
                        break
                    low = max(lo[a, k], lo[b, k])
                    corner = corner * big + int((low - origin[k]) / cell)
                if not inside or corner != key:
                    continue
                if _share_node(nodes, ptr[a], ptr[a + 1], ptr[b], ptr[b + 1]):
                    continue
                out[n_out, 0] = min(a, b)
                out[n_out, 1] = max(a, b)
                n_out += 1
        s = t
    return n_out


def box_pairs(positions, loops) -> np.ndarray:
    """(P, 2) int64 pairs (i < j) of loops (``loops``: a Loops) that share no node and
    whose axis-aligned boxes overlap, sorted: the broad phase of
    :func:`spinweb_fe.record.linking.linked_pairs`. Boxes overlap unless on some axis one
    ends where or before the other begins (hi_a <= lo_b or hi_b <= lo_a): then the plane
    x_k = hi_a (or hi_b) has one box on each side. Two boxes of a web flat in z do not
    overlap (z = 0 is such a plane); a flat loop's box inside another's extent on
    that axis does.

    A uniform hash grid of cells of the median loop size (widened while the boxes would
    fill more than ``MAX_CELLS_PER_LOOP`` cells each on average, or the grid span more
    than ``GRID_SPAN`` cells an axis), sorted by cell: O(L log L) for a web whose boxes
    overlap only their neighbours.
    """
    pos = np.ascontiguousarray(positions, dtype=np.float64)
    if loops.n_loops < 2:
        return np.zeros((0, 2), np.int64)
    lo, hi = _loop_boxes(pos, loops.ptr, loops.nodes)
    size = float(np.median(np.max(hi - lo, axis=1)))  # numba's median: 3 s to compile
    span = float(np.max(hi.max(axis=0) - lo.min(axis=0)))
    if span == 0.0:
        return np.zeros((0, 2), np.int64)
    cell = max(size, span / (GRID_SPAN - 2))
    while True:
        origin, count = _grid(lo, hi, cell)
        if count <= MAX_CELLS_PER_LOOP * loops.n_loops:
            break
        cell *= 2.0
    keys, owners, _ = grid_entries(lo, hi, np.ones(lo.shape[0], np.bool_), cell, origin,
                                   count)
    order = np.argsort(keys, kind="stable")  # numpy's: 2-3x numba's here
    keys, owners = keys[order], owners[order]
    # room for every pair within a cell (an output grown inside the kernel costs 6 s of
    # compilation)
    runs = np.diff(np.flatnonzero(np.diff(keys, prepend=-1, append=-1)))
    out = np.empty((int(np.sum(runs * (runs - 1) // 2)), 2), np.int64)
    n = _scan_cells(keys, owners, lo, hi, loops.ptr, loops.nodes, cell, origin, out)
    pairs = out[:n]
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
