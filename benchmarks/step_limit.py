"""What limits the time step of the paper's Zylon cases: energy balance and error against a
refined run over the CFL fraction (issue: fewer steps).

    python -m benchmarks.step_limit [--cases paper_free_web ...] [--end 2.0]

For each case (held coil, the case's own mesh and damping), runs time.cfl = 0.1 (the
reference) and 0.2 (the default) ... 0.9, each to ``--end`` seconds (frames off), and
records per run: steps, loop seconds, the energy-balance error (max |KE + SE - W + D - E0|
over the energy scale, record/energy.py), whether the solver's audit stopped it, and the
error against the reference on the common 1 ms history grid: L RMS over all arms / H (H the
deployed arm length of the mesh) and hub rate RMS / omega0 (the case's initial or largest
prescribed rate). Writes benchmarks/results/step_limit.json and step_limit.png.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from benchmarks.common import machine
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.errors import RunError
from spinweb_fe.record.arms import deployed_length
from spinweb_fe.record.energy import balance_error
from spinweb_fe.run.loop import Schedule, simulate

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results"
CASES = ["paper_free_arms", "paper_free_web", "paper_two_stage_web", "paper_payout_web",
         "paper_feedback_web", "paper_ramp_web"]
CFLS = (0.1, 0.2, 0.3, 0.45, 0.6, 0.75, 0.9)


def run(name, cfl, end, sets=()):
    cs = case_mod.load(ROOT / "cases" / f"{name}.toml",
                       [f"time.cfl={cfl}", f"time.end={end}", "output.frame_dt=0", *sets])
    mesh, model, control, state, dt = prepare(cs)
    t0 = time.perf_counter()
    try:
        res = simulate(model, control, state, dt, Schedule(end, cs.output.history_dt))
        h, stopped, loop_s, steps = res.history, "", res.loop_s, res.steps
    except RunError as exc:
        return {"cfl": cfl, "dt": dt, "stopped": str(exc), "wall_s": time.perf_counter() - t0}
    omega0 = max(abs(cs.initial.omega), 1e-9)
    if control.law.prescribes_rate:
        omega0 = float(np.abs(h["hub_omega"]).max())
    ke0 = max(float(h["kinetic_energy"][0]), float(np.abs(h["torque_work"]).max()), 1e-30)
    return {"cfl": cfl, "dt": dt, "steps": steps, "loop_s": loop_s, "stopped": stopped,
            "energy_error": float(balance_error(h)), "H": float(deployed_length(mesh).mean()),
            "omega0": omega0, "damping_share": float(h["damping_dissipation"][-1] / ke0),
            "history": h}


def errors(r, ref):
    n = min(len(r["history"]["time"]), len(ref["history"]["time"]))
    a, b = r["history"], ref["history"]
    dL = a["arm_length"][:n] - b["arm_length"][:n]
    dw = a["hub_omega"][:n] - b["hub_omega"][:n]
    return {"L_rms_over_H": float(np.sqrt(np.mean(dL ** 2)) / r["H"]),
            "hub_rms_over_omega0": float(np.sqrt(np.mean(dw ** 2)) / r["omega0"])}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=CASES)
    ap.add_argument("--end", type=float, default=2.0)
    ap.add_argument("--cfl", type=float, nargs="*", default=list(CFLS[1:]),
                    help="the runs' cfl values (the reference is always 0.1, undamped)")
    ap.add_argument("--set", dest="sets", action="append", default=[],
                    help="case overrides of the runs (not of the reference), e.g. "
                         "cable.damping_ratio=0.01")
    ap.add_argument("--out", default="step_limit", help="name of the JSON / PNG files")
    args = ap.parse_args(argv)
    out = {"machine": machine(), "end_s": args.end, "sets": args.sets, "cases": {}}
    for name in args.cases:
        rows = []
        ref = run(name, CFLS[0], args.end)
        for cfl in [CFLS[0]] + args.cfl:
            r = ref if cfl == CFLS[0] else run(name, cfl, args.end, args.sets)
            row = {k: v for k, v in r.items() if k != "history"}
            if "history" in r and "history" in ref:
                row.update(errors(r, ref))
            rows.append(row)
            print(name, json.dumps({k: (round(v, 6) if isinstance(v, float) else v)
                                    for k, v in row.items()}), flush=True)
        out["cases"][name] = rows
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{args.out}.json").write_text(json.dumps(out, indent=1))
    plot(out, OUT / f"{args.out}.png")
    return 0


def plot(out, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, rows in out["cases"].items():
        ok = [r for r in rows if not r["stopped"]]
        c = [r["cfl"] for r in ok]
        ax[0].semilogy(c, [max(r["energy_error"], 1e-9) for r in ok], "o-", label=name)
        c2 = [r["cfl"] for r in ok if "L_rms_over_H" in r and r["cfl"] > 0.1]
        ax[1].semilogy(c2, [max(r["L_rms_over_H"], 1e-9) for r in ok
                            if "L_rms_over_H" in r and r["cfl"] > 0.1], "o-", label=name)
    ax[0].axhline(1e-3, color="k", lw=0.8, ls=":")
    ax[0].set(xlabel="cfl (fraction of the critical step)", ylabel="energy-balance error",
              title=f"energy balance over {out['end_s']:g} s")
    ax[1].set(xlabel="cfl", ylabel="L RMS error / H (vs cfl 0.1)",
              title="error against the refined step")
    ax[0].legend(fontsize=7)
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    raise SystemExit(main())
