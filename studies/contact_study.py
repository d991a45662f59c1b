"""Cable contact: the paper's webs with a layer gap, without and with cable-cable contact
(docs/contact.md, issue #26 item 5).

    python -m studies.contact_study [--out out/contact_study] [--rerun] [--end 2.0]
                                    [--scenes ...] [--only runs analyse figs anim ...]

Scenes (all with ``fold.layer_gap = 0.005`` m, frames every 0.02 s, a history row every
1e-3 s, one thread, 2 s instead of the cases' 5 s: ``--end``):

- ``free``: ``cases/paper_free_web.toml`` as it is (hub on its fixed axis), the re-coiling
  free deployment of docs/validation.md;
- ``free_tilt``: the same with ``hub.motion = "free"`` and the tilt of
  docs/out_of_plane.md by velocity (5 m/s at the deployed tips' lever: the tilt by 1 m
  of displacement turns the stacked layers but not the nodes tied to the hub, so the
  layers' columns above the ties start through each other, which the contact refuses);
- ``feedback_tilt``: ``cases/paper_feedback_web.toml``, free hub, the same tilt;
- ``feedback_hub_tilt``: the same with the hub turning at 0.01 rad/s about its x axis;
- ``free_random``: the free deployment, free hub, the smooth random field (seed 0) by
  velocity, 5 m/s; run only when named in ``--scenes`` (not in docs/contact.md: time);
- the check ``free_gap20mm``: ``free`` with a 2 cm gap and, with contact, a 1 cm radius.

Each twice: ``audit`` (``audit.crossings = true``: crossings counted, nothing stops them)
and ``contact`` (``contact.cables = true`` and the audit). Runs go to
OUT/<scene>_<audit|contact>/results.h5 and are kept (``--rerun`` runs them again); a run the
solver stopped (its energy audit) is analysed up to where it stopped.

``analyse`` writes ``benchmarks/results/contact_study.json``: per run the crossings (count,
first time, the pairs' arms), the linked cell pairs (end, most over the frames, changes),
the contact's stored energy and dissipation against the kinetic energy at the start, the
energy-balance error, the momentum balances (and when they broke), the deepest
penetration, the out-of-plane measures; per scene the differences contact - audit of each
arm's L and phi, the hub rate / omega0 and the out-of-plane measures, over the run and
before the contact run's momenta broke. ``figs`` writes docs/img/contact_*.png (histories,
crossings and linking, energies, oblique stills of the run with the most crossings without
contact, audit over contact, via ``spinweb render``); ``anim`` the two runs' oblique
animations side by side into OUT/ (too large for the repository).

One ``spinweb`` process at a time, ``--threads 1``; about 65 minutes on the development
machine (2 shared cores).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe.io.h5 import history_of
from spinweb_fe.post.plot import out_of_plane_columns
from spinweb_fe.record.energy import balance_error
from benchmarks.common import machine
from studies.out_of_plane_study import _json, best_planes, momentum_balance

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "contact_study.json"
IMG = ROOT / "docs" / "img"
PY = sys.executable
GAP = 0.005  # m, fold.layer_gap
FRAME_DT = 0.02  # s
#: s, the runs' end: 2 s instead of the cases' 5 s (a contact run took 6-14 min for 2 s on
#: one thread); the re-coil (0.3-0.7 s) and the free hub's overturning (0.4-1 s) lie within
END = 2.0
OMEGA0 = 8 * math.pi  # rad/s, the cases' initial rate (and the feedback law's omega0)
TILT = {"perturbation.shape": '"tilt"', "perturbation.vz_amplitude": 5.0}
#: scene -> (case file stem, keys on top of the common ones)
SCENES = {
    "free": ("paper_free_web", {}),
    "free_tilt": ("paper_free_web", {"hub.motion": '"free"', **TILT}),
    "feedback_tilt": ("paper_feedback_web", {"hub.motion": '"free"', **TILT}),
    "feedback_hub_tilt": ("paper_feedback_web", {"hub.motion": '"free"',
                                                 "perturbation.hub_tilt_rate": 0.01}),
    "free_random": ("paper_free_web", {"hub.motion": '"free"',
                                       "perturbation.shape": '"random"',
                                       "perturbation.vz_amplitude": 5.0,
                                       "perturbation.seed": 0}),
}
#: a check of the contact's dissipation: the free scene with a 4 times larger gap and a
#: contact radius of half the gap (the largest allowed), so that the penalty (elastic)
#: stops closing speeds up to about r / (1.5 dt) = 150 m/s instead of 27 m/s
CHECKS = {"free_gap20mm": ("paper_free_web", {"fold.layer_gap": 0.02}),
          }
CONTACT_KEYS = {"free_gap20mm": {"contact.cable_radius": 0.01}}
#: scenes run only when named in --scenes (not in docs/contact.md)
OPTIONAL = ("free_random",)
MODES = {"audit": {"audit.crossings": "true"},
         "contact": {"audit.crossings": "true", "contact.cables": "true"}}


def settings(scene: str, mode: str, end: float | None) -> dict:
    keys = {"fold.layer_gap": GAP, "output.frame_dt": FRAME_DT, "output.history_dt": 1e-3}
    keys.update({**SCENES, **CHECKS}[scene][1])
    keys.update(MODES[mode])
    if mode == "contact":
        keys.update(CONTACT_KEYS.get(scene, {}))
    if end is not None:
        keys["time.end"] = end
    return keys


def run_one(scene: str, mode: str, out: Path, rerun: bool, end: float | None) -> dict:
    """One ``spinweb run`` into OUT/<scene>_<mode>/ unless a completed result is there."""
    d = out / f"{scene}_{mode}"
    h5 = d / "results.h5"
    if h5.is_file() and not rerun:
        with h5py.File(h5) as f:
            if str(f.attrs.get("status", "")) == "completed":
                return {"run": d.name, "skipped": True}
    case = {**SCENES, **CHECKS}[scene][0]
    cmd = [PY, "-m", "spinweb_fe", "run", str(ROOT / "cases" / f"{case}.toml"),
           "-o", str(d), "--threads", "1", "--no-progress", "--force"]
    for k, v in settings(scene, mode, end).items():
        cmd += ["--set", f"{k}={v}"]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    d.mkdir(parents=True, exist_ok=True)
    (d / "run.log").write_text(" ".join(cmd) + "\n" + r.stdout + r.stderr
                               + f"\nexit {r.returncode}, wall {wall:.1f} s\n")
    print(f"{d.name}: exit {r.returncode} in {wall:.0f} s", flush=True)
    return {"run": d.name, "exit": r.returncode, "wall_s": wall,
            "stderr_tail": r.stderr.strip().splitlines()[-3:]}


def stage_runs(out: Path, rerun: bool, scenes, end) -> list:
    return [run_one(s, m, out, rerun, end) for s in scenes for m in MODES]


# --- measures ---------------------------------------------------------------------------------

def _first(t, mask):
    """The first time where ``mask`` holds (None: never)."""
    idx = np.nonzero(mask)[0]
    return float(t[idx[0]]) if len(idx) else None


def crossing_measures(f) -> dict:
    """The audit's record: the count, the first time, the directions, the pairs' arms (the
    arm of an element: that of its first node, -1 for the hub's frame and the cross)."""
    g = f["crossings"]
    t = g["time"][()]
    a, b = g["element_a"][()], g["element_b"][()]
    arm = f["mesh/node_arm"][()][f["mesh/elements"][()][:, 0]]
    same = arm[a] == arm[b]
    out = {"count": int(g.attrs["count"]), "first_s": float(t[0]) if len(t) else None,
           "last_s": float(t[-1]) if len(t) else None,
           "positive": int(np.sum(g["direction"][()] > 0)),
           "negative": int(np.sum(g["direction"][()] < 0)),
           "same_arm": int(np.sum(same & (arm[a] >= 0))),
           "different_arms": int(np.sum(~same & (arm[a] >= 0) & (arm[b] >= 0))),
           "with_frame_or_cross": int(np.sum((arm[a] < 0) | (arm[b] < 0))),
           "distinct_pairs": int(len(set(zip(np.minimum(a, b).tolist(),
                                             np.maximum(a, b).tolist())))),
           "distinct_elements": int(len(np.union1d(a, b))),
           "rebuilds": int(g.attrs["rebuilds"]), "skin_m": float(g.attrs["skin"]),
           "touch_m": float(g.attrs["touch"])}
    for q in (0.5, 1.0, 1.5, 2.0):
        out[f"by_{q:g}_s"] = int(np.sum(t <= q))
    return out


def linking_measures(f) -> dict:
    g = f["linking"]
    t, linked = g["time"][()], g["linked"][()]
    k = int(np.argmax(linked))
    return {"checks": int(len(t)), "linked_start": int(linked[0]), "linked_end": int(linked[-1]),
            "linked_max": int(linked[k]), "linked_max_at_s": float(t[k]),
            "changed_total": int(g.attrs["changed_total"]),
            "net_changed": int(g.attrs["net_changed"]),
            "first_change_s": float(g.attrs["first_change_time"]),
            "suspect_max": int(np.max(g["suspect"][()])),
            "worst_max": float(np.max(g["worst"][()])), "loops": int(g.attrs["loops"])}


def momentum_residual(h, free_hub: bool) -> np.ndarray:
    """Per history row: the angular momentum balance |L(t) - L(0) - int M b3 dt| / max |L|
    (the control torque M about the hub axis b3 the only external moment) for a free hub;
    on a fixed axis only its axial component (the axis takes the transverse moments)."""
    t, L = h["time"], h["angular_momentum_vector"]
    Mb = h["hub_torque"][:, None] * h["hub_axis"]
    imp = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (Mb[1:] + Mb[:-1])
                                                      * np.diff(t)[:, None], axis=0)])
    res = L - L[0] - imp
    scale = max(float(np.max(np.linalg.norm(L, axis=1))), 1e-300)
    return (np.linalg.norm(res, axis=1) if free_hub else np.abs(res[:, 2])) / scale


#: a run's momenta are called broken from the first row whose balance residual exceeds
#: this share of max |L| (the verdict's momentum limit; the audit runs: 1e-14 free, 4e-5
#: under the feedback torque from the 1 ms rows' quadrature) or, with a free hub, whose
#: linear momentum changed by this share of max |L| / (largest tip distance); the first
#: departure (1e-3 and 1 kg m/s) is kept too
BROKEN = 1e-2


def analyse_run(d: Path) -> dict:
    import tomllib

    with h5py.File(d / "results.h5") as f:
        h = history_of(f)
        a = dict(f.attrs)
        free_hub = tomllib.loads(str(a["case"])).get("hub", {}).get("motion") == "free"
        res = {"status": str(a["status"]), "steps": int(a["steps"]), "dt_s": float(a["dt"]),
               "wall_time_s": float(a["wall_time_s"]), "verdict": str(a.get("verdict", "")),
               "verdict_failed": str(a.get("verdict_failed", "")),
               "end_s": float(h["time"][-1]), "rows": int(len(h["time"])),
               "crossings": crossing_measures(f), "linking": linking_measures(f)}
        cg = f["crossings"].attrs
        if "contact_radius" in cg:
            res["contact_radius_m"] = float(cg["contact_radius"])
            res["deepest_penetration_m"] = float(cg["deepest_penetration"])
        planes = best_planes(f) if "frames" in f else None
    ke0 = float(h["kinetic_energy"][0])
    res["ke0_J"] = ke0
    res["energy_balance_error"] = balance_error(h)
    for key in ("cable_contact_energy", "cable_contact_dissipation", "contact_dissipation"):
        if key in h:
            v = h[key]
            res[key] = {"max_J": float(np.max(v)), "end_J": float(v[-1]),
                        "max_rel_ke0": float(np.max(v) / ke0), "end_rel_ke0": float(v[-1] / ke0)}
    res["kinetic_energy_end_rel_ke0"] = float(h["kinetic_energy"][-1] / ke0)
    res["strain_energy_end_rel_ke0"] = float(h["strain_energy"][-1] / ke0)
    cols = out_of_plane_columns(h)
    res["out_of_plane"] = {
        "rms_max_m": float(np.max(h["out_of_plane_rms"])),
        "rms_end_m": float(h["out_of_plane_rms"][-1]),
        "max_max_m": float(np.max(h["out_of_plane_max"])),
        "hub_from_L_max_rad": float(np.nanmax(cols["hub_tilt"][:, 1])),
        "hub_from_L_end_rad": float(cols["hub_tilt"][-1, 1]),
        "tip_height_max_m": float(np.max(np.abs(cols["tip_height"])))}
    if planes is not None:
        res["out_of_plane"]["best_plane_rms_max_m"] = float(np.max(planes["rms"]))
        res["out_of_plane"]["best_plane_rms_end_m"] = float(planes["rms"][-1])
    res["arm_length_end_m"] = h["arm_length"][-1].tolist()
    res["arm_length_mean_end_m"] = float(np.mean(h["arm_length"][-1]))
    res["hub_omega_end_rad_s"] = float(h["hub_omega"][-1])
    res["hub_omega_min_rad_s"] = float(np.min(h["hub_omega"]))
    res["free_hub"] = free_hub
    r = momentum_residual(h, free_hub)
    bad, off = r > BROKEN, r > 1e-3
    if free_hub:
        res["momentum"] = momentum_balance(h)
        dp = np.linalg.norm(h["linear_momentum"] - h["linear_momentum"][0], axis=1)
        bad |= dp > BROKEN * res["momentum"]["P_scale_kg_m_s"]
        off |= dp > 1.0
    res["momentum_residual_max"] = float(np.max(r))
    res["momentum_broken_s"] = _first(h["time"], bad)
    res["momentum_off_s"] = _first(h["time"], off)
    res["hub_moved_max_m"] = float(np.max(np.linalg.norm(h["hub_position"]
                                                         - h["hub_position"][0], axis=1)))
    return res


def _diff(a, b) -> dict:
    d = np.asarray(b, float) - np.asarray(a, float)
    return {"rms": float(np.sqrt(np.mean(d ** 2))), "max_abs": float(np.max(np.abs(d))),
            "end": float(np.mean(d[-1])) if d.ndim > 1 else float(d[-1])}


def compare(da: Path, dc: Path, until: float | None = None) -> dict:
    """Contact minus audit on the common history rows: per-arm L and phi (RMS and largest
    over the rows and arms), the arms' mean L, hub rate / omega0, out-of-plane measures;
    the first time the runs differ at all and by 1 % of L / 0.1 rad / 1 % of omega0."""
    with h5py.File(da / "results.h5") as f:
        ha = history_of(f)
    with h5py.File(dc / "results.h5") as f:
        hc = history_of(f)
    n = min(len(ha["time"]), len(hc["time"]))
    if until is not None:  # the rows before ``until`` [s]
        n = min(n, int(np.searchsorted(ha["time"], until)))
    t = ha["time"][:n]
    A = {k: v[:n] for k, v in ha.items()}
    C = {k: v[:n] for k, v in hc.items()}
    dl = np.abs(C["arm_length"] - A["arm_length"])
    dp = np.abs(C["arm_angle"] - A["arm_angle"])
    dw = np.abs(C["hub_omega"] - A["hub_omega"]) / OMEGA0
    ca, cc = out_of_plane_columns(A), out_of_plane_columns(C)
    same = np.all(A["arm_length"] == C["arm_length"], axis=1) & (A["hub_omega"] == C["hub_omega"])
    first_diff = _first(t, ~same)
    lmean = np.mean(A["arm_length"], axis=1)
    out = {"rows": int(n), "until_s": float(t[-1]),
           "first_difference_s": first_diff,
           "first_dL_over_1pct_of_L_s": _first(t, np.max(dl, axis=1)
                                               > 0.01 * np.maximum(lmean, 1.0)),
           "first_dphi_over_0.1_rad_s": _first(t, np.max(dp, axis=1) > 0.1),
           "first_domega_over_1pct_s": _first(t, dw > 0.01),
           "arm_length_m": _diff(A["arm_length"], C["arm_length"]),
           "arm_length_mean_m": _diff(lmean, np.mean(C["arm_length"], axis=1)),
           "arm_angle_rad": _diff(A["arm_angle"], C["arm_angle"]),
           "hub_omega_rel_omega0": _diff(A["hub_omega"] / OMEGA0, C["hub_omega"] / OMEGA0),
           "out_of_plane_rms_m": _diff(A["out_of_plane_rms"], C["out_of_plane_rms"]),
           "hub_from_L_rad": _diff(np.nan_to_num(ca["hub_tilt"][:, 1]),
                                   np.nan_to_num(cc["hub_tilt"][:, 1])),
           "kinetic_energy_rel_ke0": _diff(A["kinetic_energy"] / A["kinetic_energy"][0],
                                           C["kinetic_energy"] / A["kinetic_energy"][0]),
           "scale": {"arm_length_mean_rms_m": float(np.sqrt(np.mean(lmean ** 2))),
                     "hub_omega_rms_rel": float(np.sqrt(np.mean((A["hub_omega"] / OMEGA0)
                                                                ** 2)))}}
    return out


def _completed(h5: Path) -> bool:
    """A finished run's file (not one being written: that one is locked): completed, or
    stopped by the run (``failed: ...``, e.g. the energy audit; analysed up to there)."""
    try:
        with h5py.File(h5) as f:
            return str(f.attrs.get("status", "")).startswith(("completed", "failed"))
    except OSError:
        return False


def stage_analyse(out: Path) -> dict:
    runs, scenes = {}, {}
    for s in (*SCENES, *CHECKS):
        if not all(_completed(out / f"{s}_{m}" / "results.h5") for m in MODES):
            continue
        for m in MODES:
            name = f"{s}_{m}"
            runs[name] = analyse_run(out / name)
            log = (out / name / "run.log").read_text().splitlines()
            runs[name]["wall_s"] = next((float(x.split("wall ")[1].rstrip(" s"))
                                         for x in log if x.startswith("exit ")), None)
            print(f"{name}: {runs[name]['crossings']['count']} crossings, linked end "
                  f"{runs[name]['linking']['linked_end']}", flush=True)
        scenes[s] = {"case": {**SCENES, **CHECKS}[s][0], "check": s in CHECKS,
                     "keys": {k: str(v) for k, v in settings(s, "contact", END).items()},
                     "contact_minus_audit": compare(out / f"{s}_audit", out / f"{s}_contact")}
        broken = runs[f"{s}_contact"]["momentum_broken_s"]
        if broken is not None:  # the same before the contact run's momenta broke
            scenes[s]["contact_minus_audit_before_broken"] = compare(
                out / f"{s}_audit", out / f"{s}_contact", until=broken)
    git = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True,
                         text=True, cwd=ROOT).stdout.strip()
    res = {"machine": {**machine(), "git": git},
           "settings": {"layer_gap_m": GAP, "frame_dt_s": FRAME_DT, "history_dt_s": 1e-3,
                        "omega0_rad_s": OMEGA0, "threads": 1},
           "runs": runs, "scenes": scenes}
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(res, indent=1, default=_json))
    print(f"wrote {RESULTS}", flush=True)
    return res


# --- figures ----------------------------------------------------------------------------------

#: oblique stills of the worst run without and with contact: the times [s]
STILL_TIMES = (0.3, 0.6, 1.0, 2.0)
STILL_SIZE = "560x440"


def _cli(args):
    r = subprocess.run([PY, "-m", "spinweb_fe", *args], capture_output=True, text=True,
                       cwd=ROOT)
    if r.returncode != 0:
        print(f"spinweb {args[0]} failed: {r.stderr.strip()}", flush=True)
    return r.returncode


def worst_scene(res) -> str:
    """The scene whose audit run counted the most crossings."""
    return max((s for s in res["scenes"] if not res["scenes"][s]["check"]),
               key=lambda s: res["runs"][f"{s}_audit"]["crossings"]["count"])


def stage_figs(out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    from spinweb_fe.record.energy import energy_balance, energy_reference

    res = json.loads(RESULTS.read_text())
    scenes = list(res["scenes"])
    IMG.mkdir(parents=True, exist_ok=True)
    hist = {}
    for s in scenes:
        for m in MODES:
            with h5py.File(out / f"{s}_{m}" / "results.h5") as f:
                hist[s, m] = (history_of(f), f["linking/time"][()], f["linking/linked"][()])
    style = {"audit": dict(lw=1.1), "contact": dict(lw=1.1, ls="--")}
    # 1. arm length, arm angle, hub rate, out of the plane: audit solid, contact dashed
    fig, axes = plt.subplots(len(scenes), 4, figsize=(16, 2.7 * len(scenes)),
                             layout="constrained", squeeze=False)
    for row, s in zip(axes, scenes):
        for m in MODES:
            h = hist[s, m][0]
            t = h["time"]
            for k in range(4):
                c = f"C{k}"
                row[0].plot(t, h["arm_length"][:, k], color=c, **style[m])
                row[1].plot(t, h["arm_angle"][:, k], color=c, **style[m])
            row[2].plot(t, h["hub_omega"] / OMEGA0, color="k" if m == "audit" else "C3",
                        label=m, **style[m])
            row[3].plot(t, h["out_of_plane_rms"], color="k" if m == "audit" else "C3",
                        label=m, **style[m])
        row[0].set(ylabel=f"{s}\nL per arm [m]")
        row[1].set(ylabel="phi per arm [rad]")
        row[2].set(ylabel="hub rate / omega0")
        row[3].set(ylabel="RMS from hub plane [m]")
        row[2].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set(xlabel="t [s]")
    fig.suptitle("paper webs, 5 mm layer gap: audit only (solid) and with cable contact "
                 "(dashed); L and phi one colour per arm")
    fig.savefig(IMG / "contact_histories.png", dpi=90)
    plt.close(fig)
    # 2. crossings and linked cell pairs
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6), layout="constrained")
    for k, s in enumerate(scenes):
        for m in MODES:
            h, lt, ln = hist[s, m]
            lab = f"{s} {m}"
            if m == "audit" or np.any(h["crossings"]):
                axes[0].plot(h["time"], h["crossings"], color=f"C{k}", label=lab, **style[m])
            axes[1].plot(lt, ln, color=f"C{k}", marker="." if m == "audit" else "",
                         ms=3, label=lab, **style[m])
    axes[0].set(xlabel="t [s]", ylabel="crossings so far", yscale="symlog",
                title="crossings of cable elements (audit)")
    axes[1].set(xlabel="t [s]", ylabel="cell pairs with Lk != 0", yscale="symlog",
                title="linked cell pairs (every frame, 0.02 s)")
    for ax in axes:
        ax.legend(fontsize=7, ncol=2)
    fig.savefig(IMG / "contact_crossings.png", dpi=100)
    plt.close(fig)
    # 3. the contact's energies and the balance error
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.6), layout="constrained")
    for k, s in enumerate(scenes):
        h = hist[s, "contact"][0]
        ke0 = h["kinetic_energy"][0]
        axes[0].plot(h["time"], h["cable_contact_dissipation"] / ke0, color=f"C{k}",
                     label=f"{s}: dissipated (fail-safe)")
        axes[0].plot(h["time"], np.maximum(h["cable_contact_energy"] / ke0, 1e-12), color=f"C{k}",
                     ls=":", label=f"{s}: stored (penalty)")
        for m in MODES:
            hm = hist[s, m][0]
            b0, sc = energy_reference(hm)
            sc = max(sc, float(np.max(np.abs(hm["torque_work"]))))
            axes[1].plot(hm["time"], np.abs(energy_balance(hm) - b0) / sc, color=f"C{k}",
                         label=f"{s} {m}", **style[m])
    axes[0].set(xlabel="t [s]", ylabel="energy / kinetic energy at start", yscale="log",
                ylim=(1e-9, None), title="cable contact: energy taken and stored")
    axes[1].set(xlabel="t [s]", ylabel="|balance - start| / energy scale", yscale="log",
                ylim=(1e-8, None), title="energy balance error")
    for ax in axes:
        ax.legend(fontsize=7, ncol=2)
    fig.savefig(IMG / "contact_energy.png", dpi=100)
    plt.close(fig)
    for name in ("contact_histories.png", "contact_crossings.png", "contact_energy.png"):
        Image.open(IMG / name).convert("RGB").quantize(256).save(IMG / name, optimize=True)
    # 4. the worst run, audit over contact, oblique, at STILL_TIMES
    worst = worst_scene(res)
    tiles = {}
    for m in MODES:
        for k, at in enumerate(STILL_TIMES):
            tile = out / f"still_{worst}_{m}_{k}.png"
            _cli(["render", str(out / f"{worst}_{m}" / "results.h5"), "-o", str(tile),
                  "--view", "oblique", "--time", f"{at:g}", "--size", STILL_SIZE])
            tiles[m, k] = Image.open(tile).convert("RGB")
    w, hgt = tiles["audit", 0].size
    sheet = Image.new("RGB", (len(STILL_TIMES) * w, 2 * hgt), "white")
    for (m, k), tile in tiles.items():
        sheet.paste(tile, (k * w, (0 if m == "audit" else 1) * hgt))
    sheet = sheet.resize((sheet.width * 3 // 4, sheet.height * 3 // 4), Image.LANCZOS)
    sheet.quantize(256).save(IMG / f"contact_oblique_{worst}.png", optimize=True)
    print(f"wrote docs/img/contact_*.png (worst: {worst})", flush=True)


def stage_animation(out: Path) -> None:
    """The worst run without and with contact, side by side, oblique: OUT/<worst>_side.gif
    (kept in OUT: too large for the repository)."""
    from PIL import Image, ImageSequence

    res = json.loads(RESULTS.read_text())
    worst = worst_scene(res)
    gifs = []
    for m in MODES:
        g = out / f"{worst}_{m}.gif"
        _cli(["render", str(out / f"{worst}_{m}" / "results.h5"), "-o", str(g), "--view",
              "oblique", "--size", "560x440", "--fps", "10"])
        gifs.append([fr.convert("RGB") for fr in ImageSequence.Iterator(Image.open(g))])
    n = min(len(g) for g in gifs)
    w, hgt = gifs[0][0].size
    frames = []
    for k in range(n):
        sheet = Image.new("RGB", (2 * w, hgt), "white")
        sheet.paste(gifs[0][k], (0, 0))
        sheet.paste(gifs[1][k], (w, 0))
        frames.append(sheet.quantize(256))
    target = out / f"{worst}_audit_vs_contact.gif"
    frames[0].save(target, save_all=True, append_images=frames[1:], duration=100, loop=0,
                   optimize=True)
    print(f"wrote {target} ({n} frames)", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "out" / "contact_study"), help="run folders")
    ap.add_argument("--rerun", action="store_true", help="run again even if a result exists")
    ap.add_argument("--scenes", nargs="+", choices=tuple(SCENES) + tuple(CHECKS),
                    default=tuple(s for s in (*SCENES, *CHECKS) if s not in OPTIONAL))
    ap.add_argument("--end", type=float, default=END,
                    help=f"time.end [s] (default {END:g}; the cases' own: 5 s)")
    ap.add_argument("--only", nargs="+", choices=("runs", "analyse", "figs", "anim"),
                    default=("runs", "analyse", "figs", "anim"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    if "runs" in args.only:
        for r in stage_runs(out, args.rerun, args.scenes, args.end):
            if r.get("exit", 0) != 0:
                print(f"{r['run']} failed: {r['stderr_tail']}", flush=True)
    if "analyse" in args.only:
        stage_analyse(out)
    if "figs" in args.only:
        stage_figs(out)
    if "anim" in args.only:
        stage_animation(out)
    print(f"contact_study: {time.perf_counter() - t0:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
