"""Out of the plane: the paper's web deployments perturbed out of their plane
(docs/out_of_plane.md).

    python -m studies.out_of_plane_study [--out out/out_of_plane] [--rerun] [--jobs N]
                                         [--only runs|analyse|figs ...]

For the free, torque-feedback and spin-ramp deployments of the paper's web
(``cases/paper_{free,feedback,ramp}_web.toml``, held coil, their full end times, default
steps) with ``hub.motion = "free"`` (the hub a rigid body of six degrees of freedom, so that
it can tilt and translate), this runs

- ``baseline``: no perturbation;
- ``tilt``: the web turned about x so that its deployed corners would be 1 m (1 % of the
  side S = 100 m) out of the plane (``perturbation.shape = "tilt"``, ``z_amplitude = 1``);
- ``random``: a smooth random out-of-plane field of largest displacement 1 m (``shape =
  "random"``, seed 0);
- ``hub_tilt``: the hub turning at 0.01 rad/s about its x axis at the start
  (``perturbation.hub_tilt_rate = 0.01``);
- ``late_arm``: arm 0's coil held on the hub for 0.1 s (``perturbation.arm = 0``,
  ``delay = 0.1``); ``late_arm_tilt``: the same with the 1 m tilt;
- ``tilt_fixed_axis``: the 1 m tilt with the hub on its fixed axis (``hub.motion =
  "fixed_axis"``), to show what the free hub changes;

each into OUT/<case>_<perturbation>/results.h5 (kept; ``--rerun`` runs them again; frames
every 0.02 s), and ``spinweb modes`` of the deployed web at 8 pi rad/s and at the feedback
web's mean rate (hub driven).

``analyse`` reads them into ``benchmarks/results/out_of_plane.json``: per run the
out-of-plane RMS and largest distance from the hub plane, the web's distance from its own
best plane (the part that is not a rigid tilt; from the frames), the angle of that plane
and of the hub axis from +z and from the angular momentum L, the growth rate of the hub's
angle from L, the tip heights, the frequencies of the tip heights split by symmetry
(umbrella, tilt, saddle) and of the hub's transverse rate (peaks of a Hann-windowed,
zero-padded FFT over the case's window, zero crossings) next to the closed forms (the
tether pendulum Omega sqrt(1 + r0/L), the modes' ratios times the window's mean rate), the
energy-balance drift and the angular and linear momentum balance; then the checks (the
feedback web's growth with half the step, a 100x smaller seed and 10x / 100x the hub's
transverse inertia, a ramp with a history row every step for the momentum balance, two
free runs with half the step) and the linear momentum of the tilted initial state with and
without a delayed arm. ``figs`` writes docs/img/oop_*.png: the out-of-plane panels of
``spinweb plot --panels out_of_plane`` and ``spinweb render --view oblique`` pictures.

One ``spinweb`` process at a time by default, one thread each; about 10.5 minutes in all on
the development machine (2 shared cores): 9 for the 21 runs, under 2 for the checks, the
analysis and the figures.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe.io.h5 import history_of
from spinweb_fe.post.plot import out_of_plane_columns
from spinweb_fe.record.energy import balance_error

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "out_of_plane.json"
IMG = ROOT / "docs" / "img"
PY = sys.executable
SIDE = 100.0  # m, web side S of the paper's web
Z_AMP = 0.01 * SIDE  # m, 1 % of the side
CASES = {"free": "paper_free_web", "feedback": "paper_feedback_web", "ramp": "paper_ramp_web"}
#: perturbation name -> case keys set on top of hub.motion = "free"
PERTURBATIONS = {
    "baseline": {},
    "tilt": {"perturbation.shape": '"tilt"', "perturbation.z_amplitude": Z_AMP},
    "random": {"perturbation.shape": '"random"', "perturbation.z_amplitude": Z_AMP,
               "perturbation.seed": 0},
    "hub_tilt": {"perturbation.hub_tilt_rate": 0.01},
    "late_arm": {"perturbation.arm": 0, "perturbation.delay": 0.1},
    "late_arm_tilt": {"perturbation.arm": 0, "perturbation.delay": 0.1,
                      "perturbation.shape": '"tilt"', "perturbation.z_amplitude": Z_AMP},
    "tilt_fixed_axis": {"hub.motion": '"fixed_axis"', "perturbation.shape": '"tilt"',
                        "perturbation.z_amplitude": Z_AMP},
}
#: the window [s] over which frequencies are measured: after the deployment's first swing
WINDOWS = {"free": (1.0, 5.0), "feedback": (2.0, 5.0), "ramp": (4.0, 10.0)}


FRAME_DT = 0.02  # s, frames for the best-plane measures and the pictures (cases: 0.05)


def settings(pert: str) -> dict:
    keys = {"hub.motion": '"free"', "output.frame_dt": FRAME_DT}
    keys.update(PERTURBATIONS[pert])
    return keys


def run_one(case: str, pert: str, out: Path, rerun: bool) -> dict:
    """One ``spinweb run`` into OUT/<case>_<pert>/ unless a completed result is there."""
    d = out / f"{case}_{pert}"
    h5 = d / "results.h5"
    if h5.is_file() and not rerun:
        with h5py.File(h5) as f:
            if str(f.attrs.get("status", "")) == "completed":
                return {"run": d.name, "skipped": True}
    cmd = [PY, "-m", "spinweb_fe", "run", str(ROOT / "cases" / f"{CASES[case]}.toml"),
           "-o", str(d), "--threads", "1", "--no-progress", "--force"]
    for k, v in settings(pert).items():
        cmd += ["--set", f"{k}={v}"]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    (d / "run.log").parent.mkdir(parents=True, exist_ok=True)
    (d / "run.log").write_text(" ".join(cmd) + "\n" + r.stdout + r.stderr)
    print(f"{d.name}: exit {r.returncode} in {wall:.0f} s", flush=True)
    return {"run": d.name, "exit": r.returncode, "wall_s": wall,
            "stderr_tail": r.stderr.strip().splitlines()[-3:]}


def run_modes(case: str, omega: float, out: Path, rerun: bool) -> Path:
    """``spinweb modes`` of the case's deployed web at ``omega`` (hub driven)."""
    d = out / f"modes_{case}"
    if (d / "modes.h5").is_file() and not rerun:
        return d / "modes.h5"
    cmd = [PY, "-m", "spinweb_fe", "modes", str(ROOT / "cases" / f"{CASES[case]}.toml"),
           "-o", str(d), "--omega", repr(omega), "--count", "16"]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    d.mkdir(parents=True, exist_ok=True)
    (d / "modes.log").write_text(" ".join(cmd) + "\n" + r.stdout + r.stderr)
    if r.returncode != 0:
        print(f"modes {case}: exit {r.returncode}: {r.stderr.strip()}", flush=True)
    return d / "modes.h5"


def stage_runs(out: Path, rerun: bool, jobs: int) -> list:
    todo = [(c, p) for c in CASES for p in PERTURBATIONS]
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        return list(pool.map(lambda cp: run_one(*cp, out, rerun), todo))


# --- measures ---------------------------------------------------------------------------------

def peak_frequency(t, y, lo=0.5, n_peaks=3) -> list:
    """The largest peaks of the spectrum of ``y`` (uniform times ``t``) above ``lo`` [rad/s]:
    [(angular frequency [rad/s], amplitude [units of y])], strongest first. Mean removed,
    Hann window, zero padded to 16x, each peak refined by a parabola through the log
    magnitudes of its three bins; the amplitude is that of a sine of that frequency."""
    y = np.asarray(y, float) - np.mean(y)
    n = len(y)
    if n < 16 or not np.any(y):
        return []
    dt = float(t[1] - t[0])
    win = np.hanning(n)
    m = 16 * (1 << int(np.ceil(np.log2(n))))
    spec = np.abs(np.fft.rfft(y * win, m)) * 2.0 / np.sum(win)
    w = 2.0 * np.pi * np.fft.rfftfreq(m, dt)
    ok = np.nonzero((w > lo) & (np.arange(len(w)) > 0) & (np.arange(len(w)) < len(w) - 1))[0]
    peaks = [i for i in ok if spec[i] >= spec[i - 1] and spec[i] > spec[i + 1]]
    peaks.sort(key=lambda i: -spec[i])
    out = []
    for i in peaks:
        a, b, c = np.log(np.maximum(spec[i - 1:i + 2], 1e-300))
        d = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
        wi = w[i] + d * (w[1] - w[0])
        # one peak per resolution cell of the unpadded window
        if all(abs(wi - o[0]) > 2 * np.pi / (n * dt) for o in out):
            out.append((float(wi), float(spec[i])))
        if len(out) == n_peaks:
            break
    return out


def crossing_rate(t, y) -> float:
    """Angular frequency [rad/s] from the zero crossings of ``y`` minus its mean: pi times
    the crossings per second (between the first and the last crossing)."""
    y = np.asarray(y, float) - np.mean(y)
    s = np.signbit(y)
    idx = np.nonzero(s[1:] != s[:-1])[0]
    if len(idx) < 3:
        return float("nan")
    # linear interpolation of each crossing time
    tc = t[idx] - y[idx] * (t[idx + 1] - t[idx]) / (y[idx + 1] - y[idx])
    return float(np.pi * (len(tc) - 1) / (tc[-1] - tc[0]))


def best_planes(h5) -> dict:
    """From the frames: per frame the web's best plane (mass-weighted least squares through
    its centre of mass, over the nodes not tied to the hub): its normal, the RMS and largest
    distance of the nodes from it [m] (the part of the out-of-plane shape that is not a rigid
    tilt) and, per radial band of the flat web (5 m wide), the RMS distance [m]."""
    fr = h5["frames"]
    t = fr["time"][()]
    mesh = h5["mesh"]
    mass = mesh["node_mass"][()]
    web = np.ones(len(mass), bool)
    web[mesh["node_sets/hub_tied"][()]] = False
    ref = mesh["reference_points"][()]
    r_ref = np.hypot(ref[:, 0], ref[:, 1])
    bands = np.arange(0.0, r_ref.max() + 5.0, 5.0)
    band = np.digitize(r_ref, bands) - 1
    m = mass[web] / mass[web].sum()
    normals, rms, big, prof = [], [], [], []
    for k in range(len(t)):
        x = fr["position"][k][web]
        c = m @ x
        d = x - c
        _, _, vt = np.linalg.svd(d * np.sqrt(m)[:, None], full_matrices=False)
        n = vt[2] * (1.0 if vt[2, 2] >= 0 else -1.0)
        dist = d @ n
        normals.append(n)
        rms.append(float(np.sqrt(m @ dist ** 2)))
        big.append(float(np.max(np.abs(dist))))
        prof.append([float(np.sqrt(np.mean(dist[band[web] == b] ** 2)))
                     if np.any(band[web] == b) else 0.0 for b in range(len(bands) - 1)])
    return {"time": t, "normal": np.array(normals), "rms": np.array(rms),
            "max": np.array(big), "band_edges": bands, "band_rms": np.array(prof)}


def angle(a, b) -> np.ndarray:
    """Angle [rad] between the lines along the rows of ``a`` and ``b`` (T, 3), 0 .. pi/2 (a
    plane's normal has no sign)."""
    na = np.linalg.norm(a, axis=-1)
    nb = np.linalg.norm(b, axis=-1)
    c = np.abs(np.einsum("td,td->t", a, b)) / np.maximum(na * nb, 1e-300)
    return np.arccos(np.clip(c, 0.0, 1.0))


def momentum_balance(h) -> dict:
    """Angular momentum against the control's impulse: L(t) - L(0) - int M b3 dt (the only
    external moment is the control torque M about the hub axis b3; trapezoidal rule on the
    history rows), relative to max |L|; and |P| relative to the momentum scale
    max |L| / (largest tip distance)."""
    t, L = h["time"], h["angular_momentum_vector"]
    if "hub_axis" in h:
        Mb = h["hub_torque"][:, None] * h["hub_axis"]
    else:
        Mb = h["hub_torque"][:, None] * np.array([0.0, 0.0, 1.0])
    imp = np.concatenate([np.zeros((1, 3)), np.cumsum(0.5 * (Mb[1:] + Mb[:-1])
                                                      * np.diff(t)[:, None], axis=0)])
    scale = max(float(np.max(np.linalg.norm(L, axis=1))), 1e-300)
    res = L - L[0] - imp
    r_tip = float(np.max(np.linalg.norm(h["tip_position"][..., :2], axis=-1)))
    p_scale = scale / max(r_tip, 1e-300)
    return {"L0_N_m_s": L[0].tolist(), "L_end_N_m_s": L[-1].tolist(),
            "L_max_N_m_s": scale,
            "torque_impulse_end_N_m_s": imp[-1].tolist(),
            "L_residual_rel": float(np.max(np.linalg.norm(res, axis=1)) / scale),
            "L_transverse_residual_rel": float(np.max(np.linalg.norm(res[:, :2], axis=1))
                                               / scale),
            "P_max_kg_m_s": float(np.max(np.linalg.norm(h["linear_momentum"], axis=1))),
            "P0_kg_m_s": float(np.linalg.norm(h["linear_momentum"][0])),
            "P_change_max_kg_m_s": float(np.max(np.linalg.norm(
                h["linear_momentum"] - h["linear_momentum"][0], axis=1))),
            "P_scale_kg_m_s": p_scale}



# --- analysis -----------------------------------------------------------------------------------

def tip_components(z) -> dict:
    """The four tip heights z (T, 4) (arms 90 degrees apart, in order) split by symmetry:
    umbrella U (all together), tilt A = (z0 - z2) / 2 and B = (z1 - z3) / 2, saddle S
    (opposite corners together)."""
    return {"umbrella": z.mean(axis=1), "tilt_a": 0.5 * (z[:, 0] - z[:, 2]),
            "tilt_b": 0.5 * (z[:, 1] - z[:, 3]),
            "saddle": 0.25 * (z[:, 0] - z[:, 1] + z[:, 2] - z[:, 3])}


def mode_ratios(path: Path) -> dict:
    """omega_k / omega of the lowest out-of-plane modes of ``spinweb modes``, named by the
    tips' symmetry (umbrella, tilt pair, saddle), and the steady state's largest strain."""
    out = {}
    with h5py.File(path) as f:
        tips = f["mesh/node_sets/tips"][()]
        kinds = [k.decode() if isinstance(k, bytes) else str(k) for k in f["kind"][()]]
        out["omega_rad_s"] = float(f.attrs["omega"])
        out["max_strain"] = float(np.max(f["steady/strain"][()]))
        for k, kind in enumerate(kinds):
            if kind != "out_of_plane":
                continue
            z = f["shape"][k][tips, 2]
            z = z / max(np.max(np.abs(z)), 1e-300)
            comp = tip_components(z[None, :])
            name = max(comp, key=lambda n: abs(comp[n][0]))
            name = "tilt" if name.startswith("tilt") else name
            if name not in out and np.max(np.abs(z)) > 0:
                out[name] = float(f["ratio"][k])
        out["all_out_of_plane"] = [float(f["ratio"][k]) for k, kind in enumerate(kinds)
                                   if kind == "out_of_plane"]
    return out


def growth_rate(t, y, lo=1e-3, hi=0.1) -> dict:
    """Exponential rate [1/s] of ``y`` from a straight-line fit of log y over the first
    stretch where y rises from ``lo`` to ``hi`` (None if it never does)."""
    above = np.nonzero(y >= hi)[0]
    if not len(above):
        return {"rate_1_s": None}
    j1 = int(above[0])
    below = np.nonzero(y[:j1] < lo)[0]
    j0 = int(below[-1]) + 1 if len(below) else 0
    if j1 - j0 < 10:
        return {"rate_1_s": None}
    g = np.polyfit(t[j0:j1], np.log(np.maximum(y[j0:j1], 1e-300)), 1)[0]
    return {"rate_1_s": float(g), "from_s": float(t[j0]), "to_s": float(t[j1])}


def summary(v) -> dict:
    v = np.asarray(v, float)
    return {"max": float(np.max(v)), "end": float(v[-1])}


def frequencies(h, case: str, modes: dict, r0: float) -> dict:
    """The spectra of the tip-height components and of the hub's transverse rate over the
    case's window, next to the closed forms at the window's mean spin rate."""
    t = h["time"]
    a, b = WINDOWS[case]
    sel = (t >= a) & (t <= b)
    W = float(np.mean(h["hub_omega"][sel]))
    L = float(np.mean(h["arm_length"][sel]))
    z = h["tip_position"][sel][:, :, 2]
    out = {"window_s": [a, b], "omega_mean_rad_s": W,
           "omega_std_rad_s": float(np.std(h["hub_omega"][sel])), "arm_length_mean_m": L,
           "tip_height_rms_m": float(np.sqrt(np.mean((z - z.mean(0)) ** 2)))}
    for name, y in tip_components(z).items():
        out[name] = {"rms_m": float(np.std(y)), "peaks_rad_s": [
            {"omega_rad_s": w, "ratio": w / W if W else None, "amplitude_m": amp}
            for w, amp in peak_frequency(t[sel], y)]}
    out["tip_crossings_rad_s"] = [crossing_rate(t[sel], z[:, k]) for k in range(z.shape[1])]
    if "hub_angular_velocity" in h:
        out["hub_rate_x"] = {"peaks_rad_s": [
            {"omega_rad_s": w, "ratio": w / W if W else None, "amplitude_rad_s": amp}
            for w, amp in peak_frequency(t[sel], h["hub_angular_velocity"][sel][:, 0])]}
    out["theory_rad_s"] = {
        "tether_pendulum": W * math.sqrt(1.0 + r0 / L) if L > 0 else None,
        "rigid_spin": W,
        **{f"modes_{k}": W * v for k, v in modes.items() if k in ("umbrella", "tilt",
                                                                  "saddle")}}
    return out


def verdict(r: dict) -> str:
    """One word for the run: planar (no node ever leaves the plane), overturns (the hub axis
    turns more than 1 rad away from the angular momentum at some time) or bounded."""
    if r["out_of_plane_max_m"]["max"] == 0.0:
        return "planar"
    if r["hub_tilt_from_L_rad"]["max"] > 1.0:
        return "overturns"
    return "bounded"


def analyse_run(d: Path, case: str, pert: str, modes: dict) -> dict:
    with h5py.File(d / "results.h5") as f:
        h = history_of(f)
        attrs = {k: f.attrs[k] for k in ("status", "dt", "steps", "wall_time_s")}
        r0 = float(f["mesh"].attrs.get("hub_radius", 6.3))
        planes = best_planes(f)
    cols = out_of_plane_columns(h)
    t = h["time"]
    tilt = cols["hub_tilt"]
    L = h["angular_momentum_vector"]
    nL = np.linalg.norm(L, axis=1)
    k0 = int(np.argmax(nL > 1e-3 * np.max(nL)))  # L defined (a ramp starts at rest)
    Li = np.interp(planes["time"], t, np.arange(len(t))).round().astype(int)
    web_from_l = angle(planes["normal"], L[Li])[Li >= k0]
    r = {"case": CASES[case], "perturbation": pert, "settings": settings(pert),
         "status": str(attrs["status"]), "end_s": float(t[-1]), "dt_s": float(attrs["dt"]),
         "steps": int(attrs["steps"]), "wall_s": float(attrs["wall_time_s"]),
         "omega_end_rad_s": float(h["hub_omega"][-1]),
         "arm_length_end_m": [float(x) for x in h["arm_length"][-1]],
         "max_tension_N": float(np.max(h["max_tension"]))}
    r["out_of_plane_rms_m"] = summary(h["out_of_plane_rms"])
    r["out_of_plane_max_m"] = summary(h["out_of_plane_max"])
    for key, v in (("out_of_plane_rms_m", h["out_of_plane_rms"]),
                   ("out_of_plane_max_m", h["out_of_plane_max"])):
        r[key]["t_max_s"] = float(t[int(np.argmax(v))])
        r[key]["initial"] = float(v[0])
    r["best_plane_rms_m"] = summary(planes["rms"])
    r["best_plane_max_m"] = summary(planes["max"])
    r["web_normal_from_L_rad"] = summary(web_from_l)
    r["hub_tilt_from_z_rad"] = summary(tilt[:, 0])
    # from L where it is defined: |L| above 1e-3 of its largest
    r["hub_tilt_from_L_rad"] = summary(tilt[k0:, 1])
    r["hub_tilt_from_L_rad"]["initial"] = float(tilt[k0, 1])
    r["hub_tilt_from_L_rad"]["from_s"] = float(t[k0])
    r["hub_tilt_growth"] = growth_rate(t[k0:], tilt[k0:, 1])
    r["hub_transverse_rate_rad_s"] = summary(cols["hub_transverse_rate"])
    r["hub_displacement_max_m"] = float(np.max(np.linalg.norm(h["hub_position"], axis=1)))
    r["tip_height_abs_max_m"] = float(np.max(np.abs(h["tip_position"][..., 2])))
    r["tip_height_above_hub_plane_abs_max_m"] = float(np.max(np.abs(cols["tip_height"])))
    r["energy_drift"] = balance_error(h)
    r["momentum"] = momentum_balance(h)
    r["frequencies"] = frequencies(h, case, modes, r0) if r["out_of_plane_max_m"]["max"] > 0 \
        else None
    r["verdict"] = verdict(r)
    return r, planes


def stage_checks(out: Path, rerun: bool) -> dict:
    """Is it the physics? The feedback web's hub-tilt growth with half the step, a 100x
    smaller seed and 10x / 100x the hub's transverse inertia; the angular momentum balance
    with a history row every step; the free web's end state (tilted, and tilted with the
    late arm) with half the step."""
    base = ["hub.motion=\"free\"", "perturbation.shape=\"tilt\"", "output.frame_dt=0"]
    checks = {
        "feedback_tilt_1s": ("feedback", ["perturbation.z_amplitude=1.0", "time.end=1.0"]),
        "feedback_tilt_1s_cfl0.1": ("feedback", ["perturbation.z_amplitude=1.0",
                                                 "time.end=1.0", "time.cfl=0.1"]),
        "feedback_tilt_1cm_1s": ("feedback", ["perturbation.z_amplitude=0.01",
                                              "time.end=1.0"]),
        "feedback_tilt_1s_I1x10": ("feedback", ["perturbation.z_amplitude=1.0", "time.end=1.0",
                                                "hub.inertia_transverse=19845.0"]),
        "feedback_tilt_1s_I1x100": ("feedback", ["perturbation.z_amplitude=1.0",
                                                 "time.end=1.0",
                                                 "hub.inertia_transverse=198450.0"]),
        "ramp_tilt_1.5s_every_step": ("ramp", ["perturbation.z_amplitude=1.0", "time.end=1.5",
                                               "output.history_dt=4.545454545454546e-05"]),
        "free_tilt_cfl0.1": ("free", ["perturbation.z_amplitude=1.0", "time.cfl=0.1"]),
        "free_late_arm_tilt_cfl0.1": ("free", ["perturbation.z_amplitude=1.0", "time.cfl=0.1",
                                               "perturbation.arm=0", "perturbation.delay=0.1"]),
    }
    res = {}
    for name, (case, keys) in checks.items():
        d = out / f"check_{name}"
        if not ((d / "results.h5").is_file() and not rerun):
            cmd = [PY, "-m", "spinweb_fe", "run", str(ROOT / "cases" / f"{CASES[case]}.toml"),
                   "-o", str(d), "--threads", "1", "--no-progress", "--force"]
            for k in base + keys:
                cmd += ["--set", k]
            r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
            d.mkdir(parents=True, exist_ok=True)
            (d / "run.log").write_text(" ".join(cmd) + "\n" + r.stdout + r.stderr)
            print(f"check_{name}: exit {r.returncode}", flush=True)
        with h5py.File(d / "results.h5") as f:
            h = history_of(f)
            dt = float(f.attrs["dt"])
        cols = out_of_plane_columns(h)
        t = h["time"]
        at = {f"{x:g}": float(cols["hub_tilt"][int(np.argmin(np.abs(t - x))), 1])
              for x in (0.1, 0.2, 0.3, 0.5, 1.0) if x <= t[-1] + 1e-9}
        res[name] = {"keys": base + keys, "dt_s": dt, "rows": int(len(t)),
                     "hub_tilt_from_L_rad_at": at,
                     "hub_tilt_growth": growth_rate(t, cols["hub_tilt"][:, 1],
                                                    lo=1e-4 if "1cm" in name else 1e-3,
                                                    hi=1e-3 if "1cm" in name else 0.1),
                     "growth_0.05_0.25_s": float(np.polyfit(
                         t[(t >= 0.05) & (t <= 0.25)],
                         np.log(cols["hub_tilt"][(t >= 0.05) & (t <= 0.25), 1]), 1)[0]),
                     "growth_0.3_1.0_s": float(np.polyfit(
                         t[(t >= 0.3) & (t <= 1.0)],
                         np.log(cols["hub_tilt"][(t >= 0.3) & (t <= 1.0), 1]), 1)[0]),
                     "energy_drift": balance_error(h), "momentum": momentum_balance(h),
                     "out_of_plane_rms_end_m": float(h["out_of_plane_rms"][-1]),
                     "out_of_plane_max_max_m": float(np.max(h["out_of_plane_max"])),
                     "hub_tilt_from_L_max_rad": float(np.max(cols["hub_tilt"][1:, 1]))}
    return res


def initial_momentum() -> dict:
    """The linear momentum of the initial state of the free web tilted by 1 m, without and
    with arm 0 delayed (built as ``spinweb run`` builds it), and the largest difference of
    the start-free nodes' velocities from a spin about z at their (tilted) positions."""
    from spinweb_fe.case.load import load
    from spinweb_fe.case.scene import prepare

    base = ['hub.motion="free"', 'perturbation.shape="tilt"', 'perturbation.z_amplitude=1.0']
    out = {}
    for name, extra in (("tilt", []), ("tilt_delay", ["perturbation.arm=0",
                                                      "perturbation.delay=0.1"])):
        case = load(ROOT / "cases" / "paper_free_web.toml", base + extra)
        _, _, _, st, _ = prepare(case)
        free = st.node_inv_mass > 0
        p = (st.node_mass[free, None] * st.node_vel[free]).sum(0) \
            + st.rigid.mass[0] * st.rigid.velocity
        w = case.initial.omega
        spin = np.column_stack([-w * st.node_pos[:, 1], w * st.node_pos[:, 0],
                                np.zeros(len(st.node_pos))])
        out[name] = {"P_kg_m_s": [float(x) for x in p],
                     "max_velocity_off_spin_m_s": float(np.max(np.abs(
                         st.node_vel[free] - spin[free])))}
    return out


def stage_analyse(out: Path, rerun: bool) -> dict:
    mh = run_modes("ramp", 8 * math.pi, out, rerun)
    modes = {"ramp": mode_ratios(mh)}
    with h5py.File(out / "feedback_tilt_fixed_axis" / "results.h5") as f:
        h = history_of(f)
    a, b = WINDOWS["feedback"]
    sel = (h["time"] >= a) & (h["time"] <= b)
    w_fb = float(np.mean(h["hub_omega"][sel]))
    modes["feedback"] = mode_ratios(run_modes("feedback", w_fb, out, rerun))
    modes["free"] = modes["ramp"]  # (ratios only: the free web is never deployed steadily)
    runs, planes = {}, {}
    for case in CASES:
        for pert in PERTURBATIONS:
            name = f"{case}_{pert}"
            runs[name], planes[name] = analyse_run(out / name, case, pert, modes[case])
            print(f"{name}: {runs[name]['verdict']}", flush=True)
    git = subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True,
                         text=True, cwd=ROOT).stdout.strip()
    res = {"machine": {"platform": platform.platform(), "processor": platform.processor(),
                       "cores": os.cpu_count(), "python": platform.python_version(),
                       "date": time.strftime("%Y-%m-%d"),
                       "load_1min": os.getloadavg()[0], "git": git},
           "settings": {"z_amplitude_m": Z_AMP, "hub_tilt_rate_rad_s": 0.01,
                        "delay_s": 0.1, "delayed_arm": 0, "frame_dt_s": FRAME_DT,
                        "windows_s": WINDOWS, "hub_motion": "free (but tilt_fixed_axis)",
                        "cfl": 0.2, "threads": 1},
           "modes": modes, "runs": runs, "checks": stage_checks(out, rerun),
           "initial_momentum": initial_momentum()}
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(res, indent=1, default=_json))
    np.savez_compressed(out / "planes.npz", **{f"{k}/{q}": v[q] for k, v in planes.items()
                                               for q in ("time", "rms", "band_rms",
                                                         "band_edges")})
    print(f"wrote {RESULTS}", flush=True)
    return res


def _json(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    raise TypeError(type(o))



# --- figures ----------------------------------------------------------------------------------

PANEL_RUNS = ("tilt", "random", "hub_tilt", "late_arm_tilt", "tilt_fixed_axis")
#: oblique pictures: (file, run, time [s] or None for the last frame, z scale)
OBLIQUE = (("oop_oblique_feedback_fixed_axis.png", "feedback_tilt_fixed_axis", None, 10.0),
           ("oop_oblique_free_tilt.png", "free_tilt", None, 5.0),
           ("oop_oblique_ramp_tilt.png", "ramp_tilt", 1.1, 1.0))
MONTAGE = ("feedback_tilt", (0.2, 0.3, 0.4, 0.6))


def _cli(args):
    r = subprocess.run([PY, "-m", "spinweb_fe", *args], capture_output=True, text=True,
                       cwd=ROOT)
    if r.returncode != 0:
        print(f"spinweb {args[0]} failed: {r.stderr.strip()}", flush=True)
    return r.returncode


def stage_figs(out: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    res = json.loads(RESULTS.read_text())
    IMG.mkdir(parents=True, exist_ok=True)
    from spinweb_fe.post.plot import load_for_plot, plot_histories

    # 1. the out-of-plane panels of each case: those of `spinweb plot --panels out_of_plane`
    # (its plot_histories), one colour per run ("C0".. as the style: the command line gives
    # every line of a run its own colour)
    for case in CASES:
        curves = [(*load_for_plot(out / f"{case}_{p}" / "results.h5"), f"C{k}")
                  for k, p in enumerate(PANEL_RUNS)]
        plot_histories(curves, IMG / f"oop_panels_{case}.png", panels="out_of_plane",
                       title=f"{CASES[case]}, free hub (but tilt_fixed_axis): 1 m tilt / "
                             "random, hub 0.01 rad/s, arm 0 late + tilt")
    # 2. oblique pictures: `spinweb render --view oblique`
    for name, run, at, zs in OBLIQUE:
        args = ["render", str(out / run / "results.h5"), "-o", str(IMG / name), "--view",
                "oblique", "--z-scale", f"{zs:g}", "--size", "800x600"]
        _cli(args + (["--time", f"{at:g}"] if at is not None else []))
    run, times = MONTAGE
    tiles = []
    for k, at in enumerate(times):
        tile = out / f"montage_{k}.png"
        _cli(["render", str(out / run / "results.h5"), "-o", str(tile), "--view", "oblique",
              "--time", f"{at:g}", "--size", "640x480"])
        tiles.append(Image.open(tile).convert("RGB"))
    w, h = tiles[0].size
    sheet = Image.new("RGB", (2 * w, 2 * h), "white")
    for k, tile in enumerate(tiles):
        sheet.paste(tile, ((k % 2) * w, (k // 2) * h))
    sheet.save(IMG / "oop_oblique_feedback_tilt.png")
    # 3. growth of the hub tilt from the angular momentum
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8), layout="constrained")
    for case, style in (("free", "-"), ("feedback", "--"), ("ramp", ":")):
        for pert in ("tilt", "random", "hub_tilt", "late_arm_tilt"):
            with h5py.File(out / f"{case}_{pert}" / "results.h5") as f:
                hh = history_of(f)
            c = out_of_plane_columns(hh)
            axes[0].semilogy(hh["time"], np.maximum(c["hub_tilt"][:, 1], 1e-6), style, lw=0.9,
                             label=f"{case} {pert}")
    axes[0].set(xlabel="t [s]", ylabel="hub axis from L [rad]", xlim=(0, 10),
                title="free hub: the perturbed runs")
    axes[0].legend(fontsize=7, ncol=3)
    for name in ("feedback_tilt_1s", "feedback_tilt_1s_cfl0.1", "feedback_tilt_1cm_1s",
                 "feedback_tilt_1s_I1x10", "feedback_tilt_1s_I1x100"):
        with h5py.File(out / f"check_{name}" / "results.h5") as f:
            hh = history_of(f)
        c = out_of_plane_columns(hh)
        g = res["checks"][name]["growth_0.05_0.25_s"]
        axes[1].semilogy(hh["time"], np.maximum(c["hub_tilt"][:, 1], 1e-6), lw=1.0,
                         label=f"{name} ({g:.1f} 1/s over 0.05-0.25 s)")
    axes[1].set(xlabel="t [s]", ylabel="hub axis from L [rad]", xlim=(0, 1),
                title="feedback web, 1 m tilt: step, seed and hub inertia")
    axes[1].legend(fontsize=7)
    fig.savefig(IMG / "oop_growth.png", dpi=110)
    plt.close(fig)
    # 4. spectra of the tip-height components against the modes
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), layout="constrained")
    for ax, (run, case) in zip(axes, (("feedback_tilt_fixed_axis", "feedback"),
                                      ("ramp_tilt_fixed_axis", "ramp"),
                                      ("free_tilt", "free"))):
        with h5py.File(out / run / "results.h5") as f:
            hh = history_of(f)
        a, b = WINDOWS[case]
        tt = hh["time"]
        sel = (tt >= a) & (tt <= b)
        W = float(np.mean(hh["hub_omega"][sel]))
        for name, y in tip_components(hh["tip_position"][sel][:, :, 2]).items():
            y = y - y.mean()
            win = np.hanning(len(y))
            m = 8 * len(y)
            spec = np.abs(np.fft.rfft(y * win, m)) * 2 / win.sum()
            w = 2 * np.pi * np.fft.rfftfreq(m, tt[1] - tt[0])
            ax.plot(w / W, spec, lw=0.9, label=name)
        modes = res["modes"][case]
        for key, ls in (("umbrella", ":"), ("tilt", "--"), ("saddle", "-.")):
            ax.axvline(modes[key], color="k", ls=ls, lw=0.8, label=f"modes: {key}")
        L = float(np.mean(hh["arm_length"][sel]))
        ax.axvline(math.sqrt(1 + 6.3 / L), color="r", lw=0.8, label="sqrt(1 + r0/L)")
        ax.set(xlim=(0, 3), xlabel="omega / Omega (Omega: mean hub rate of the window)",
               ylabel="amplitude [m]",
               title=f"{run}, {a:g}-{b:g} s, Omega = {W:.2f} rad/s")
        ax.legend(fontsize=7)
    fig.savefig(IMG / "oop_spectra.png", dpi=110)
    plt.close(fig)
    # 5. where the web leaves its best plane: RMS distance per 5 m band of the flat web
    planes = np.load(out / "planes.npz")
    fig, axes = plt.subplots(1, 4, figsize=(17, 4.2), layout="constrained")
    for ax, run in zip(axes, ("free_tilt", "feedback_tilt_fixed_axis", "feedback_tilt",
                              "ramp_tilt")):
        tt, band, edges = (planes[f"{run}/{q}"] for q in ("time", "band_rms", "band_edges"))
        im = ax.pcolormesh(tt, 0.5 * (edges[1:] + edges[:-1]), band.T, shading="nearest",
                           cmap="magma")
        fig.colorbar(im, ax=ax, label="RMS distance from the best plane [m]")
        ax.set(xlabel="t [s]", ylabel="radius in the flat web [m]", title=run)
    fig.savefig(IMG / "oop_bands.png", dpi=100)
    plt.close(fig)
    for name in ("oop_panels_free.png", "oop_panels_feedback.png", "oop_panels_ramp.png",
                 "oop_growth.png", "oop_spectra.png", "oop_bands.png"):  # 256 colours
        Image.open(IMG / name).convert("RGB").quantize(256).save(IMG / name, optimize=True)
    print("wrote docs/img/oop_*.png", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "out" / "out_of_plane"), help="run folders")
    ap.add_argument("--rerun", action="store_true", help="run again even if a result exists")
    ap.add_argument("--jobs", type=int, default=1, help="spinweb runs at a time")
    ap.add_argument("--only", nargs="+", choices=("runs", "analyse", "figs"),
                    default=("runs", "analyse", "figs"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    if "runs" in args.only:
        for r in stage_runs(out, args.rerun, args.jobs):
            if r.get("exit", 0) != 0:
                print(f"{r['run']} failed: {r['stderr_tail']}", flush=True)
    if "analyse" in args.only:
        stage_analyse(out, args.rerun)
    if "figs" in args.only:
        stage_figs(out)
    print(f"out_of_plane_study: {time.perf_counter() - t0:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
