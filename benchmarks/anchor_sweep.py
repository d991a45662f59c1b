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
benchmarks/results/anchor_sweep.json and a bar chart anchor_sweep.png. The layouts and
kernels are in anchor_kernels.py.
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

import numba
import numpy as np
from anchor_kernels import (advance_csr, advance_slots, advance_soa, advance_split,
                            anchor_order, forces_csr, make_anchored, make_slot_kernel,
                            make_slot_major, make_slots, max_block_elems, split_ranges)
from feature_cost import reference_advance
from limit_ratio import LIMIT, build, run_c
from throughput import load_average, machine, measure, spinning_web

from spinweb_fe.fe.forces import make_links, make_work
from spinweb_fe.fe.model import choose_dt

OUT = Path(__file__).resolve().parent / "results" / "anchor_sweep.json"
MESH_WIDTH = 0.5


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


def sample(runs, samples):
    """One round: each of ``runs`` (name -> callable returning element-updates/s) once, in
    order, into ``samples`` (name -> [(element-updates/s, 1-minute load)])."""
    for name, fn in runs.items():
        load = load_average()
        eu = fn()
        samples.setdefault(name, []).append((eu, load))
        print(f"{name:34s} {eu:.3e} element-updates/s (load {load:.2f})", flush=True)


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
            sample(runs, samples)
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
            sample(runs, samples)
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
