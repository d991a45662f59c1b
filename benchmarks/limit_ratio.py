"""spinweb's bare step loop against the hand-written C loop of ../shared/limit, in one run.

    python -m benchmarks.limit_ratio [--rounds 3] [--steps 300] [--mesh fine|coarse] [--replot]

Builds ``../shared/limit/limit.c`` with gcc (``-O3 -march=native -fno-math-errno -fopenmp``,
as its README says) into a temporary folder, then runs, interleaved A B A B for ``--rounds``
rounds and for 1 and 2 threads: spinweb's spinning-web problem (benchmarks/throughput.py,
the same web, cable and step as the C problem R3) and the C variants ``anchor`` (the best
general-connectivity kernel) and ``soa`` (a plain scalar loop). Each spinweb sample is the
fastest of ``--repeat`` loops of one process; each C sample the best of its repetitions.
The medians over the rounds and their ratios go to ``benchmarks/results/limit_ratio.json``
with the CPU model, family/model and ISA and the load before every sample, and the same
summary into ``benchmarks/results/throughput.json`` (key ``limit_ratio``), with the bytes
each loop moves per element-update (:func:`traffic`), and a bar chart into
``limit_ratio.png`` (``--replot`` redraws it from the JSON); compare numbers only within one
file.
Without gcc or the limit folder it says so and exits 2.
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.common import load_average, machine, measure, spinning_web

ROOT = Path(__file__).resolve().parent.parent
LIMIT = ROOT.parent / "shared" / "limit" / "limit.c"
OUT = ROOT / "benchmarks" / "results" / "limit_ratio.json"
THROUGHPUT = ROOT / "benchmarks" / "results" / "throughput.json"
#: bytes per element-update of the C ``anchor`` loop (its README's layout: one int32 slot and
#: 1/L0 per element, 12 B; per node x and v read and written and 1/m, 104 B, x 0.5 nodes per
#: element; no force array: the node update is fused into the sweep)
C_ANCHOR_BYTES = 12 + 104 * 0.5


def traffic(model) -> dict:
    """Bytes each pass of spinweb's step streams per element-update (arrays read or written
    once per step; the position gathers and the second read of an element's force vector hit
    lines the neighbours brought in, so they count once)."""
    m, n = model.n_elems, model.n_nodes
    slots = model.links.node_elems.shape[1]
    elem = 8 + 8 + 8 + 24 + 24 * n / m  # ends, 1/L0, EA, force vector written, x read
    sums = 24 + (4 * slots + 24) * n / m  # force vectors read, incidence, node force written
    update = (24 + 8 + 48 + 48) * n / m  # force, 1/m, v and x read and written
    return {"element_pass": elem, "node_sums": sums, "node_update": update,
            "total": elem + sums + update, "c_anchor_total": C_ANCHOR_BYTES}
MESH_WIDTH = {"fine": 0.5, "coarse": 2.5}


def build(workdir: Path) -> Path:
    exe = workdir / "limit"
    subprocess.run(["gcc", "-O3", "-march=native", "-fno-math-errno", "-fopenmp", "-w",
                    str(LIMIT), "-o", str(exe), "-lm"], check=True)
    return exe


def run_c(exe: Path, variant: str, mesh: str, threads: int, steps: int, reps: int = 3):
    """(best element-updates/s, header line) of one C run."""
    out = subprocess.run([str(exe), variant, mesh, str(threads), "il", str(reps)],
                         env={"R3_STEPS": str(steps), "OMP_NUM_THREADS": str(threads)},
                         capture_output=True, text=True, check=True).stdout
    res = [ln for ln in out.splitlines() if ln.startswith("RESULT")][-1].split()
    # RESULT var prec math mesh order threads ne steps median min max eu/s ...
    ne, nsteps, t_min = int(res[7]), int(res[8]), float(res[10])
    head = next(ln for ln in out.splitlines() if ln.startswith("variant="))
    return ne * nsteps / t_min, head


def plot(out, path):
    """Bars of the median element-updates/s of each loop on 1 and 2 threads."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    med = out["median_element_updates_per_s"]
    names = ("spinweb", "anchor", "soa")
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    for k, t in enumerate((1, 2)):
        vals = [med[f"{n}_{t}t"] for n in names]
        bars = ax.bar([x + 0.38 * k for x in range(3)], vals, 0.36, label=f"{t} thread(s)")
        ax.bar_label(bars, labels=[f"{v:.2g}" for v in vals], fontsize=7)
    ax.set_xticks([x + 0.19 for x in range(3)],
                  ["spinweb", "C anchor (hand SIMD)", "C soa (plain scalar)"])
    m = out["machine"]
    ax.set(ylabel="element-updates / s",
           title=f"80 400-element web, {m['processor']} {m['cpu_family_model']} {m['isa']}, "
                 f"{out['date']}")
    ax.title.set_fontsize(8)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--steps", type=int, default=300, help="steps of each sample")
    ap.add_argument("--repeat", type=int, default=3, help="spinweb loops per sample")
    ap.add_argument("--mesh", choices=sorted(MESH_WIDTH), default="fine")
    ap.add_argument("--replot", action="store_true", help="redraw the plot from the JSON only")
    args = ap.parse_args(argv)
    if args.replot:
        plot(json.loads(OUT.read_text()), OUT.with_suffix(".png"))
        return 0
    if shutil.which("gcc") is None or not LIMIT.is_file():
        print(f"limit_ratio: needs gcc and {LIMIT}", file=sys.stderr)
        return 2
    mw = MESH_WIDTH[args.mesh]
    with tempfile.TemporaryDirectory() as tmp:
        exe = build(Path(tmp))
        samples = {}
        header = {}
        for threads in (1, 2):
            # the C problem's dt is 0.9 t / c: run spinweb at cfl 0.9 for the same steps
            measure("spinning-web", mw, 0.0, threads)  # compile / cache load, not timed
            for _ in range(args.rounds):
                for who in ("spinweb", "anchor", "soa"):
                    load = load_average()
                    if who == "spinweb":
                        dt = 0.9 * mw / (180e9 / 1540.0) ** 0.5
                        r = measure("spinning-web", mw, args.steps * dt, threads, cfl=0.9,
                                    repeat=args.repeat)
                        eu = r["element_updates_per_s"]
                        header["spinweb_bytes_per_element"] = r["bytes_per_element"]
                    else:
                        eu, header[who] = run_c(exe, who, args.mesh, threads, args.steps)
                    samples.setdefault(f"{who}_{threads}t", []).append((eu, load))
                    print(f"{who:8s} {threads} thread(s): {eu:.3e} element-updates/s "
                          f"(load {load:.2f})", flush=True)
    med = {k: statistics.median(e for e, _ in v) for k, v in samples.items()}
    out = {"machine": machine(), "mesh": args.mesh, "steps": args.steps, "rounds": args.rounds,
           "samples": {k: [{"element_updates_per_s": e, "load_1min": ld} for e, ld in v]
                       for k, v in samples.items()},
           "median_element_updates_per_s": med,
           "ratio_spinweb_to_anchor": {f"{t}t": med[f"spinweb_{t}t"] / med[f"anchor_{t}t"]
                                       for t in (1, 2)},
           "ratio_spinweb_to_soa": {f"{t}t": med[f"spinweb_{t}t"] / med[f"soa_{t}t"]
                                    for t in (1, 2)},
           "speedup_2_threads": {w: med[f"{w}_2t"] / med[f"{w}_1t"]
                                 for w in ("spinweb", "anchor", "soa")},
           "spinweb_bytes_per_element": header.get("spinweb_bytes_per_element"),
           "bytes_per_element_update": traffic(spinning_web(mw)[0]),
           "c_headers": {k: v for k, v in header.items() if k != "spinweb_bytes_per_element"},
           "date": time.strftime("%Y-%m-%d %H:%M %Z")}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1))
    summary = {k: out[k] for k in ("machine", "mesh", "steps", "rounds",
                                   "median_element_updates_per_s", "ratio_spinweb_to_anchor",
                                   "ratio_spinweb_to_soa", "speedup_2_threads",
                                   "bytes_per_element_update", "date")}
    through = json.loads(THROUGHPUT.read_text()) if THROUGHPUT.is_file() else {}
    through["limit_ratio"] = summary
    THROUGHPUT.write_text(json.dumps(through, indent=1))
    plot(out, OUT.with_suffix(".png"))
    print(json.dumps({k: out[k] for k in ("median_element_updates_per_s",
                                          "ratio_spinweb_to_anchor", "speedup_2_threads")},
                     indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
