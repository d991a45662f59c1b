"""The payout devices from t = 0, swept (issue 43, item 1): the FE reel and brake against
their analytical twins over the whole run, never restarted, on point-mass tethers
(validation/free_arms_stiff_light.toml, 100x Zylon) and stiff Eq. 7 tethers
(paper_free_arms_eq7_stiff.toml), for brake forces 0-50 kN and reel rates 2-30 m/s.

    .venv/bin/python -m studies.validate_devices [--only brake,reel] [--tethers light,eq7]
                                                 [--cache DIR]

Writes ``benchmarks/results/validation/devices.json`` and ``docs/img/devices_*.png``;
``--only tables`` prints docs/validation.md's tables from the JSON. Norms as
studies/validate_payout.py (rows from 1 ms to the end of the shorter history: the
analytical model stops where an arm swings over its held coil, its validity), the
targets of issue #24: L 0.5 % of H, phi 0.02 rad, hub rate 1 % of omega0 (RMS), the
device's work 1 %.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from studies import validate_payout as vp
from spinweb_fe.analytic.compare import analytic_twin

ROOT = Path(__file__).resolve().parent.parent
FORCES = (0.0, 10e3, 20e3, 30e3, 40e3, 50e3)
RATES = (2.0, 5.0, 10.0, 20.0, 30.0)
TETHERS = {"light": (vp.LIGHT, [vp.E_100X]), "eq7": (vp.EQ7_STIFF, [])}
END = 2.0  # s, the longest run
BRAKE_END = 0.6  # s: the brakes' course (runaway, peel, re-coil or hold) is decided by then


def compare(cs, tag):
    """FE and analytical run of a case from t = 0: the norms over the common rows, the
    device's work at the last common row, the analytical model's end and regimes."""
    H, omega0 = cs.tethers.length, cs.initial.omega
    t0 = time.perf_counter()
    an, res = analytic_twin(cs)
    t_an = time.perf_counter() - t0
    fe, info, mesh, _ = vp.run_fe(cs, tag)
    f, a = vp.aligned(fe, an)
    t = f["time"]
    sel = t > 1e-3 - 1e-12
    rec = dict(vp.norms(f, a, sel, H, omega0), stopped=res.stopped,
               an_end_s=float(an["time"][-1]), an_switches=len(res.switches),
               an_regimes=res.info["regimes"], an_wall_s=t_an, fe_wall_s=info["wall_s"],
               an_speed_max_mps=float(np.abs(an["payout_speed"]).max()),
               fe_speed_max_mps=float(np.abs(fe["payout_speed"]).max()),
               an_L_end_m=float(a["arm_length"][-1, 0]), fe_L_end_m=float(f["arm_length"][-1, 0]),
               balance_fe_over_KE0=vp.balance(fe))
    first = next((sw[0] for sw in res.switches if sw[2] in ("peel", "coiled", "laid")
                  and sw[0] > 1e-3), None)  # the brake's first return to the coil's tangent
    if first is not None and np.sum(sel & (t <= first)) > 5:
        win = sel & (t <= first)
        rec["to_tangent"] = dict(vp.norms(f, a, win, H, omega0),
                                 work=vp.work(f, a, int(np.flatnonzero(win)[-1])))
    i = len(t) - 1
    w = vp.work(f, a, i)
    rec["work"] = w if abs(w["an_J"]) > 1e-6 * f["kinetic_energy"][0] else {
        **w, "rel": None}  # a device that did (next to) no work: no relative error
    return rec, f, a


def sweep(kind, tethers):
    out = {}
    path, sets = TETHERS[tethers]
    values = FORCES if kind == "brake" else RATES
    curves = []
    for k, v in enumerate(values):
        if kind == "brake":
            cs = vp.load(path, sets + vp.brake_sets(v, BRAKE_END))
            name = f"{v / 1e3:g}kN"
        else:
            cs = vp.load(path, sets + vp.reel_sets(v, 50.0)[:2]
                         + [f"time.end={min(50.0 / v + 0.05, END)}"])
            name = f"{v:g}mps"
        rec, f, a = compare(cs, f"dev_{kind}_{tethers}_{name}")
        out[name] = rec
        print(f"{kind} {tethers} {name}: L rms {rec['L_rms_over_H']:.2e} H, phi rms "
              f"{rec['phi_rms_rad']:.3g}, hub rms {rec['hub_rms_over_omega0']:.2e}, work "
              f"{rec['work']['rel']}, an to {rec['an_end_s']:.3f} s "
              f"({rec['an_switches']} switches, {rec['an_wall_s']:.1f} s) "
              f"{rec['stopped'][:60]}", flush=True)
        if k % 2 == 0:
            curves.append((name, f, a, f"C{k}"))
    vp.plot_device(curves, vp.IMG / f"devices_{kind}_{tethers}.png",
                   f"{kind} from t = 0, {tethers} tethers: FE (solid) vs analytical (dashed)")
    return out


def tables(data):
    for key, runs in data.items():
        if not isinstance(runs, dict) or key == "machine":
            continue
        print(f"\n**{key}**\n")
        print("| run | window [s] | L RMS / H | phi RMS [rad] | hub RMS / omega0 | work FE / "
              "analytical | analytical end |")
        print("|---|---|---|---|---|---|---|")
        for name, r in runs.items():
            if "to_tangent" in r and key.startswith("brake"):
                q = r["to_tangent"]
                print(f"| {name}, to the first tangent | {q['window_s'][0]:.3f}-"
                      f"{q['window_s'][1]:.3f} | {100 * q['L_rms_over_H']:.2g} % | "
                      f"{q['phi_rms_rad']:.2g} | {100 * q['hub_rms_over_omega0']:.2g} % | "
                      f"{q['work']['fe_J'] / 1e3:.4g} / {q['work']['an_J'] / 1e3:.4g} kJ "
                      f"({100 * q['work']['rel']:.2g} %) | |")
            w = r["work"]
            ws = "-" if w["rel"] is None else (f"{w['fe_J'] / 1e3:.4g} / {w['an_J'] / 1e3:.4g} kJ"
                                               f" ({100 * w['rel']:.2g} %)")
            print(f"| {name} | {r['window_s'][0]:.3f}-{r['window_s'][1]:.3f} | "
                  f"{100 * r['L_rms_over_H']:.2g} % | {r['phi_rms_rad']:.2g} | "
                  f"{100 * r['hub_rms_over_omega0']:.2g} % | {ws} | "
                  f"{r['stopped'][:40] or 'completed'} |")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="brake,reel")
    ap.add_argument("--tethers", default="light,eq7")
    ap.add_argument("--cache", default=None)
    args = ap.parse_args(argv)
    out_json = vp.OUT / "devices.json"
    if args.only == "tables":
        tables(json.loads(out_json.read_text()))
        return 0
    vp.CACHE = Path(args.cache) if args.cache else None
    data = json.loads(out_json.read_text()) if out_json.exists() else {}
    for kind in args.only.split(","):
        for tethers in args.tethers.split(","):
            data[f"{kind}_{tethers}"] = sweep(kind, tethers)
            (vp.OUT / "devices.partial.json").write_text(json.dumps(data, default=float))
    vp.OUT.mkdir(parents=True, exist_ok=True)
    out_json.write_text(json.dumps({"machine": vp.machine(), **data}, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
