"""Does an owner-partitioned element pass make two threads pay? (issue #14, a measured idea)

    python benchmarks/owner_scatter.py [--mesh-width 0.5] [--rounds 5] [--reps 200]

The element pass of the bare loop on the spinning QuadQuad web of benchmarks/throughput.py,
three ways, timed in turn (A B C A B C ...) on one and two threads:

- ``serial``: the production kernel ``fe.step.accumulate_elements`` over every element;
- ``private``: what ``spinweb run --threads N`` does today: thread c adds its contiguous
  share of the elements into its own full force buffer, then the buffers are folded into the
  first (the node pass does the fold in production; here it is timed with the pass);
- ``owner``: the nodes cut into 16 contiguous blocks (independent of the thread count); the
  elements whose two nodes lie in one block are added straight into the one shared buffer
  by the thread that owns the block (no two threads touch a node), the few that cross a
  block boundary afterwards in one serial sweep. No private buffers, no fold, and the same
  sums for every thread count.

The forces of ``owner`` equal the serial pass's to round-off (the check is printed). Writes
benchmarks/results/owner_scatter.json (element-updates per second of each round, with the
machine).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from numba import njit, prange, set_num_threads
from throughput import machine, spinning_web

from spinweb_fe.fe.step import accumulate_elements, split

BLOCKS = 16
OUT = Path(__file__).resolve().parent / "results" / "owner_scatter.json"


@njit(cache=True)
def listed_elements(elems, pos, force, elist, lo, hi):
    """The production element law (undamped) over the listed elements elist[lo:hi]."""
    en, inv_rest, ea = elems.nodes, elems.inv_rest, elems.ea
    for k in range(lo, hi):
        e = elist[k]
        i, j = en[e, 0], en[e, 1]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        ln = np.sqrt(dx * dx + dy * dy + dz * dz + 1e-300)
        c = ea[e] * max(ln * inv_rest[e] - 1.0, 0.0) / ln
        force[i, 0] += c * dx
        force[i, 1] += c * dy
        force[i, 2] += c * dz
        force[j, 0] -= c * dx
        force[j, 1] -= c * dy
        force[j, 2] -= c * dz


@njit(cache=True, parallel=True)
def owner_pass(elems, pos, force, elist, eptr, nblocks):
    """Blocks in parallel into the shared buffer, then the crossing elements serially."""
    for b in prange(nblocks):
        listed_elements(elems, pos, force, elist, eptr[b], eptr[b + 1])
    listed_elements(elems, pos, force, elist, eptr[nblocks], eptr[nblocks + 1])


@njit(cache=True, parallel=True)
def private_pass(elems, pos, vel, forces, bounds):
    """Today's threaded pass: a buffer per thread, folded into the first."""
    for c in prange(forces.shape[0]):
        accumulate_elements(elems, pos, vel, forces[c], bounds[c], bounds[c + 1], False,
                            np.empty(0))
    for c in range(1, forces.shape[0]):
        for i in range(forces.shape[1]):
            for d in range(3):
                forces[0, i, d] += forces[c, i, d]
                forces[c, i, d] = 0.0


def owner_lists(nodes: np.ndarray, n: int, blocks: int):
    """(element list, pointers (blocks + 2,)): each block's inner elements, then the rest."""
    bounds = split(n, blocks)
    block = np.searchsorted(bounds, np.arange(n), side="right") - 1
    bi, bj = block[nodes[:, 0]], block[nodes[:, 1]]
    key = np.where(bi == bj, bi, blocks)
    order = np.argsort(key, kind="stable").astype(np.int64)
    ptr = np.concatenate([[0], np.cumsum(np.bincount(key, minlength=blocks + 1))])
    return order, ptr.astype(np.int64)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mesh-width", type=float, default=0.5)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--reps", type=int, default=200, help="calls per timing")
    a = ap.parse_args()
    model, _, state = spinning_web(a.mesh_width)
    elems = model.elements
    m, n = elems.nodes.shape[0], state.node_pos.shape[0]
    pos = state.node_pos.copy()
    pos[:, :2] *= 1.001  # every element taut
    vel = state.node_vel
    elist, eptr = owner_lists(elems.nodes, n, BLOCKS)

    fo, fs = np.zeros((n, 3)), np.zeros((n, 3))
    owner_pass(elems, pos, fo, elist, eptr, BLOCKS)
    accumulate_elements(elems, pos, vel, fs, 0, m, False, np.empty(0))
    diff = float(np.abs(fo - fs).max() / np.abs(fs).max())

    def timed(fn):
        fn()
        t = time.perf_counter()
        for _ in range(a.reps):
            fn()
        return m * a.reps / (time.perf_counter() - t)

    rates = {nt: {"serial": [], "private": [], "owner": []} for nt in (1, 2)}
    for _ in range(a.rounds):
        for nt in (1, 2):
            set_num_threads(nt)
            f1 = np.zeros((n, 3))
            fp = np.zeros((nt, n, 3))
            bounds = split(m, nt)
            rates[nt]["serial"].append(timed(
                lambda: accumulate_elements(elems, pos, vel, f1, 0, m, False, np.empty(0))))
            rates[nt]["private"].append(timed(lambda: private_pass(elems, pos, vel, fp, bounds)))
            rates[nt]["owner"].append(timed(lambda: owner_pass(elems, pos, f1, elist, eptr,
                                                               BLOCKS)))
    out = {"machine": machine(), "mesh_width": a.mesh_width, "elements": m, "nodes": n,
           "blocks": BLOCKS, "crossing_elements": int(eptr[-1] - eptr[-2]),
           "owner_vs_serial_max_rel_force_difference": diff,
           "element_updates_per_s": {str(k): v for k, v in rates.items()},
           "median": {str(k): {w: float(np.median(r)) for w, r in v.items()}
                      for k, v in rates.items()}}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1))
    for nt in (1, 2):
        print(nt, "thread(s), median element-updates/s:",
              ", ".join(f"{w} {np.median(r):.3g}" for w, r in rates[nt].items()))
    print(f"crossing elements {out['crossing_elements']} of {m}; owner vs serial forces "
          f"{diff:.1e}; wrote {OUT}")


if __name__ == "__main__":
    main()
