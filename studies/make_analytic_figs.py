"""Figures of docs/analytic.md: printed vs consistent model, and the paper's Fig. 8 study.

Run from the project root: ``.venv/bin/python -m studies.make_analytic_figs``. Writes
docs/img/analytic_free.png, analytic_ramp.png, analytic_drift.png and analytic_fig8.png and
prints the numbers quoted in docs/analytic.md.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from spinweb_fe import case as case_mod  # noqa: E402
from spinweb_fe.analytic import solve as analytic  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
IMG = ROOT / "docs" / "img"
W0 = 8 * math.pi


def four_panel(runs, title, path):
    """Plot L, phi, omega_centre and omega_tip of several (label, result, style) runs."""
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    keys = [("arm_length", "L [m]"), ("arm_angle", "phi [rad]"),
            ("hub_omega", "omega_centre [rad/s]"), ("tip_omega", "omega_tip [rad/s]")]
    for ax, (key, label) in zip(axes.flat, keys):
        for name, res, style in runs:
            h = res.history
            y = h[key] if h[key].ndim == 1 else h[key][:, 0]
            ax.plot(h["time"], y, style, lw=1.2, label=name)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def paper_case(*sets):
    return case_mod.load(ROOT / "cases" / "paper_free_web.toml", list(sets))


def drift_report(label, res, t_marks=(0.1, 0.25, 0.5, 1.0, 5.0)):
    dk, de = analytic.drifts(res)
    t = res.history["time"]
    parts = []
    for tm in t_marks:
        i = t <= tm + 1e-12
        if tm <= t[-1]:
            parts.append(f"t<={tm:g}s: |dK|={np.abs(dk[i]).max():.3g} |dE|={np.abs(de[i]).max():.3g}")
    print(f"{label}: " + "; ".join(parts))
    return dk, de


def main():
    IMG.mkdir(parents=True, exist_ok=True)
    # free deployment of the paper's web (Figs. 5-6)
    free = paper_case()
    runs = {m: analytic.solve_case(free, model=m) for m in ("printed", "consistent")}
    four_panel([("printed (Eqs. 4, 8a-b as printed)", runs["printed"], "r-"),
                ("consistent (Lagrangian)", runs["consistent"], "k-")],
               "Free deployment, S = 100 m, r0 = 6.3 m, 8 pi rad/s", IMG / "analytic_free.png")
    fig, ax = plt.subplots(1, 2, figsize=(10, 3.5), sharex=True)
    for m, style in (("printed", "r-"), ("consistent", "k-")):
        dk, de = drift_report(f"free {m}", runs[m])
        ax[0].plot(runs[m].history["time"], dk, style, label=m)
        ax[1].plot(runs[m].history["time"], de, style, label=m)
    ax[0].set_ylabel("(K - K0)/K0")
    ax[1].set_ylabel("(E - E0)/E0")
    for a in ax:
        a.set_xlabel("t [s]")
        a.grid(alpha=0.3)
        a.legend()
    fig.suptitle("Free deployment: angular momentum and energy balance errors")
    fig.tight_layout()
    fig.savefig(IMG / "analytic_drift.png", dpi=110)
    plt.close(fig)
    print(f"wrote {IMG / 'analytic_drift.png'}")
    # spin ramp 0 -> 8 pi in 2 s (Salama et al., Figs. 9-10)
    ramp = paper_case('control.law="spin_ramp"', f"control.omega_max={W0!r}",
                      "control.ramp_time=2.0", "time.end=6.0", "initial.omega=0.0")
    rr = {m: analytic.solve_case(ramp, model=m) for m in ("printed", "consistent")}
    for m in rr:
        drift_report(f"ramp {m}", rr[m], (0.5, 1.0, 2.0, 6.0))
        h = rr[m].history
        print(f"  ramp {m}: first release {rr[m].switches[0][0]:.4f} s, L(2 s) = "
              f"{h['arm_length'][2000, 0]:.2f} m, min L after 2 s = "
              f"{h['arm_length'][2000:, 0].min():.2f} m, max |M| = "
              f"{np.abs(h['hub_torque']).max():.3g} N m, min N = {h['max_tension'].min():.3g} N")
    four_panel([("printed", rr["printed"], "r-"), ("consistent", rr["consistent"], "k-")],
               "Spin ramp 0 -> 8 pi rad/s in 2 s (prescribed hub rate)", IMG / "analytic_ramp.png")
    # the paper's Fig. 8: r0 = 1 m, M0 = 60 pi N m, omega0 = pi/2, 2 pi, 8 pi
    fig8 = []
    for stem, label, style in (("pi2", "omega0 = pi/2", "b-"), ("2pi", "omega0 = 2 pi", "g-"),
                               ("8pi", "omega0 = 8 pi", "r-")):
        c = case_mod.load(ROOT / "cases" / f"analytic_fig8_{stem}.toml")
        res = analytic.solve_case(c, model="consistent")
        h = res.history
        L = h["arm_length"][:, 0]
        full = h["time"][np.argmax(L >= c.web.side / 2 - 1e-9)] if L.max() >= 49.999 else None
        later = h["time"] > (full or 0) + 1
        print(f"fig8 {label}: regime switches {len(res.switches) - 1}, first fully out at "
              f"{full} s, min L after that {L[later].min():.2f} m, omega range "
              f"[{h['hub_omega'].min():.3g}, {h['hub_omega'].max():.3g}] rad/s, max M "
              f"{h['hub_torque'].max():.4g} N m, final omega {h['hub_omega'][-1]:.3g} rad/s")
        fig8.append((label, res, style))
    four_panel(fig8, "Paper Fig. 8 study (consistent model): r0 = 1 m, M = 60 pi (1 - omega/omega0)",
               IMG / "analytic_fig8.png")


if __name__ == "__main__":
    main()
