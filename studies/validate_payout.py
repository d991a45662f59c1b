"""Validation of the payout devices (issue 24, item 5): the reel (``payout = "rate"``) and
the brake (``payout = "brake"``) of fe.coil.payout against their analytical twins (the paying
regime of analytic.payout, the stick, slip and peel of analytic.brake), with the numbers quoted
by docs/validation.md, section 0.5.

    .venv/bin/python -m studies.validate_payout [--only reel,held,brake,eq7,eq7brake,web,webbrake,explore,stiff]
                                                 [--cache DIR]

Studies (each writes ``benchmarks/results/validation/payout_<study>.json``, most a figure
``docs/img/payout_<study>.png``):

- ``reel``: point-mass tethers (validation/free_arms_stiff_light.toml: light uniform
  tethers, 10 kg tips) with a cable 100x Zylon (``stiff``: why), reeled out at 10 and
  20 m/s, over the payout (the analytical arm shorter than H);
- ``held``: the same tethers braked at 42 and 45 kN, above the tips' pull, over 2 s:
  slip, then stick (the controlled regime);
- ``brake``: the same tethers braked at 30 and 38 kN, over the analytical brake's span
  from t = 0 (the sweep over 0-50 kN: studies/validate_devices.py);
- ``eq7``: stiff (1000x) Eq. 7 tethers (cases/paper_free_arms_eq7_stiff.toml), reel at 10
  and 20 m/s, and the bow of the heavy string in the FE frames;
- ``web``: the paper's web reeled at 10 m/s (cases/paper_payout_web.toml): the energy
  balance with the reel's work, the re-coil checks, the four panels against the analytical
  arm;
- ``explore``: the analytical brake only: how long a constant force (or a force table)
  slips before the arm comes back to its tangent;
- ``stiff``: the reel at 10 m/s over 0-1 s and the 30 kN brake with the case's 1000x
  cable against 100x: the choice of ``reel`` and ``brake``.

Norms: over the window, L max and RMS over all arms / H, phi max and RMS [rad] (all arms),
hub rate RMS / omega0; the rows from t = history_dt on (at t = 0 the FE arm has no length:
its tip sits at the departure point D and phi is not defined). The device's work: the sum
over the arms of ``brake_work`` at the window's end, FE against analytical. The line's
tension at D rings about the analytical one in the FE (the stiff line's axial vibration,
undamped): its means over 0.1 s bins are compared, not its samples. ``--cache DIR`` keeps
the FE histories (npz) between invocations.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from benchmarks.common import machine
from spinweb_fe import case as case_mod
from spinweb_fe.analytic.compare import analytic_twin, web_params
from spinweb_fe.analytic.models import HALF_PI, params_from_case
from spinweb_fe.case.scene import prepare
from spinweb_fe.errors import RunError
from spinweb_fe.post.plot import plot_histories
from spinweb_fe.record.energy import energy_balance
from spinweb_fe.record.recorders import Recorder
from spinweb_fe.run.loop import Schedule, simulate

ROOT = Path(__file__).resolve().parent.parent
CASES = ROOT / "cases"
OUT = ROOT / "benchmarks" / "results" / "validation"
IMG = ROOT / "docs" / "img"
LIGHT = CASES / "validation" / "free_arms_stiff_light.toml"
EQ7_STIFF = CASES / "paper_free_arms_eq7_stiff.toml"
WEB_REEL = CASES / "paper_payout_web.toml"
WEB_BRAKE = CASES / "paper_brake_web.toml"
#: the point-mass tethers' cable: 100x Zylon (E A = 1.845e8 N), see the ``stiff`` study
E_100X = "cable.youngs_modulus=180e11"
REEL_RATES = (10.0, 20.0)
BRAKE_FORCES = (30e3, 38e3)
#: brakes just above the point-mass tips' pull at the rim (39.8 kN): they slip, then hold
HELD_FORCES = (42e3, 45e3)
TARGETS = {"L_rms_over_H": 0.005, "phi_rms_rad": 0.02, "hub_rms_over_omega0": 0.01,
           "work_rel": 0.01}
CACHE: Path | None = None


# --------------------------------------------------------------------------- helpers

def load(path, sets=()):
    return case_mod.load(path, list(sets) + ["output.frame_dt=0"])


def reel_sets(rate, H):
    return ["stowage.payout='rate'", f"stowage.payout_rate={rate}", f"time.end={H / rate + 0.05}"]


def brake_sets(force, end=0.3):
    return ["stowage.payout='brake'", f"stowage.brake_force={force}", f"time.end={end}"]


def dump(name, data):
    OUT.mkdir(parents=True, exist_ok=True)
    data = {"machine": machine(), **data}
    (OUT / f"payout_{name}.json").write_text(json.dumps(data, indent=1, default=float))


class ArmFrames(Recorder):
    """Keeps arm 0's node positions at every frame (the string's bow)."""

    name = "arm_frames"

    def __init__(self, nodes):
        self.nodes = nodes
        self.times, self.pos = [], []

    def frame(self, frame):
        self.times.append(frame.time)
        self.pos.append(frame.pos[self.nodes].copy())


def run_fe(case, tag=None, frame_dt=0.0, energy_limit=None):
    """The FE run of a case in memory (spinweb_fe.analytic.compare.fe_run, with arm 0's
    frames every ``frame_dt`` and an optional energy limit); returns (history, info,
    mesh, frames). ``tag``: the cache's name of the run (histories only)."""
    path = CACHE / f"{tag}.npz" if CACHE and tag else None
    mesh, model, control, state, dt = prepare(case)
    sel = np.flatnonzero(mesh.node_arm == 0)
    frames = ArmFrames(sel) if frame_dt else None
    if path is not None and path.exists():
        data = np.load(path, allow_pickle=True)
        h = {k: data[k] for k in data.files if not k.startswith("_")}
        if frames is not None:
            frames.times, frames.pos = list(data["_frame_t"]), list(data["_frame_pos"])
        return h, data["_info"].item(), mesh, frames
    kw = {} if energy_limit is None else {"energy_limit": energy_limit}
    t0 = time.perf_counter()
    status = "completed"
    try:
        res = simulate(model, control, state, dt,
                       Schedule(case.time.end, case.output.history_dt, frame_dt),
                       [frames] if frames else (), **kw)
        h = res.history
        steps = int(res.steps)
    except RunError as exc:  # the energy audit stopped it
        raise RuntimeError(f"{tag}: {exc}") from exc
    wall = time.perf_counter() - t0
    info = {"elements": int(model.n_elems), "nodes": int(model.n_nodes), "dt": dt,
            "steps": steps, "wall_s": wall, "status": status}
    if path is not None:
        CACHE.mkdir(parents=True, exist_ok=True)
        extra = {"_frame_t": np.array(frames.times), "_frame_pos": np.array(frames.pos)} \
            if frames is not None else {}
        np.savez(path, _info=np.array(info, dtype=object), **extra,
                 **{k: v for k, v in h.items() if isinstance(v, np.ndarray)})
    return h, info, mesh, frames


def aligned(fe, an):
    """Both histories cut to their common rows (same history_dt from t = 0)."""
    n = min(len(fe["time"]), len(an["time"]))
    assert np.allclose(fe["time"][:n], an["time"][:n], atol=1e-9)
    cut = lambda h: {k: v[:n] for k, v in h.items() if isinstance(v, np.ndarray) and len(v) >= n}
    return cut(fe), cut(an)


def norms(f, a, sel, H, omega0):
    """The issue's norms on the rows ``sel`` of aligned histories."""
    dL = np.abs(f["arm_length"][sel] - a["arm_length"][sel])
    dphi = np.abs(f["arm_angle"][sel] - a["arm_angle"][sel])
    dw = np.abs(f["hub_omega"][sel] - a["hub_omega"][sel])
    t = f["time"][sel]
    return {"window_s": [float(t[0]), float(t[-1])], "rows": int(sel.sum()),
            "L_max_over_H": float(dL.max() / H),
            "L_rms_over_H": float(np.sqrt(np.mean(dL ** 2)) / H),
            "phi_max_rad": float(dphi.max()), "phi_rms_rad": float(np.sqrt(np.mean(dphi ** 2))),
            "phi_max_at_s": float(t[np.argmax(dphi.max(axis=1))]),
            "hub_max_over_omega0": float(dw.max() / abs(omega0)),
            "hub_rms_over_omega0": float(np.sqrt(np.mean(dw ** 2)) / abs(omega0))}


def work(f, a, i):
    """The devices' work summed over the arms at row i, FE and analytical [J]."""
    w_fe, w_an = float(f["brake_work"][i].sum()), float(a["brake_work"][i].sum())
    return {"fe_J": w_fe, "an_J": w_an, "rel": (w_fe - w_an) / abs(w_an)}


def tension_bins(f, a, sel, width):
    """The line's tension at D (arm 0) in bins of ``width`` [s] over the rows ``sel``: the
    means of each, their RMS difference over the analytical mean, the whole window's."""
    t = f["time"][sel]
    x, y = f["brake_tension"][sel, 0], a["brake_tension"][sel, 0]
    edges = np.arange(t[0], t[-1] + width, width)
    k = np.clip(np.searchsorted(edges, t, side="right") - 1, 0, len(edges) - 1)
    fm = np.array([x[k == j].mean() for j in np.unique(k)])
    am = np.array([y[k == j].mean() for j in np.unique(k)])
    return {"bin_s": width, "fe_mean_N": float(x.mean()), "an_mean_N": float(y.mean()),
            "mean_rel": float((x.mean() - y.mean()) / y.mean()),
            "bins_rms_rel": float(np.sqrt(np.mean((fm - am) ** 2)) / y.mean()),
            "bins_max_rel": float(np.max(np.abs(fm - am) / np.maximum(am, 1e-9))),
            "fe_sample_min_N": float(x.min()), "fe_sample_max_N": float(x.max()),
            "fe_rows_below_10pct": int(np.sum(x < 0.1 * y))}


def balance(h):
    """Largest |energy balance drift| (KE + SE - W_torque - W_device + losses) / KE0."""
    bal = energy_balance(h)
    return float(np.max(np.abs(bal - bal[0])) / h["kinetic_energy"][0])


def beta(h, root_coord, r0, w=1.0):
    """The arm's angle from the radial at its departure point (all arms): phi + w alpha_D,
    alpha_D = (s_D - root) / r0 the departure's wound angle (-w pi/2: the coil's tangent)."""
    return h["arm_angle"] + w * (h["payout_front"] - root_coord) / r0


def report(label, rec):
    keys = ("L_rms_over_H", "L_max_over_H", "phi_rms_rad", "phi_max_rad", "hub_rms_over_omega0")
    print(f"{label}: " + ", ".join(f"{k} {rec[k]:.3g}" for k in keys if k in rec), flush=True)


def smooth(t, y, width):
    """Running mean of y over ``width`` [s] (rows evenly spaced)."""
    n = max(1, round(width / (t[1] - t[0])))
    return np.convolve(y, np.ones(n) / n, mode="same")


def plot_device(curves, out, title, t_max=None, t_marks=(), extra=()):
    """FE (solid) against the analytical model (dashed): L, phi, hub rate, device work of
    one arm, the line's tension at D (FE: 10 ms running mean, samples faint), payout speed.
    curves: (label, fe, an, colour); extra: (label, history, colour) drawn dash-dotted on
    the panels of the keys they have."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = (("arm_length", "L [m]"), ("arm_angle", "phi [rad]"),
              ("hub_omega", "omega_centre [rad/s]"), ("brake_work", "device work, one arm [kJ]"),
              ("brake_tension", "tension at D [kN]"), ("payout_speed", "payout speed [m/s]"))
    fig, axes = plt.subplots(2, 3, figsize=(14, 7.5), sharex=True)
    for label, fe, an, colour in curves:
        for ax, (key, ylab) in zip(axes.flat, panels):
            for h, style, lab in ((fe, "-", f"FE {label}"), (an, "--", f"analytic {label}")):
                t = h["time"]
                sel = t <= (t_max or t[-1]) + 1e-12
                y = h[key][:, 0] if h[key].ndim == 2 else h[key]
                scale = 1e-3 if key in ("brake_work", "brake_tension") else 1.0
                if key == "brake_tension" and h is fe:
                    ax.plot(t[sel], scale * y[sel], "-", color=colour, lw=0.4, alpha=0.25)
                    y = smooth(t, y, 0.01)
                ax.plot(t[sel], scale * y[sel], style, color=colour, lw=1.1,
                        label=lab)
                ax.set_ylabel(ylab)
    for label, h, colour in extra:
        for ax, (key, _) in zip(axes.flat, panels):
            if key in h:
                scale = 1e-3 if key == "brake_work" else 1.0
                ax.plot(h["time"], scale * h[key], "-.", color=colour, lw=1.0, label=label)
    for ax in axes.flat:
        ax.grid(alpha=0.3)
        for tm in t_marks:
            ax.axvline(tm, color="0.5", lw=0.6, ls=":")
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=100)
    plt.close(fig)


# --------------------------------------------------------------------------- reel

def reel_run(path, rate, sets, tag, frame_dt=0.0):
    """FE and analytical reel at ``rate``; the norms over the payout."""
    cs = load(path, list(sets) + reel_sets(rate, 50.0))
    H, omega0 = cs.tethers.length, cs.initial.omega
    an, res = analytic_twin(cs)
    fe, info, mesh, frames = run_fe(cs, tag, frame_dt)
    f, a = aligned(fe, an)
    t = f["time"]
    paying = a["arm_length"][:, 0] < H * (1.0 - 1e-9)
    sel = (t > 1e-12) & paying
    i_end = int(np.flatnonzero(sel)[-1])
    rec = dict(norms(f, a, sel, H, omega0), rate_mps=rate, stopped=res.stopped,
               t_paid_out_s=float(t[i_end]), work=work(f, a, i_end),
               tension=tension_bins(f, a, sel, 0.1), balance_over_KE0=balance(fe),
               KE0_J=float(fe["kinetic_energy"][0]), dt=info["dt"], wall_s=info["wall_s"],
               steps=info["steps"])
    late = sel & (t >= 0.1 - 1e-12)  # the arm longer than the first element (10 m/s)
    rec["from_0.1s"] = norms(f, a, late, H, omega0)
    lf = f["arm_length"][sel] - rate * t[sel, None]
    rec["L_minus_law_m"] = {"max": float(lf.max()), "min": float(lf.min())}
    v = f["payout_speed"][sel]
    rec["payout_speed_dev_mps"] = float(np.max(np.abs(v - rate)))
    return rec, fe, an, cs, mesh, frames


def reel_study():
    """The point-mass tethers reeled out at 10 and 20 m/s."""
    recs, curves = {}, []
    for rate, colour in zip(REEL_RATES, ("C0", "C3")):
        rec, fe, an, *_ = reel_run(LIGHT, rate, [E_100X], f"reel_light_{rate:g}")
        recs[f"reel_{rate:g}mps"] = rec
        report(f"reel {rate:g} m/s", rec)
        print(f"   work {rec['work']['rel']:.2e}, tension {rec['tension']}, balance "
              f"{rec['balance_over_KE0']:.2e}, wall {rec['wall_s']:.0f} s", flush=True)
        curves.append((f"{rate:g} m/s", fe, an, colour))
    plot_device(curves, IMG / "payout_reel.png", "reel at D, point-mass tethers (light uniform, "
                "10 kg tips, 100x Zylon): FE (solid) vs analytical paying regime (dashed)")
    dump("reel", {"case": str(LIGHT.relative_to(ROOT)), "sets": [E_100X], "runs": recs})


# --------------------------------------------------------------------------- brake

def brake_run(path, force, sets, tag, H=50.0, end=0.3):
    cs = load(path, list(sets) + brake_sets(force, end))
    omega0 = cs.initial.omega
    an, res = analytic_twin(cs)
    fe, info, mesh, _ = run_fe(cs, tag)
    f, a = aligned(fe, an)
    t = f["time"]
    sel = t > 1e-12
    i_end = len(t) - 1
    rec = dict(norms(f, a, sel, H, omega0), force_N=force, stopped=res.stopped,
               an_end_s=float(an["time"][-1]), an_L_end_m=float(an["arm_length"][-1, 0]),
               work=work(f, a, i_end), work_row_before_end=work(f, a, i_end - 1),
               balance_over_KE0=balance(fe),
               KE0_J=float(fe["kinetic_energy"][0]), dt=info["dt"], wall_s=info["wall_s"],
               steps=info["steps"], fe_end_s=float(fe["time"][-1]),
               fe_L_end_m=[float(x) for x in fe["arm_length"][-1]],
               fe_L_at_an_end_m=float(f["arm_length"][-1, 0]))
    b = beta(fe, mesh.arm_root_coord, cs.hub.radius)[:, 0]
    back = np.flatnonzero((fe["time"] > 0.002) & (b <= -HALF_PI))
    rec["fe_tangent_s"] = float(fe["time"][back[0]]) if len(back) else None
    # the slip's tension at D against the force, and the slip speed there
    slip = sel & (f["payout_speed"][:, 0] > 1.0)
    ex = (f["brake_tension"][slip, 0] - force) / force
    rec["slip_tension_excess"] = {"max_rel": float(ex.max()),
                                  "at_speed_mps": float(f["payout_speed"][slip, 0][ex.argmax()]),
                                  "at_s": float(t[slip][ex.argmax()])} if slip.any() else None
    for ts in (0.005, 0.01, 0.02):
        j = int(np.argmin(np.abs(t - ts)))
        rec[f"at_{ts:g}s"] = {"fe_L": float(f["arm_length"][j, 0]),
                              "an_L": float(a["arm_length"][j, 0]),
                              "fe_speed": float(f["payout_speed"][j, 0]),
                              "an_speed": float(a["payout_speed"][j, 0])}
    dW = np.diff(fe["brake_work"].sum(axis=1))
    rec["fe_work_increase_max_J"] = float(max(dW.max(), 0.0))
    rec["fe_work_end_J"] = float(fe["brake_work"][-1].sum())
    return rec, fe, an, cs


def braked_tethers(path, sets, tag, label, name, title):
    """Tethers braked at BRAKE_FORCES from t = 0: records, report, figure
    ``payout_<name>.png`` and ``payout_<name>.json`` (the sweep over the forces from t = 0
    is studies/validate_devices.py)."""
    recs, curves, marks, extra = {}, [], [], []
    for force, colour in zip(BRAKE_FORCES, ("C0", "C3")):
        rec, fe, an, cs = brake_run(path, force, sets, f"brake_{tag}_{force:g}")
        recs[f"brake_{force / 1e3:g}kN"] = rec
        report(f"{label} {force / 1e3:g} kN (0-{rec['an_end_s']:.3f} s)", rec)
        print(f"   work {rec['work']['rel']:.2e}, FE tangent {rec['fe_tangent_s']}, FE L end "
              f"{rec['fe_L_end_m'][0]:.1f} m", flush=True)
        curves.append((f"{force / 1e3:g} kN", fe, an, colour))
        marks.append(rec["an_end_s"])
    plot_device(curves, IMG / f"payout_{name}.png", title, t_max=0.2, t_marks=marks,
                extra=extra)
    dump(name, {"case": str(path.relative_to(ROOT)), "sets": list(sets), "runs": recs})


def brake_study():
    """The point-mass tethers braked at 30 and 38 kN."""
    braked_tethers(LIGHT, [E_100X], "light", "brake", "brake",
                   "brake at D, point-mass tethers (100x Zylon): FE (solid) vs analytical "
                   "stick/slip (dashed, to the arm's return to its tangent: dotted lines)")


# --------------------------------------------------------------------------- Eq. 7

def bow(frames, fe, mesh, r0, w=1.0):
    """Largest distance [m] of arm 0's free nodes (arm coordinate beyond D's) from the
    straight line D -> tip, at each frame."""
    coord = mesh.node_arm_coord[frames.nodes]
    root = mesh.arm_root_angle[0]
    out = []
    for tf, pos in zip(frames.times, frames.pos):
        i = int(np.argmin(np.abs(fe["time"] - tf)))
        s_d = fe["payout_front"][i, 0]
        alpha = (s_d - mesh.arm_root_coord) / r0
        th = fe["hub_angle"][i] + root - w * alpha
        d = r0 * np.array([math.cos(th), math.sin(th)])
        free = coord > s_d + 1e-9
        tip = pos[np.argmax(coord), :2]
        u = tip - d
        Lc = np.hypot(*u)
        if Lc < 1.0 or free.sum() < 3:
            out.append((tf, 0.0, Lc))
            continue
        q = pos[free, :2] - d
        dist = np.abs(u[0] * q[:, 1] - u[1] * q[:, 0]) / Lc
        out.append((tf, float(dist.max()), float(Lc)))
    return out


def eq7_study():
    """Stiff Eq. 7 tethers: reel at 10 and 20 m/s."""
    recs, curves = {}, []
    for rate, colour in zip(REEL_RATES, ("C0", "C3")):
        rec, fe, an, cs, mesh, frames = reel_run(EQ7_STIFF, rate, [], f"reel_eq7_{rate:g}",
                                                 frame_dt=0.05)
        f, a = aligned(fe, an)
        t = f["time"]
        paying = a["arm_length"][:, 0] < 50.0 * (1.0 - 1e-9)
        for tb in (0.15, 0.3, 1.0, 2.0):
            rec[f"to_{tb:g}s"] = norms(f, a, (t > 1e-12) & (t <= tb + 1e-12) & paying, 50.0,
                                       cs.initial.omega)
        # the error in bins of a tenth of the payout (L: RMS over the arms, / H)
        t_full = rec["t_paid_out_s"]
        rec["L_rms_bins_over_H"] = []
        for k in range(10):
            s = (t > k * t_full / 10) & (t <= (k + 1) * t_full / 10 + 1e-12) & paying
            dL = f["arm_length"][s] - a["arm_length"][s]
            rec["L_rms_bins_over_H"].append([float(t[s][-1]),
                                             float(np.sqrt(np.mean(dL ** 2)) / 50.0)])
        rec["bow_m"] = [{"t": tb, "bow": b, "chord": c} for tb, b, c in
                        bow(frames, fe, mesh, cs.hub.radius)]
        recs[f"reel_{rate:g}mps"] = rec
        report(f"Eq. 7 reel {rate:g} m/s", rec)
        report("   to 0.15 s", rec["to_0.15s"])
        print(f"   work {rec['work']['rel']:.2e}, L bins {rec['L_rms_bins_over_H']}, bow "
              + ", ".join(f"{x['t']:.2f}:{x['bow']:.2f}" for x in rec["bow_m"][::4]), flush=True)
        curves.append((f"reel {rate:g} m/s", fe, an, colour))
    plot_device(curves, IMG / "payout_eq7_reel.png", "reel, stiff Eq. 7 tethers (1000x Zylon): "
                "FE (solid) vs analytical paying regime (dashed)")
    dump("eq7", {"case": str(EQ7_STIFF.relative_to(ROOT)), "runs": recs})


def eq7_brake_study():
    """Stiff Eq. 7 tethers braked at 30 and 38 kN (from t = 0 and restarted from the FE)."""
    braked_tethers(EQ7_STIFF, [], "eq7", "Eq. 7 brake", "eq7_brake",
                   "brake at D, stiff Eq. 7 tethers (1000x Zylon): FE (solid) vs analytical "
                   "stick/slip (dashed; dotted: restarted from the FE at 5 ms)")


# --------------------------------------------------------------------------- web

def recoil_checks(h, mesh, r0, level, t_a, t_b, paying):
    """What says the arms never wind back, from the histories over [t_a, t_b]: the largest
    fall of each arm's length from its running maximum (in level spacings), the payout
    speed's minimum, the hub rate's minimum, and the arm's angle at its anchor: while
    ``paying``, beta = phi + alpha_D from the radial at D (beyond the coil's tangent or
    over the coil: |beta| > pi/2), after it phi about the root (wrapped: |phi| > pi/2)."""
    t = h["time"]
    sel = (t >= t_a - 1e-12) & (t <= t_b + 1e-12) & (t > 1e-12)
    L = h["arm_length"][sel]
    fall = np.maximum.accumulate(L, axis=0) - L
    b = beta(h, mesh.arm_root_coord, r0)[sel] if paying else h["arm_angle"][sel]
    return {"window_s": [float(t[sel][0]), float(t[sel][-1])],
            "L_fall_max_m": float(fall.max()), "L_fall_max_levels": float(fall.max() / level),
            "payout_speed_min_mps": float(h["payout_speed"][sel].min()),
            "angle": "beta at D" if paying else "phi at the root",
            "angle_min_rad": float(b.min()), "angle_max_rad": float(b.max()),
            "beyond_pi_2_rad": float(np.abs(b).max() - HALF_PI),
            "hub_omega_min": float(h["hub_omega"][sel].min()),
            "hub_omega_min_at_s": float(t[sel][np.argmin(h["hub_omega"][sel])])}


def web_study():
    """The paper's web reeled out at 10 m/s."""
    cs = load(WEB_REEL)
    fe, info, mesh, _ = run_fe(cs, "web_reel")
    an, _ = analytic_twin(cs)
    _, model = prepare(cs)[:2]
    p, mapped = web_params(cs, mesh, model)
    an_m, _ = analytic_twin(cs, p)
    r0 = cs.hub.radius
    front = fe["payout_front"][:, 0]
    base = float(front.min())
    i_out = int(np.argmax(front <= base + 1e-9))  # the last level released
    t_out = float(fe["time"][i_out])
    coil = model.coil
    level = float(np.max(np.abs(np.diff(coil.level_coord[coil.arm_ptr[0]:coil.arm_ptr[1]]))))
    rec = {"case": str(WEB_REEL.relative_to(ROOT)), "wall_s": info["wall_s"], "dt": info["dt"],
           "elements": info["elements"], "KE0_J": float(fe["kinetic_energy"][0]),
           "balance_over_KE0": balance(fe), "t_coil_out_s": t_out,
           "reel_work_J": float(fe["brake_work"][-1].sum()),
           "an_reel_work_J": float(an["brake_work"][-1].sum()),
           "an_mapped_reel_work_J": float(an_m["brake_work"][-1].sum()),
           "mapped_arm": mapped, "level_spacing_m": level,
           "recoil_payout": recoil_checks(fe, mesh, r0, level, 0.0,
                                          float(fe["time"][i_out - 1]), True),
           "recoil_after": recoil_checks(fe, mesh, r0, level, t_out, float(fe["time"][-1]),
                                         False),
           "front_jump_at_coil_out_m": float(front[i_out - 1] - front[i_out]),
           "hub_omega_end": float(fe["hub_omega"][-1]),
           "L_end_m": [float(x) for x in fe["arm_length"][-1]]}
    # the reel's law: the FE line at D follows it to round-off
    t = fe["time"]
    paying = t < t_out - 1e-9
    rec["law_dev_m"] = float(np.max(np.abs(50.0 - front[paying] - 10.0 * t[paying])))
    print(f"web reel: balance {rec['balance_over_KE0']:.2e}, coil out {t_out:.3f} s, "
          f"work {rec['reel_work_J']:.4g} J (an {rec['an_reel_work_J']:.4g}, mapped "
          f"{rec['an_mapped_reel_work_J']:.4g}), recoil {rec['recoil_payout']}, after "
          f"{rec['recoil_after']}", flush=True)
    plot_histories([(fe, "FE web, reel 10 m/s", "-"),
                    (an, "analytic, the paper's arm (Eq. 7, H = 50 m)", "k--"),
                    (an_m, f"analytic, mapped arm (H = {p.H:.1f} m)", "k:")],
                   IMG / "payout_web.png", t_max=cs.time.end,
                   title="paper web (Zylon), reel at D at 10 m/s from 8 pi: FE vs analytical "
                         "paying regime")
    dump("web", rec)


def web_brake_study():
    """The paper's web through a 30 kN brake, against the free web and the analytical brake
    of the paper's arm: what a brake alone does to a web."""
    cs = load(WEB_BRAKE)
    fe, info, mesh, _ = run_fe(cs, "web_brake")
    free, _, _, _ = run_fe(load(CASES / "paper_free_web.toml"), "web_free")
    an, res = analytic_twin(cs)
    _, model = prepare(cs)[:2]
    coil = model.coil
    level = float(np.max(np.abs(np.diff(coil.level_coord[coil.arm_ptr[0]:coil.arm_ptr[1]]))))
    front = fe["payout_front"][:, 0]
    i_out = int(np.argmax(front <= float(front.min()) + 1e-9))
    t = fe["time"]
    paid = 50.0 - fe["payout_front"]
    rec = {"case": str(WEB_BRAKE.relative_to(ROOT)), "wall_s": info["wall_s"], "dt": info["dt"],
           "force_N": cs.stowage.brake_force, "KE0_J": float(fe["kinetic_energy"][0]),
           "balance_over_KE0": balance(fe), "t_coil_out_s": float(t[i_out]),
           "free_t_coil_out_s": float(free["time"][int(np.argmax(
               free["payout_front"][:, 0] <= float(free["payout_front"][:, 0].min()) + 1e-9))]),
           "brake_work_J": float(fe["brake_work"][-1].sum()),
           "friction_bound_J": float(-cs.stowage.brake_force * paid[-1].sum()),
           "work_increase_rows": int((np.diff(fe["brake_work"], axis=0) > 0).sum()),
           "hub_omega_min": float(fe["hub_omega"].min()),
           "hub_omega_min_at_s": float(t[np.argmin(fe["hub_omega"])]),
           "free_hub_omega_min": float(free["hub_omega"].min()),
           "an_end_s": float(an["time"][-1]), "an_stopped": res.stopped,
           "an_brake_work_J": float(an["brake_work"][-1].sum()),
           "recoil_after": recoil_checks(fe, mesh, cs.hub.radius, level, float(t[i_out]),
                                         float(t[-1]), False),
           "L_end_m": [float(x) for x in fe["arm_length"][-1]]}
    print(f"web brake: {rec}", flush=True)
    plot_histories([(fe, "FE web, brake 30 kN", "-"), (free, "FE web, free payout", ":"),
                    (an, "analytic brake, the paper's arm (Eq. 7)", "k--")],
                   IMG / "payout_web_brake.png", t_max=cs.time.end,
                   title="paper web (Zylon), brake at D at 30 kN from 8 pi: the line runs "
                         "away and the web re-coils as the free web does")
    dump("web_brake", rec)


# --------------------------------------------------------------------------- explore

def explore_study():
    """The analytical brake: how long it slips before the arm is back at its tangent."""
    out = {}
    for name, path in (("light", LIGHT), ("eq7_stiff", EQ7_STIFF)):
        rows = []
        for force in (5e3, 10e3, 20e3, 30e3, 34e3, 36e3, 38e3, 39e3, 39.5e3, 40e3, 41e3,
                      45e3, 60e3):
            cs = load(path, brake_sets(force, 2.0))
            try:
                an, res = analytic_twin(cs)
            except np.linalg.LinAlgError as exc:
                rows.append({"force_N": force, "error": f"LinAlgError: {exc}"})
                continue
            rows.append({"force_N": force, "end_s": float(an["time"][-1]),
                         "L_end_m": float(an["arm_length"][-1, 0]),
                         "work_J": float(an["brake_work"][-1].sum()),
                         "speed_max_mps": float(an["payout_speed"][:, 0].max()),
                         "hub_end": float(an["hub_omega"][-1]), "stopped": res.stopped})
        out[name] = {"constant": rows}
        for r in rows:
            print(name, r, flush=True)
    # force tables on the point-mass tethers: the reel's own tension, and ramps
    reel = load(LIGHT, reel_sets(10.0, 50.0))
    an_r, _ = analytic_twin(reel)
    tables = {}
    for scale in (0.97, 1.0, 1.03):
        tt = an_r["time"][::50]
        nn = an_r["brake_tension"][::50, 0] * scale
        nn[0] = nn[1]
        tables[f"reel_tension_x{scale:g}"] = list(zip(tt[nn > 0], nn[nn > 0]))
    for f0, slope in ((38e3, 50e3), (38e3, 100e3)):
        tables[f"ramp_{f0 / 1e3:g}kN_plus_{slope / 1e3:g}kN_per_s"] = [(0.0, f0),
                                                                       (5.0, f0 + 5 * slope)]
    trows = {}
    for name, tab in tables.items():
        text = "[" + ",".join(f"[{float(a)!r},{float(b)!r}]" for a, b in tab) + "]"
        cs = load(LIGHT, ["stowage.payout='brake'", f"stowage.brake_force_table={text}",
                          "time.end=5.0"])
        an, res = analytic_twin(cs)
        trows[name] = {"end_s": float(an["time"][-1]), "L_end_m": float(an["arm_length"][-1, 0]),
                       "work_J": float(an["brake_work"][-1].sum()),
                       "hub_end": float(an["hub_omega"][-1]), "stopped": res.stopped}
        print(name, trows[name], flush=True)
    out["light"]["tables"] = trows
    p = params_from_case(load(LIGHT))
    out["light"]["tip_pull_at_rim_N"] = p.m_tip * p.r0 * load(LIGHT).initial.omega ** 2
    dump("explore", out)


# --------------------------------------------------------------------------- stiffness

def stiff_study():
    """The case's 1000x cable against 100x: the reel at 10 m/s over 0-1 s, the 30 kN brake."""
    out = {}
    runs = {}
    for tag, sets in (("1000x", []), ("100x", [E_100X])):
        cs = load(LIGHT, sets + ["stowage.payout='rate'", "stowage.payout_rate=10.0",
                                 "time.end=1.0"])
        an, _ = analytic_twin(cs)
        fe, info, *_ = run_fe(cs, f"stiff_reel_{tag}")
        f, a = aligned(fe, an)
        rec = dict(norms(f, a, f["time"] > 1e-12, 50.0, cs.initial.omega), dt=info["dt"],
                   wall_s=info["wall_s"], work=work(f, a, len(f["time"]) - 1),
                   tension=tension_bins(f, a, f["time"] > 1e-12, 0.1),
                   max_tension_N=float(fe["max_tension"].max()),
                   EA_N=cs.cable.youngs_modulus * cs.cable.area)
        rec["max_strain"] = rec["max_tension_N"] / rec["EA_N"]
        rec["stretch_bound_over_H"] = rec["max_strain"]  # the whole line at the largest strain
        runs[tag] = (fe, rec)
        out[f"reel_10mps_{tag}"] = rec
        report(f"reel 10 m/s 0-1 s, {tag}", rec)
        print(f"   {rec}", flush=True)
    f1, f2 = runs["1000x"][0], runs["100x"][0]
    n = min(len(f1["time"]), len(f2["time"]))
    out["reel_100x_vs_1000x"] = {
        "L_max_m": float(np.abs(f1["arm_length"][:n] - f2["arm_length"][:n]).max()),
        "phi_max_rad": float(np.abs(f1["arm_angle"][1:n] - f2["arm_angle"][1:n]).max()),
        "hub_max": float(np.abs(f1["hub_omega"][:n] - f2["hub_omega"][:n]).max())}
    for tag, sets in (("1000x", []), ("100x", [E_100X])):
        rec, fe, an, cs = brake_run(LIGHT, 30e3, sets, f"stiff_brake_{tag}", end=0.04)
        out[f"brake_30kN_{tag}"] = {k: rec[k] for k in
                                    ("slip_tension_excess", "at_0.02s", "dt", "wall_s",
                                     "L_rms_over_H", "work")}
        print(tag, out[f"brake_30kN_{tag}"], flush=True)
    print(out["reel_100x_vs_1000x"])
    dump("stiffness", out)


def held_study():
    """The point-mass tethers under brakes just above their pull (41 and 42 kN), over 2 s:
    the line slips while the tension at D exceeds the force and sticks once the despun hub
    pulls less (the controlled regime; below about 40.5 kN the slip runs away, brake)."""
    recs, curves = {}, []
    for force, colour in zip(HELD_FORCES, ("C0", "C3")):
        rec, fe, an, cs = brake_run(LIGHT, force, [E_100X], f"brake_held_{force:g}", end=2.0)
        recs[f"brake_{force / 1e3:g}kN"] = rec
        report(f"brake {force / 1e3:g} kN (0-2 s)", rec)
        print(f"   work {rec['work']}, L end FE {rec['fe_L_end_m'][0]:.3f} m, analytic "
              f"{rec['an_L_end_m']:.3f} m, balance {rec['balance_over_KE0']:.2e}, "
              f"slip excess {rec['slip_tension_excess']}", flush=True)
        curves.append((f"{force / 1e3:g} kN", fe, an, colour))
    plot_device(curves, IMG / "payout_brake_held.png", "brake at D just above the tips' pull, "
                "point-mass tethers (100x Zylon): FE (solid) vs analytical stick/slip (dashed)")
    dump("brake_held", {"case": str(LIGHT.relative_to(ROOT)), "sets": [E_100X], "runs": recs})


STUDIES = {"reel": reel_study, "brake": brake_study, "held": held_study, "eq7": eq7_study,
           "eq7brake": eq7_brake_study, "web": web_study,
           "webbrake": web_brake_study, "explore": explore_study,
           "stiff": stiff_study}


def main(argv=None) -> int:
    global CACHE
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default=",".join(STUDIES))
    ap.add_argument("--cache", default=None, help="folder for the FE histories (npz)")
    args = ap.parse_args(argv)
    CACHE = Path(args.cache) if args.cache else None
    for name in args.only.split(","):
        t0 = time.perf_counter()
        STUDIES[name]()
        print(f"== {name}: {time.perf_counter() - t0:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
