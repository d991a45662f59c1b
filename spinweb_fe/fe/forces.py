"""The internal forces of a step: element force vectors, then one sum per node.

The element pass evaluates every element's force vector f_e = N_e (x_j - x_i) / L_e (the force
on its first end i; the second end j takes -f_e) into ``Work.ef`` (3, m + 1), in blocks of
``BLOCK`` elements: the end differences are gathered into a small buffer, then lengths,
strains and tensions are computed in a straight loop that LLVM vectorises (sqrt and divide
on all lanes). The node pass sums each node's element forces through ``Links.node_elems``, the
node's elements in element order: no scatter, no force buffer per thread, each node written
once by one thread. Adding in element order gives the forces of a scatter loop (each
element's force added to both ends in element order) bit for bit; blocks are fixed and their
partial sums (strain energy, damping power, the node pass's energy and momentum sums) are
added in block order, so every thread count gives the same bits.

Indices in the passes are unsigned: numba adds a negative-index fix-up to every signed
index, and that alone keeps LLVM from vectorising the loop (measured: 2.7e8 against 1.7e9
element evaluations per second). Kernels take the block size from the workspace's buffer,
never from a module global.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from spinweb_fe.fe.law import damped_tension, length_strain, rate

#: elements (and nodes) per block: the gather buffers of a block stay in L1
BLOCK = 512
#: most elements per node kept in the padded table; more go to the overflow list
SLOTS_MAX = 8
#: bit of a ``node_elems`` entry: the node is the element's second end (its force is -f_e)
SECOND = 0x80000000


class Links(NamedTuple):
    """Which nodes each element joins, and which elements each node has.

    Attributes
    ----------
    first, second : (m,) uint32
        End nodes i, j of each element (as ``Elements.nodes``).
    node_elems : (n, D) uint32
        Each node's first D elements in element order; the SECOND bit marks the node as the
        element's second end; unused slots hold m (a zero force). D = the largest element
        count of a node, at most SLOTS_MAX.
    extra_nodes : (k,) int64
        Nodes with more than D elements (increasing).
    extra_ptr : (k + 1,) int64
        Their further elements: ``extra_elems[extra_ptr[p]:extra_ptr[p + 1]]``.
    extra_elems : (.,) uint32
        Encoded as ``node_elems``, in element order after the node's first D.
    """

    first: np.ndarray
    second: np.ndarray
    node_elems: np.ndarray
    extra_nodes: np.ndarray
    extra_ptr: np.ndarray
    extra_elems: np.ndarray


class Work(NamedTuple):
    """Scratch of the force passes (nothing in it outlives a step).

    Attributes
    ----------
    force : (n, 3) float64 [N]
        The internal force on each node (written by the node pass; the step's features
        read and amend it).
    tension : (m,) float64 [N]
        Element tensions, written on record steps and by damped elements.
    inside : (n,) bool
        The node update's mark of the nodes heading inside the hub this step.
    ef : (3, m + 1) float64 [N]
        Element force vectors f_e (column m stays zero: the padding slot).
    buf : (chunks, 8, BLOCK) float64
        Gather buffers, one set per chunk of blocks (one chunk per thread).
    eout : (element blocks, 8) float64
        Per element block: strain energy [J], max tension [N], damping power [W], and the
        strength pass's peak utilisation, its strain, its element, released energy [J],
        breaks.
    nout : (node blocks, 5) float64
        Per node block: kinetic energy and angular momentum sums before and after the update,
        contact dissipation [J].
    order : (element blocks,) int64
        The element blocks in the order the threads take them, thread c the c-th of
        ``chunks`` equal runs: sorted by their elements' mean node index, so that a thread's
        elements join the nodes of its own node range (:func:`thread_order`).
    """

    force: np.ndarray
    tension: np.ndarray
    inside: np.ndarray
    ef: np.ndarray
    buf: np.ndarray
    eout: np.ndarray
    nout: np.ndarray
    order: np.ndarray


def make_links(elem_nodes: np.ndarray, n_nodes: int) -> Links:
    """The :class:`Links` of elements ``elem_nodes`` (m, 2) over ``n_nodes`` nodes."""
    m = len(elem_nodes)
    if m >= SECOND or n_nodes >= SECOND:
        raise ValueError(f"{m} elements / {n_nodes} nodes: at most {SECOND - 1} each")
    ends = np.concatenate([elem_nodes[:, 0], elem_nodes[:, 1]]).astype(np.int64)
    code = np.concatenate([np.arange(m), np.arange(m) | SECOND]).astype(np.uint32)
    elem = np.concatenate([np.arange(m), np.arange(m)])
    order = np.lexsort((elem, ends))  # by node, then element order
    ends, code = ends[order], code[order]
    count = np.bincount(ends, minlength=n_nodes)
    start = np.concatenate([[0], np.cumsum(count)])
    slots = int(min(max(count.max(initial=0), 1), SLOTS_MAX))
    node_elems = np.full((n_nodes, slots), m, np.uint32)
    rank = np.arange(len(ends)) - start[ends]  # position of each entry in its node's list
    keep = rank < slots
    node_elems[ends[keep], rank[keep]] = code[keep]
    extra_nodes = np.flatnonzero(count > slots).astype(np.int64)
    extra_ptr = np.concatenate([[0], np.cumsum(count[extra_nodes] - slots)]).astype(np.int64)
    extra_elems = code[~keep]
    return Links(elem_nodes[:, 0].astype(np.uint32), elem_nodes[:, 1].astype(np.uint32),
                 node_elems, extra_nodes, extra_ptr, extra_elems)


def make_work(n_nodes: int, n_elems: int, chunks: int = 1, block: int = BLOCK,
              elem_nodes: np.ndarray | None = None) -> Work:
    """A :class:`Work` for a model, with gather buffers for ``chunks`` threads and blocks of
    ``block`` elements (and nodes). With ``elem_nodes`` (m, 2) the threads take the element
    blocks in :func:`thread_order`, else in element order (one thread: the order is not
    used)."""
    blocks = max(1, -(-n_elems // block))
    order = (thread_order(elem_nodes, block) if elem_nodes is not None
             else np.arange(blocks, dtype=np.int64))
    return Work(np.zeros((n_nodes, 3)), np.zeros(n_elems), np.zeros(n_nodes, np.bool_),
                np.zeros((3, n_elems + 1)),
                np.zeros((chunks, 8, block)),
                np.zeros((blocks, 8)),
                np.zeros((max(1, -(-n_nodes // block)), 5)),
                order)


def thread_order(elem_nodes: np.ndarray, block: int = BLOCK) -> np.ndarray:
    """The element blocks of ``block`` elements sorted (stably) by the mean node index of
    their elements' ends.

    The node passes give each thread one contiguous range of nodes, and they write the
    positions the next element pass reads. A thread that took a contiguous run of blocks in
    element order would read nodes that the other thread has just written wherever the
    element order does not follow the node order (a web lists all its x-lines, then all its
    y-lines: each half of the elements spans every node), and the cache lines of the
    positions then travel between the cores every step (measured: two threads 1.16x one on
    the 80 400-element web, 1.96x with the elements sorted). Sorted blocks keep a thread's
    elements on its own nodes. Which thread computes a block does not change a bit: each
    block writes its own elements and its own sums."""
    m = len(elem_nodes)
    if m == 0:
        return np.zeros(1, np.int64)
    starts = np.arange(0, m, block)
    ends = np.asarray(elem_nodes, np.float64).sum(axis=1)
    key = np.add.reduceat(ends, starts) / np.diff(np.append(starts, m))
    return np.argsort(key, kind="stable").astype(np.int64)


@njit(inline="always", error_model="numpy")
def gather_ends(first, second, x, buf, row, lo, hi):
    """buf[row + d, k] = x[j, d] - x[i, d] of elements lo + k < hi (x: positions or
    velocities)."""
    for k in range(hi - lo):
        e = np.uint64(lo + k)
        i = first[e]
        j = second[e]
        buf[row, k] = x[j, 0] - x[i, 0]
        buf[row + 1, k] = x[j, 1] - x[i, 1]
        buf[row + 2, k] = x[j, 2] - x[i, 2]


@njit(inline="always", error_model="numpy")
def plain_block(inv_rest, ea, ef, buf, lo, hi):
    """f_e of the elements lo..hi-1 from their gathered end differences: the straight loop
    (no damping, no records) that LLVM vectorises."""
    for k in range(hi - lo):
        e = np.uint64(lo + k)
        dx, dy, dz = buf[0, k], buf[1, k], buf[2, k]
        inv, strain = length_strain(dx, dy, dz, inv_rest[e])
        c = ea[e] * strain * inv  # N / L, N = EA max(eps, 0)
        ef[0, e] = c * dx
        ef[1, e] = c * dy
        ef[2, e] = c * dz


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def full_block(inv_rest, ea, cdamp, damped, ef, tension, buf, lo, hi, record, eout, b):
    """f_e of the elements lo..hi-1 with the damper and the records: a straight loop that
    keeps each element's strain energy (buffer row 6), tension (``tension``) and damping
    power (row 3), then their sums in element order: eout[b, 0] strain energy (record
    steps), eout[b, 1] max tension (record steps), eout[b, 2] damping power."""
    n = hi - lo
    for k in range(n):
        e = np.uint64(lo + k)
        dx, dy, dz = buf[0, k], buf[1, k], buf[2, k]
        inv, strain = length_strain(dx, dy, dz, inv_rest[e])
        n_el = ea[e] * strain
        n_tot = n_el
        if damped:  # N_d = c dL/dt while taut, total tension never negative
            ldot = rate(dx, dy, dz, inv, buf[3, k], buf[4, k], buf[5, k])
            n_tot = damped_tension(n_el, strain, cdamp[e], ldot)
            buf[3, k] = (n_tot - n_el) * ldot  # damping power
        buf[6, k] = 0.5 * n_el * strain / inv_rest[e]  # U = EA eps^2 L0 / 2
        tension[e] = n_tot
        c = n_tot * inv
        ef[0, e] = c * dx
        ef[1, e] = c * dy
        ef[2, e] = c * dz
    se = 0.0
    tmax = 0.0
    pdamp = 0.0
    for k in range(n):
        if record:
            se += buf[6, k]
            tmax = max(tmax, tension[lo + k])
        if damped:
            pdamp += buf[3, k]
    eout[b, 0] = se
    eout[b, 1] = tmax
    eout[b, 2] = pdamp


@njit(cache=True, error_model="numpy", no_cpython_wrapper=True)
def element_block(inv_rest, ea, cdamp, damped, first, second, pos, vel, ef, tension, eout, buf,
                  b, record):
    """Element block b: its force vectors into ``ef``, its sums into ``eout[b]``; ``buf``
    (8, block) is the chunk's gather buffer. (Arrays, not the Elements, Links and Work
    tuples: numba counts a reference for every array of every tuple a call hands over, and
    this runs once per block and step.)"""
    m = inv_rest.shape[0]
    lo = b * buf.shape[1]
    hi = min(lo + buf.shape[1], m)
    gather_ends(first, second, pos, buf, 0, lo, hi)
    if not (record or damped):
        plain_block(inv_rest, ea, ef, buf, lo, hi)
        eout[b, 0] = 0.0
        eout[b, 1] = 0.0
        eout[b, 2] = 0.0
        return
    if damped:
        gather_ends(first, second, vel, buf, 3, lo, hi)
    full_block(inv_rest, ea, cdamp, damped, ef, tension, buf, lo, hi, record, eout, b)


@njit(cache=True, parallel=True)
def element_threads(elems, links, pos, vel, work, record):
    """:func:`element_block` of every block, thread c taking the c-th of ``nc`` equal runs of
    the blocks in ``work.order``."""
    nc = work.buf.shape[0]
    nb = work.eout.shape[0]
    inv_rest, ea, cdamp, damped = elems.inv_rest, elems.ea, elems.cdamp, elems.damped
    first, second, ef, tension, eout = links.first, links.second, work.ef, work.tension, work.eout
    order = work.order
    for c in prange(nc):
        buf = work.buf[c]
        for q in range(nb * c // nc, nb * (c + 1) // nc):
            b = order[q]
            element_block(inv_rest, ea, cdamp, damped, first, second, pos, vel, ef, tension, eout,
                          buf, b, record)


@njit(cache=True, no_cpython_wrapper=True)
def node_block(links, ef, force, lo, hi):
    """force[i] = the sum of the element forces on node i, for nodes lo..hi-1, in element
    order (-f_e where the node is the element's second end)."""
    ne = links.node_elems
    fx, fy, fz = ef[0], ef[1], ef[2]
    for q in range(hi - lo):
        i = np.uint64(lo + q)
        sx = 0.0
        sy = 0.0
        sz = 0.0
        for s in range(ne.shape[1]):
            v = ne[i, s]
            e = v & np.uint32(0x7FFFFFFF)
            if v >= np.uint32(0x80000000):
                sx -= fx[e]
                sy -= fy[e]
                sz -= fz[e]
            else:
                sx += fx[e]
                sy += fy[e]
                sz += fz[e]
        force[i, 0] = sx
        force[i, 1] = sy
        force[i, 2] = sz
    extra = links.extra_nodes
    for p in range(extra.shape[0]):  # nodes with more elements than slots: the rest
        i = extra[p]
        if lo <= i < hi:
            for s in range(links.extra_ptr[p], links.extra_ptr[p + 1]):
                v = links.extra_elems[s]
                e = v & np.uint32(0x7FFFFFFF)
                sign = -1.0 if v >= np.uint32(0x80000000) else 1.0
                for d in range(3):
                    force[i, d] += sign * ef[d, e]


@njit(cache=True, parallel=True)
def node_threads(links, ef, force, chunks):
    """:func:`node_block` over every node, the node blocks in one contiguous chunk per
    thread (``chunks`` threads)."""
    n = force.shape[0]
    for c in prange(chunks):
        node_block(links, ef, force, n * c // chunks, n * (c + 1) // chunks)


@njit(cache=True, no_cpython_wrapper=True)
def sum_blocks(eout):
    """(strain energy, max tension, damping power) over the element blocks, in block order."""
    se = 0.0
    tmax = 0.0
    pdamp = 0.0
    for b in range(eout.shape[0]):
        se += eout[b, 0]
        tmax = max(tmax, eout[b, 1])
        pdamp += eout[b, 2]
    return se, tmax, pdamp


@njit(cache=True)
def element_forces(elems, links, pos, vel, work, record, threads):
    """Every element's force vector at x_n into ``work.ef``. Returns (strain energy [J] and
    max tension [N] on record steps, damping power [W]). ``threads`` None: one thread (numba
    compiles no thread kernel); otherwise each chunk of the workspace runs on a thread."""
    if threads is None:
        buf = work.buf[0]
        inv_rest, ea, cdamp, damped = elems.inv_rest, elems.ea, elems.cdamp, elems.damped
        first, second = links.first, links.second
        ef, tension, eout = work.ef, work.tension, work.eout
        for b in range(eout.shape[0]):
            element_block(inv_rest, ea, cdamp, damped, first, second, pos, vel, ef, tension,
                          eout, buf, b, record)
    else:
        element_threads(elems, links, pos, vel, work, record)
    return sum_blocks(work.eout)


@njit(cache=True)
def node_forces(links, work, threads):
    """``work.force`` (n, 3) = the element forces of ``work.ef`` summed per node."""
    n = work.force.shape[0]
    size = work.buf.shape[2]
    if threads is None:
        for b in range(-(-n // size)):
            node_block(links, work.ef, work.force, b * size, min(n, (b + 1) * size))
    else:
        node_threads(links, work.ef, work.force, work.buf.shape[0])


def internal_forces(elems, links, pos, vel, work, record):
    """One thread: every element's force vector and tension (``work.ef``, ``work.tension``)
    and their sums per node (``work.force``) at the given positions. Returns (strain energy
    [J], max tension [N], damping power [W]); the first two on ``record`` only, which also
    writes the tensions. Python calling the step loop's own compiled passes with the same
    argument types (an explicit None for the threads, ``record`` a bool from Python, never
    a literal), so nothing is compiled for it; a kernel of its own cost about 0.5 s of cold
    compile, LLVM optimising and emitting the passes' code once more."""
    se, tmax, pdamp = element_forces(elems, links, pos, vel, work, bool(record), None)
    node_forces(links, work, None)
    return se, tmax, pdamp
