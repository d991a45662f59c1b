"""The design search on the paper's questions (docs/design.md, "Design search" and "Design
charts").

    python -m studies.design_charts [observe] [design] [charts] [dense] [loft] [figs]
                                    [--workers 1] [--out out/design] [--rerun]

- ``observe``: the analytical and FE verdicts of the paper's free web and of its Eq. 3 law
  (M0 = omega0 1e5) at 8 pi rad/s over 5 s (cases/paper_free_web.toml,
  cases/paper_feedback_web.toml).
- ``design``: ``spinweb design cases/design/paper_web_8pi.toml``, timed (the cost goal: one
  design point, search and FE verification, within 10 minutes on 2 cores).
- ``charts``: ``spinweb design --chart`` of cases/design/fig8_hub.toml (the Fig. 8 hub,
  r0 = 1 m, at pi/2, 2 pi, 8 pi; FE checks over the full 200 s) and
  cases/design/paper_web_omega.toml (the paper's web, pi/16 .. 8 pi; FE checks at 8 pi).
- ``dense``: every chart row's least M0 against a dense scan of the analytical model (21
  log-spaced M0 between least/1.5 and 1.5 least): the first passing scan value must be the
  first at or above the bisection's answer, and nothing below it may pass.
- ``loft``: ``spinweb design cases/design/paper_web_loft.toml``: the fastest deployment of
  the paper's web within Hedgepeth's 200 N m.
- ``figs``: docs/img/design_*.png from the outputs.

Writes OUT/<name>/ (the command's folders) and OUT/design_charts.json (each stage updates
its own entry, with the machine and date).
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import shutil
import subprocess
import time
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe.analytic import solve
from spinweb_fe.case.load import load as load_case
from spinweb_fe.cli import main as cli
from spinweb_fe.record import verdict
from spinweb_fe.run.driver import run_case
from spinweb_fe.sweep import chart as ch
from spinweb_fe.sweep import outputs  # noqa: F401
from spinweb_fe.sweep import design as ds

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "cases"
IMG = ROOT / "docs" / "img"
REQUIRE = ("completed", "deployed", "recoil")
STAGES = ("observe", "design", "charts", "dense", "loft", "figs")


def machine() -> str:
    try:
        text = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        return next(line.split(":", 1)[1].strip() for line in text.splitlines()
                    if line.startswith("Model name"))
    except (OSError, StopIteration):
        return platform.processor() or "unknown"


def save(out: Path, name: str, entry: dict):
    path = out / "design_charts.json"
    data = json.loads(path.read_text()) if path.is_file() else {}
    data[name] = {**entry, "machine": machine(), "date": time.strftime("%Y-%m-%d %H:%M %Z")}
    out.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=1, default=float) + "\n")
    print(json.dumps({name: data[name]}, indent=1, default=float))


def _summary(crits) -> dict:
    return {"deploys": all(c.passed is not False for c in crits if c.name in REQUIRE),
            "failed": verdict.failed_names(crits),
            **{c.name: None if c.passed is None else [c.passed, c.value, c.limit]
               for c in crits}}


def observe(out: Path):
    """Analytical and FE verdicts of the free web and the Eq. 3 law, 8 pi, 5 s."""
    entry = {}
    for name in ("paper_free_web", "paper_feedback_web"):
        case = load_case(CASES / f"{name}.toml", ["output.frame_dt=0.0"])
        res = solve.solve_case(case)
        a = _summary(solve.judge(case, res))
        t0 = time.perf_counter()
        run_case(case, out / "observe" / name, progress=False)
        with h5py.File(out / "observe" / name / "results.h5") as h5:
            f = _summary(verdict.read_group(h5))
        entry[name] = {"analytic": a, "fe": f, "fe_wall_s": time.perf_counter() - t0}
    save(out, "observe", entry)


def run_design(out: Path, name: str, workers: int):
    t0 = time.perf_counter()
    rc = cli(["design", str(CASES / "design" / f"{name}.toml"), "-o", str(out / name),
              "--workers", str(workers)])
    wall = time.perf_counter() - t0
    info = json.loads((out / name / "design.json").read_text())
    chosen = info["chosen"]
    save(out, name, {"exit": rc, "wall_s": wall, "timing_s": info["timing_s"],
                     "analytic_solves": len(info["analytic"]),
                     "fe_runs": len(info["verified"]),
                     "verified": [{"values": a["values"], "analytic": a["feasible"],
                                   "fe": f["feasible"], "fe_failed": f["failed"],
                                   "objective": [a["objective"], f["objective"]],
                                   "fe_wall_s": f["wall_s"]} for a, f in info["verified"]],
                     "chosen": None if chosen is None else {
                         "values": chosen[0]["values"],
                         "objective": [chosen[0]["objective"], chosen[1]["objective"]],
                         "metrics_fe": chosen[1]["metrics"]}})


def run_charts(out: Path, workers: int, rerun: bool):
    """Each chart (kept from an earlier run unless ``rerun``)."""
    for name in ("fig8_hub", "paper_web_omega"):
        t0, rc = time.perf_counter(), None
        if rerun or not (out / f"{name}_chart" / "chart.json").is_file():
            rc = cli(["design", str(CASES / "design" / f"{name}.toml"), "--chart", "-o",
                      str(out / f"{name}_chart"), "--workers", str(workers)])
        rows = json.loads((out / f"{name}_chart" / "chart.json").read_text())["rows"]
        wall = time.perf_counter() - t0 if rc is not None else None
        save(out, f"{name}_chart", {"exit": rc, "wall_s": wall, "rows": [
            {"omega0": r["value"], "least_M0": r["least"], "note": r["note"],
             "solves": len(r["points"]), "wall_s": r["wall_s"],
             "deploy_time": (r["point"] or {}).get("metrics", {}).get("deploy_time"),
             "peak_torque": (r["point"] or {}).get("metrics", {}).get("peak_torque"),
             "fe_above": None if r["fe_above"] is None else [r["fe_above"]["feasible"],
                                                             r["fe_above"]["failed"]],
             "fe_below": None if r["fe_below"] is None else [r["fe_below"]["feasible"],
                                                             r["fe_below"]["failed"]]}
            for r in rows]})


def dense(out: Path):
    """Each chart row's bisection answer against a dense scan of the analytical model."""
    entry = {}
    for name in ("fig8_hub", "paper_web_omega"):
        d = ch.load_chart(CASES / "design" / f"{name}.toml")
        rows = json.loads((out / f"{name}_chart" / "chart.json").read_text())["rows"]
        entry[name] = []
        for r in rows:
            least = r["least"]
            if least is None:
                continue
            scan = np.geomspace(least / 1.5, least * 1.5, 21)
            ok = [ds.evaluate(d, {"control.M0": float(x)}, {d.chart_key: r["value"]}).feasible
                  for x in scan]
            first = next((float(x) for x, p in zip(scan, ok) if p), math.nan)
            below_pass = [float(x) for x, p in zip(scan, ok) if p and x < least * (1 - d.rtol)]
            above_fail = [float(x) for x, p in zip(scan, ok) if not p and x >= least]
            entry[name].append({"omega0": r["value"], "least": least, "dense_first": first,
                                "ratio": first / least, "passing_below": below_pass,
                                "failing_above": above_fail,
                                "agrees": not below_pass and first / least <= 1.5 ** (2 / 20)
                                * (1 + d.rtol)})
            print(name, entry[name][-1])
    save(out, "dense", entry)


def figs(out: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    for name, img in (("paper_web_8pi", "design_paper_web_8pi.png"),
                      ("paper_web_loft", "design_paper_web_loft.png"),
                      ("fig8_hub_chart", "design_chart_fig8.png")):
        src = out / name / ("chart.png" if name.endswith("chart") else "design.png")
        if src.is_file():
            shutil.copyfile(src, IMG / img)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, label, c in (("paper_web_omega_chart", "paper web, r0 = 6.3 m", "C0"),
                           ("fig8_hub_chart", "Fig. 8 hub, r0 = 1 m", "C1")):
        path = out / name / "chart.json"
        if not path.is_file():
            continue
        rows = json.loads(path.read_text())["rows"]
        w = np.array([r["value"] for r in rows])
        least = np.array([np.nan if r["least"] is None else r["least"] for r in rows])
        ax[0].plot(w, least, "o-", c=c, label=f"least M0, {label} (analytic)")
        for r in rows:
            for side, mk in (("fe_above", "^"), ("fe_below", "v")):
                p = r[side]
                if p is not None:
                    ok = p["feasible"]
                    ax[0].plot(r["value"], p["values"]["control.M0"], mk, ms=9,
                               c="C2" if ok else "C3", mfc="C2" if ok else "none")
        dep = [np.nan if r["point"] is None or r["point"]["metrics"]["deploy_time"] in (
            None, "inf") else r["point"]["metrics"]["deploy_time"] for r in rows]
        ax[1].plot(w, dep, "o-", c=c, label=label)
    ww = np.geomspace(0.15, 30, 50)
    ax[0].plot(ww, ww * 1e5, "k--", lw=1, label="paper's Eq. 3 gain: M0 = omega0 1e5")
    ax[0].axhline(60 * math.pi, c="0.4", ls=":", label="60 pi N m (Fig. 8, Hedgepeth's ~200)")
    for name, mk, label in (("paper_web_8pi", "*", "FE-verified design, 8 pi, 5 s"),
                            ("paper_web_loft", "P", "FE-verified design, peak <= 200 N m")):
        path = out / name / "design.json"
        chosen = json.loads(path.read_text())["chosen"] if path.is_file() else None
        if chosen:
            v = chosen[0]["values"]
            ax[0].plot(v.get("initial.omega", 8 * math.pi), v["control.M0"], mk, ms=13,
                       c="gold", mec="k", label=label)
    ax[0].plot([], [], "^", c="0.3", mfc="none", label="FE at 1.25 x least (green: passes)")
    ax[0].plot([], [], "v", c="0.3", mfc="none", label="FE at least / 1.25 (red open: fails)")
    ax[0].set_ylabel("least M0 that deploys without re-coil [N m]")
    ax[1].set_ylabel("deployment time at the least M0 [s]")
    for a in ax:
        a.set_xscale("log")
        a.set_yscale("log")
        a.xaxis.set_minor_formatter(NullFormatter())
        a.set_xlabel("omega0 = initial spin [rad/s]")
        a.grid(alpha=0.3, which="both")
        a.legend(fontsize=7, loc="lower right" if a is ax[0] else "upper right")
    fig.suptitle("feedback law M = M0 (1 - omega/omega0): least M0 within 200 s "
                 "(consistent analytical model; FE checks)", fontsize=10)
    fig.tight_layout()
    fig.savefig(IMG / "design_chart_omega.png", dpi=110)
    print("wrote", IMG / "design_chart_omega.png")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stages", nargs="*", help=f"any of {', '.join(STAGES)} (default: all)")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "design")
    ap.add_argument("--rerun", action="store_true", help="charts: run again even if their "
                    "chart.json exists")
    args = ap.parse_args(argv)
    stages = args.stages or STAGES
    if set(stages) - set(STAGES):
        ap.error(f"unknown stage(s) {sorted(set(stages) - set(STAGES))} (valid: {STAGES})")
    if "observe" in stages:
        observe(args.out)
    if "design" in stages:
        run_design(args.out, "paper_web_8pi", args.workers)
    if "charts" in stages:
        run_charts(args.out, args.workers, args.rerun)
    if "dense" in stages:
        dense(args.out)
    if "loft" in stages:
        run_design(args.out, "paper_web_loft", args.workers)
    if "figs" in stages:
        figs(args.out)


if __name__ == "__main__":
    main()
