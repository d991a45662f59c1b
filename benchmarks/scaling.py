"""Run time against element count and against simulated time; memory per element.

    python -m benchmarks.scaling [--widths 5 2.5 1.25 1 0.5 0.25] [--threads 1 2]

The flat spinning web of benchmarks/throughput.py (S = 100 m) at several mesh widths, each
run for about ``--updates`` element-updates (steps = updates / elements), fastest of
``--repeat``; then the W = 2.5 m web for growing simulated times. Memory per element: the
arrays the step loop touches (model, state, force buffers; benchmarks.common.model_bytes) and the
peak of Python-traced allocations (tracemalloc: numpy arrays included) while building the
model and running it. Writes benchmarks/results/scaling.json and scaling.png.
"""

from __future__ import annotations

import argparse
import json
import math
import tracemalloc
from pathlib import Path


from benchmarks.common import machine, measure, model_bytes, spinning_web
from spinweb_fe.fe.model import choose_dt
from spinweb_fe.run.loop import Schedule, simulate

OUT = Path(__file__).resolve().parent / "results"


def traced_bytes(width, steps=10):
    """Peak traced allocation [B] of building the scene and running ``steps`` steps."""
    tracemalloc.start()
    model, control, state = spinning_web(width)
    dt = choose_dt(model, 0.9, history_dt=1e-3)
    simulate(model, control, state, dt, Schedule(steps * dt, 1e-3), threads=1,
             energy_limit=math.inf)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak, model.n_elems, model_bytes(model)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--widths", type=float, nargs="+", default=[5.0, 2.5, 1.25, 1.0, 0.5, 0.25])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--updates", type=float, default=1.5e8)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--ends", type=float, nargs="+", default=[0.05, 0.1, 0.2, 0.4, 0.8])
    args = ap.parse_args(argv)
    out = {"machine": machine(), "sizes": [], "time": [], "memory": []}
    for w in args.widths:
        model, _, _ = spinning_web(w)
        dt = choose_dt(model, 0.9, history_dt=1e-3)
        end = max(20, int(args.updates / model.n_elems)) * dt
        for nt in args.threads:
            r = measure("spinning-web", w, end, nt, repeat=args.repeat)
            out["sizes"].append(r)
            print(f"W={w} {r['elements']} el, {nt} thr: {r['ns_per_element_update']:.2f} ns "
                  f"({r['element_updates_per_s']:.3g}/s)", flush=True)
    for end in args.ends:
        r = measure("spinning-web", 2.5, end, 1, repeat=args.repeat)
        out["time"].append(r)
        print(f"end={end}: loop {r['loop_s']:.3f} s, {r['steps']} steps", flush=True)
    for w in args.widths:
        peak, m, loop_bytes = traced_bytes(w)
        out["memory"].append({"mesh_width": w, "elements": m, "loop_bytes_per_element":
                              loop_bytes / m, "traced_peak_bytes_per_element": peak / m})
        print(f"W={w}: {loop_bytes / m:.0f} B/element in the loop, traced peak {peak / m:.0f}",
              flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "scaling.json").write_text(json.dumps(out, indent=1))
    plot(out)
    return out


def plot(out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 3, figsize=(15, 4))
    for nt in sorted({r["threads"] for r in out["sizes"]}):
        rs = sorted((r for r in out["sizes"] if r["threads"] == nt), key=lambda r: r["elements"])
        el = [r["elements"] for r in rs]
        ax[0].loglog(el, [r["loop_s"] / r["steps"] for r in rs], "o-", label=f"{nt} thread(s)")
        ax[1].semilogx(el, [r["ns_per_element_update"] for r in rs], "o-",
                       label=f"{nt} thread(s)")
    ax[0].set(xlabel="elements", ylabel="loop time per step [s]", title="run time vs size")
    ax[1].set(xlabel="elements", ylabel="ns per element-update",
              title="cost per element-update (flat = ideal)")
    ax[1].set_ylim(bottom=0)
    rs = out["time"]
    ax[2].plot([r["simulated_s"] for r in rs], [r["loop_s"] for r in rs], "o-")
    ax[2].set(xlabel="simulated time [s]", ylabel="loop time [s]",
              title=f"W = 2.5 m ({rs[0]['elements']} elements), 1 thread")
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
    ax[0].legend()
    ax[1].legend()
    fig.tight_layout()
    fig.savefig(OUT / "scaling.png", dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    main()
