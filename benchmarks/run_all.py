"""All benchmarks, one after the other (``make bench``); results in benchmarks/results/.

    python -m benchmarks.run_all [--only throughput limit ramp feature_cost profile scaling wp]
                                 [--wait-quiet 30]

- throughput.json: the bare spinning web at W = 2.5 m (3280 elements) and W = 0.5 m
  (80 400 elements) and the full-feature web, on 1 and 2 threads (fastest of 5), and the cold
  compile time (empty NUMBA_CACHE_DIR, in a fresh process);
- limit_ratio.json (and the ``limit_ratio`` key of throughput.json): spinweb's bare loop
  against the C loops of ../shared/limit, interleaved, 1 and 2 threads (limit_ratio.py);
- ramp_run.json: cases/paper_ramp_web.toml (10 s at the README's accuracy: cfl 0.3 with 1
  and with 2 elements per segment; frames and results.h5 written) on 2 threads and 1 thread,
  wall time per run;
- feature_cost.json, profile_loop.json, scaling.json/png, work_precision.json/png: see those
  scripts.

Benchmarks only: the studies (``studies/``, e.g. studies.energy_attribution, where the step's
energy error is made) and the tools (``tools/``) are run on their own.

The machine is shared: before each part the script waits (at most ``--wait-quiet`` s) for a
1-minute load below 0.5 and records the load it ran at.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import load_average, machine, wait_for_quiet

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"
PY = sys.executable


def bench(module, *args, env=None):
    """Run ``python -m benchmarks.<module>`` in a fresh process from the repository root;
    returns its stdout."""
    cmd = [PY, "-m", f"benchmarks.{module}", *map(str, args)]
    print("$", " ".join(cmd[1:]), flush=True)
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, env=env, check=True)
    sys.stderr.write(r.stderr[-2000:])
    return r.stdout


def throughput(wait):
    rows = []
    for problem, end05, end25 in (("spinning-web", 0.04, 0.4), ("full-feature", 0.02, 0.2)):
        for w, end in ((2.5, end25), (0.5, end05)):
            for nt in (1, 2):
                load = wait_for_quiet(max_wait=wait)
                r = json.loads(bench("throughput", "--problem", problem, "--mesh-width", w,
                                     "--end", end, "--threads", nt, "--repeat", 5, "--json"))
                r["load_1min_at_start"] = load
                rows.append(r)
                print(f"  {problem} W={w} threads={nt}: {r['element_updates_per_s']:.3g} "
                      f"element-updates/s (load {load:.2f})", flush=True)
    with tempfile.TemporaryDirectory() as cache:  # cold compile: nothing cached
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        cold = {}
        for nt in (1, 2):
            r = json.loads(bench("throughput", "--mesh-width", 2.5, "--end", 0.01,
                                 "--threads", nt, "--json", env=env))
            cold[str(nt)] = r["compile_s"]
    out = {"machine": machine(), "runs": rows, "cold_compile_s": cold,
           "note": "compile_s of a run is the first call in its process (cache load); "
                   "cold_compile_s compiles the loop with an empty NUMBA_CACHE_DIR "
                   "(threads 1: serial kernels; threads 2 adds the parallel ones)"}
    old = OUT / "throughput.json"
    if old.is_file():  # keep the C comparison of limit_ratio.py
        limit = json.loads(old.read_text()).get("limit_ratio")
        if limit:
            out["limit_ratio"] = limit
    (OUT / "throughput.json").write_text(json.dumps(out, indent=1))


def ramp(wait):
    from spinweb_fe import case as case_mod
    from spinweb_fe.run.driver import run_case

    rows = []
    for eps, nt in ((1, 2), (1, 1), (2, 2), (2, 1)):
        load = wait_for_quiet(max_wait=wait)
        case = case_mod.load(ROOT / "cases" / "paper_ramp_web.toml",
                             [f"web.elements_per_segment={eps}"])
        t0 = time.perf_counter()
        res = run_case(case, ROOT / "out" / "bench" / f"ramp_{eps}_{nt}", progress=False,
                       threads=nt)
        wall = time.perf_counter() - t0
        n_el = int(res.state.node_pos.shape[0])
        rows.append({"elements_per_segment": eps, "threads": nt, "wall_s": wall, "loop_s": res.loop_s,
                     "compile_s": res.compile_s, "steps": res.steps, "dt": res.dt,
                     "frames": res.frames, "nodes": n_el, "load_1min_at_start": load,
                     "end_s": case.time.end, "cfl": case.time.cfl})
        print(f"  ramp web 10 s, {eps} element(s)/segment, {nt} thread(s): {wall:.1f} s wall (loop {res.loop_s:.1f} s, "
              f"load {load:.2f})", flush=True)
    (OUT / "ramp_run.json").write_text(json.dumps({"machine": machine(), "runs": rows},
                                                  indent=1))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parts = ["throughput", "limit", "ramp", "feature_cost", "profile", "scaling", "wp"]
    ap.add_argument("--only", nargs="+", choices=parts, default=parts)
    ap.add_argument("--wait-quiet", type=float, default=30.0,
                    help="seconds to wait for a 1-minute load below 0.5 before each part")
    args = ap.parse_args(argv)
    OUT.mkdir(parents=True, exist_ok=True)
    wait = args.wait_quiet
    for part in args.only:
        print(f"[{part}] load {load_average():.2f}", flush=True)
        if part == "throughput":
            throughput(wait)
        elif part == "ramp":
            ramp(wait)
        else:
            wait_for_quiet(max_wait=wait)
            module = {"limit": "limit_ratio", "feature_cost": "feature_cost",
                      "profile": "profile_loop", "scaling": "scaling",
                      "wp": "work_precision"}[part]
            print(bench(module), flush=True)


if __name__ == "__main__":
    main()
