"""Where the step loop's time goes: ns per element-update of each pass of the step.

    python -m benchmarks.profile_loop [--mesh-width 0.5] [--repeat 20] [--rounds 3]

On the flat spinning web of benchmarks/throughput.py (every element on the slack/taut kink),
each pass of the production step is called on the same arrays, on 1 and on 2 threads; each
number is the fastest of ``repeat`` calls in the fastest of ``rounds`` interleaved rounds:

- element pass (fe.forces.element_forces): gather the end differences, the vectorised
  length/strain/tension loop, the force vectors; also on a record step (strain energy and max
  tension kept per element and summed) and with an axial damper (velocities gathered too);
- node sums (fe.forces.node_forces): each node's element forces added in element order;
- node update (fe.hub.axis.axis_nodes, the fixed-axis node pass): kick and drift, without contact
  and with the hub contact check of every node (r0 = 0.1 m: no node reaches it, so only the
  check is priced);
- the whole step loop (fe.step.advance, one history row per 256 steps) for comparison.

Also reports whether numba emitted packed sqrt and divide (vsqrtpd / vdivpd) for the element
pass. Writes benchmarks/results/profile_loop.json with the machine (CPU model and ISA).
"""

from __future__ import annotations

import argparse
import json
import re
import time
from pathlib import Path

import numba
import numpy as np
from numba import njit

from benchmarks.common import load_average, machine, spinning_web
from spinweb_fe.fe import forces, step
from spinweb_fe.fe.hub.axis import AxisKick, NodeMotion, axis_nodes
from spinweb_fe.fe.forces import make_work
from spinweb_fe.fe.layout import ARM, ROW_WIDTH, SLOTS
from spinweb_fe.fe.model import choose_dt

OUT = Path(__file__).resolve().parent / "results" / "profile_loop.json"


@njit
def element_pass(elems, links, pos, vel, work, record, threads):
    """The element pass alone (a CPython entry for the kernel that has none)."""
    return forces.element_forces(elems, links, pos, vel, work, record, threads)


@njit
def node_sums(links, work, threads):
    """The node sums alone."""
    forces.node_forces(links, work, threads)


def best_of(fn, repeat):
    fn()
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def packed_math() -> dict:
    """Counts of packed and scalar sqrt/divide in the element pass's machine code (empty when
    the kernels came from numba's cache, which keeps no assembly)."""
    out = {}
    for cres in forces.element_block.overloads.values():
        asm = cres.library.get_asm_str()
        out = {k: len(re.findall(k, asm)) for k in ("vsqrtpd", "vdivpd", "vsqrtsd", "vdivsd")}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh-width", type=float, default=0.5, help="m")
    ap.add_argument("--repeat", type=int, default=20)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    model, law, state0 = spinning_web(args.mesh_width)
    k = model.kernel
    axis, body = model.hub_kind  # a fixed axis: body is None
    m = model.n_elems
    dt = choose_dt(model, 0.9)
    damped = k.elements._replace(cdamp=k.elements.cdamp + 1.0, damped=True)
    contact_hub = k.hub._replace(radius=0.1)
    results = {}
    for nt in (1, 2):
        numba.set_num_threads(nt)
        th = None if nt == 1 else nt
        work = make_work(model.n_nodes, m, nt, elem_nodes=model.elements.nodes)
        st = state0.copy()
        pos, vel = st.node_pos, st.node_vel
        sums = np.zeros(5)
        mv = NodeMotion(st.node_pos, st.node_vel, st.node_mass, st.node_inv_mass)
        # the hub at rest (omega_{n-1/2} = omega_{n+1/2} = 0), as the pass ran before
        kick = AxisKick(0.0, 0.0, 0.0, float(st.hub.inertia[0]))
        parts = {
            "element pass": lambda: element_pass(k.elements, k.links, pos, vel, work, False, th),
            "element pass, record step": lambda: element_pass(k.elements, k.links, pos, vel,
                                                              work, True, th),
            "element pass, damped": lambda: element_pass(damped, k.links, pos, vel, work,
                                                         False, th),
            "node sums": lambda: node_sums(k.links, work, th),
            "node update": lambda: axis_nodes(k.nodes, k.hub, mv, kick, work, dt, sums, False,
                                              th),
            "node update, contact check": lambda: axis_nodes(
                k.nodes._replace(contact=k.nodes.inv_mass > 0), contact_hub, mv, kick, work, dt,
                sums, False, th),
        }
        best = {name: np.inf for name in parts}
        for _ in range(args.rounds):
            for name, fn in parts.items():
                best[name] = min(best[name], best_of(fn, args.repeat))
        rec = step.Recording(256, np.zeros(0, np.int64), np.zeros((2, ROW_WIDTH)),
                             np.zeros((2, 0, 3)), np.zeros((2, 0, 3)), np.zeros((2, 0, len(ARM))),
                             np.zeros((2, 0)), SLOTS)
        loop = np.inf
        for _ in range(args.rounds):
            st2 = state0.copy()
            step.advance(k, axis, body, law.kernel, st2, work, rec, dt, 1, None, th)
            t0 = time.perf_counter()
            step.advance(k, axis, body, law.kernel, st2, work, rec, dt, 200, None, th)
            loop = min(loop, (time.perf_counter() - t0) / 200)
        best["whole step (advance)"] = loop
        results[f"{nt}_thread"] = {name: 1e9 * s / m for name, s in best.items()}
        for name, ns in results[f"{nt}_thread"].items():
            print(f"{nt} thread(s)  {name:28s} {ns:6.2f} ns per element-update", flush=True)
    out = {"machine": machine(), "mesh_width": args.mesh_width, "elements": m,
           "nodes": model.n_nodes, "ns_per_element_update": results,
           "element_pass_machine_code": packed_math(), "load_1min_after": load_average()}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
