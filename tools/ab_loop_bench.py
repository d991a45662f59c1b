"""Element-updates per second of one problem of benchmarks/common.py, for A B pairs of two
checkouts across the one-loop change: this repository's problem definitions run on the
spinweb_fe of whichever checkout is first on PYTHONPATH (the interface they use, case.loads,
scene.prepare, run.loop.simulate, is the same on both sides; a checkout from before 1af7030
has no benchmarks/common.py, so it is loaded from this file's repository by path).

    PYTHONPATH=CHECKOUT python tools/ab_loop_bench.py PROBLEM MESH_WIDTH END REPEAT

PROBLEM: spinning-web (the flat web, no hub), full-feature (the coiled web with contact,
torque feedback and damping, fixed axis) or free-hub (the same on a free hub of 100 kg).
Prints one JSON line: elements, steps, the best loop time of REPEAT runs [s],
element-updates/s, and the first run's compile (or cache load) time [s].
"""

import importlib.util
import json
import math
import sys
from pathlib import Path

spec = importlib.util.spec_from_file_location(
    "ab_common", Path(__file__).resolve().parents[1] / "benchmarks" / "common.py")
common = importlib.util.module_from_spec(spec)
spec.loader.exec_module(common)

from spinweb_fe.fe.model import choose_dt  # noqa: E402 - the checkout on PYTHONPATH
from spinweb_fe.run.loop import Schedule, simulate  # noqa: E402

problem, width, end, repeat = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4])
model, control, state0 = common.PROBLEMS[problem](width)
dt = choose_dt(model, 0.9, history_dt=1e-3)
best = comp = None
for _ in range(repeat):
    r = simulate(model, control, state0.copy(), dt, Schedule(end, 1e-3), threads=1,
                 energy_limit=math.inf)
    comp = comp if comp is not None else r.compile_s
    best = r.loop_s if best is None else min(best, r.loop_s)
print(json.dumps({"problem": problem, "elements": model.n_elems, "steps": r.steps,
                  "loop_s": best, "eu_per_s": model.n_elems * r.steps / best,
                  "compile_s": comp}))
