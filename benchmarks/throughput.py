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

Prints one JSON object: elements, nodes, steps, dt, loop_s (fastest of --repeat), compile_s
(first run in the process: cache load, or the compilation with an empty NUMBA_CACHE_DIR),
element_updates_per_s (elements x steps / loop seconds), threads, angular_momentum_drift
(max |K - K0| / |K0|; for full-feature the control torque changes K, so it is not meaningful
there and reported as null), machine.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time

import numpy as np

from meshgen.flat import flat_quadquad
from spinweb_fe import case as case_mod
from spinweb_fe.fe.control import free
from spinweb_fe.fe.model import build_model, choose_dt
from spinweb_fe.fe.state import initial_state
from spinweb_fe.case.scene import prepare
from spinweb_fe.run.loop import Schedule, simulate

E, RHO, A = 180e9, 1540.0, 1.025e-5


def spinning_web(mesh_width, side=100.0):
    mesh = flat_quadquad(side, mesh_width, 1, 10.0, 0.0)
    model = build_model(mesh, E, RHO, A, hub_radius=0.0, hub_inertia=1.0, contact=False)
    state = initial_state(model, 2 * math.pi, "all")
    return model, free(), state


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


def cpu_model():
    """CPU model name and core count (lscpu / /proc/cpuinfo), for the benchmark records."""
    name = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    name = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return name, os.cpu_count()


def load_average():
    """1-minute load average (the machine is shared: threads are sensitive to it)."""
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


def cpu_family():
    """'family/model' of the CPU (AMD 26/2 is Zen 5, 25/17 Zen 4, 25/1 Zen 3), '' if unknown."""
    fields = {}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() in ("cpu family", "model") and key.strip() not in fields:
                    fields[key.strip()] = value.strip()
                if not line.strip():
                    break
    except OSError:
        pass
    return f"{fields.get('cpu family', '')}/{fields.get('model', '')}".strip("/")


def cpu_isa():
    """The widest x86 vector extension the CPU reports: 'avx512', 'avx2' or 'portable'."""
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((ln.split(":", 1)[1].split() for ln in f if ln.startswith("flags")), [])
    except OSError:
        flags = []
    return "avx512" if "avx512f" in flags else "avx2" if "avx2" in flags else "portable"


def machine():
    import numba

    name, cores = cpu_model()
    return {"platform": platform.platform(), "processor": name, "cpu_family_model": cpu_family(),
            "isa": cpu_isa(), "cores": cores,
            "python": platform.python_version(), "numba": numba.__version__,
            "numpy": np.__version__, "date": time.strftime("%Y-%m-%d %H:%M %Z"),
            "load_1min": load_average()}


def wait_for_quiet(max_load=0.5, max_wait=0.0, poll=10.0):
    """Wait (at most ``max_wait`` s) until the 1-minute load is below ``max_load``; returns
    the load seen last."""
    t0 = time.time()
    load = load_average()
    while load >= max_load and time.time() - t0 < max_wait:
        time.sleep(poll)
        load = load_average()
    return load


def measure(problem, mesh_width, end, threads, cfl=0.9, history_dt=1e-3, repeat=1):
    """Run one problem ``repeat`` times (fresh state each) and return the JSON-ready result
    dict of the fastest loop; ``loop_s_all`` lists every repetition."""
    model, control, state0 = PROBLEMS[problem](mesh_width)
    dt = choose_dt(model, cfl, history_dt=history_dt)
    best, loops, compiles, loads = None, [], [], []
    for _ in range(max(1, repeat)):
        state = state0.copy()
        loads.append(load_average())
        t0 = time.perf_counter()
        r = simulate(model, control, state, dt, Schedule(end, history_dt), threads=threads,
                     energy_limit=math.inf)
        w = time.perf_counter() - t0
        loops.append(r.loop_s)
        compiles.append(r.compile_s)
        if best is None or r.loop_s < best[0].loop_s:
            best = (r, w)
    res, wall = best
    K = res.history["angular_momentum"]
    drift = float(np.max(np.abs(K - K[0])) / abs(K[0])) if problem == "spinning-web" else None
    return {"problem": problem, "mesh_width": mesh_width, "elements": model.n_elems,
            "nodes": model.n_nodes, "steps": res.steps, "dt": dt, "cfl": cfl,
            "simulated_s": end, "loop_s": res.loop_s, "compile_s": compiles[0],
            "wall_s": wall,
            "element_updates_per_s": model.n_elems * res.steps / max(res.loop_s, 1e-12),
            "ns_per_element_update": 1e9 * res.loop_s / max(model.n_elems * res.steps, 1),
            "threads": threads, "angular_momentum_drift": drift,
            "bytes_per_element": model_bytes(model) / model.n_elems, "repeat": len(loops),
            "loop_s_all": loops, "compile_s_all": compiles, "load_1min_before": loads,
            "machine": machine()}


def model_bytes(model):
    """Bytes of the arrays the step loop touches (model, incidence, state positions and
    velocities, the force passes' workspace)."""
    from spinweb_fe.fe.forces import make_work

    n = model.n_nodes
    arrays = (*model.nodes, *model.elements[:-1], *model.links,
              *make_work(n, model.n_elems))
    return sum(a.nbytes for a in arrays) + n * 3 * 8 * 2  # + pos, vel


def main(argv=None):
    ap = argparse.ArgumentParser(description="element-updates per second of the step loop")
    ap.add_argument("--problem", choices=sorted(PROBLEMS), default="spinning-web")
    ap.add_argument("--mesh-width", type=float, default=2.5, help="m")
    ap.add_argument("--end", type=float, default=0.05, help="simulated seconds")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--cfl", type=float, default=0.9)
    ap.add_argument("--repeat", type=int, default=1, help="repetitions; the fastest is reported")
    ap.add_argument("--json", action="store_true", help="print only the JSON object")
    args = ap.parse_args(argv)
    out = measure(args.problem, args.mesh_width, args.end, args.threads, args.cfl,
                  repeat=args.repeat)
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{out['problem']}: {out['elements']} elements, {out['steps']} steps, "
              f"{out['threads']} thread(s): {out['element_updates_per_s']:.3g} element-updates/s "
              f"(loop {out['loop_s']:.3f} s, compile/load {out['compile_s']:.3f} s)")
    return out


if __name__ == "__main__":
    main()
