"""Throughput of the explicit step loop, in element-updates per second.

    python benchmarks/throughput.py --problem spinning-web --mesh-width 0.5 --end 0.05 \
        --threads 1 --json

Problems
--------
spinning-web
    Flat QuadQuad web (S = 100 m, Zylon, corner masses 10 kg), every node spinning at
    2 pi rad/s about the centre, unstretched, no hub contact, no damping, no frames.
full-feature
    The same web star-folded and coiled on the paper's hub (r0 = 6.3 m) with cable-hub contact,
    torque feedback, 5 % axial damping and history output (frames off).

Prints one JSON object: elements, nodes, steps, dt, loop_s, compile_s,
element_updates_per_s (elements x steps / loop seconds), threads, angular_momentum_drift
(max |K - K0| / |K0|; for full-feature the control torque changes K, so it is not meaningful
there and reported as null), machine.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time

import numpy as np

from meshgen.flat import flat_quadquad
from spinweb_fe import case as case_mod
from spinweb_fe.control import LAWS, Control
from spinweb_fe.model import build_model, choose_dt, initial_state
from spinweb_fe.solver import prepare, simulate

E, RHO, A = 180e9, 1540.0, 1.025e-5


def spinning_web(mesh_width, side=100.0):
    mesh = flat_quadquad(side, mesh_width, 1, 10.0, 0.0)
    model = build_model(mesh, E, RHO, A, hub_radius=0.0, hub_inertia=1.0, contact=False)
    state = initial_state(model, 2 * math.pi, "all")
    return model, Control(LAWS["free"], np.zeros(1)), state


def full_feature(mesh_width, side=100.0):
    text = f"""
    [web]
    side = {side}
    mesh_width = {mesh_width}
    areal_density = 1.267e-2
    [cable]
    damping_ratio = 0.05
    [control]
    law = "torque_feedback"
    M0 = 2513274.1228718345
    omega0 = 25.132741228718345
    [time]
    end = 1.0
    [output]
    frame_dt = 0.0
    """
    case = case_mod.loads(text)
    _, model, control, state, _ = prepare(case)
    return model, control, state


PROBLEMS = {"spinning-web": spinning_web, "full-feature": full_feature}


def machine():
    return {"platform": platform.platform(), "processor": platform.processor() or platform.machine(),
            "python": platform.python_version(), "date": time.strftime("%Y-%m-%d %H:%M")}


def measure(problem, mesh_width, end, threads, cfl=0.9, history_dt=1e-3):
    """Run one problem and return the JSON-ready result dict."""
    model, control, state = PROBLEMS[problem](mesh_width)
    dt = choose_dt(model, cfl, history_dt=history_dt)
    t0 = time.perf_counter()
    res = simulate(model, control, state, dt, end, history_dt, threads=threads,
                   energy_limit=math.inf)
    wall = time.perf_counter() - t0
    K = res.history["angular_momentum"]
    drift = float(np.max(np.abs(K - K[0])) / abs(K[0])) if problem == "spinning-web" else None
    return {"problem": problem, "mesh_width": mesh_width, "elements": model.n_elems,
            "nodes": model.n_nodes, "steps": res.steps, "dt": dt, "cfl": cfl,
            "simulated_s": end, "loop_s": res.loop_s, "compile_s": res.compile_s,
            "wall_s": wall,
            "element_updates_per_s": model.n_elems * res.steps / max(res.loop_s, 1e-12),
            "ns_per_element_update": 1e9 * res.loop_s / max(model.n_elems * res.steps, 1),
            "threads": threads, "angular_momentum_drift": drift,
            "bytes_per_element": model_bytes(model) / model.n_elems, "machine": machine()}


def model_bytes(model):
    """Bytes of the arrays the step loop touches (model + state + workspace)."""
    n, m = model.n_nodes, model.n_elems
    arrays = (model.node_mass, model.node_inv_mass, model.elem_nodes, model.elem_rest_len,
              model.elem_ea, model.elem_cdamp, model.node_contact)
    return sum(a.nbytes for a in arrays) + n * 3 * 8 * 3 + m * 8  # pos, vel, force; 1/L0


def main(argv=None):
    ap = argparse.ArgumentParser(description="element-updates per second of the step loop")
    ap.add_argument("--problem", choices=sorted(PROBLEMS), default="spinning-web")
    ap.add_argument("--mesh-width", type=float, default=2.5, help="m")
    ap.add_argument("--end", type=float, default=0.05, help="simulated seconds")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--cfl", type=float, default=0.9)
    ap.add_argument("--json", action="store_true", help="print only the JSON object")
    args = ap.parse_args(argv)
    out = measure(args.problem, args.mesh_width, args.end, args.threads, args.cfl)
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{out['problem']}: {out['elements']} elements, {out['steps']} steps, "
              f"{out['threads']} thread(s): {out['element_updates_per_s']:.3g} element-updates/s "
              f"(loop {out['loop_s']:.3f} s, compile/load {out['compile_s']:.3f} s)")
    return out


if __name__ == "__main__":
    main()
