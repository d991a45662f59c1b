"""Layouts and kernels of the node-anchored sweep prototype: bare loop only (no hub,
contact, damping, records); what each variant is and how it is timed: anchor_sweep.py."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from spinweb_fe.fe.forces import gather_ends
from spinweb_fe.fe.law import length_strain


class Anchored(NamedTuple):
    """Elements in anchor order (first < second, sorted by first) and their node blocks.

    first, second : (m,) uint32 end nodes; inv_rest, ea : (m,) float64 [1/m], [N];
    elem_start : (blocks + 1,) uint64: the elements anchored in node block b are
    elem_start[b]..elem_start[b + 1] - 1; block : nodes per block."""

    first: np.ndarray
    second: np.ndarray
    inv_rest: np.ndarray
    ea: np.ndarray
    elem_start: np.ndarray
    block: int


class Slots(NamedTuple):
    """The C code's layout: S slots per node q (elements anchored at q, in anchor order),
    empty ones j = q with 1/L0 = 0 (zero force). other, inv_rest, ea : (n S,)."""

    other: np.ndarray
    inv_rest: np.ndarray
    ea: np.ndarray
    slots: int
    block: int


def anchor_order(elem_nodes):
    """(order, first, second): the stable permutation that sorts the elements by their
    smaller node, and the oriented ends in that order."""
    lo = elem_nodes.min(axis=1)
    hi = elem_nodes.max(axis=1)
    order = np.argsort(lo, kind="stable")
    return order, lo[order], hi[order]


def make_anchored(elems, n_nodes, block) -> Anchored:
    order, first, second = anchor_order(elems.nodes)
    bounds = np.minimum(np.arange(0, n_nodes + block, block), n_nodes)
    if bounds[-1] != n_nodes:
        bounds = np.append(bounds, n_nodes)
    start = np.searchsorted(first, bounds[:-1], side="left")
    start = np.append(start, len(first)).astype(np.uint64)
    return Anchored(first.astype(np.uint32), second.astype(np.uint32),
                    elems.inv_rest[order].copy(), elems.ea[order].copy(), start, block)


def make_slots(elems, n_nodes, block) -> Slots:
    order, first, second = anchor_order(elems.nodes)
    count = np.bincount(first, minlength=n_nodes)
    s = int(count.max())
    rank = np.arange(len(first)) - np.concatenate([[0], np.cumsum(count)])[first]
    other = np.repeat(np.arange(n_nodes), s).astype(np.uint32)  # empty: j = q, d = 0
    inv_rest = np.zeros(n_nodes * s)
    ea = np.zeros(n_nodes * s)
    k = first * s + rank
    other[k] = second
    inv_rest[k] = elems.inv_rest[order]
    ea[k] = elems.ea[order]
    return Slots(other, inv_rest, ea, s, block)


def max_block_elems(lay) -> int:
    if isinstance(lay, Slots):
        return lay.block * lay.slots
    return int(np.diff(lay.elem_start.astype(np.int64)).max())


# --- kernels: (a) element vectors, (b) scatter, (c) node update ------------------------------

@njit(inline="always", error_model="numpy")
def element_vectors(inv_rest, ea, buf, lo, hi):
    """Rows 0-2 of buf: end differences in, force vectors f_e = N d / |d| out (the straight
    loop of production's plain_block, written in place)."""
    for k in range(hi - lo):
        e = np.uint64(lo + k)
        dx, dy, dz = buf[0, k], buf[1, k], buf[2, k]
        inv, strain = length_strain(dx, dy, dz, inv_rest[e])
        c = ea[e] * strain * inv  # N / L, N = EA max(eps, 0)
        buf[0, k] = c * dx
        buf[1, k] = c * dy
        buf[2, k] = c * dz


@njit(inline="always", error_model="numpy")
def scatter_pairs(first, second, force, buf, lo, hi):
    """force[i] += f_e, force[j] -= f_e for the elements lo..hi-1, in element order."""
    for k in range(hi - lo):
        e = np.uint64(lo + k)
        i = first[e]
        j = second[e]
        for d in range(3):
            force[i, d] += buf[d, k]
            force[j, d] -= buf[d, k]


@njit(inline="always", error_model="numpy")
def kick_drift_zero(pos, vel, force, inv_mass, dt, lo, hi):
    """v += dt F / m, x += dt v (nodes with active mass), F = 0, for nodes lo..hi-1."""
    for q in range(hi - lo):
        i = np.uint64(lo + q)
        im = inv_mass[i]
        h = dt if im > 0.0 else 0.0
        for d in range(3):
            v = vel[i, d] + dt * force[i, d] * im
            vel[i, d] = v
            pos[i, d] += h * v
            force[i, d] = 0.0


@njit(error_model="numpy")
def advance_csr(lay, pos, vel, inv_mass, force, buf, dt, nsteps):
    """nsteps of the node-anchored sweep, general layout; pos/vel/force (n, 3) or (n, 4)
    (the fourth column unused), force zero on entry and exit."""
    n = pos.shape[0]
    nb = lay.elem_start.shape[0] - 1
    for _ in range(nsteps):
        for b in range(nb):
            lo = lay.elem_start[b]
            hi = lay.elem_start[b + 1]
            gather_ends(lay.first, lay.second, pos, buf, 0, lo, hi)
            element_vectors(lay.inv_rest, lay.ea, buf, lo, hi)
            scatter_pairs(lay.first, lay.second, force, buf, lo, hi)
            kick_drift_zero(pos, vel, force, inv_mass, dt, b * lay.block,
                            min(n, (b + 1) * lay.block))


@njit(error_model="numpy")
def forces_csr(lay, pos, force, buf):
    """The internal forces alone (no update) into force (n, 3), zero on entry."""
    for b in range(lay.elem_start.shape[0] - 1):
        lo = lay.elem_start[b]
        hi = lay.elem_start[b + 1]
        gather_ends(lay.first, lay.second, pos, buf, 0, lo, hi)
        element_vectors(lay.inv_rest, lay.ea, buf, lo, hi)
        scatter_pairs(lay.first, lay.second, force, buf, lo, hi)


@njit(inline="always", error_model="numpy")
def gather_slots(other, pos, buf, s, lo, hi):
    """buf[d, k] = x[j, d] - x[q, d] of the slots of nodes lo..hi-1 (k = (q - lo) s + slot)."""
    for q in range(hi - lo):
        i = np.uint64(lo + q)
        for t in range(s):
            k = q * s + t
            j = other[i * np.uint64(s) + np.uint64(t)]
            for d in range(3):
                buf[d, k] = pos[j, d] - pos[i, d]


@njit(inline="always", error_model="numpy")
def update_slots(pos, vel, force, inv_mass, buf, s, dt, lo, hi):
    """Each node's +f_e (its slots, in order) added to its force in registers, then
    v += dt F / m, x += dt v, F = 0."""
    for q in range(hi - lo):
        i = np.uint64(lo + q)
        im = inv_mass[i]
        h = dt if im > 0.0 else 0.0
        for d in range(3):
            f = force[i, d]
            for t in range(s):
                f += buf[d, q * s + t]
            v = vel[i, d] + dt * f * im
            vel[i, d] = v
            pos[i, d] += h * v
            force[i, d] = 0.0


@njit(error_model="numpy")
def advance_slots(lay, pos, vel, inv_mass, force, buf, dt, nsteps):
    """nsteps of the sweep in the slot layout: only F_j -= f_e scattered."""
    n = pos.shape[0]
    s = lay.slots
    nb = -(-n // lay.block)
    for _ in range(nsteps):
        for b in range(nb):
            lo = b * lay.block
            hi = min(n, lo + lay.block)
            gather_slots(lay.other, pos, buf, s, lo, hi)
            element_vectors(lay.inv_rest, lay.ea, buf, np.uint64(lo * s), np.uint64(hi * s))
            for k in range((hi - lo) * s):
                j = lay.other[np.uint64(lo * s + k)]
                for d in range(3):
                    force[j, d] -= buf[d, k]
            update_slots(pos, vel, force, inv_mass, buf, s, dt, lo, hi)


@njit(inline="always", error_model="numpy")
def scatter_minus_plus(first, second, force, buf, lo, hi):
    """The same adds as :func:`scatter_pairs` in two loops, all -f_e first, then all +f_e
    (no store-to-load chain from one element to the next; per node still in element
    order: every element where the node is second is anchored earlier)."""
    for k in range(hi - lo):
        j = second[np.uint64(lo + k)]
        for d in range(3):
            force[j, d] -= buf[d, k]
    for k in range(hi - lo):
        i = first[np.uint64(lo + k)]
        for d in range(3):
            force[i, d] += buf[d, k]


@njit(error_model="numpy")
def advance_split(lay, pos, vel, inv_mass, force, buf, dt, nsteps):
    """:func:`advance_csr` with :func:`scatter_minus_plus`."""
    n = pos.shape[0]
    nb = lay.elem_start.shape[0] - 1
    for _ in range(nsteps):
        for b in range(nb):
            lo = lay.elem_start[b]
            hi = lay.elem_start[b + 1]
            gather_ends(lay.first, lay.second, pos, buf, 0, lo, hi)
            element_vectors(lay.inv_rest, lay.ea, buf, lo, hi)
            scatter_minus_plus(lay.first, lay.second, force, buf, lo, hi)
            kick_drift_zero(pos, vel, force, inv_mass, dt, b * lay.block,
                            min(n, (b + 1) * lay.block))


@njit(inline="always", error_model="numpy")
def gather_soa(first, second, x, buf, lo, hi):
    """buf[d, k] = x[d, j] - x[d, i] (node arrays (3, n))."""
    for k in range(hi - lo):
        e = np.uint64(lo + k)
        i = first[e]
        j = second[e]
        for d in range(3):
            buf[d, k] = x[d, j] - x[d, i]


@njit(inline="always", error_model="numpy")
def scatter_soa(first, second, force, buf, lo, hi):
    for k in range(hi - lo):
        e = np.uint64(lo + k)
        i = first[e]
        j = second[e]
        for d in range(3):
            force[d, i] += buf[d, k]
            force[d, j] -= buf[d, k]


@njit(inline="always", error_model="numpy")
def kick_drift_soa(pos, vel, force, inv_mass, dt, lo, hi):
    """:func:`kick_drift_zero` on (3, n) arrays: three straight unit-stride loops."""
    for d in range(3):
        for q in range(hi - lo):
            i = np.uint64(lo + q)
            im = inv_mass[i]
            h = dt if im > 0.0 else 0.0
            v = vel[d, i] + dt * force[d, i] * im
            vel[d, i] = v
            pos[d, i] += h * v
            force[d, i] = 0.0


@njit(error_model="numpy")
def advance_soa(lay, pos, vel, inv_mass, force, buf, dt, nsteps):
    """:func:`advance_csr` with node arrays (3, n) (struct of arrays)."""
    n = pos.shape[1]
    nb = lay.elem_start.shape[0] - 1
    for _ in range(nsteps):
        for b in range(nb):
            lo = lay.elem_start[b]
            hi = lay.elem_start[b + 1]
            gather_soa(lay.first, lay.second, pos, buf, lo, hi)
            element_vectors(lay.inv_rest, lay.ea, buf, lo, hi)
            scatter_soa(lay.first, lay.second, force, buf, lo, hi)
            kick_drift_soa(pos, vel, force, inv_mass, dt, b * lay.block,
                           min(n, (b + 1) * lay.block))


def make_slot_major(elems, n_nodes, block):
    """:class:`Slots` laid out per node block slot-major: the slot t of node lo + q of block
    [lo, hi) is entry s lo + t (hi - lo) + q, so that each pass over a block is unit-stride
    (the update reads a node's slots t = 0, 1, ... as s straight rows)."""
    node_major = make_slots(elems, n_nodes, block)
    s = node_major.slots
    perm = np.empty(n_nodes * s, np.int64)
    for lo in range(0, n_nodes, block):
        hi = min(n_nodes, lo + block)
        q = np.arange(lo, hi)
        for t in range(s):
            perm[s * lo + t * (hi - lo) + (q - lo)] = s * q + t
    return Slots(node_major.other[perm], node_major.inv_rest[perm], node_major.ea[perm], s,
                 block)


def make_slot_kernel(s):
    """(advance, advance_threads): the sweep on node arrays (3, n) in the slot-major layout
    of :func:`make_slot_major` for s slots per node, s frozen into the compiled code (one
    kernel per slot count, chosen once per run) so that LLVM unrolls the slot loops."""

    @njit(error_model="numpy")
    def sweep(lay, pos, vel, inv_mass, force, buf, dt, nlo, nhi):
        """Node blocks of nlo..nhi-1 (nlo a multiple of the block): (a) gather x_j - x_q,
        (b) the element vectors (the straight loop), (c) F_j -= f_e, (d) per node F + its
        +f_e in slot order, kick-drift, F = 0, in unit-stride loops."""
        other = lay.other
        for lo in range(nlo, nhi, lay.block):
            nq = min(nhi, lo + lay.block) - lo
            base = np.uint64(s * lo)
            for t in range(s):
                for q in range(nq):
                    i = np.uint64(lo + q)
                    j = other[base + np.uint64(t * nq + q)]
                    for d in range(3):
                        buf[d, t * nq + q] = pos[d, j] - pos[d, i]
            element_vectors(lay.inv_rest, lay.ea, buf, base, base + np.uint64(s * nq))
            for k in range(s * nq):
                j = other[base + np.uint64(k)]
                for d in range(3):
                    force[d, j] -= buf[d, k]
            for d in range(3):
                for q in range(nq):
                    i = np.uint64(lo + q)
                    im = inv_mass[i]
                    h = dt if im > 0.0 else 0.0
                    f = force[d, i]
                    for t in range(s):
                        f += buf[d, t * nq + q]
                    v = vel[d, i] + dt * f * im
                    vel[d, i] = v
                    pos[d, i] += h * v
                    force[d, i] = 0.0

    @njit(error_model="numpy")
    def advance(lay, pos, vel, inv_mass, force, buf, dt, nsteps):
        for _ in range(nsteps):
            sweep(lay, pos, vel, inv_mass, force, buf, dt, 0, pos.shape[1])

    @njit(error_model="numpy", parallel=True)
    def advance_threads(lay, cross, bounds, pos, vel, inv_mass, force, bufs, dt, nsteps):
        """One node range per thread (``bounds``); the elements joining two ranges
        (``cross``, left out of ``lay``) add their forces first, then the ranges sweep."""
        for _ in range(nsteps):
            for c in range(cross.first.shape[0]):
                i = cross.first[c]
                j = cross.second[c]
                dx = pos[0, j] - pos[0, i]
                dy = pos[1, j] - pos[1, i]
                dz = pos[2, j] - pos[2, i]
                inv, strain = length_strain(dx, dy, dz, cross.inv_rest[c])
                k = cross.ea[c] * strain * inv
                force[0, i] += k * dx
                force[1, i] += k * dy
                force[2, i] += k * dz
                force[0, j] -= k * dx
                force[1, j] -= k * dy
                force[2, j] -= k * dz
            for t in prange(bounds.shape[0] - 1):
                sweep(lay, pos, vel, inv_mass, force, bufs[t], dt, bounds[t], bounds[t + 1])

    return advance, advance_threads


class Cross(NamedTuple):
    """Elements joining two threads' node ranges: ends, 1/L0, EA (k,)."""

    first: np.ndarray
    second: np.ndarray
    inv_rest: np.ndarray
    ea: np.ndarray


def split_ranges(lay: Slots, n_nodes, threads):
    """(layout without the crossing elements, Cross, bounds (threads + 1,) int64): node
    ranges of whole blocks, one per thread."""
    nb = -(-n_nodes // lay.block)
    bounds = np.minimum(np.array([nb * t // threads for t in range(threads + 1)]) * lay.block,
                        n_nodes).astype(np.int64)
    owner = np.searchsorted(bounds, np.arange(n_nodes), side="right") - 1
    # the node of every slot-major entry
    anchor = np.empty(len(lay.other), np.int64)
    for lo in range(0, n_nodes, lay.block):
        hi = min(n_nodes, lo + lay.block)
        anchor[lay.slots * lo:lay.slots * hi] = np.tile(np.arange(lo, hi), lay.slots)
    cut = owner[anchor] != owner[lay.other]
    other, inv_rest, ea = lay.other.copy(), lay.inv_rest.copy(), lay.ea.copy()
    cross = Cross(anchor[cut].astype(np.uint32), other[cut].copy(), inv_rest[cut].copy(),
                  ea[cut].copy())
    other[cut] = anchor[cut]  # an empty slot: zero force
    inv_rest[cut] = 0.0
    ea[cut] = 0.0
    return lay._replace(other=other, inv_rest=inv_rest, ea=ea), cross, bounds
