"""Validation of the FE solver against the consistent analytical model, and the paper's Figs. 5-10.

One command runs the whole study (about 10 minutes of wall time on one core)::

    .venv/bin/python -m studies.validate_analytic [--only tethers,web,tri,effects,figs]

It writes ``benchmarks/results/validation/*.json`` (error tables, timings), overlaid
four-panel plots ``benchmarks/results/validation/*.png`` and the figures quoted by
docs/validation.md (``docs/img/validation_*.png``, ``docs/img/fig5.png`` ... ``fig10.png``).
The mappings and error norms are spinweb_fe.analytic.compare's; method and discussion:
docs/validation.md.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from spinweb_fe import case as case_mod
from spinweb_fe.analytic.compare import (QUANTITIES, analytic_twin, error_table, fe_run,
                                         first_pivot, web_params)
from spinweb_fe.case.scene import prepare
from spinweb_fe.errors import RunError
from spinweb_fe.post.plot import plot_histories

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "cases"
OUT = ROOT / "benchmarks" / "results" / "validation"
IMG = ROOT / "docs" / "img"


def load_case(path, sets=()):
    return case_mod.load(path, sets=list(sets))


# ----------------------------------------------------------------------------- plots

def plot4(curves, out, title=None, t_max=None):
    """Four-panel overlay of a list of (history, label, style)."""
    plot_histories(curves, out, title=title, t_max=t_max)


def dump(name, data):
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{name}.json").write_text(json.dumps(data, indent=1, default=float))


def save_hist(name, h):
    OUT.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(OUT / f"{name}.npz", **{k: v for k, v in h.items()
                                                if isinstance(v, np.ndarray)})


# ----------------------------------------------------------------------------- studies

def compare(label, case, params=None, windows=None, store=None, variant=None):
    """One FE run and its analytical twin: error table, info. Returns (fe, an, record)."""
    an, res = analytic_twin(case, params)
    try:
        fe, info, mesh, model = fe_run(case, variant)
    except RunError as exc:
        print(f"{label}: FE run failed: {exc}")
        return None, an, {"label": label, "failed": str(exc)}
    t1 = first_pivot(an)
    wins = {"uncoil": (0.0, t1)}
    wins.update({k: (t1 if a is None else a, b) for k, (a, b) in (windows or {}).items()})
    rec = {"label": label, "fe": info, "t_uncoil": t1, "errors": error_table(fe, an, wins),
           "switches": [(float(s[0]), s[2]) for s in res.switches][:6]}
    print(f"{label}: {info['elements']} elements, dt {info['dt']:.3g} s, {info['steps']} steps, "
          f"{info['wall_s']:.1f} s wall, energy error {info['energy_balance_error']:.2g}; "
          f"uncoil to {t1:.3f} s")
    for w in rec["errors"]:
        print("   ", w, {s: (round(rec['errors'][w][s]['max'], 4), round(rec['errors'][w][s]['rms'], 4))
                         for _, s, _ in QUANTITIES})
    if store:
        save_hist(store + "_fe", fe)
        save_hist(store + "_an", an)
    return fe, an, rec


def tether_study():
    """Stiff tethers (free and ramp): convergence in mesh and time step, light variant."""
    base = CASES / "paper_free_arms_stiff.toml"
    t_end, win_after = 0.7, {"after": (None, 0.7)}
    recs = {"mesh": [], "cfl": [], "light": [], "ramp": []}
    curves = []
    # mesh study at cfl 0.15 (0.3 gains energy in the slack/snap of fine stiff tethers)
    for k in (25, 50, 100, 200):
        cs = load_case(base, [f"tethers.elements={k}", "time.cfl=0.15", f"time.end={t_end}"])
        fe, an, rec = compare(f"free, {k} elements, cfl 0.15", cs, windows=win_after,
                              store=f"tethers_free_{k}" if k == 50 else None)
        recs["mesh"].append(dict(rec, elements=k, cfl=0.15))
        if fe is not None:
            curves.append((fe, f"FE {k} el.", "-"))
    curves.append((an, "analytic (consistent)", "k--"))
    plot4(curves, IMG / "validation_tethers_free.png",
          "stiff tethers (1000x Zylon), free at 8 pi, cfl 0.15: FE mesh study vs consistent model")
    for k, cfl in ((50, 0.3), (50, 0.075), (100, 0.3), (200, 0.3)):
        cs = load_case(base, [f"tethers.elements={k}", f"time.cfl={cfl}", f"time.end={t_end}"])
        _, _, rec = compare(f"free, {k} elements, cfl {cfl}", cs, windows=win_after)
        recs["cfl"].append(dict(rec, elements=k, cfl=cfl))
    # lighter tether: density / 10 at the same EA (0.079 kg per tether instead of 0.79 kg)
    light = CASES / "validation" / "free_arms_stiff_light.toml"
    for k in (25, 50):
        cs = load_case(light, [f"tethers.elements={k}", "time.cfl=0.15", f"time.end={t_end}"])
        fe, an, rec = compare(f"light, {k} elements", cs, windows=win_after,
                              store="tethers_light_%d" % k if k == 50 else None)
        recs["light"].append(dict(rec, elements=k))
    # beyond the first cycle (2 s): where the models part
    cs = load_case(base, ["time.end=2.0", "time.cfl=0.15"])
    fe, an, rec = compare("free, 50 elements, cfl 0.15, to 2 s", cs,
                          windows={"swing_recoil": (0.32, 0.7), "second_cycle": (0.7, 2.0)})
    recs["long"] = rec
    plot4([(fe, "FE 50 el.", "-"), (an, "analytic (consistent)", "k--")],
          IMG / "validation_tethers_free_long.png",
          "stiff tethers, free at 8 pi, 2 s: the models part after the first re-coil")
    # spin ramp 0 -> 8 pi in 2 s
    ramp = CASES / "validation" / "ramp_arms_stiff.toml"
    curves = []
    for k, cfl in ((25, 0.3), (25, 0.15), (50, 0.15)):
        cs = load_case(ramp, [f"tethers.elements={k}", f"time.cfl={cfl}"])
        fe, an, rec = compare(f"ramp, {k} elements, cfl {cfl}", cs,
                              windows={"ramp": (0.0, 2.0), "after": (2.0, cs.time.end)})
        recs["ramp"].append(dict(rec, elements=k, cfl=cfl))
        if fe is not None:
            curves.append((fe, f"FE {k} el., cfl {cfl}", "-"))
    curves.append((an, "analytic (consistent)", "k--"))
    plot4(curves, IMG / "validation_tethers_ramp.png",
          "stiff tethers, spin ramp 0 -> 8 pi in 2 s: FE vs consistent model")
    dump("tethers", recs)
    return recs


def effects_study():
    """Targeted experiments on what separates FE and analytic (stiff tethers, 50 elements)."""
    base = CASES / "paper_free_arms_stiff.toml"
    recs = {}
    runs = {"reference": [], "friction_0.3": ["hub.friction=0.3"],
            "friction_1.0": ["hub.friction=1.0"],
            "EA_10x_lower": ["cable.area=1.025e-6", "cable.density=15400.0"]}
    for name, sets in runs.items():
        cs = load_case(base, sets + ["time.end=0.7"])
        _, _, rec = compare(name, cs, windows={"after": (None, 0.7)})
        recs[name] = rec
    dump("effects", recs)
    return recs


def web_study():
    """Stiff web (free and ramp) against the mapped distributed arm.

    Both hub attachments of the star fold (fold.ties = 'frame', the default, and 'axes'),
    each as folded and with the root region tied to the hub (:func:`rigid_root`).
    """
    recs = {"free": [], "ramp": [], "mapping": {}}
    free = CASES / "paper_free_web_stiff.toml"
    ramp = CASES / "paper_ramp_web_stiff.toml"
    variants = [(ties, v) for ties in ("frame", "axes") for v in (None, "rigid_root")]
    for path, t_end, key, wins in ((free, 0.8, "free", {"after": (None, 0.8)}),
                                   (ramp, 4.0, "ramp", {"ramp": (0.0, 2.0),
                                                        "after": (2.0, 4.0)})):
        curves, ans = [], []
        for ties, variant in variants:
            cs = load_case(path, ["web.mesh_width=5.0", f"fold.ties='{ties}'",
                                  f"time.end={t_end}"])
            mesh, model = prepare(cs)[:2]
            p, mp = web_params(cs, mesh, model)
            recs["mapping"][f"{ties}, mesh_width 5"] = mp
            label = f"{key}, t = 5 m, ties {ties}, {variant or 'as folded'}"
            fe, an, rec = compare(label, cs, params=p, windows=wins, variant=variant)
            recs[key].append(dict(rec, mesh_width=5.0, ties=ties, variant=variant or "as folded"))
            if fe is not None:
                curves.append((fe, f"FE ties {ties}, {variant or 'as folded'}", "-"))
            if variant is None:
                ans.append((an, f"analytic, {ties} mapping (H = {p.H:.1f} m)",
                            "k--" if ties == "frame" else "k:"))
        curves += ans
        plot4(curves, IMG / f"validation_web_{key}.png",
              f"stiff web (1000x Zylon, t = 5 m), {key}: FE variants vs consistent model")
    # mesh refinement of the closest variant, and of the default fold for the free case
    for path, t_end, key, wins, ties, variant in (
            (free, 0.8, "free", {"after": (None, 0.8)}, "frame", None),
            (free, 0.8, "free", {"after": (None, 0.8)}, "frame", "rigid_root"),
            (ramp, 3.0, "ramp", {"ramp": (0.0, 2.0), "after": (2.0, 3.0)}, "frame",
             "rigid_root")):
        cs = load_case(path, ["web.mesh_width=2.5", f"fold.ties='{ties}'", f"time.end={t_end}"])
        mesh, model = prepare(cs)[:2]
        p, mp = web_params(cs, mesh, model)
        recs["mapping"][f"{ties}, mesh_width 2.5"] = mp
        fe, an, rec = compare(f"{key}, t = 2.5 m, ties {ties}, {variant or 'as folded'}", cs,
                              params=p, windows=wins, variant=variant)
        recs[key].append(dict(rec, mesh_width=2.5, ties=ties, variant=variant or "as folded"))
    # how much the root-region inertia in the mapping matters (analytic vs analytic)
    cs = load_case(free, ["web.mesh_width=5.0", "time.end=0.8"])
    mesh, model = prepare(cs)[:2]
    an_drop, _ = analytic_twin(cs, web_params(cs, mesh, model, root="drop")[0])
    an_map, _ = analytic_twin(cs, web_params(cs, mesh, model)[0])
    recs["mapping_effect_root_dropped"] = error_table(an_drop, an_map, {"all": (0.0, 0.8)})
    dump("web", recs)
    return recs


def tri_study():
    """The stiff triangular web (tritri, 3 arms) against the mapped distributed arm, as
    folded and with the root region tied to the hub, free at 8 pi and under the spin ramp:
    the same comparison as :func:`web_study` for the 3-arm star fold."""
    recs = {"free": [], "ramp": [], "mapping": {}}
    case = CASES / "tri_ramp_web.toml"
    stiff = ["cable.youngs_modulus=180e12", "web.mesh_width=5.0"]
    free = stiff + ["control.law='free'", "initial.omega=25.132741228718345", "time.end=0.8"]
    ramp = stiff + ["time.end=4.0"]
    for sets, key, wins in ((free, "free", {"after": (None, 0.8)}),
                            (ramp, "ramp", {"ramp": (0.0, 2.0), "after": (2.0, 4.0)})):
        curves = []
        for variant in (None, "rigid_root"):
            cs = load_case(case, sets)
            mesh, model = prepare(cs)[:2]
            p, mp = web_params(cs, mesh, model)
            recs["mapping"]["tritri, mesh_width 5"] = mp
            label = f"tritri {key}, t = 5 m, {variant or 'as folded'}"
            fe, an, rec = compare(label, cs, params=p, windows=wins, variant=variant)
            recs[key].append(dict(rec, mesh_width=5.0, ties="frame",
                                  variant=variant or "as folded"))
            if fe is not None:
                curves.append((fe, f"FE tritri, {variant or 'as folded'}", "-"))
        curves.append((an, f"analytic, 3 arms (H = {p.H:.1f} m)", "k--"))
        plot4(curves, IMG / f"validation_tri_{key}.png",
              f"stiff triangular web (1000x Zylon, t = 5 m), {key}: FE vs consistent model")
    dump("tri", recs)
    return recs


def figures():
    """The paper's Figs. 5-10 (Zylon unless stated), FE and analytic overlaid."""
    recs = {}

    def fe_an(path, sets=(), web=False, t_end=None):
        cs = load_case(path, list(sets) + ([f"time.end={t_end}"] if t_end else []))
        fe, info, mesh, model = fe_run(cs)
        an_case, _ = analytic_twin(cs)
        an_map = analytic_twin(cs, web_params(cs, mesh, model)[0])[0] if web else None
        return cs, fe, info, an_case, an_map

    def loose(path, t_end=None):
        """The same case with the coil loose on the hub (the behaviour before the held coil)."""
        cs = load_case(path, ["stowage.coil='loose'"] + ([f"time.end={t_end}"] if t_end else []))
        fe = fe_run(cs)[0]
        return fe, {**summary(fe), "contact_dissipation_J": float(fe["contact_dissipation"][-1])}

    def summary(h):
        w = h["hub_omega"]
        L = h["arm_length"][:, 0]
        return {"omega_min": float(w.min()), "omega_max": float(w.max()),
                "omega_end": float(w[-1]), "L_end": float(L[-1]), "L_min_after_max": float(
                    L[int(np.argmax(L)):].min()), "t_L_max": float(h["time"][int(np.argmax(L))]),
                "L_max": float(L.max()), "tip_omega_range": [float(h["tip_omega"][:, 0].min()),
                                                             float(h["tip_omega"][:, 0].max())]}

    # Fig. 5: free deployment, arms (tethers) only, Zylon
    cs, fe, info, an, _ = fe_an(CASES / "paper_free_arms.toml")
    fe_l, recs_l = loose(CASES / "paper_free_arms.toml")
    plot4([(fe, "FE (Zylon tethers), held coil", "-"), (fe_l, "FE, loose coil", ":"),
           (an, "analytic (consistent)", "k--")],
          IMG / "fig5.png", "Fig. 5: free deployment at 8 pi, four tethers with 10 kg tips")
    recs["fig5"] = {"fe": summary(fe), "an": summary(an), "run": info, "fe_loose": recs_l}
    # Fig. 6: free deployment, arms only and whole web
    cs, few, info, an_w, an_wm = fe_an(CASES / "paper_free_web.toml", web=True)
    few_l, recs_l = loose(CASES / "paper_free_web.toml")
    plot4([(fe, "FE arms only", "-"), (few, "FE whole web, held coil", "-"),
           (few_l, "FE whole web, loose coil", ":"),
           (an, "analytic arms only", "k--"), (an_wm, "analytic web (mapped)", "k:")],
          IMG / "fig6.png", "Fig. 6: free deployment at 8 pi, arms only and whole web (Zylon)")
    recs["fig6"] = {"fe_web": summary(few), "an_web_mapped": summary(an_wm),
                    "an_web_case": summary(an_w), "run": info, "fe_web_loose": recs_l,
                    "fe_web_contact_dissipation_J": float(few["contact_dissipation"][-1])}
    # Fig. 7: feedback torque M0 = omega0 1e5
    cs, fe7, info, an7, an7m = fe_an(CASES / "paper_feedback_web.toml", web=True,
                                     )
    fe7_l, recs_l = loose(CASES / "paper_feedback_web.toml")
    plot4([(fe7, "FE web (Zylon), held coil", "-"), (fe7_l, "FE web, loose coil", ":"),
           (an7m, "analytic (mapped)", "k--"), (an7, "analytic (case mapping)", "k:")],
          IMG / "fig7.png", "Fig. 7: feedback torque M = M0 (1 - omega/omega0), M0 = omega0 1e5")
    recs["fig7"] = {"fe": summary(fe7), "an_mapped": summary(an7m), "an_case": summary(an7),
                    "run": info, "fe_loose": recs_l}
    # Fig. 8: analytical only, r0 = 1 m, M0 = 60 pi, omega0 = pi/2, 2 pi, 8 pi
    curves, recs["fig8"] = [], {}
    for tag, lab in (("pi2", "omega0 = pi/2"), ("2pi", "omega0 = 2 pi"), ("8pi", "omega0 = 8 pi")):
        an8, _ = analytic_twin(load_case(CASES / f"analytic_fig8_{tag}.toml"))
        curves.append((an8, lab, "-"))
        recs["fig8"][tag] = summary(an8)
    plot4(curves, IMG / "fig8.png", "Fig. 8 (analytical): r0 = 1 m, M0 = 60 pi N m")
    # Figs. 9-10: spin ramp 0 -> 8 pi in 2 s; Fig. 9 Zylon, Fig. 10 1000x stiffer cable
    cs, fe9, info9, an9, an9m = fe_an(CASES / "paper_ramp_web.toml", web=True,
                                      )
    fe9_l, recs_l = loose(CASES / "paper_ramp_web.toml")
    plot4([(fe9, "FE web (Zylon), held coil", "-"), (fe9_l, "FE web, loose coil", ":"),
           (an9m, "analytic (mapped)", "k--"), (an9, "analytic (case mapping)", "k:")],
          IMG / "fig9.png", "Fig. 9: spin ramp 0 -> 8 pi in 2 s, Zylon web")
    t_u = first_pivot(an9m)
    recs["fig9"] = {"fe": summary(fe9), "an_mapped": summary(an9m), "run": info9,
                    "fe_loose": recs_l,
                    "errors": error_table(fe9, an9m, {"uncoil": (0, t_u), "ramp": (0, 2),
                                                      "after": (2, cs.time.end)}),
                    "errors_loose": error_table(fe9_l, an9m, {"uncoil": (0, t_u),
                                                              "ramp": (0, 2)})}
    cs, fe10, info10, an10, an10m = fe_an(CASES / "paper_ramp_web_stiff.toml", web=True,
                                          t_end=4.0)
    fe10_l, recs_l = loose(CASES / "paper_ramp_web_stiff.toml", t_end=4.0)
    plot4([(fe10, "FE web (1000x Zylon), held coil", "-"), (fe10_l, "FE web, loose coil", ":"),
           (an10m, "analytic (mapped)", "k--"), (an10, "analytic (case mapping)", "k:")],
          IMG / "fig10.png", "Fig. 10: spin ramp 0 -> 8 pi in 2 s, 1000x stiffer web (run to 4 s)")
    t_u = first_pivot(an10m)
    recs["fig10"] = {"fe": summary(fe10), "an_mapped": summary(an10m), "run": info10,
                     "fe_loose": recs_l,
                     "errors": error_table(fe10, an10m, {"uncoil": (0, t_u), "ramp": (0, 2),
                                                         "after": (2, 4)}),
                     "errors_loose": error_table(fe10_l, an10m, {"uncoil": (0, t_u),
                                                                 "ramp": (0, 2)})}
    dump("figures", recs)
    return recs


def tables():
    """Markdown error tables (max / RMS per window) from the JSON files, for docs/validation.md."""
    head = ("| run | energy err. | window | L [m] | phi [rad] | omega_centre [rad/s] "
            "| omega_tip [rad/s] |\n|---|---|---|---|---|---|---|")
    lines = []

    def rows(recs):
        for rec in recs:
            if "failed" in rec:
                lines.append(f"| {rec['label']} | failed | | | | | |")
                continue
            for w in rec["errors"]:
                cells = " | ".join(f"{rec['errors'][w][s]['max']:.3g} / "
                                   f"{rec['errors'][w][s]['rms']:.3g}" for _, s, _ in QUANTITIES)
                ta, tb = rec["errors"][w]["t"]
                lines.append(f"| {rec['label']} | {rec['fe']['energy_balance_error']:.1e} | "
                             f"{w} {ta:.2f}-{tb:.2f} s | {cells} |")

    for name, groups in (("tethers", ("mesh", "cfl", "light", "long", "ramp")),
                         ("effects", None), ("web", ("free", "ramp")),
                         ("tri", ("free", "ramp"))):
        path = OUT / f"{name}.json"
        if not path.is_file():
            continue
        data = json.loads(path.read_text())
        if groups is None:
            lines += ["", f"**{name}**", "", head]
            rows(list(data.values()))
            continue
        for g in groups:
            recs = data[g] if isinstance(data[g], list) else [data[g]]
            lines += ["", f"**{name}: {g}**", "", head]
            rows(recs)
    print("\n".join(lines))


STUDIES = {"tethers": tether_study, "effects": effects_study, "web": web_study,
           "tri": tri_study, "figs": figures, "tables": tables}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="tethers,effects,web,tri,figs,tables",
                    help=f"comma-separated studies to run (default: all of {', '.join(STUDIES)})")
    args = ap.parse_args(argv)
    for name in args.only.split(","):
        t0 = time.perf_counter()
        STUDIES[name]()
        print(f"== {name}: {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
