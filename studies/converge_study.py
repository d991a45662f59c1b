"""Every answer with its error bar: mesh convergence of the paper's webs, and why it is slow
(docs/validation.md, section 6; docs/converge.md).

    python -m studies.converge_study [paper] [why] [corners] [figs] [tables] [reanalyse]
                                     [--workers 2] [--scenes a,b]

- ``paper``: the free web, the feedback web and the spin ramp (``cases/paper_*_web.toml``)
  over their whole runs at t = 5, 2.5, 1.25 and 0.625 m (the GCI from the three finest, the
  verdict's stability from all four), through ``spinweb_fe.sweep.converge`` on a local Dask
  cluster: ``benchmarks/results/converge/paper_*_web.json``, ``docs/img/converge_*.png``,
  the wall time of each study and the machine's load.
- ``why`` (``--scenes a,b``: only these): the first 0.2 s of eight scenes that take one
  ingredient of the paper's web at a time (straight tethers, coiled tethers, the bundled
  web, the paper's web, the web without corner masses, the web with a 10x stiffer cable, the
  flat web with and without corner masses) on three grids each, and each scene's
  sensitivity: the same scene on its coarsest grid with the hub inertia changed by 1e-9:
  ``benchmarks/results/converge/why.json``.
- ``corners``: the flat web's steady spin at 8 pi rad/s (``initial.state = "steady"``, the
  Newton solve of linear.steady) at t = 5 ... 0.625 m with and without its 10 kg corner
  masses: the largest strain and the tips' radius (``corners`` in why.json).
- ``figs``: ``docs/img/converge_why.png`` from why.json.
- ``tables``: the markdown tables of docs/validation.md from the JSON files.
- ``reanalyse``: the paper studies' estimates again from their stored values (no run).
"""

from __future__ import annotations

import argparse
import copy
import json
import math
import os
import platform
import time
import tomllib
from pathlib import Path

import numpy as np

from spinweb_fe.case.load import dumps_toml
from spinweb_fe.sweep import converge, converge_report

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "converge"
IMG = ROOT / "docs" / "img"
OMEGA0, H = 8 * math.pi, 50.0
PAPER = {"paper_free_web": (0.1, 0.2, 0.3, 0.5, 1.0, 2.5, 5.0),
         "paper_feedback_web": (0.1, 0.2, 0.3, 0.5, 1.0, 2.5, 5.0),
         "paper_ramp_web": (0.5, 1.0, 1.5, 2.0, 5.0, 10.0)}
PAPER_WIDTHS = (5.0, 2.5, 1.25, 0.625)
WHY_END = 0.2
WHY_TIMES = tuple(round(0.025 * k, 3) for k in range(1, 9))
PERTURBATION = 1e-9  # relative change of the hub inertia


def _variant(base: str, change) -> dict:
    raw = tomllib.loads((ROOT / "cases" / f"{base}.toml").read_text())
    change(raw)
    return raw


def _no_coil(raw, fold):
    raw.pop("stowage", None)
    raw["fold"] = {"pattern": fold}


def _no_tips(raw):
    raw["tip_mass"] = {"mass": 0.0}


def _stiffer(raw, factor):
    raw["cable"]["youngs_modulus"] *= factor


#: name -> (label, case dict, widths [m] or element lengths)
VARIANTS = {
    "tethers_straight": ("tethers, straight (no coil, no fold)",
                         lambda: _variant("paper_free_arms", lambda r: _no_coil(r, "straight")),
                         (1.0, 0.5, 0.25)),
    "tethers_coiled": ("tethers, held coil (the coil's discrete release)",
                       lambda: _variant("paper_free_arms", lambda r: None), (1.0, 0.5, 0.25)),
    "web_bundled": ("web, bundled arms (layers held together)",
                    lambda: _variant("paper_two_stage_web", lambda r: None), (2.5, 1.25, 0.625)),
    "web": ("web, the paper's",
            lambda: _variant("paper_free_web", lambda r: None), (2.5, 1.25, 0.625)),
    "web_no_tips": ("web without corner masses",
                    lambda: _variant("paper_free_web", _no_tips), (2.5, 1.25, 0.625)),
    "web_stiff10": ("web, cable 10x stiffer (corners 10x less compliant)",
                    lambda: _variant("paper_free_web", lambda r: _stiffer(r, 10.0)),
                    (2.5, 1.25, 0.625)),
    "flat": ("flat web, free (no coil, no fold)",
             lambda: _variant("paper_free_web", lambda r: _no_coil(r, "flat")),
             (2.5, 1.25, 0.625)),
    "flat_no_tips": ("flat web without corner masses",
                     lambda: _variant("paper_free_web",
                                      lambda r: (_no_coil(r, "flat"), _no_tips(r))),
                     (2.5, 1.25, 0.625)),
}


def _machine() -> dict:
    return {"machine": platform.processor() or platform.machine(), "cpus": os.cpu_count(),
            "load_1min": os.getloadavg()[0]}


def _study(case_path, out, widths, end=None, times=None, quantities=None, workers=2):
    """(the study's result with its wall time and the machine's load, its plan)."""
    t0 = time.perf_counter()
    load0 = _machine()
    p = converge.plan(case_path, widths=widths, end=end, times=times, quantities=quantities)
    rows = converge.execute(p, out, workers=workers, progress=True)
    result = converge_report.analyse(p, rows)
    converge_report.write(result, out)
    result["study_wall_s"] = time.perf_counter() - t0
    result["machine_before"], result["machine_after"] = load0, _machine()
    return result, p


def _save(name, result):
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / f"{name}.json").write_text(json.dumps(converge_report._clean(result),
                                                     indent=1) + "\n")


def paper(out: Path, workers: int):
    for name, times in PAPER.items():
        result, _ = _study(ROOT / "cases" / f"{name}.toml", out / name, PAPER_WIDTHS,
                           times=times, workers=workers)
        _save(name, result)
        converge_report.plot(result, IMG / f"converge_{name}.png")
        print(f"{name}: {result['study_wall_s']:.0f} s")
        print("\n".join(converge_report.lines(result)))


def reanalyse():
    """The paper studies' estimates again from their stored values (after a change of the
    numerics; no run)."""
    for name, times in PAPER.items():
        path = RESULTS / f"{name}.json"
        if not path.is_file():
            continue
        old = json.loads(path.read_text())
        plan = converge.plan(ROOT / "cases" / f"{name}.toml", widths=PAPER_WIDTHS, times=times)
        vals = {q["name"]: q["values"] for q in old["quantities"]}
        rows = []
        for k, g in enumerate(old["grids"]):
            passed = {v["criterion"]: v["passed"][k] for v in old["verdicts"]
                      if v["criterion"] != "verdict"}
            rows.append({"values": {q: (math.nan if vals.get(q) is None or vals[q][k] is None
                                        else vals[q][k]) for q in plan.quantities},
                         "passed": passed, "status": g["status"],
                         "wall_time_s": g["wall_time_s"],
                         "info": {"elements": g["elements"], "dt": g["dt"],
                                  "steps": g["steps"]}})
        result = converge_report.analyse(plan, rows)
        for key in ("study_wall_s", "machine_before", "machine_after"):
            result[key] = old[key]
        _save(name, result)
        converge_report.plot(result, IMG / f"converge_{name}.png")


def _hub_rate(path) -> tuple:
    import h5py

    with h5py.File(path, "r") as h5:
        g = h5["history"]
        return g["time"][()], g["hub_omega"][()], g["arm_length"][()].mean(axis=1)


def why(out: Path, workers: int, scenes=None):
    from spinweb_fe.case.load import validate
    from spinweb_fe.run.driver import run_case

    path = RESULTS / "why.json"
    report = json.loads(path.read_text()) if path.is_file() else {}
    report.update(end=WHY_END, times=WHY_TIMES, perturbation=PERTURBATION)
    report.setdefault("scenes", {})
    qs = [f"hub_omega@{t:g}" for t in WHY_TIMES] + [f"arm_length@{t:g}" for t in WHY_TIMES]
    qs += ["hub_omega@mean", "arm_length@mean", "contact_dissipation@end", "kinetic_energy@end"]
    for name, (label, make, widths) in VARIANTS.items():
        if scenes and name not in scenes:
            continue
        folder = out / "why" / name
        folder.mkdir(parents=True, exist_ok=True)
        case_path = folder / "case.toml"
        case_path.write_text(dumps_toml(make()))
        res, plan = _study(case_path, folder / "study", widths, end=WHY_END, quantities=qs,
                           workers=workers)
        # sensitivity: the coarsest grid again with the hub inertia changed by 1e-9
        coarse = plan.members[0]
        base = folder / "study" / "runs" / coarse.name / "results.h5"
        raw = copy.deepcopy(coarse.raw)
        inertia = validate(raw, str(case_path)).hub.inertia
        raw.setdefault("hub", {})["inertia"] = inertia * (1.0 + PERTURBATION)
        run_case(validate(raw, str(case_path)), folder / "perturbed", progress=False,
                 threads=1)
        t, w0, l0 = _hub_rate(base)
        _, w1, l1 = _hub_rate(folder / "perturbed" / "results.h5")
        sens_w = [float(abs(np.interp(x, t, w0) - np.interp(x, t, w1))) for x in WHY_TIMES]
        sens_l = [float(abs(np.interp(x, t, l0) - np.interp(x, t, l1))) for x in WHY_TIMES]
        by = {q["name"]: q for q in res["quantities"]}
        report["scenes"][name] = {
            "label": label, "h": [g["h"] for g in res["grids"]],
            "elements": [g["elements"] for g in res["grids"]],
            "quantities": {q: {k: by[q][k] for k in ("values", "kind", "order",
                                                      "extrapolated", "gci_fine", "low",
                                                      "high")} for q in by},
            "sensitivity_hub_omega": sens_w, "sensitivity_arm_length": sens_l,
            "wall_s": res["study_wall_s"]}
        RESULTS.mkdir(parents=True, exist_ok=True)
        report["scenes"] = {k: report["scenes"][k] for k in VARIANTS if k in report["scenes"]}
        path.write_text(json.dumps(converge_report._clean(report), indent=1) + "\n")
        print(f"{name}: {res['study_wall_s']:.0f} s")


def corners():
    """The steady flat web with and without corner masses on four grids."""
    from spinweb_fe.case.load import validate
    from spinweb_fe.case.scene import prepare

    raw0 = _variant("paper_free_web", lambda r: _no_coil(r, "flat"))
    rows = []
    for tip in (10.0, 0.0):
        for t in PAPER_WIDTHS:
            raw = copy.deepcopy(raw0)
            raw["web"].update(mesh_width=t, hub_cutout=7.5)
            raw["initial"]["state"] = "steady"
            raw["tip_mass"] = {"mass": tip}
            mesh, model, _, state, _ = prepare(validate(raw, "flat web"))
            x, e = state.node_pos, model.elements.nodes
            strain = np.linalg.norm(x[e[:, 1]] - x[e[:, 0]], axis=1) / model.elements.rest_len - 1
            tips = mesh.node_sets["tips"]
            rows.append({"tip_mass": tip, "h": t, "max_strain": float(strain.max()),
                         "tip_radius": float(np.hypot(x[tips, 0], x[tips, 1]).mean()),
                         "edge_ea": float(model.elements.ea.max())})
            print(rows[-1])
    path = RESULTS / "why.json"
    rep = json.loads(path.read_text()) if path.is_file() else {}
    rep["corners"] = rows
    RESULTS.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(converge_report._clean(rep), indent=1) + "\n")


def figs():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rep = json.loads((RESULTS / "why.json").read_text())
    t = np.array(rep["times"])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    for k, (name, sc) in enumerate(rep["scenes"].items()):
        for ax, col, scale, sens in ((axes[0], "hub_omega", OMEGA0, "sensitivity_hub_omega"),
                                     (axes[1], "arm_length", H, "sensitivity_arm_length")):
            vals = np.array([sc["quantities"][f"{col}@{x:g}"]["values"] for x in t], float)
            spread = (vals.max(axis=1) - vals.min(axis=1)) / scale
            ax.semilogy(t, np.maximum(spread, 1e-12), "-o", color=f"C{k}", ms=3,
                        label=sc["label"])
            ax.semilogy(t, np.maximum(np.array(sc[sens]) / scale, 1e-12), ":",
                        color=f"C{k}")
    axes[0].set_ylabel("hub rate: spread of 3 grids / omega0")
    axes[1].set_ylabel("mean arm length: spread of 3 grids / H")
    for ax in axes[:2]:
        ax.set_xlabel("t [s]   (dotted: one grid, hub inertia changed by 1e-9)")
        ax.set_ylim(1e-11, 2.0)
        ax.grid(alpha=0.3)
    axes[1].legend(fontsize=7, loc="lower right")
    rows = rep.get("corners", [])
    for tip, mk in ((10.0, "o-"), (0.0, "s--")):
        r = [x for x in rows if x["tip_mass"] == tip]
        if r:
            axes[2].loglog([x["h"] for x in r], [x["max_strain"] for x in r], mk,
                           label=f"corner masses {tip:g} kg")
    if rows:
        h = np.array(PAPER_WIDTHS)
        axes[2].loglog(h, 0.134 * 2.5 / h, "k:", lw=1, label="1/t")
        axes[2].set_xlabel("mesh width t [m]")
        axes[2].set_ylabel("largest strain, flat web in steady spin at 8 pi")
        axes[2].legend(fontsize=7)
        axes[2].grid(alpha=0.3, which="both")
        axes[2].set_xticks(h, [f"{x:g}" for x in h])
        axes[2].minorticks_off()
        axes[2].invert_xaxis()
    fig.tight_layout()
    fig.savefig(IMG / "converge_why.png", dpi=110)
    plt.close(fig)


def _f(v, d=3):
    return "-" if v is None or not math.isfinite(v) else f"{v:.{d}g}"


def tables():
    for name in PAPER:
        path = RESULTS / f"{name}.json"
        if not path.is_file():
            continue
        r = json.loads(path.read_text())
        i25 = [g["h"] for g in r["grids"]].index(2.5)
        print(f"\n{name} (study {r['study_wall_s']:.0f} s, load "
              f"{r['machine_before']['load_1min']:.1f}-{r['machine_after']['load_1min']:.1f})")
        print("| quantity | t = 5 | 2.5 | 1.25 | 0.625 m | convergence | order | "
              "extrapolated | error bar at 2.5 m |")
        print("|---|---|---|---|---|---|---|---|---|")
        for q in r["quantities"]:
            v = [x if x is not None else math.nan for x in q["values"]]
            bar = q["error_bar"][i25]
            print(f"| {q['name']} | " + " | ".join(_f(x, 4) for x in v) + f" | {q['kind']} | "
                  f"{_f(q['order'])} | {_f(q['extrapolated'], 4)} | {_f(bar)} |")
        for v in r["verdicts"]:
            print(f"- {v['criterion']}: {v['passed']} stable from {v['stable_from']}")
    path = RESULTS / "why.json"
    if path.is_file():
        rep = json.loads(path.read_text())
        print("\n| scene | hub rate at 0.1 s: spread / omega0, order | arm length at 0.2 s: "
              "spread / H, order | 1e-9 change at 0.2 s: hub / omega0 |")
        print("|---|---|---|---|")
        for sc in rep["scenes"].values():
            out = []
            for q, scale in (("hub_omega@0.1", OMEGA0), ("arm_length@0.2", H)):
                x = sc["quantities"][q]
                vals = [v for v in x["values"] if v is not None]
                out.append(f"{100 * (max(vals) - min(vals)) / scale:.2g} %, "
                           f"{x['kind']}" + (f" p = {x['order']:.2f}" if x["kind"] == "monotone"
                                              else ""))
            s = sc["sensitivity_hub_omega"][-1] / OMEGA0
            print(f"| {sc['label']} | {out[0]} | {out[1]} | {s:.1e} |")
        print("\n| corner masses | t [m] | largest strain | tips' radius [m] |")
        print("|---|---|---|---|")
        for c in rep.get("corners", []):
            print(f"| {c['tip_mass']:g} kg | {c['h']:g} | {100 * c['max_strain']:.3g} % | "
                  f"{c['tip_radius']:.4f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("stages", nargs="*", default=["paper", "why", "corners", "figs", "tables"])
    ap.add_argument("--out", default="out/converge_study", type=Path)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scenes", default="", help="why: only these scenes (comma-separated)")
    args = ap.parse_args(argv)
    import logging

    logging.basicConfig(level=logging.INFO, format="%(message)s")
    for stage in args.stages:
        if stage == "paper":
            paper(args.out, args.workers)
        elif stage == "why":
            why(args.out, args.workers, [x for x in args.scenes.split(",") if x])
        elif stage == "reanalyse":
            reanalyse()
        elif stage == "corners":
            corners()
        elif stage == "figs":
            figs()
        elif stage == "tables":
            tables()
        else:
            raise SystemExit(f"unknown stage {stage}")


if __name__ == "__main__":
    main()
