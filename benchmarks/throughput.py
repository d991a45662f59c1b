"""Throughput of the explicit step loop, in element-updates per second.

    python -m benchmarks.throughput --problem spinning-web --mesh-width 0.5 --end 0.05 \
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

from benchmarks.common import PROBLEMS, measure


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
