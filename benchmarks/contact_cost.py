"""Cost of the crossing audit and of the cable-cable contact against the plain step (issue #26).

    python -m benchmarks.contact_cost [--repeat 2] [--quick]

Scenes: the paper's feedback web (cases/paper_feedback_web.toml) folded with a 5 mm layer
gap (``fold.layer_gap``), as it is (3 220 elements, dt 4.6e-5 s, its first 0.1 s: 2 200
steps) and meshed at 0.5 m (79 100 elements, dt 9.2e-6 s, its first 5 ms: 545 steps), on
one thread. Variants: the plain step loop, the audit (``audit.crossings``) and the contact
(``contact.cables``, which runs the audit too), at the default skin and at other skins.
Variants run round-robin (A B C A B C), ``repeat`` times, fastest kept; the time is the
step loop's (``RunResult.loop_s``: the compiled loop and the list rebuilds between its
calls, not the compile). Writes benchmarks/results/contact_cost.json and .png.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from benchmarks.common import machine
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.record.contact import CableContact, cable_radius
from spinweb_fe.record.crossings import CrossingAudit
from spinweb_fe.run.loop import Schedule, simulate

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results"
CASE = ROOT / "cases" / "paper_feedback_web.toml"

#: (name, overrides, end [s], skins to try besides the default)
SCENES = (("paper web, 3 220 elements", [], 0.1, (0.25, 1.0)),
          ("0.5 m mesh, 79 100 elements", ["web.mesh_width=0.5"], 0.005, (0.02, 0.05)))


def run(overrides, end, variant, skin):
    """Loop seconds, steps and what the audit and contact saw for one variant."""
    case = case_mod.load(CASE, ["fold.layer_gap=0.005", f"time.end={end}",
                                "output.frame_dt=0", *overrides])
    scene = prepare(case)
    audit = contact = None
    if variant != "plain":
        audit = CrossingAudit(scene.model, skin)
    if variant == "contact":
        contact = CableContact(scene.model, cable_radius(case, scene.model), audit=audit)
    features = [f for f in (audit, contact) if f is not None]
    res = simulate(scene.model, scene.control, scene.state, scene.dt, Schedule(end, 1e-3),
                   threads=1, features=features)
    out = {"loop_s": res.loop_s, "steps": res.steps, "elements": scene.model.n_elems,
           "dt": scene.dt}
    if audit is not None:
        out.update(skin=audit.skin, crossings=audit.count, rebuilds=audit.rebuilds,
                   pairs_last=int(len(audit.pairs)))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="the small web, default skin only")
    args = ap.parse_args(argv)
    scenes = SCENES[:1] if args.quick else SCENES
    results = []
    for name, overrides, end, skins in scenes:
        variants = [("plain", None), ("audit", None), ("contact", None)]
        if not args.quick:
            variants += [(v, s) for s in skins for v in ("audit", "contact")]
        best = {}
        for v, s in variants:  # compile / load every variant's loop outside the timing
            run(overrides, min(end, 2e-3), v, s)
        for _ in range(args.repeat):
            for v, s in variants:
                r = run(overrides, end, v, s)
                key = (v, s)
                if key not in best or r["loop_s"] < best[key]["loop_s"]:
                    best[key] = r
        plain = best[("plain", None)]
        per_plain = plain["loop_s"] / plain["steps"]
        for (v, s), r in best.items():
            r.update(scene=name, variant=v, skin_given=s,
                     us_per_step=1e6 * r["loop_s"] / r["steps"],
                     ratio=r["loop_s"] / r["steps"] / per_plain)
            results.append(r)
            print(f"{name:30s} {v:8s} skin {r.get('skin', '-')!s:6s} "
                  f"{r['us_per_step']:9.1f} us/step  x{r['ratio']:.2f}  "
                  f"crossings {r.get('crossings', '-')}  rebuilds {r.get('rebuilds', '-')}")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "contact_cost.json").write_text(json.dumps({"machine": machine(), "threads": 1,
                                                       "results": results}, indent=1))
    plot(results, OUT / "contact_cost.png")


def plot(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in results))
    fig, axes = plt.subplots(1, len(scenes), figsize=(5 * len(scenes), 3.6))
    axes = [axes] if len(scenes) == 1 else axes
    for ax, scene in zip(axes, scenes):
        rows = [r for r in results if r["scene"] == scene]
        labels = [r["variant"] + ("" if r["variant"] == "plain" else f"\nskin {r['skin']:g} m")
                  for r in rows]
        ax.bar(range(len(rows)), [r["ratio"] for r in rows], color="tab:blue")
        ax.set_xticks(range(len(rows)), labels, fontsize=7)
        ax.set_ylabel("time per step / plain step")
        ax.set_title(scene, fontsize=9)
        ax.axhline(1.0, color="k", lw=0.5)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
