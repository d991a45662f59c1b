"""What the benchmarks share: the problems they time, one timed run, the machine's record.

- ``spinning_web`` / ``full_feature`` / ``free_hub``: the problems of
  ``benchmarks.throughput`` (flat QuadQuad web, S = 100 m, Zylon; the coiled paper web with
  every feature; the same on a free hub), ``PROBLEMS`` by name; ``E``, ``RHO``, ``A``: the cable (Zylon, 1.025e-5 m^2);
- ``measure``: the fastest of ``repeat`` runs of one problem, as a JSON-ready dict;
- ``machine``, ``load_average``, ``wait_for_quiet``: what every benchmark records of the
  shared machine; ``model_bytes``: the bytes the step loop touches.

Imported as ``from benchmarks.common import ...`` (the studies and tools use it too).
"""

from __future__ import annotations

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


def full_feature(mesh_width, side=100.0, motion="fixed_axis"):
    """The coiled paper web with contact, torque feedback and damping; ``motion`` "free"
    puts it on a free hub of 100 kg."""
    hub = '[hub]\n    motion = "free"\n    mass = 100.0' if motion == "free" else ""
    text = f"""
    {hub}
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


def free_hub(mesh_width, side=100.0):
    return full_feature(mesh_width, side, motion="free")


PROBLEMS = {"spinning-web": spinning_web, "full-feature": full_feature, "free-hub": free_hub}


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
