"""Cost of the crossing audit and of the cable-cable contact over whole deployments (issues
#26, #42).

    python -m benchmarks.contact_cost [--quick] [--scenes NAME,...] [--repeat 1]
                                      [--threads 1,2]

Scenes (docs/contact.md, docs/performance.md), each folded with a 5 mm layer gap
(``fold.layer_gap``), one thread:

- ``feedback_0.6``: cases/paper_feedback_web.toml over its first 0.6 s (the coiled start and
  the unfolding of the arms: the stacked layers close together);
- ``feedback_2``: the same over 2 s (the arms out, breathing);
- ``free_tilt_2``: cases/paper_free_web.toml on a free hub tilted by 5 m/s at the tips
  (docs/contact.md's ``free_tilt``) over 2 s: plain and contact only;
- ``--quick``: ``feedback_0.1``, the first 0.1 s (a minute).

Variants: the plain step loop, the audit (``audit.crossings``) and the contact
(``contact.cables``, which runs the audit too), as a user turns them on (the case's keys,
``run.features.features_of``); with ``--threads 1,2`` each on one and on two threads
(``audit@2``: its ratio is against the plain loop on as many threads). The variants of a scene run round-robin (A B C, ``repeat``
times, fastest kept) after one short run of each that compiles or loads its loop. The time
is the step loop's (``RunResult.loop_s``: the compiled loop and the list rebuilds between
its calls, not the compile). Beside it: the seconds in the list's rebuilds (the broad phase,
timed around ``CrossingAudit.build``), the list's length at the end, the rebuild count, the
skin, the crossings counted and the fail-safe's impulses, and the profile of the passes
(fe.contact.clock, record.profile: the cycle counter's ticks per pass in the compiled loop,
in seconds, and the pairs each pass read, looked at, tested): :func:`breakdown` turns it into
ns per step and per listed pair-step of each pass, the counts per step, and what the profile
does not cover (the loop less the plain step, the rebuilds and the passes: copies of x_n,
the penalty's addition, the hub's placing after a reaction, the physics' own change).
Writes benchmarks/results/contact_cost.json and .png (the time per step of each variant
stacked by pass), with the machine (CPU model, ISA, load).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from benchmarks.common import machine
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.record.crossings import CrossingAudit
from spinweb_fe.run.features import features_of
from spinweb_fe.run.loop import Schedule, simulate

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks" / "results"
GAP = ["fold.layer_gap=0.005", "output.frame_dt=0"]
TILT = ['hub.motion="free"', 'perturbation.shape="tilt"', "perturbation.vz_amplitude=5"]
#: name -> (case, keys, end [s], variants)
SCENES = {
    "feedback_0.1": ("paper_feedback_web", [], 0.1, ("plain", "audit", "contact")),
    "feedback_0.6": ("paper_feedback_web", [], 0.6, ("plain", "audit", "contact")),
    "feedback_2": ("paper_feedback_web", [], 2.0, ("plain", "audit", "contact")),
    "free_tilt_2": ("paper_free_web", TILT, 2.0, ("plain", "contact")),
}
FULL = ("feedback_0.6", "feedback_2", "free_tilt_2")
MODES = {"plain": [], "audit": ["audit.crossings=true"],
         "contact": ["audit.crossings=true", "contact.cables=true"]}


class _BuildClock:
    """Seconds spent in :meth:`CrossingAudit.build` (the broad phase) while active."""

    def __init__(self):
        self.seconds, self.calls = 0.0, 0
        self.lists = []  # (step, pairs listed) after each build
        self._orig = CrossingAudit.build

    def __enter__(self):
        orig, clock = self._orig, self

        def build(audit, state, *a, **k):
            t0 = time.perf_counter()
            try:
                return orig(audit, state, *a, **k)
            finally:
                clock.seconds += time.perf_counter() - t0
                clock.calls += 1
                clock.lists.append((int(state.step[0]), len(audit.pairs)))

        CrossingAudit.build = build
        return self

    def __exit__(self, *exc):
        CrossingAudit.build = self._orig


def run(case_name: str, keys: list, end: float, variant: str, threads: int = 1) -> dict:
    """Loop seconds, steps and what the audit and the contact saw for one variant."""
    case = case_mod.load(ROOT / "cases" / f"{case_name}.toml",
                         [*GAP, *keys, *MODES[variant], f"time.end={end}"])
    scene = prepare(case)
    features = features_of(scene.model, scene.state, case)
    with _BuildClock() as clock:
        res = simulate(scene.model, scene.control, scene.state, scene.dt, Schedule(end, 1e-3),
                       threads=threads, features=features)
    out = {"loop_s": res.loop_s, "steps": res.steps, "elements": scene.model.n_elems,
           "dt": scene.dt, "end": end, "build_s": clock.seconds}
    if clock.lists:  # pair-steps: the listed pairs summed over the steps they were listed
        marks = [s for s, _ in clock.lists[1:]] + [res.steps]
        out["pair_steps"] = float(sum(n * (b - a) for (a, n), b in zip(clock.lists, marks)))
    named = {f.name: f for f in features}
    if "crossings" in named:
        au = named["crossings"]
        out.update(skin=au.skin, base_skin=au.base_skin, crossings=au.count,
                   rebuilds=au.rebuilds, pairs_last=int(len(au.pairs)),
                   audit_profile=au.profile.seconds())
    if "contact" in named:
        co = named["contact"]
        out.update(impulses=co.impulses, impulses_after_reactions=co.impulses_after_reactions,
                   contact_profile=co.profile.seconds())
    return out


#: (label, profile, seconds key or a function of the profile) of each pass, in plot order
PASSES = (
    ("audit: motion", "audit", "motion_s"),
    ("audit: certificate read", "audit", lambda a: a["certificates_s"] - _looked(a)
     - a["exact_s"]),
    ("audit: looked at (sampled)", "audit", lambda a: _looked(a)),
    ("audit: exact branch", "audit", "exact_s"),
    ("audit: wide steps", "audit", "wide_s"),
    ("contact: near selection", "contact", "near_selection_s"),
    ("contact: closest points", "contact", "closest_points_s"),
    ("contact: push", "contact", "push_s"),
    ("contact: fail-safe motion", "contact", "motion_s"),
    ("contact: fail-safe round 0", "contact", "failsafe_round0_s"),
    ("contact: later rounds", "contact", "failsafe_rounds_s"),
    ("contact: impact zones", "contact", "impact_zones_s"),
    ("contact: friction", "contact", "friction_s"),
    ("contact: reaction", "contact", "reaction_s"),
    ("contact: fail-safe rest", "contact", lambda c: c["failsafe_first_call_s"] - sum(
        c[k] for k in ("motion_s", "failsafe_round0_s", "failsafe_rounds_s",
                       "impact_zones_s", "friction_s", "reaction_s"))),
    ("contact: after reactions", "contact", "after_reactions_s"),
)
#: counts per step worth quoting: (label, profile, key)
COUNTS = (("audit pairs read", "audit", "pairs_read"),
          ("audit pairs looked at", "audit", "pairs_looked_at"),
          ("audit exact branch", "audit", "pairs_exact_branch"),
          ("audit pairs tested (apart)", "audit", "pairs_apart_tested"),
          ("audit pairs tested (crossing)", "audit", "pairs_crossing_tested"),
          ("audit wide steps", "audit", "wide_steps"),
          ("contact near pairs", "contact", "near_pairs"),
          ("contact pairs in contact", "contact", "pairs_in_contact"),
          ("fail-safe round 0 read", "contact", "round0_pairs_read"),
          ("fail-safe round 0 looked at", "contact", "round0_pairs_looked_at"),
          ("fail-safe round 0 tested", "contact", "round0_pairs_tested"),
          ("fail-safe later rounds", "contact", "later_rounds"),
          ("fail-safe later-round pairs reached", "contact", "later_round_pairs_looked_at"),
          ("fail-safe later-round pairs tested", "contact", "later_round_pairs_tested"),
          ("calls after reactions", "contact", "calls_after_reactions"),
          ("impulses", "contact", "impulses"),
          ("impulses after reactions", "contact", "impulses_after_reactions"))


def _looked(a: dict) -> float:
    """The looked-at pairs' seconds, scaled up from the timed sample [s]."""
    n = a["pairs_looked_at_sampled"]
    return a["looked_at_sample_s"] * a["pairs_looked_at"] / n if n else 0.0


def breakdown(r: dict, per_plain: float) -> dict:
    """Each pass's ns per step and per listed pair-step, the counts per step, and the
    loop's overhead over the plain step that the passes do not cover (``other``)."""
    steps, pair_steps = r["steps"], r.get("pair_steps") or 0.0
    rows, covered = {}, 0.0
    for label, which, key in PASSES:
        prof = r.get(f"{which}_profile")
        if prof is None:
            continue
        sec = key(prof) if callable(key) else prof[key]
        covered += sec
        rows[label] = {"s": sec, "ns_per_step": 1e9 * sec / steps,
                       "ns_per_pair_step": 1e9 * sec / pair_steps if pair_steps else None}
    overhead = r["loop_s"] - r["build_s"] - per_plain * steps
    other = overhead - covered
    rows["other (not profiled)"] = {"s": other, "ns_per_step": 1e9 * other / steps,
                                    "ns_per_pair_step":
                                        1e9 * other / pair_steps if pair_steps else None}
    counts = {label: r[f"{which}_profile"][key] / steps for label, which, key in COUNTS
              if f"{which}_profile" in r}
    return {"passes": rows, "counts_per_step": counts, "overhead_s": overhead,
            "profiled_s": covered,
            "profiled_share": covered / overhead if overhead > 0 else None}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--quick", action="store_true", help="the first 0.1 s of the feedback web")
    ap.add_argument("--scenes", help=f"comma-separated, of {', '.join(SCENES)}")
    ap.add_argument("--out", default=str(OUT / "contact_cost.json"))
    ap.add_argument("--threads", default="1",
                    help="comma-separated thread counts, each a variant of its own (1,2)")
    args = ap.parse_args(argv)
    counts = [int(t) for t in args.threads.split(",")]
    names = (["feedback_0.1"] if args.quick else
             args.scenes.split(",") if args.scenes else list(FULL))
    info = {"machine_start": machine(), "threads": counts, "repeat": args.repeat}
    results = []
    for name in names:
        case_name, keys, end, variants = SCENES[name]
        # (a variant on more threads than one is named by them: "audit@2")
        runs = [(v, t) for t in counts for v in variants]
        named = {(v, t): v if t == 1 else f"{v}@{t}" for v, t in runs}
        for v, t in runs:  # compile (or load from the cache) each variant's loop
            run(case_name, keys, min(end, 2e-3), v, t)
        best = {}
        for _ in range(args.repeat):
            for v, t in runs:
                r = run(case_name, keys, end, v, t)
                r["threads"] = t
                if named[v, t] not in best or r["loop_s"] < best[named[v, t]]["loop_s"]:
                    best[named[v, t]] = r
        for v, r in best.items():
            # (each variant against the plain loop on as many threads)
            plain = best[named["plain", r["threads"]]]
            per_plain = plain["loop_s"] / plain["steps"]
            r.update(scene=name, case=case_name, keys=keys, variant=v,
                     us_per_step=1e6 * r["loop_s"] / r["steps"],
                     ratio=r["loop_s"] / r["steps"] / per_plain)
            if r.get("pair_steps"):  # what the rest of the step costs per listed pair
                rest = r["loop_s"] - r["build_s"] - per_plain * r["steps"]
                r["ns_per_pair_step"] = 1e9 * rest / r["pair_steps"]
                r["pairs_mean"] = r["pair_steps"] / r["steps"]
            if not v.startswith("plain"):
                r["profile"] = breakdown(r, per_plain)
            results.append(r)
            print(f"{name:14s} {v:8s} {r['us_per_step']:9.1f} us/step  x{r['ratio']:7.1f}  "
                  f"rebuilds {r.get('rebuilds', '-')} ({r['build_s']:.1f} s)  "
                  f"pairs {r.get('pairs_mean', 0):.0f} mean  {r.get('ns_per_pair_step', 0):.1f} ns/pair  "
                  f"crossings {r.get('crossings', '-')}",
                  flush=True)
            for label, row in r.get("profile", {}).get("passes", {}).items():
                if abs(row["ns_per_step"]) >= 1000.0:
                    print(f"    {label:30s} {row['ns_per_step'] / 1e3:9.1f} us/step  "
                          f"{row['ns_per_pair_step'] or 0:6.2f} ns/pair", flush=True)
    info.update(machine_end=machine(), results=results)
    path = Path(args.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(info, indent=1))
    plot(results, path.with_suffix(".png"))


def plot(results, path):
    """Per scene, each variant's time per step [us] stacked: the plain step, the rebuilds,
    each pass of the profile, and what the profile does not cover."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(dict.fromkeys(r["scene"] for r in results))
    labels = ["plain step", "list rebuilds", *(p[0] for p in PASSES), "other (not profiled)"]
    cmap = plt.get_cmap("tab20")
    colours = {lab: cmap(i % 20) for i, lab in enumerate(labels)}
    fig, axes = plt.subplots(1, len(scenes), figsize=(4.2 * len(scenes), 4.6), squeeze=False)
    for ax, scene in zip(axes[0], scenes):
        rows = [r for r in results if r["scene"] == scene]
        plain = {r.get("threads", 1): 1e6 * r["loop_s"] / r["steps"] for r in rows
                 if r["variant"].startswith("plain")}
        for i, r in enumerate(rows):
            parts = {"plain step": plain[r.get("threads", 1)],
                     "list rebuilds": 1e6 * r["build_s"] / r["steps"]}
            for lab, row in r.get("profile", {}).get("passes", {}).items():
                parts[lab] = row["ns_per_step"] / 1e3
            bottom = 0.0
            for lab in labels:
                h = max(parts.get(lab, 0.0), 0.0)
                if h > 0.0:
                    ax.bar(i, h, bottom=bottom, color=colours[lab], width=0.6)
                    bottom += h
            ax.annotate(f"x{r['ratio']:.1f}", (i, bottom), ha="center", va="bottom",
                        fontsize=8)
        ax.set_xticks(range(len(rows)), [r["variant"] for r in rows])
        ax.set_ylabel("time per step [us]")
        ax.set_title(f"{scene}: {rows[0]['elements']} elements, {rows[0]['steps']} steps",
                     fontsize=9)
    handles = [plt.Rectangle((0, 0), 1, 1, color=colours[lab]) for lab in labels]
    fig.legend(handles, labels, fontsize=6, loc="lower center", ncol=5)
    fig.tight_layout(rect=(0, 0.2, 1, 1))
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
