"""Which elements and which steps make the energy-balance error of the paper's Zylon cases
(issue: fewer steps). An exact bookkeeping, element by element, of the central-difference
step.

    python -m studies.energy_attribution [--end 2.0] [--replot]

Why it is exact: with half-step velocities, the kinetic energy a step adds is
``sum_i F_i(x_n) . (x_{n+1} - x_{n-1}) / 2``, and each element's force is the gradient of its
strain energy U_e(d) at d_n = x_j - x_i (tension only: U_e = EA L0 max(|d|/L0 - 1, 0)^2 / 2).
So the balance KE + U - W + D changes over a step by the sum over elements of

    e_n = [U_e(d_{n+1}) - U_e(d_{n-1}) - grad U_e(d_n) . (d_{n+1} - d_{n-1})] / 2,

the midpoint-rule error of each element's strain energy over [t_{n-1}, t_{n+1}] (the hub's
kinematic nodes and the control torque enter through W; contact through D). This script
steps the solver one step at a time, sums e_n per element and per kind of step, and checks
the sum against the solver's own balance:

* **crossing**: the element is not taut at all of x_{n-1}, x_n, x_{n+1} (it crosses or
  touches the slack/taut kink, where U_e has no second derivative and the midpoint rule
  loses its second order);
* **taut**: taut at all three (the smooth O(h^3) error of stretch with rotation);
* **at the hub**: steps where an end of the element is kinematic (tied to the hub or in the
  held coil), counted in both of the above too.

Scenes: the free web with its coil held (paper_free_web), the coiled tethers
(paper_free_arms), four straight tethers dragged from rest by the spinning hub, and the web
under the spin ramp (paper_ramp_web), each over ``--end`` seconds at cfl 0.2, 0.3, 0.45.
Writes benchmarks/results/energy_attribution.json and energy_attribution.png.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from benchmarks.common import machine
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.record.arms import ArmTracker
from spinweb_fe.run.loop import _Chunks, start
from studies.energy_drift import row_balance, straight_tethers

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results" / "energy_attribution.json"
CFLS = (0.2, 0.3, 0.45)


def scenes():
    arms = (ROOT / "cases" / "paper_free_arms.toml").read_text()
    straight = straight_tethers(arms)
    return {
        "free web, held coil": ((ROOT / "cases" / "paper_free_web.toml").read_text(), ()),
        "web under the spin ramp": ((ROOT / "cases" / "paper_ramp_web.toml").read_text(), ()),
        "coiled tethers, held coil": (arms, ()),
        "straight tethers dragged by the hub": (straight, ("initial.spin='hub'",)),
    }


def strain_energy(d, rest, ea):
    """(U_e [J], tension [N], length [m]) of every element at end differences d (m, 3)."""
    length = np.sqrt((d * d).sum(1))
    eps = np.maximum(length / rest - 1.0, 0.0)
    return 0.5 * ea * eps * eps * rest, ea * eps, length


def attribute(text, sets, cfl, end, samples=200):
    """Step one scene one step at a time; the per-element midpoint errors by kind of step."""
    cs = case_mod.loads(text, [f"time.cfl={cfl}", f"time.end={end}", "output.frame_dt=0",
                               *sets])
    _, model, control, state, dt = prepare(cs)
    chunks = _Chunks(model, control, ArmTracker(model.mesh, model.hub.radius), 1, 1, dt)
    start(model, control, state, dt, chunks.work)
    el = model.elements
    i, j = el.nodes[:, 0], el.nodes[:, 1]
    rest, ea = el.rest_len, el.ea
    m = len(rest)
    nsteps = int(round(end / dt))
    every = max(1, nsteps // samples)
    per_elem = np.zeros(m)
    kinds = {"crossing": 0.0, "taut": 0.0, "at the hub": 0.0}
    crossings = 0
    series = []  # (t, balance change, crossing, taut) every ``every`` steps
    balance = []
    scale_w = 0.0  # largest |torque work| [J]
    d_prev, d_cur = None, state.node_pos[j] - state.node_pos[i]
    taut_prev = taut_cur = None
    for n in range(nsteps):
        kinematic = state.node_inv_mass == 0.0
        chunks.advance(state, dt, 1)
        b, w = row_balance(chunks.rec.table[0])  # KE + SE - W + D, the torque work W
        balance.append(b)
        scale_w = max(scale_w, abs(w))
        d_next = state.node_pos[j] - state.node_pos[i]
        u_next, _, l_next = strain_energy(d_next, rest, ea)
        taut_next = l_next > rest
        if d_prev is not None:
            u_prev, _, _ = strain_energy(d_prev, rest, ea)
            _, tension, l_cur = strain_energy(d_cur, rest, ea)
            grad = (tension / np.where(l_cur > 0, l_cur, 1.0))[:, None] * d_cur
            e = 0.5 * ((u_next - u_prev) - (grad * (d_next - d_prev)).sum(1))
            per_elem += e
            taut = taut_prev & taut_cur & taut_next
            kinds["taut"] += float(e[taut].sum())
            kinds["crossing"] += float(e[~taut].sum())
            kinds["at the hub"] += float(e[kinematic[i] | kinematic[j]].sum())
            crossings += int(np.count_nonzero(taut_cur != taut_next))
            if n % every == 0:
                series.append([float(f"{v:.5g}") for v in (
                    state.time[0], balance[-1] - balance[0], kinds["crossing"],
                    kinds["taut"])])
        d_prev, d_cur = d_cur, d_next
        taut_prev, taut_cur = taut_cur, taut_next
        if taut_prev is None:
            taut_prev = taut_cur
    # the energy scale of record.energy.balance_error: the first balance (KE + U at t = 0)
    # or the largest torque work (a run from rest)
    scale = max(abs(balance[0]), scale_w)
    order = np.argsort(-np.abs(per_elem))
    share10 = float(np.abs(per_elem[order[:max(1, m // 10)]]).sum()
                    / max(np.abs(per_elem).sum(), 1e-300))
    return {
        "cfl": cfl, "dt_s": dt, "steps": nsteps, "end_s": end, "elements": m,
        "energy_scale_J": scale,
        "balance_change_J": float(balance[-1] - balance[0]),
        "element_errors_J": float(per_elem.sum()),
        "crossing_J": kinds["crossing"], "taut_J": kinds["taut"],
        "at_hub_J": kinds["at the hub"],
        "share_of_top_10pct_elements": share10,
        "crossings_per_element_per_s": crossings / (m * nsteps * dt),
        "series": series,
    }


def plot(out, path):
    """Left: relative error by kind of step, each scene and cfl. Right: how the free web's
    error accrues over time (balance and its two parts)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(12.5, 4.6))
    rows = out["runs"]
    names = list(dict.fromkeys(r["scene"] for r in rows))
    labels, cross, taut, hub = [], [], [], []
    for r in rows:
        labels.append(f"{r['scene']}, cfl {r['cfl']}")
        cross.append(r["crossing_J"] / r["energy_scale_J"])
        taut.append(r["taut_J"] / r["energy_scale_J"])
        hub.append(r["at_hub_J"] / r["energy_scale_J"])
    y = np.arange(len(rows))
    ax[0].barh(y - 0.27, cross, 0.26, label="steps crossing the kink")
    ax[0].barh(y, taut, 0.26, label="taut steps")
    ax[0].barh(y + 0.27, hub, 0.26, label="steps with an end on the hub")
    ax[0].set_yticks(y, labels, fontsize=7)
    ax[0].invert_yaxis()
    ax[0].axvline(1e-3, color="k", lw=0.8, ls=":")
    ax[0].axvline(0.0, color="k", lw=0.6)
    ax[0].set_xscale("symlog", linthresh=1e-4)
    ax[0].set(xlabel=f"energy error / energy scale over {rows[0]['end_s']:g} s "
                     "(0.1 % dotted)", title="where the energy error is made")
    fig.legend(*ax[0].get_legend_handles_labels(), loc="lower left", ncol=3, fontsize=8)
    web = [r for r in rows if r["scene"] == names[0]]
    for r, style in zip(web, ("-", "--", ":")):
        s = np.array(r["series"])
        sc = r["energy_scale_J"]
        ax[1].plot(s[:, 0], s[:, 1] / sc, "k" + style, label=f"balance, cfl {r['cfl']}")
        ax[1].plot(s[:, 0], s[:, 2] / sc, "C0" + style, label=f"crossing steps, cfl {r['cfl']}")
        ax[1].plot(s[:, 0], s[:, 3] / sc, "C1" + style, label=f"taut steps, cfl {r['cfl']}")
    ax[1].set(xlabel="t [s]", ylabel="accumulated error / energy scale",
              title=f"{names[0]}: the error accrues steadily")
    ax[1].legend(fontsize=7, ncol=2)
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--end", type=float, default=2.0)
    ap.add_argument("--replot", action="store_true", help="redraw the plot from the JSON only")
    args = ap.parse_args(argv)
    if args.replot:
        plot(json.loads(OUT.read_text()), OUT.with_suffix(".png"))
        return 0
    runs = []
    for name, (text, sets) in scenes().items():
        for cfl in CFLS:
            r = {"scene": name, **attribute(text, sets, cfl, args.end)}
            runs.append(r)
            sc = r["energy_scale_J"]
            print(f"{name:36s} cfl {cfl:4.2f}: balance {r['balance_change_J'] / sc:+.2e}, "
                  f"elements {r['element_errors_J'] / sc:+.2e} (crossing "
                  f"{r['crossing_J'] / sc:+.2e}, taut {r['taut_J'] / sc:+.2e}, at the hub "
                  f"{r['at_hub_J'] / sc:+.2e}), top 10 % of elements "
                  f"{r['share_of_top_10pct_elements']:.2f}, crossings "
                  f"{r['crossings_per_element_per_s']:.0f} per element per s", flush=True)
    out = {"machine": machine(), "runs": runs}
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text(json.dumps(out, separators=(",", ":")))  # 12 series of 200 rows: compact
    plot(out, OUT.with_suffix(".png"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
