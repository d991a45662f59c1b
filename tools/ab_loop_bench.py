"""Element-updates per second of one problem, for A B pairs of two checkouts: it uses only the
interface both sides of the one-loop change share (case.loads, scene.prepare, run.loop.simulate),
so the same file times either checkout put first on PYTHONPATH.

    PYTHONPATH=CHECKOUT python tools/ab_loop_bench.py PROBLEM MESH_WIDTH END REPEAT

PROBLEM: spinning-web (the flat web of benchmarks.throughput, no hub), full-feature (the
coiled web with contact, torque feedback and damping, fixed axis) or free-hub (the same on a
free hub of 100 kg). Prints one JSON line: elements, steps, the best loop time of REPEAT runs
[s], element-updates/s, and the first run's compile (or cache load) time [s].
"""
import json, math, sys, time
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.fe.model import choose_dt
from spinweb_fe.run.loop import Schedule, simulate

problem, width, end, repeat = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
if problem == "spinning-web":
    from meshgen.flat import flat_quadquad
    from spinweb_fe.fe.control import free
    from spinweb_fe.fe.model import build_model
    from spinweb_fe.fe.state import initial_state
    mesh = flat_quadquad(100.0, width, 1, 10.0, 0.0)
    model = build_model(mesh, 180e9, 1540.0, 1.025e-5, hub_radius=0.0, hub_inertia=1.0, contact=False)
    state0 = initial_state(model, 2 * math.pi, "all"); control = free()
else:
    hub = '[hub]\nmotion = "free"\nmass = 100.0\n' if problem == "free-hub" else ""
    text = f"""
[web]
side = 100.0
mesh_width = {width}
areal_density = 1.267e-2
[cable]
damping_ratio = 0.05
[control]
law = "torque_feedback"
M0 = 2513274.1228718345
omega0 = 25.132741228718345
{hub}[time]
end = 1.0
[output]
frame_dt = 0.0
"""
    sc = prepare(case_mod.loads(text))
    model, control, state0 = sc[1], sc[2], sc[3]
dt = choose_dt(model, 0.9, history_dt=1e-3)
best = None
comp = None
for _ in range(repeat):
    r = simulate(model, control, state0.copy(), dt, Schedule(end, 1e-3), threads=1, energy_limit=math.inf)
    comp = comp if comp is not None else r.compile_s
    best = r.loop_s if best is None else min(best, r.loop_s)
print(json.dumps({"problem": problem, "elements": model.n_elems, "steps": r.steps, "loop_s": best,
                  "eu_per_s": model.n_elems * r.steps / best, "compile_s": comp}))
