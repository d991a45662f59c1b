"""Where the step loop's time goes: ns per element of each part of the element and node passes.

    python benchmarks/profile_loop.py [--mesh-width 0.5] [--repeat 20]

Microbenchmarks on the flat spinning web (benchmarks/throughput.py), one thread, every
kernel called on the same arrays; each is the fastest of ``repeat`` calls in the fastest of
``rounds`` interleaved rounds. Standalone kernels called from Python are compiled on their
own: inside ``kernels.advance`` LLVM inlines them and the production passes run faster
(see feature_cost.py for the end-to-end comparison).

- gather: read the node pairs and form dx, dy, dz (summed, so nothing is optimised away);
- gather + sqrt/div: the same plus the length, 1/L and the tension-only force factor;
- scatter: add a force (made from the element's own data, no node reads) into both nodes;
- element pass (reference): gather + math + scatter, as feature_cost.reference_elements;
- element pass (production): kernels.accumulate_elements, no damping, no records;
- element pass (production, record): the same on a history step (energy and max tension);
- element pass, elements in random order: what the mesh's locality is worth;
- node pass (reference / production kernels.integrate_nodes);
- the threaded kernels (accumulate_threads, integrate_threads) on 1 and 2 threads, each
  called repeatedly (warm caches), then alternately (a real step each), and the whole
  kernels.advance loop;
- a core probe: sqrt/divide-bound against latency-bound scalar work on 1 and 2 threads.
Also reports whether the production element pass uses packed AVX-512 sqrt and divide
(vsqrtpd / vdivpd on zmm registers) in numba's assembly. Writes
benchmarks/results/profile_loop.json.
"""

from __future__ import annotations

import argparse
import json
import re
import time
from pathlib import Path

import numpy as np
from feature_cost import reference_elements as element_pass
from feature_cost import reference_nodes as node_pass
from numba import njit, prange
from throughput import load_average, machine, spinning_web

from spinweb_fe.fe import step as kernels
from spinweb_fe.fe.control import free
from spinweb_fe.fe.threads import thread_ranges

OUT = Path(__file__).resolve().parent / "results"


@njit(cache=True, error_model="numpy")
def gather_only(pos, elem_nodes, out):
    for e in range(elem_nodes.shape[0]):
        i = elem_nodes[e, 0]
        j = elem_nodes[e, 1]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        out[e] = dx * dx + dy * dy + dz * dz


@njit(cache=True, error_model="numpy")
def gather_math(pos, elem_nodes, inv_rest, ea, out):
    for e in range(elem_nodes.shape[0]):
        i = elem_nodes[e, 0]
        j = elem_nodes[e, 1]
        dx = pos[j, 0] - pos[i, 0]
        dy = pos[j, 1] - pos[i, 1]
        dz = pos[j, 2] - pos[i, 2]
        ln = np.sqrt(dx * dx + dy * dy + dz * dz + 1e-300)
        inv = 1.0 / ln
        out[e] = ea[e] * max(ln * inv_rest[e] - 1.0, 0.0) * inv


@njit(cache=True, error_model="numpy")
def scatter_only(elem_nodes, inv_rest, force):
    for e in range(elem_nodes.shape[0]):
        i = elem_nodes[e, 0]
        j = elem_nodes[e, 1]
        f = inv_rest[e]
        force[i, 0] += f
        force[i, 1] += f
        force[i, 2] += f
        force[j, 0] -= f
        force[j, 1] -= f
        force[j, 2] -= f


@njit(cache=True, parallel=True)
def core_probe(a, reps, divide):
    """Two independent chunks of scalar work, one per thread: sqrt/divide-bound (``divide``)
    or a dependent multiply-add chain (latency-bound). If 2 threads speed up the latter 2x but
    the former less, the two CPUs share a divide/sqrt unit (SMT siblings on the host)."""
    s = np.zeros(2)
    for c in prange(2):
        acc = 0.0
        for r in range(reps):
            for i in range(a.shape[0]):
                if divide:
                    acc += np.sqrt(a[i] + r) / (a[i] + 1.0)
                else:
                    acc = acc * 0.999 + a[i]
        s[c] = acc
    return s


def loop_threads(model, state, nt, steps=300):
    """ns per element-update of kernels.advance (bare web, no records) on nt threads, and of
    the two threaded kernels called alternately from Python (a real step each)."""
    import numba

    numba.set_num_threads(nt)
    m, n = model.n_elems, model.n_nodes
    dt = 0.9 * model.dt_critical
    inv_rest = 1.0 / model.elements.rest_len

    control = free()
    ranges = thread_ranges(model.elements.nodes, n, nt, True) if nt > 1 else (None,) * 3
    kern_model = model.kernel

    def adv(k):
        st = state.copy()
        pp = np.zeros((2, 0, 3))
        rec = kernels.Recording(10**9, np.zeros(0, np.int64),
                                np.zeros((2, len(kernels.REC_COLUMNS))), pp, pp.copy(),
                                np.zeros((2, 0, 5)), np.zeros((2, 0)))
        t0 = time.perf_counter()
        kernels.advance(kern_model, control.kernel, st, np.zeros((nt, n, 3)), rec, dt, k,
                        None, *ranges)
        return time.perf_counter() - t0

    def kern(k):
        st = state.copy()
        mv = kernels.NodeMotion(st.node_pos, st.node_vel, st.node_mass, st.node_inv_mass)
        forces = np.zeros((nt, n, 3))
        eb, nb, lists = thread_ranges(model.elements.nodes, n, nt, True)
        eo, no = np.zeros((nt, 3)), np.zeros((nt, 5))
        t0 = time.perf_counter()
        for _ in range(k):
            kernels.accumulate_threads(model.elements, mv.pos, mv.vel, forces, lists[0], False,
                                       eo, lists[1])
            kernels.integrate_threads(model.nodes, model.hub, mv, forces, 0.0, 0.0, 1.0, dt, nb,
                                      False, no)
        return time.perf_counter() - t0

    adv(2)
    kern(2)
    a = min(adv(steps) for _ in range(3))
    b = min(kern(steps) for _ in range(3))
    return {"advance_ns": 1e9 * a / (steps * m), "threaded_kernels_alternating_ns":
            1e9 * b / (steps * m)}


def best_of(fn, repeat):
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return min(ts)


def vector_math(fn, *args):
    """(packed zmm sqrt, packed zmm div, ymm sqrt, ymm div) in the assembly of ``fn``'s Python
    source compiled afresh (cached code cannot be inspected) with error_model='numpy'."""
    fresh = njit(error_model="numpy")(fn.py_func)
    fresh(*args)
    asm = "\n".join(fresh.inspect_asm().values())
    return (bool(re.search(r"vsqrtpd\s+.*zmm", asm)), bool(re.search(r"vdivpd\s+.*zmm", asm)),
            bool(re.search(r"vsqrtpd\s+.*ymm", asm)), bool(re.search(r"vdivpd\s+.*ymm", asm)))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh-width", type=float, default=0.5)
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args(argv)
    model, _, state = spinning_web(args.mesh_width)
    pos, vel = state.node_pos, state.node_vel
    # a slightly stretched web, so that the tension-only max is taut for part of the elements
    pos *= 1.0 + 1e-4 * np.sin(np.arange(pos.shape[0]))[:, None]
    en = model.elements.nodes
    inv_rest = 1.0 / model.elements.rest_len
    ea, cd = model.elements.ea, model.elements.cdamp
    damped = model.elements._replace(cdamp=cd + 1.0, damped=True)
    force = np.zeros_like(pos)
    m = model.n_elems
    n = model.n_nodes
    perm = np.random.default_rng(0).permutation(m)
    en_rand = np.ascontiguousarray(en[perm])
    out4 = np.zeros(5)
    motion = kernels.NodeMotion(pos, vel, state.node_mass, state.node_inv_mass)
    tmp = np.zeros(m)
    no_t = np.zeros(0)  # no tension output (as in the step loop)
    dt = 1e-9  # tiny: the state hardly changes between repetitions
    parts = {
        "gather": lambda: gather_only(pos, en, tmp),
        "gather + sqrt/div": lambda: gather_math(pos, en, inv_rest, ea, tmp),
        "scatter": lambda: scatter_only(en, inv_rest, force),
        "element pass (reference)": lambda: element_pass(pos, en, inv_rest, ea, force),
        "element pass (production)": lambda: kernels.accumulate_elements(
            model.elements, pos, vel, force, 0, m, False, no_t),
        "element pass (production, record)": lambda: kernels.accumulate_elements(
            model.elements, pos, vel, force, 0, m, True, no_t),
        "element pass (production, damped)": lambda: kernels.accumulate_elements(
            damped, pos, vel, force, 0, m, False, no_t),
        "element pass, random element order": lambda: element_pass(pos, en_rand, inv_rest, ea,
                                                                    force),
        "node pass (reference)": lambda: node_pass(pos, vel, force, model.nodes.inv_mass, dt),
        "node pass (production)": lambda: kernels.integrate_nodes(
            model.nodes, model.hub, motion, force, 0.0, 0.0, 1.0, dt, 0, n, False, out4),
    }
    rows = {}
    for _ in range(args.rounds):  # rounds interleave the parts; the fastest round is kept
        for name, fn in parts.items():
            s = best_of(fn, args.repeat)
            if name not in rows or s < rows[name]["s"]:
                rows[name] = {"s": s, "ns_per_element": 1e9 * s / m}
    for name, r in rows.items():
        print(f"{name:38s} {r['ns_per_element']:6.2f} ns/element", flush=True)
    threads = {}
    import numba

    for nt in sorted({1, min(2, numba.config.NUMBA_NUM_THREADS)}):
        numba.set_num_threads(nt)
        forces = np.zeros((nt, n, 3))
        eb, nb, lists = thread_ranges(model.elements.nodes, n, nt, True)
        eo, no = np.zeros((nt, 3)), np.zeros((nt, 5))
        mv = kernels.NodeMotion(pos, vel, state.node_mass, state.node_inv_mass)

        def elem_pass(forces=forces, lists=lists, eo=eo):
            kernels.accumulate_threads(model.elements, pos, vel, forces, lists[0], False, eo,
                                       lists[1])

        def node_pass_t(forces=forces, nb=nb, no=no, mv=mv):
            kernels.integrate_threads(model.nodes, model.hub, mv, forces, 0.0, 0.0, 1.0, dt, nb,
                                      False, no)

        e_s = min(best_of(elem_pass, args.repeat) for _ in range(args.rounds))
        n_s = min(best_of(node_pass_t, args.repeat) for _ in range(args.rounds))
        threads[str(nt)] = {"element_pass_ns": 1e9 * e_s / m, "node_pass_ns": 1e9 * n_s / m}
        print(f"threads kernels, {nt} thread(s): element pass {1e9 * e_s / m:.2f} ns, "
              f"node pass (buffer reduction included) {1e9 * n_s / m:.2f} ns per element")
    for nt in list(threads):
        numba.set_num_threads(int(nt))
        threads[nt].update(loop_threads(model, state, int(nt)))
        a = np.random.default_rng(1).random(1000)
        for divide, key in ((True, "core_probe_sqrt_div_s"), (False, "core_probe_fma_chain_s")):
            core_probe(a, 1, divide)
            t0 = time.perf_counter()
            core_probe(a, 20000, divide)
            threads[nt][key] = time.perf_counter() - t0
        print(f"{nt} thread(s): " + ", ".join(f"{k} {v:.3g}" for k, v in threads[nt].items()))
    vec = {}
    for name, fn, a in (
            ("accumulate_elements", kernels.accumulate_elements,
             (model.elements, pos, vel, force, 0, m, False, no_t)),
            ("element_pass", element_pass, (pos, en, inv_rest, ea, force)),
            ("gather_math", gather_math, (pos, en, inv_rest, ea, tmp))):
        vec[name] = dict(zip(("zmm_sqrt", "zmm_div", "ymm_sqrt", "ymm_div"),
                             vector_math(fn, *a)))
    print(vec)
    out = {"machine": machine(), "mesh_width": args.mesh_width, "elements": m, "nodes": n,
           "repeat": args.repeat, "rounds": args.rounds, "load_1min": load_average(), "parts": rows,
           "threads_kernels": threads, "vectorisation": vec,
           "bytes_touched_per_element": {
               "element pass": (2 * 8 + 8 + 8 + 2 * 3 * 8 * 2),  # nodes, 1/L0, EA, pos+force x2
               "note": "elem_nodes 16 B, 1/L0 8 B, EA 8 B, two pos rows read and two force "
                       "rows read-modified-written (48 B each, mostly cache hits)"}}
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "profile_loop.json").write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
