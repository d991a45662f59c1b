"""A node-anchored blocked sweep of the bare step, against production's loop and C ``anchor``.

    python benchmarks/anchor_sweep.py [--rounds 5] [--steps 300] [--repeat 3] [--replot]

Prototype (bare loop only: no hub, contact, damping, records) of a step restructured as
one sweep over node blocks. Preprocessing orients every element so that its first node is
the smaller index (the anchor) and sorts the elements by anchor (stable); the elements
anchored in a block of B consecutive nodes [lo, hi) are then one contiguous range. Per
step, for each node block in order: (a) gather the anchored elements' end differences into
a small buffer and compute their force vectors in a straight loop that LLVM vectorises
(the law of fe.law, as production's ``plain_block``); (b) add +f_e into F[i] and -f_e into
F[j] (j > i: this block or a later one); (c) advance the block's nodes: v += dt F / m,
x += dt v, F = 0. It is exact: when a block's nodes move, every element touching them has
been added (its anchor is in this block or an earlier one), and no element gathered later
reads a moved position (its nodes are >= the block's lo).

Variants (one thread): ``csr`` (general: one element range per node block; node arrays
(n, 3)) with B = 128, 512, 2048 nodes per block; ``csr (n,4)`` (node arrays padded to (n, 4):
numba compiles the same code, the loops still touch three columns); ``split`` (the scatter as
two loops, all -f_e then all +f_e, against a store-to-load chain); ``slots`` (the C code's
layout: S slots per node, empty ones zero-force; only F_j -= f_e scattered, each node's +f_e
added in its update; S a run-time value); ``soa`` (csr on node arrays (3, n)); ``slot-major``
(the slots per node block stored slot-major, node arrays (3, n), S frozen into the kernel:
every pass a unit-stride loop). Two threads (slot-major): one node range of whole blocks per
thread; the elements joining the two ranges are left out of the sweep and add their forces
before it each step.

Correctness: forces and x, v after 1 and N steps against production's passes (fe.forces
element and node passes + the bare kick-drift of feature_cost's reference loop) on the same
state, on the web's own element order and on the same web with its elements put in anchor
order (where each node's sum runs in production's order, so the bits must agree).

Timing, interleaved per round: every prototype variant (fastest of ``--repeat`` loops of
``--steps`` steps), production's bare loop (benchmarks/throughput.py ``measure``, as
benchmarks/limit_ratio.py runs it), production's force passes alone on the web's element
order and on anchor order (benchmarks/feature_cost.py ``reference_advance``), and C
``anchor`` built and run by limit_ratio.py's functions; then the same on two threads
(slot-major, production, C anchor); medians over the rounds. Writes
benchmarks/results/anchor_sweep.json and a bar chart anchor_sweep.png.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import NamedTuple

import numba
import numpy as np
from feature_cost import reference_advance
from limit_ratio import LIMIT, build, run_c
from numba import njit, prange
from throughput import load_average, machine, measure, spinning_web

from spinweb_fe.fe.forces import gather_ends, make_links, make_work
from spinweb_fe.fe.law import length_strain
from spinweb_fe.fe.model import choose_dt
from spinweb_fe.fe.step import NodeMotion, kick_drift

OUT = Path(__file__).resolve().parent / "results" / "anchor_sweep.json"
MESH_WIDTH = 0.5


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


# --- set-up, checks, timing -----------------------------------------------------------------

KERNELS = {"csr": advance_csr, "split": advance_split, "slots": advance_slots,
           "soa": advance_soa}
SLOT_KERNELS = {}  # slot count: compiled slot-major kernel
VARIANTS = {  # name: (kernel, nodes per block, node array layout)
    "csr B=128": ("csr", 128, "n3"), "csr B=512": ("csr", 512, "n3"),
    "csr B=2048": ("csr", 2048, "n3"), "csr (n,4) B=512": ("csr", 512, "n4"),
    "split B=512": ("split", 512, "n3"), "slots B=512": ("slots", 512, "n3"),
    "soa (3,n) B=512": ("soa", 512, "3n"), "soa (3,n) B=2048": ("soa", 2048, "3n"),
    "slot-major (3,n) B=512": ("slotmajor", 512, "3n"),
    "slot-major (3,n) B=2048": ("slotmajor", 2048, "3n"),
}


def prepare(elems, n_nodes, variant):
    """(kernel, layout, buffer, node array layout) of a variant."""
    kind, block, nodes = VARIANTS[variant]
    if kind == "slotmajor":
        lay = make_slot_major(elems, n_nodes, block)
        if lay.slots not in SLOT_KERNELS:
            SLOT_KERNELS[lay.slots] = make_slot_kernel(lay.slots)
        return SLOT_KERNELS[lay.slots][0], lay, np.zeros((3, block * lay.slots)), nodes
    lay = (make_slots if kind == "slots" else make_anchored)(elems, n_nodes, block)
    return KERNELS[kind], lay, np.zeros((3, max_block_elems(lay))), nodes


def node_arrays(state, nodes):
    """Copies of positions and velocities in the variant's layout, and a zero force."""
    n = len(state.node_pos)
    if nodes == "3n":
        return (np.ascontiguousarray(state.node_pos.T), np.ascontiguousarray(state.node_vel.T),
                np.zeros((3, n)))
    w = 4 if nodes == "n4" else 3
    pos, vel = np.zeros((n, w)), np.zeros((n, w))
    pos[:, :3] = state.node_pos
    vel[:, :3] = state.node_vel
    return pos, vel, np.zeros((n, w))


def back(a, nodes):
    return a.T if nodes == "3n" else a[:, :3]


def reordered(kernel):
    """The kernel's elements put in anchor order (first < second, sorted by first), with
    their Links: the same web; production's passes on it sum per node in anchor order."""
    e = kernel.elements
    order, first, second = anchor_order(e.nodes)
    nodes = np.stack([first, second], axis=1)
    elems = e._replace(nodes=nodes, rest_len=e.rest_len[order], inv_rest=e.inv_rest[order],
                       ea=e.ea[order], cdamp=e.cdamp[order])
    return elems, make_links(nodes, len(kernel.nodes.mass))


def run_production(elems, links, state, inv_mass, dt, steps):
    """x, v after ``steps`` of production's passes (feature_cost's reference loop)."""
    pos, vel = state.node_pos.copy(), state.node_vel.copy()
    reference_advance(elems, links, pos, vel, inv_mass, make_work(len(pos), len(elems.ea)),
                      dt, steps)
    return pos, vel


def run_variant(elems, state, inv_mass, dt, steps, variant):
    fn, lay, buf, nodes = prepare(elems, len(state.node_pos), variant)
    pos, vel, force = node_arrays(state, nodes)
    fn(lay, pos, vel, inv_mass, force, buf, dt, steps)
    return back(pos, nodes), back(vel, nodes)


def checks(kernel, state, dt, steps):
    """Prototype against production's passes: forces, and x, v after 1 and ``steps`` steps,
    on the web's element order and on anchor order, from a state in tension."""
    from spinweb_fe.fe.forces import internal_forces

    inv_mass = kernel.nodes.inv_mass
    pos0, vel0 = run_production(kernel.elements, kernel.links, state, inv_mass, dt, 200)
    st = state._replace(node_pos=pos0, node_vel=vel0)
    out = {"state": "after 200 production steps from the unstretched start (all forces "
                    "zero there)"}
    for order, (elems, links) in {"web order": (kernel.elements, kernel.links),
                                  "anchor order": reordered(kernel)}.items():
        work = make_work(len(pos0), len(elems.ea))
        internal_forces(elems, links, pos0, vel0, work, False)
        lay = make_anchored(elems, len(pos0), 512)
        f = np.zeros_like(pos0)
        forces_csr(lay, pos0, f, np.zeros((3, max_block_elems(lay))))
        rec = {"forces_bit_identical": bool(np.array_equal(f, work.force)),
               "forces_max_abs_diff_over_max_abs": float(np.abs(f - work.force).max()
                                                         / np.abs(work.force).max())}
        for k in (1, steps):
            xp, vp = run_production(elems, links, st, inv_mass, dt, k)
            for variant in VARIANTS:
                x, v = run_variant(elems, st, inv_mass, dt, k, variant)
                rec[f"{variant}, {k} step(s)"] = {
                    "bit_identical": bool(np.array_equal(x, xp) and np.array_equal(v, vp)),
                    "pos_max_abs_diff_m": float(np.abs(x - xp).max()),
                    "vel_max_abs_diff_m_per_s": float(np.abs(v - vp).max())}
        out[order] = rec
    return out


def time_variant(elems, state, inv_mass, dt, steps, repeat, variant):
    """Element-updates/s of the fastest of ``repeat`` loops of ``steps`` steps."""
    fn, lay, buf, nodes = prepare(elems, len(state.node_pos), variant)
    best = np.inf
    for _ in range(repeat):
        pos, vel, force = node_arrays(state, nodes)
        t0 = time.perf_counter()
        fn(lay, pos, vel, inv_mass, force, buf, dt, steps)
        best = min(best, time.perf_counter() - t0)
    return len(elems.ea) * steps / best


def time_threads(elems, state, inv_mass, dt, steps, repeat, block, threads):
    """Element-updates/s of the slot-major sweep on ``threads`` node ranges (fastest of
    ``repeat`` loops)."""
    lay, cross, bounds = split_ranges(make_slot_major(elems, len(state.node_pos), block),
                                      len(state.node_pos), threads)
    if lay.slots not in SLOT_KERNELS:
        SLOT_KERNELS[lay.slots] = make_slot_kernel(lay.slots)
    fn = SLOT_KERNELS[lay.slots][1]
    bufs = np.zeros((threads, 3, block * lay.slots))
    best = np.inf
    for _ in range(repeat):
        pos, vel, force = node_arrays(state, "3n")
        t0 = time.perf_counter()
        fn(lay, cross, bounds, pos, vel, inv_mass, force, bufs, dt, steps)
        best = min(best, time.perf_counter() - t0)
    return len(elems.ea) * steps / best, (pos.T, vel.T)


def time_floor(elems, links, state, inv_mass, dt, steps, repeat):
    """Element-updates/s of production's force passes + bare kick-drift (feature_cost's
    floor) on the given element order."""
    work = make_work(len(state.node_pos), len(elems.ea))
    best = np.inf
    for _ in range(repeat):
        pos, vel = state.node_pos.copy(), state.node_vel.copy()
        t0 = time.perf_counter()
        reference_advance(elems, links, pos, vel, inv_mass, work, dt, steps)
        best = min(best, time.perf_counter() - t0)
    return len(elems.ea) * steps / best


def compile_times(kernel, state, dt):
    """Cold compile [s] of each prototype kernel: its first call (1 step) less a warm one
    (the kernels are not cached: every run of this script compiles them)."""
    out = {}
    first_of = {}
    for variant, (kind, _, _) in VARIANTS.items():
        first_of.setdefault(kind, variant)
    for kind, variant in first_of.items():
        fn, lay, buf, nodes = prepare(kernel.elements, len(state.node_pos), variant)
        pos, vel, force = node_arrays(state, nodes)
        t0 = time.perf_counter()
        fn(lay, pos, vel, kernel.nodes.inv_mass, force, buf, dt, 1)
        cold = time.perf_counter() - t0
        t0 = time.perf_counter()
        fn(lay, pos, vel, kernel.nodes.inv_mass, force, buf, dt, 1)
        name = f"advance_{kind}" if kind != "slotmajor" else f"slot-major, {lay.slots} slots"
        out[name] = cold - (time.perf_counter() - t0)
    return out


def plot(out, path):
    """Bars of the median element-updates/s of every loop."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    med = out["median_element_updates_per_s"]
    names = list(med)
    fig, ax = plt.subplots(figsize=(7.6, 4.2))
    bars = ax.barh(range(len(names)), [med[k] for k in names], color=[
        "tab:red" if k.startswith("C ") else "tab:gray" if k.startswith("production")
        else "tab:blue" for k in names])
    ratio = out["ratio_to_c_anchor"]
    ax.bar_label(bars, labels=[f"{med[k]:.3g} ({ratio[k]:.2f})" for k in names], fontsize=7)
    ax.set_yticks(range(len(names)), names, fontsize=7)
    ax.invert_yaxis()
    m = out["machine"]
    ax.set(xlabel="element-updates / s (ratio to C anchor on as many threads)",
           title=f"80 400-element web, {m['processor']} {m['cpu_family_model']} {m['isa']}, "
                 f"{out['date']}")
    ax.title.set_fontsize(8)
    ax.set_xlim(0, 1.25 * max(med.values()))
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--steps", type=int, default=300, help="steps of each sample")
    ap.add_argument("--repeat", type=int, default=3, help="loops per sample (fastest kept)")
    ap.add_argument("--replot", action="store_true", help="redraw the plot from the JSON only")
    args = ap.parse_args(argv)
    if args.replot:
        plot(json.loads(OUT.read_text()), OUT.with_suffix(".png"))
        return 0
    if shutil.which("gcc") is None or not LIMIT.is_file():
        print(f"anchor_sweep: needs gcc and {LIMIT}", file=sys.stderr)
        return 2
    model, _, state = spinning_web(MESH_WIDTH)
    kernel = model.kernel
    inv_mass = kernel.nodes.inv_mass
    dt = choose_dt(model, 0.9)
    compile_s = compile_times(kernel, state, dt)
    check = checks(kernel, state, dt, 100)
    sorted_elems, sorted_links = reordered(kernel)
    mdt = 0.9 * MESH_WIDTH / (180e9 / 1540.0) ** 0.5  # the C problem's dt, as limit_ratio.py
    measure("spinning-web", MESH_WIDTH, 0.0, 1)  # compile / cache load, not timed
    samples = {}
    with tempfile.TemporaryDirectory() as tmp:
        exe = build(Path(tmp))
        for _ in range(args.rounds):
            runs = {v: (lambda v=v: time_variant(kernel.elements, state, inv_mass, dt,
                                                 args.steps, args.repeat, v))
                    for v in VARIANTS}
            runs["production bare loop (simulate)"] = lambda: measure(
                "spinning-web", MESH_WIDTH, args.steps * mdt, 1, cfl=0.9,
                repeat=args.repeat)["element_updates_per_s"]
            runs["production passes, web order"] = lambda: time_floor(
                kernel.elements, kernel.links, state, inv_mass, dt, args.steps, args.repeat)
            runs["production passes, anchor order"] = lambda: time_floor(
                sorted_elems, sorted_links, state, inv_mass, dt, args.steps, args.repeat)
            runs["C anchor"] = lambda: run_c(exe, "anchor", "fine", 1, args.steps,
                                             args.repeat)[0]
            for name, fn in runs.items():
                load = load_average()
                eu = fn()
                samples.setdefault(name, []).append((eu, load))
                print(f"{name:34s} {eu:.3e} element-updates/s (load {load:.2f})", flush=True)
        # two threads: the slot-major sweep on two node ranges, production, C anchor
        numba.set_num_threads(2)
        measure("spinning-web", MESH_WIDTH, 0.0, 2)  # compile / cache load, not timed
        t0 = time.perf_counter()
        time_threads(kernel.elements, state, inv_mass, dt, 1, 1, 2048, 2)
        compile_s["slot-major threads (parallel=True), first call of 1 step"] = (
            time.perf_counter() - t0)
        _, (x2, v2) = time_threads(kernel.elements, state, inv_mass, dt, 100, 1, 2048, 2)
        xp, vp = run_production(kernel.elements, kernel.links, state, inv_mass, dt, 100)
        check["2 threads slot-major B=2048, 100 steps from the start, web order"] = {
            "bit_identical": bool(np.array_equal(x2, xp) and np.array_equal(v2, vp)),
            "pos_max_abs_diff_m": float(np.abs(x2 - xp).max()),
            "vel_max_abs_diff_m_per_s": float(np.abs(v2 - vp).max())}
        for _ in range(args.rounds):
            runs = {f"slot-major (3,n) B={b}, 2 threads": (
                lambda b=b: time_threads(kernel.elements, state, inv_mass, dt, args.steps,
                                         args.repeat, b, 2)[0]) for b in (512, 2048)}
            runs["production bare loop (simulate), 2 threads"] = lambda: measure(
                "spinning-web", MESH_WIDTH, args.steps * mdt, 2, cfl=0.9,
                repeat=args.repeat)["element_updates_per_s"]
            runs["C anchor, 2 threads"] = lambda: run_c(exe, "anchor", "fine", 2, args.steps,
                                                        args.repeat)[0]
            for name, fn in runs.items():
                load = load_average()
                eu = fn()
                samples.setdefault(name, []).append((eu, load))
                print(f"{name:34s} {eu:.3e} element-updates/s (load {load:.2f})", flush=True)
    med = {k: statistics.median(e for e, _ in v) for k, v in samples.items()}
    out = {"machine": machine(), "mesh_width": MESH_WIDTH, "elements": model.n_elems,
           "nodes": model.n_nodes, "steps": args.steps, "rounds": args.rounds,
           "repeat": args.repeat, "threads": 1,
           "median_element_updates_per_s": med,
           "median_ns_per_element_update": {k: 1e9 / v for k, v in med.items()},
           "ratio_to_c_anchor": {k: v / med["C anchor, 2 threads" if "2 threads" in k
                                             else "C anchor"] for k, v in med.items()},
           # C anchor's samples spread widely (bimodal on this shared VM): also the ratio
           # to its fastest sample
           "c_anchor_min_max": {k: [min(e for e, _ in samples[k]), max(e for e, _ in samples[k])]
                                for k in ("C anchor", "C anchor, 2 threads")},
           "ratio_to_fastest_c_anchor": {k: v / max(e for e, _ in samples[
               "C anchor, 2 threads" if "2 threads" in k else "C anchor"])
               for k, v in med.items()},
           "cold_compile_s": compile_s, "checks": check,
           "samples": {k: [{"element_updates_per_s": e, "load_1min": ld} for e, ld in v]
                       for k, v in samples.items()},
           "date": time.strftime("%Y-%m-%d %H:%M %Z")}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1))
    plot(out, OUT.with_suffix(".png"))
    print(json.dumps({k: out[k] for k in ("median_element_updates_per_s", "ratio_to_c_anchor",
                                          "cold_compile_s")}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
