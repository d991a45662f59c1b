"""Where the energy error of the paper's Zylon cases comes from at larger steps (issue: fewer
steps), and what a slack/taut transition consistent with the step does to it.

    python -m studies.energy_drift [--end 2.0] [--replot]

1. One-sided spring impact (pure numpy): a unit mass at unit speed runs into a spring that
   pushes only when compressed (the tension-only law's kink), leapfrog with step h; the
   relative kinetic-energy change after the impact, over 400 entry phases, for h w = 0.1 ...
   1.2 (a cable element's own mode has h w = 2 cfl). Two kicks: the force sampled at x_n (the
   solver's), and the kink averaged over the step: the mean of max(x_n + u s, 0) over
   s in [-h/2, h/2] with u the velocity of the last half step, which is the exact impulse for
   a straight-line passage and equals the sampled force wherever the step does not cross the
   kink.
2. The solver (no kernel change): energy-balance error over ``--end`` seconds at cfl 0.2 and
   0.45 of the free web with its coil held (as in the case), the same without cable-hub
   contact, with the coil loose; the flat spinning web with no hub (throughput.py's scene,
   W = 2.5 m); four straight tethers dragged from rest by the spinning hub (no coil).
3. For the coiled tethers (paper_free_arms, 0.2 s): the energy change of the steps within
   four steps after a peel-front release against that of all other steps.

Writes benchmarks/results/energy_drift.json and energy_drift.png (``--replot`` redraws the
plot from the JSON).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
from pathlib import Path

import numpy as np

from benchmarks.common import machine, spinning_web
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.fe.layout import SLOTS
from spinweb_fe.fe.model import choose_dt
from spinweb_fe.record.arms import ArmTracker
from spinweb_fe.record.energy import balance_error
from spinweb_fe.run.loop import Schedule, _Chunks, simulate, start

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results" / "energy_drift.json"


def ramp_mean(a, b):
    """Mean of max(a + b s, 0) over s in [-1, 1] (b >= 0)."""
    if a >= b:
        return a
    if a <= -b:
        return 0.0
    return (a + b) ** 2 / (4.0 * b)


def impact(h, phase, averaged):
    """Relative kinetic-energy change of a unit mass (speed 1) through a unit one-sided spring."""
    x = -h * phase - 1e-12
    v = 1.0
    for _ in range(int(40 / h)):
        f = -(ramp_mean(x, 0.5 * h * abs(v)) if averaged else max(x, 0.0))
        v += h * f
        x += h * v
        if x < -2.0 and v < 0.0:
            break
    return v * v - 1.0


def impact_table():
    rows = []
    for hw in (0.1, 0.2, 0.4, 0.6, 0.8, 1.2):
        for averaged in (False, True):
            e = np.array([impact(hw, p, averaged) for p in np.linspace(0, 1, 401)[:-1]])
            rows.append({"h_omega": hw, "kink": "averaged" if averaged else "sampled",
                         "mean": float(e.mean()), "rms": float(np.sqrt(np.mean(e ** 2))),
                         "max_abs": float(np.abs(e).max())})
            print(f"impact h w = {hw:3.1f} {rows[-1]['kink']:8s} rms {rows[-1]['rms']:.2e} "
                  f"mean {rows[-1]['mean']:+.2e}", flush=True)
    return rows


def case_run(text, cfl, end, sets=(), no_contact=False):
    cs = case_mod.loads(text, [f"time.cfl={cfl}", f"time.end={end}", "output.frame_dt=0",
                               *sets])
    _, model, control, state, dt = prepare(cs)
    if no_contact:
        model = dataclasses.replace(model, nodes=model.nodes._replace(
            contact=np.zeros_like(model.nodes.contact)))
    r = simulate(model, control, state, dt, Schedule(end, cs.output.history_dt),
                 energy_limit=math.inf)
    return balance_error(r.history)


def straight_tethers(arms):
    """The case text ``arms`` (the coiled tethers) with straight tethers and no stowage table."""
    return re.sub(r"\[stowage\][^\[]*", "", arms).replace('pattern = "coiled"',
                                                          'pattern = "straight"')


def solver_table(end):
    web = (ROOT / "cases" / "paper_free_web.toml").read_text()
    arms = (ROOT / "cases" / "paper_free_arms.toml").read_text()
    straight = straight_tethers(arms)
    variants = {
        "free web, held coil": (web, (), False),
        "free web, held coil, no contact": (web, (), True),
        "free web, loose coil": (web, ("stowage.coil='loose'",), False),
        "coiled tethers, held coil": (arms, (), False),
        "straight tethers dragged by the hub": (straight, ("initial.spin='hub'",), False),
    }
    rows = []
    for cfl in (0.2, 0.45):
        for name, (text, sets, nc) in variants.items():
            err = case_run(text, cfl, end, sets, nc)
            rows.append({"scene": name, "cfl": cfl, "end_s": end, "energy_error": err})
            print(f"{name:38s} cfl {cfl}: {err:.2e}", flush=True)
        model, law, state = spinning_web(2.5)
        dt = choose_dt(model, cfl, history_dt=1e-3)
        r = simulate(model, law, state, dt, Schedule(end, 1e-3), energy_limit=math.inf)
        err = balance_error(r.history)
        rows.append({"scene": "flat spinning web, no hub", "cfl": cfl, "end_s": end,
                     "energy_error": err})
        print(f"{'flat spinning web, no hub':38s} cfl {cfl}: {err:.2e}", flush=True)
    return rows


def row_balance(row):
    """(KE + SE - W + D, W) [J] of a scalar row of the step loop's table (fe.layout's slots):
    W the torque work, D the damping and contact dissipation."""
    sr, e, term = SLOTS.row, SLOTS.row.energy, SLOTS.term
    w = row[e + term.torque_work]
    return (row[sr.kinetic_energy] + row[sr.strain_energy] - w
            + row[e + term.damping_dissipation] + row[e + term.contact_dissipation]), w


def release_windows(cfl, end=0.2):
    """Energy change of the coiled tethers in the 4 steps after each release vs elsewhere."""
    cs = case_mod.load(ROOT / "cases" / "paper_free_arms.toml",
                       [f"time.cfl={cfl}", f"time.end={end}", "output.frame_dt=0"])
    _, model, control, state, dt = prepare(cs)
    chunks = _Chunks(model, control, ArmTracker(model.mesh, model.hub.radius), 1, 1, dt)
    start(model, control, state, dt, chunks.work)
    energy, releases = [], []
    for _ in range(int(end / dt)):
        before = int(state.coil.front.sum())
        chunks.advance(state, dt, 1)
        energy.append(row_balance(chunks.rec.table[0])[0])  # KE + SE - W + D
        releases.append(int(state.coil.front.sum()) - before)
    de = np.diff(energy) / energy[0]
    rel = np.array(releases[1:]) > 0
    near = rel.copy()
    for lag in (1, 2, 3):
        near[lag:] |= rel[:-lag]
    out = {"cfl": cfl, "end_s": end, "releases": int(sum(releases)),
           "energy_change": float((energy[-1] - energy[0]) / energy[0]),
           "change_near_releases": float(de[near].sum()),
           "change_elsewhere": float(de[~near].sum())}
    print(f"coiled tethers cfl {cfl}: {out}", flush=True)
    return out


def plot(out, path):
    """Left: the impact's RMS energy error against h w, sampled and averaged kink. Right: the
    solver's energy-balance error of each scene at the two cfl values."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(12, 4.2))
    for kink, style in (("sampled", "o-"), ("averaged", "s--")):
        rows = [r for r in out["impact"] if r["kink"] == kink]
        ax[0].loglog([r["h_omega"] for r in rows], [r["rms"] for r in rows], style,
                     label=f"kink {kink}")
    ax[0].set(xlabel="h omega (a cable element's own mode: 2 cfl)",
              ylabel="RMS relative energy change per impact",
              title="one-sided spring impact, leapfrog (400 entry phases)")
    ax[0].legend()
    scenes = list(dict.fromkeys(r["scene"] for r in out["solver"]))
    for k, cfl in enumerate(sorted({r["cfl"] for r in out["solver"]})):
        vals = [next(r["energy_error"] for r in out["solver"]
                     if r["scene"] == sc and r["cfl"] == cfl) for sc in scenes]
        ax[1].barh([y + 0.4 * k for y in range(len(scenes))], vals, 0.38, label=f"cfl {cfl}")
    ax[1].set_xscale("log")
    ax[1].set_yticks([y + 0.2 for y in range(len(scenes))], scenes, fontsize=8)
    ax[1].axvline(1e-3, color="k", lw=0.8, ls=":")
    ax[1].set(xlabel=f"energy-balance error over {out['solver'][0]['end_s']:g} s",
              title="the solver (0.1 % dotted)")
    ax[1].legend()
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--end", type=float, default=2.0)
    ap.add_argument("--replot", action="store_true", help="redraw the plot from the JSON only")
    args = ap.parse_args(argv)
    if args.replot:
        plot(json.loads(OUT.read_text()), OUT.with_suffix(".png"))
        return 0
    out = {"machine": machine(), "impact": impact_table(), "solver": solver_table(args.end),
           "release_windows": [release_windows(c) for c in (0.2, 0.45)]}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, indent=1))
    plot(out, OUT.with_suffix(".png"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
