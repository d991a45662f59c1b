"""Cost of each solver feature, present and absent, against a minimal reference loop.

    python -m benchmarks.feature_cost [--mesh-width 0.5] [--steps 600] [--repeat 5]

Scene: the flat spinning QuadQuad web of benchmarks/throughput.py (S = 100 m, Zylon, 10 kg
corners, every node at 2 pi rad/s, unstretched), one thread, the same dt for every variant.

- ``floor``: ``reference_advance`` below, a numba loop of the production force passes
  (fe.forces: element force vectors, node sums; one thread, no records) and the node update
  v += dt f/m, x += dt v, and nothing else (no hub, contact, control, damping, records).
- ``bare``: the production loop (``run.loop.simulate``) on the same scene with every feature
  absent: no tied nodes, no contact, law 'free', no damping, one history row per 256 x 1000
  steps (i.e. almost never), no frames.
- one feature switched on at a time: hub ties (the nodes within 3 m of the centre tied to a
  hub), contact (every free node checked against a hub of radius 0.2 m; no node is inside),
  control (torque feedback law), damping (5 % of critical), history every step, frames every
  100 steps to a recorder (positions, velocities and tensions copied, as the writer
  gets them).

A second table prices the stowage on the paper's coiled web (cases/paper_free_web.toml,
3 220 elements, its first 0.2 s, one thread, frames off): the coil loose on the hub (contact
only), held (released by the peel fronts) and held in bundles (two-stage). The three deploy
differently in that time, so the differences hold the physics (contact events, releases)
as well as the machinery; the held coil's per-step work is the hub moment and placement of
the held nodes and the peel test of each arm.

Production variants are timed by wall time of ``simulate`` less its compile/cache-load part
(i.e. with the Python orchestration between chunks and the frame callbacks); the loop-only
time is reported too. Variants run round-robin, ``repeat`` times, fastest kept. Writes
benchmarks/results/feature_cost.json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np
from numba import njit

from benchmarks.common import RHO, A, E, load_average, machine
from meshgen.flat import flat_quadquad
from spinweb_fe.fe.control import free, make_control
from spinweb_fe.fe.forces import element_forces, make_work, node_forces
from spinweb_fe.fe.model import build_model, choose_dt, make_hub
from spinweb_fe.fe.state import initial_state
from spinweb_fe.record.recorders import Recorder
from spinweb_fe.run.loop import Schedule, simulate

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results"


@njit(cache=True, error_model="numpy")
def reference_nodes(pos, vel, force, inv_mass, dt):
    """v += dt f/m, x += dt v for every node (no tied-node test, no contact, no records)."""
    for q in range(pos.shape[0]):
        i = np.uint64(q)
        im = inv_mass[i]
        for d in range(3):
            vel[i, d] += dt * force[i, d] * im
            pos[i, d] += dt * vel[i, d]


@njit(cache=True)
def reference_advance(elements, links, pos, vel, inv_mass, work, dt, nsteps):
    """The cost floor: nsteps of the production force passes (element vectors, node sums;
    one thread, no records) and the bare node update above."""
    record = nsteps < 0  # False, but not a literal: the same compiled pass as the loop's
    for _ in range(nsteps):
        element_forces(elements, links, pos, vel, work, record, None)
        node_forces(links, work, None)
        reference_nodes(pos, vel, work.force, inv_mass, dt)


def scene(mesh_width, variant):
    """(model, control, state, history_dt factor, frame every) of one variant."""
    mesh = flat_quadquad(100.0, mesh_width, 1, 10.0, 0.0)
    zeta = 0.05 if variant == "damping" else 0.0
    r0 = 0.2 if variant == "contact" else 0.0
    model = build_model(mesh, E, RHO, A, damping_ratio=zeta, hub_radius=r0, hub_inertia=1.0,
                        contact=variant == "contact")
    if variant == "hub ties":
        pos = mesh.node_pos
        tied = np.flatnonzero(np.hypot(pos[:, 0], pos[:, 1]) < 3.0).astype(np.int64)
        inv = model.nodes.inv_mass.copy()
        inv[tied] = 0.0
        hub = make_hub(model.hub.radius, 0.0, 1.0, model.nodes.mass, tied, pos[tied])
        model = dataclasses.replace(model, nodes=model.nodes._replace(inv_mass=inv), hub=hub)
    if variant == "control":
        control = make_control("torque_feedback", {"M0": 10.0, "omega0": 2 * math.pi})
    else:
        control = free()
    state = initial_state(model, 2 * math.pi, "all")
    return model, control, state


VARIANTS = ["bare", "hub ties", "contact", "control", "damping", "history every step",
            "frames every 100 steps"]


def run_variant(mesh_width, variant, dt, steps):
    model, control, state = scene(mesh_width, variant)
    every_step = variant == "history every step"
    history_dt = dt if every_step else dt * 1000 * 256  # one row per 256 000 steps
    frame_dt = 100 * dt if variant.startswith("frames") else 0.0
    end = steps * dt
    frames = FrameCount()
    t0 = time.perf_counter()
    res = simulate(model, control, state, dt, Schedule(end, history_dt, frame_dt), [frames],
                   threads=1, energy_limit=math.inf)
    wall = time.perf_counter() - t0
    return {"wall_s": wall - res.compile_s, "loop_s": res.loop_s, "steps": res.steps,
            "elements": model.n_elems, "frames": frames.count}


class FrameCount(Recorder):
    """Takes the frames as the result writer gets them (copies made by the loop)."""

    count = 0

    def frame(self, frame):
        self.count += 1


def run_floor(mesh_width, dt, steps):
    model, _, state = scene(mesh_width, "bare")
    args = (model.elements, model.links, state.node_pos, state.node_vel, model.nodes.inv_mass,
            make_work(model.n_nodes, model.n_elems), dt)
    reference_advance(*args, 1)  # compile / cache load
    t0 = time.perf_counter()
    reference_advance(*args, steps)
    s = time.perf_counter() - t0
    return {"wall_s": s, "loop_s": s, "steps": steps, "elements": model.n_elems, "frames": 0}


STOWAGE = {"loose coil": ["stowage.coil='loose'"], "held coil": [],
           "held coil, bundles": ["stowage.bundle='until_length'", "stowage.bundle_release=0.95"]}


def run_stowage(name, end):
    """One run of the coiled paper web with the given stowage (wall less compile)."""
    from spinweb_fe import case as case_mod
    from spinweb_fe.case.scene import prepare

    cs = case_mod.load(ROOT / "cases" / "paper_free_web.toml",
                       [f"time.end={end}", "output.frame_dt=0", *STOWAGE[name]])
    _, model, control, state, dt = prepare(cs)
    t0 = time.perf_counter()
    res = simulate(model, control, state, dt, Schedule(end, cs.output.history_dt), threads=1,
                   energy_limit=math.inf)
    wall = time.perf_counter() - t0 - res.compile_s
    return {"wall_s": wall, "loop_s": res.loop_s, "steps": res.steps,
            "elements": model.n_elems}


def stowage_costs(end, repeat):
    """ns per element-update of the coiled web under each stowage (fastest of ``repeat``)."""
    best = {}
    for name in STOWAGE:
        run_stowage(name, 0.002)  # compile / load
    for _ in range(repeat):
        for name in STOWAGE:
            r = run_stowage(name, end)
            if name not in best or r["wall_s"] < best[name]["wall_s"]:
                best[name] = r
    rows = []
    for name, r in best.items():
        ns = 1e9 * r["wall_s"] / (r["steps"] * r["elements"])
        rows.append({"variant": name, "ns_per_element_update": ns, **r})
        print(f"coiled web {name:20s} {ns:6.2f} ns/el-update", flush=True)
    return {"case": "paper_free_web", "end_s": end, "rows": rows}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh-width", type=float, nargs="+", default=[0.5, 2.5])
    ap.add_argument("--updates", type=float, default=5e7,
                    help="element-updates per timed run (steps = updates / elements)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--cfl", type=float, default=0.8)
    ap.add_argument("--stowage-end", type=float, default=0.2,
                    help="simulated seconds of the coiled-web stowage runs")
    args = ap.parse_args(argv)
    out = {"machine": machine(), "repeat": args.repeat, "sizes": {}}
    for w in args.mesh_width:
        model, _, _ = scene(w, "bare")
        dt = choose_dt(model, args.cfl)
        steps = max(100, int(args.updates / model.n_elems))
        names = ["floor"] + VARIANTS
        best = {}
        loads = []
        for name in names:  # warm up: compile / load every specialisation once
            (run_floor(w, dt, 2) if name == "floor" else run_variant(w, name, dt, 2))
        for _ in range(args.repeat):
            loads.append(load_average())
            for name in names:
                r = run_floor(w, dt, steps) if name == "floor" else run_variant(w, name, dt, steps)
                if name not in best or r["wall_s"] < best[name]["wall_s"]:
                    best[name] = r
        floor = best["floor"]["wall_s"]
        bare = best["bare"]["wall_s"]
        rows = []
        for name in names:
            r = best[name]
            ns = 1e9 * r["wall_s"] / (r["steps"] * r["elements"])
            row = {"variant": name, "ns_per_element_update": ns,
                   "ns_per_element_update_loop_only":
                       1e9 * r["loop_s"] / (r["steps"] * r["elements"]),
                   "vs_floor_pct": 100 * (r["wall_s"] / floor - 1),
                   "vs_bare_pct": 100 * (r["wall_s"] / bare - 1), **r}
            rows.append(row)
            print(f"W={w} {name:24s} {ns:6.2f} ns/el-update  vs floor {row['vs_floor_pct']:+6.1f} %"
                  f"  vs bare {row['vs_bare_pct']:+6.1f} %", flush=True)
        out["sizes"][str(w)] = {"mesh_width": w, "elements": model.n_elems, "dt": dt,
                                "steps": steps, "load_1min_per_round": loads, "rows": rows}
    out["stowage"] = stowage_costs(args.stowage_end, min(args.repeat, 3))
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "feature_cost.json").write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
