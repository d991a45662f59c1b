"""Run the paper's FE cases to their end and summarise them (issue: explicit solver).

    python -m benchmarks.paper_runs [--cases paper_free_web ...] [--out out/paper]

Writes results into OUT/<case>/ (results.h5, ParaView frames), a four-panel plot per case to
docs/img/paper_<case>.png, and benchmarks/results/paper_runs.json with, per case: steps, dt,
loop and compile seconds, element-updates/s, the energy-balance error (max |KE + SE - W + D -
E0| over the energy scale) and the angular-momentum error (free runs: max |K - K0| / K0; with a
torque: max |K - K0 - integral of M dt| / K0), and the final arm length and hub rate.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from benchmarks.common import machine
from spinweb_fe import case as case_mod
from spinweb_fe.post.plot import four_panel
from spinweb_fe.record.energy import energy_balance
from spinweb_fe.run.driver import run_case

ROOT = Path(__file__).resolve().parent.parent
DEFAULT = ["paper_free_arms", "paper_free_arms_eq7", "paper_free_web", "paper_two_stage_web",
           "paper_payout_web", "paper_reel_arms", "paper_brake_arms",
           "paper_feedback_web", "paper_ramp_web", "tri_ramp_web",
           "paper_free_arms_stiff", "paper_free_arms_eq7_stiff", "paper_free_web_stiff",
           "paper_feedback_web_stiff", "paper_ramp_web_stiff"]


def errors(h):
    """(energy balance error, angular momentum error) of a history dict."""
    e = energy_balance(h)
    scale = max(np.abs(h["kinetic_energy"]).max(), np.abs(h["torque_work"]).max())
    t = h["time"]
    K = h["angular_momentum"]
    # angular impulse of the control torque (trapezoid on the history grid)
    impulse = np.concatenate([[0.0], np.cumsum(0.5 * (h["hub_torque"][1:] + h["hub_torque"][:-1])
                                              * np.diff(t))])
    k_scale = max(np.abs(K).max(), 1e-30)
    return float(np.abs(e - e[0]).max() / scale), float(np.abs(K - K[0] - impulse).max() / k_scale)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=DEFAULT)
    ap.add_argument("--out", default=str(ROOT / "out" / "paper"))
    ap.add_argument("--set", dest="sets", action="append", default=[])
    args = ap.parse_args(argv)
    out_json = ROOT / "benchmarks" / "results" / "paper_runs.json"
    summary = json.loads(out_json.read_text()) if out_json.exists() else {}
    # the machine of the latest run (CPU model and ISA); each case row carries its own date
    summary["machine"] = dict(machine(), date=time.strftime("%Y-%m-%d"))
    for name in args.cases:
        case = case_mod.load(ROOT / "cases" / f"{name}.toml", args.sets)
        d = Path(args.out) / name
        t0 = time.perf_counter()
        res = run_case(case, d, progress=False)
        wall = time.perf_counter() - t0
        h = res.history
        e_err, k_err = errors(h)
        m = res.state.node_pos.shape[0]
        from spinweb_fe.case.scene import build_mesh

        n_el = build_mesh(case).n_elems
        row = {"title": case.title, "end_s": case.time.end, "steps": res.steps, "dt": res.dt,
               "elements": n_el, "nodes": m, "wall_s": wall, "loop_s": res.loop_s,
               "compile_s": res.compile_s,
               "element_updates_per_s": n_el * res.steps / max(res.loop_s, 1e-9),
               "energy_error": e_err, "angular_momentum_error": k_err,
               "contact_dissipation_J": float(h["contact_dissipation"][-1]),
               "contact_share_of_KE0": float(h["contact_dissipation"][-1]
                                             / max(h["kinetic_energy"][0], 1e-30)),
               "stowage": f"{case.stowage.coil}, {case.stowage.payout}"
                          + (f", bundle {case.stowage.bundle}" if case.stowage.bundle != "none"
                             else ""),
               "final_arm_length_m": [float(x) for x in h["arm_length"][-1]],
               "final_hub_omega": float(h["hub_omega"][-1]),
               "max_tension_N": float(h["max_tension"].max()),
               "date": time.strftime("%Y-%m-%d")}
        summary[name] = row
        four_panel([d / "results.h5"], ROOT / "docs" / "img" / f"paper_{name}.png",
                   labels=[name], title=case.title)
        print(name, json.dumps(row))
        out_json.write_text(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
