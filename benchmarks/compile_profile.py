"""What numba compiles on a cold start, and how long each function takes.

    python -m benchmarks.compile_profile [--case cases/demo.toml ...] [--rounds 1] [--helper on off]

Each case is run as a whole ``spinweb run`` in a fresh process with an empty numba cache
(a new NUMBA_CACHE_DIR), with numba's "numba:compile" events recorded. Each compiled
function is reported with its inclusive time (its own compile, which types and compiles the
callees it meets) and its exclusive time (less the callees compiled inside it), whether it
was a top-level compile (an entry point called from Python) and the compile's nesting. The
sum of the top-level compiles is the cold start's compile time; the rest of the process's
wall time is Python, the set-up, the loop and the output; ``cpu_s`` is the CPU time of the
run's process and of the children it waited for (the helper among them). Results (machine with CPU model
and ISA) go to ``benchmarks/results/compile_profile.json``; with ``--rounds`` > 1 the cases
run in turn, round after round, and every round is kept. ``--helper`` runs each case with the
cold start's compile helper (spinweb_fe.run.warmup) on, off, or both in turn (A B pairs);
its events are not recorded (it is another process), so with it on the functions listed are
those this process compiled itself, and the functions it loaded from the helper's cache
are missing from the list.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import load_average, machine

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results" / "compile_profile.json"

#: run inside the child: record the compile events of one `spinweb run`
CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
from numba.core import event as ev
from spinweb_fe.cli import main
with ev.install_recorder("numba:compile") as rec:
    status = main(sys.argv[2:])
wall = time.perf_counter() - t0
events = []
for stamp, e in rec.buffer:
    d = e.data["dispatcher"]
    events.append([stamp, e.is_start, d.py_func.__module__, d.py_func.__qualname__])
json.dump({"status": status, "wall_s": wall, "events": events}, open(sys.argv[1], "w"))
"""


def functions(events):
    """Per compile: module.function, inclusive and exclusive seconds, depth, top-level."""
    stack, out = [], []
    for stamp, start, module, name in events:
        if start:
            stack.append({"function": f"{module}.{name}", "t0": stamp, "children": 0.0,
                          "depth": len(stack)})
            continue
        item = stack.pop()
        incl = stamp - item.pop("t0")
        item["inclusive_s"] = incl
        item["exclusive_s"] = incl - item.pop("children")
        item["top_level"] = item["depth"] == 0
        if stack:
            stack[-1]["children"] += incl
        out.append(item)
    return out


def profile(case: Path, helper: bool = True) -> dict:
    """One cold ``spinweb run`` of ``case``: its wall time and every compile."""
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ, NUMBA_CACHE_DIR=str(Path(tmp) / "cache"),
                   SPINWEB_COMPILE_HELPER="1" if helper else "0")
        env.pop("SPINWEB_THREADS", None)
        result = Path(tmp) / "events.json"
        argv = [sys.executable, "-c", CHILD, str(result), "run", str(case),
                "--out", str(Path(tmp) / "run"), "--no-progress"]
        load = load_average()
        cpu0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(argv, env=env, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
        process = time.perf_counter() - t0
        cpu1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        data = json.loads(result.read_text())
    compiles = functions(data["events"])
    top = [c for c in compiles if c["top_level"]]
    return {"case": str(case.relative_to(ROOT)) if case.is_relative_to(ROOT) else str(case),
            "compile_helper": helper, "process_wall_s": process, "run_wall_s": data["wall_s"],
            "exit": data["status"], "cpu_s": (cpu1.ru_utime + cpu1.ru_stime
                                               - cpu0.ru_utime - cpu0.ru_stime),
            "compile_s": sum(c["inclusive_s"] for c in top), "functions": len(compiles),
            "top_level": len(top), "load_1min_before": load,
            "compiles": sorted(compiles, key=lambda c: -c["exclusive_s"])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", action="append", type=Path,
                    help="case file (default cases/demo.toml); repeat for several")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--top", type=int, default=12, help="functions printed per run")
    ap.add_argument("--helper", nargs="+", choices=["on", "off"], default=["on", "off"],
                    help="the compile helper on, off, or both in turn (default)")
    args = ap.parse_args(argv)
    cases = [c.resolve() for c in (args.case or [ROOT / "cases" / "demo.toml"])]
    runs = []
    for r in range(args.rounds):
        for case, helper in itertools.product(cases, args.helper):
            res = profile(case, helper == "on")
            res["round"] = r
            runs.append(res)
            print(f"{res['case']} (helper {helper}): process {res['process_wall_s']:.1f} s "
                  f"(CPU {res['cpu_s']:.1f} s), "
                  f"compile {res['compile_s']:.1f} s in {res['functions']} functions "
                  f"({res['top_level']} entry points)", flush=True)
            for c in res["compiles"][:args.top]:
                print(f"  {c['exclusive_s']:6.2f} s own {c['inclusive_s']:6.2f} s incl  "
                      f"{'entry ' if c['top_level'] else '      '}{c['function']}")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps({"machine": machine(), "runs": runs}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
