"""Validation of the held coil, the rate payout and the two-stage deployment (issue: the stowed
coil), with the numbers quoted by docs/validation.md.

    .venv/bin/python -m studies.validate_coil [--only eq7,rate,web,ramp]

Studies (each writes ``benchmarks/results/validation/coil_<study>.json`` and its figure
``docs/img/coil_<study>.png``):

- ``eq7``: stiff (1000x Zylon) Eq. 7 tethers, held coil, free payout, 50 and 100 elements,
  against the consistent distributed-arm model; uniform light stiff tethers beside them;
- ``rate``: the same tethers let out at 10 m/s by the gate (``payout = "gate"``, a latch
  that does no work), against the analytical reel (``payout = "rate"``), with the reel's
  work beside the FE energy (the FE reel against it: studies/validate_payout.py);
- ``web``: the paper's whole web (Zylon, as folded, free payout) against the Eq. 7 Zylon
  tethers (paper Fig. 6), held with and without bundling and loose, contact dissipation;
- ``ramp``: the stiff whole web under the spin ramp, as folded, held and loose, against the
  mapped analytical model (paper Fig. 10).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from spinweb_fe import case as case_mod
from spinweb_fe.analytic.compare import analytic_twin, fe_run, first_pivot, web_params
from spinweb_fe.case.scene import prepare
from spinweb_fe.post.plot import plot_histories

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "cases"
OUT = ROOT / "benchmarks" / "results" / "validation"
IMG = ROOT / "docs" / "img"
EQ7_STIFF = CASES / "paper_free_arms_eq7_stiff.toml"
EQ7 = CASES / "paper_free_arms_eq7.toml"


def load(path, sets=()):
    return case_mod.load(path, list(sets) + ["output.frame_dt=0"])


def dump(name, data):
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"coil_{name}.json").write_text(json.dumps(data, indent=1, default=float))


def rms_rel(a, b, key, sel, scale):
    """RMS over the window (all arms) of |a - b| / scale."""
    x, y = a[key][sel], b[key][sel]
    return float(np.sqrt(np.mean((x - y) ** 2)) / scale)


def norms(fe, ref, t_a, t_b, H, omega0):
    """The issue's norms on [t_a, t_b]: L (max and RMS over all arms) / H, phi max and RMS
    [rad], hub rate RMS / omega0; ``fe`` and ``ref`` on the same time grid."""
    n = min(len(fe["time"]), len(ref["time"]))
    f = {k: v[:n] for k, v in fe.items() if isinstance(v, np.ndarray) and len(v) >= n}
    r = {k: v[:n] for k, v in ref.items() if isinstance(v, np.ndarray) and len(v) >= n}
    t = f["time"]
    sel = (t >= t_a - 1e-12) & (t <= t_b + 1e-12)
    dL = np.abs(f["arm_length"][sel] - r["arm_length"][sel])
    dphi = np.abs(f["arm_angle"][sel] - r["arm_angle"][sel])
    return {"window_s": [t_a, t_b], "L_max_over_H": float(dL.max() / H),
            "L_rms_over_H": rms_rel(f, r, "arm_length", sel, H),
            "phi_max_rad": float(dphi.max()), "phi_rms_rad": rms_rel(f, r, "arm_angle", sel, 1.0),
            "hub_rms_over_omega0": rms_rel(f, r, "hub_omega", sel, abs(omega0))}


def contact_share(h, t):
    """Contact dissipation by time t over the initial kinetic energy."""
    i = int(np.searchsorted(h["time"], t - 1e-12))
    return float(h["contact_dissipation"][min(i, len(h["time"]) - 1)] / h["kinetic_energy"][0])


def report(label, rec):
    keys = ("L_max_over_H", "L_rms_over_H", "phi_max_rad", "phi_rms_rad", "hub_rms_over_omega0")
    print(f"{label}: " + ", ".join(f"{k} {rec[k]:.4g}" for k in keys if k in rec)
          + "".join(f", {k} {v:.4g}" for k, v in rec.items()
                    if k.startswith("contact") or k.endswith("_J")))


def eq7_study():
    """Stiff Eq. 7 tethers, held coil, free payout, against the consistent model."""
    recs, curves = {}, []
    for k in (50, 100):
        cs = load(EQ7_STIFF, [f"tethers.elements={k}", "time.end=0.4"])
        an, _ = analytic_twin(cs)
        fe, info = fe_run(cs)[:2]
        t1 = first_pivot(an)
        rec = dict(norms(fe, an, 0.0, t1, cs.tethers.length, cs.initial.omega),
                   elements=k, wall_s=info["wall_s"], t_uncoil=t1)
        recs[f"eq7_stiff_{k}"] = rec
        report(f"Eq. 7 stiff, {k} el.", rec)
        curves.append((fe, f"FE Eq. 7 tethers, {k} el.", "-"))
        if k == 50:
            first = norms(fe, an, 0.0, 0.15, cs.tethers.length, cs.initial.omega)
            recs["eq7_stiff_50_to_0.15s"] = first
            report("Eq. 7 stiff, 50 el., 0-0.15 s", first)
            curves.append((an, "analytic (consistent, Eq. 7 arm)", "k--"))
    uni = load(CASES / "validation" / "free_arms_stiff_light.toml", ["time.end=0.4"])
    an_u, _ = analytic_twin(uni)
    fe_u = fe_run(uni)[0]
    rec = norms(fe_u, an_u, 0.0, first_pivot(an_u), uni.tethers.length, uni.initial.omega)
    recs["uniform_light_stiff_50"] = rec
    report("uniform light stiff tethers", rec)
    plot_histories(curves, IMG / "coil_eq7.png", t_max=0.4,
                   title="held coil, stiff Eq. 7 tethers, free at 8 pi: FE vs consistent model")
    dump("eq7", recs)


def rate_study():
    """Stiff Eq. 7 tethers let out at 10 m/s by the FE gate, against the analytical reel."""
    recs, curves = {}, []
    for omega, tag in ((25.132741228718345, "8pi"), (6.283185307179586, "2pi")):
        law = ["stowage.payout_rate=10.0", f"initial.omega={omega}", "time.end=1.0"]
        an, res = analytic_twin(load(EQ7_STIFF, ["stowage.payout='rate'", *law]))
        cs = load(EQ7_STIFF, ["stowage.payout='gate'", *law])
        fe, info = fe_run(cs)[:2]
        t_b = float(an["time"][-1])
        rec = norms(fe, an, 0.0, t_b, cs.tethers.length, omega)
        ke0 = float(fe["kinetic_energy"][0])
        rec.update(stopped=res.stopped, KE0_J=ke0,
                   fe_KE_end_J=float(fe["kinetic_energy"][-1]),
                   fe_strain_end_J=float(fe["strain_energy"][-1]),
                   an_KE_end_J=float(an["kinetic_energy"][-1]),
                   an_reel_work_J=float(an["brake_work"][-1].sum()),
                   contact_by_end=contact_share(fe, t_b), wall_s=info["wall_s"])
        recs[f"rate_10mps_{tag}"] = rec
        report(f"rate payout 10 m/s at {tag}", rec)
        if tag == "8pi":
            curves += [(fe, "FE Eq. 7 tethers, gate 10 m/s", "-"),
                       (an, "analytic reel (consistent)", "k--")]
    plot_histories(curves, IMG / "coil_rate.png", t_max=1.0,
                   title="gate 10 m/s (FE) vs analytical reel, stiff Eq. 7 tethers at 8 pi")
    dump("rate", recs)


def web_study():
    """The paper's whole web (Zylon, as folded) against the Eq. 7 Zylon tethers (Fig. 6)."""
    base = load(EQ7, ["time.end=0.5"])
    ref = fe_run(base)[0]
    an, _ = analytic_twin(base)
    t1 = first_pivot(an)
    H, omega0 = base.tethers.length, base.initial.omega
    recs = {"t_uncoil": t1, "eq7_tethers": {"contact_by_t1": contact_share(ref, t1),
                                            "KE0_J": float(ref["kinetic_energy"][0])}}
    recs["eq7_vs_analytic"] = norms(ref, an, 0.0, t1, H, omega0)
    report("Eq. 7 Zylon tethers vs analytic", recs["eq7_vs_analytic"])
    curves = [(ref, "FE Eq. 7 tethers (held)", "k-"), (an, "analytic (Eq. 7 arm)", "k--")]
    web = CASES / "paper_free_web.toml"
    for label, sets in (("held", []),
                        ("held, bundled to 0.95", ["stowage.bundle='until_length'",
                                                   "stowage.bundle_release=0.95"]),
                        ("loose", ["stowage.coil='loose'"])):
        cs = load(web, sets + ["time.end=0.5"])
        fe, info = fe_run(cs)[:2]
        rec = dict(norms(fe, ref, 0.0, t1, H, omega0), contact_by_t1=contact_share(fe, t1),
                   KE0_J=float(fe["kinetic_energy"][0]), wall_s=info["wall_s"])
        recs[f"web_{label}"] = rec
        report(f"web {label} vs Eq. 7 tethers", rec)
        curves.append((fe, f"FE web, {label}", "-"))
    plot_histories(curves, IMG / "coil_web.png", t_max=0.5,
                   title="paper web (Zylon, as folded) vs Eq. 7 tethers, free at 8 pi")
    dump("web", recs)


def ramp_study():
    """The stiff whole web under the spin ramp, as folded, held and loose (paper Fig. 10)."""
    recs, curves = {}, []
    path = CASES / "paper_ramp_web_stiff.toml"
    for label, sets in (("held", []), ("loose", ["stowage.coil='loose'"])):
        cs = load(path, sets + ["web.mesh_width=5.0", "time.end=2.5"])
        mesh, model = prepare(cs)[:2]
        p, _ = web_params(cs, mesh, model)
        an, _ = analytic_twin(cs, p)
        fe, info = fe_run(cs)[:2]
        ramp = norms(fe, an, 0.0, 2.0, 1.0, 8 * np.pi)
        rec = {"H_mapped_m": p.H, "L_rms_m": ramp["L_rms_over_H"], "L_max_m": ramp["L_max_over_H"],
               "phi_rms_rad": ramp["phi_rms_rad"], "phi_max_rad": ramp["phi_max_rad"],
               "contact_by_2s_J": float(fe["contact_dissipation"][np.searchsorted(fe["time"], 2.0)]),
               "wall_s": info["wall_s"]}
        for t_b in (0.5, 1.0, 1.5):
            w = norms(fe, an, 0.0, t_b, 1.0, 8 * np.pi)
            rec[f"to_{t_b}s"] = {"L_rms_m": w["L_rms_over_H"], "phi_rms_rad": w["phi_rms_rad"]}
        recs[label] = rec
        print(f"ramp {label}: {rec}")
        curves.append((fe, f"FE stiff web, {label} coil", "-"))
        if label == "held":
            curves.append((an, f"analytic (mapped, H = {p.H:.1f} m)", "k--"))
    plot_histories(curves, IMG / "coil_ramp.png", t_max=2.5,
                   title="stiff web (t = 5 m, as folded), spin ramp 0 -> 8 pi in 2 s")
    dump("ramp", recs)


STUDIES = {"eq7": eq7_study, "rate": rate_study, "web": web_study, "ramp": ramp_study}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=",".join(STUDIES))
    args = ap.parse_args(argv)
    for name in args.only.split(","):
        t0 = time.perf_counter()
        STUDIES[name]()
        print(f"== {name}: {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
