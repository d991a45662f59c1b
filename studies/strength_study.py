"""Would the cables hold? The paper's deployments with Zylon's strength (docs/strength.md).

    python -m studies.strength_study [margins] [scan] [rupture] [figs] [--skip-stiff]
                                     [--cases NAME ...] [--out out/strength]

Zylon AS (Toyobo, "PBO fiber ZYLON" technical information, 2005): tensile strength 5.8 GPa,
tensile modulus 180 GPa, so the linear-elastic cable breaks at eps_f = 5.8 / 180 = 3.22 %
(the data sheet's elongation at break, 3.5 %, includes the fibre's slight stiffening). A case
with another modulus (the 1000x stiffer ``*_stiff`` cases) keeps the strength: eps_f =
5.8 GPa / E.

- ``margins``: every ``cases/paper_*.toml`` to its end with ``cable.failure_strain`` set and
  rupture off: the worst utilisation, when and where (arm, arm coordinate, web edge), the
  first time it exceeds 1 and how long it stays above.
- ``steady``: the deployed web and the straight tethers spinning steadily at 8 pi rad/s
  (``linear.steady``): the utilisation without any deployment dynamics, and the rate at
  which it reaches 1.
- ``damping``: the free web at 8 pi rad/s with axial damping 0.05 and 0.2 of critical.
- ``scan``: the largest initial spin rate (free web, free arms), ramp rate (spin ramp) or
  feedback reference rate (torque feedback, the paper's gain M0 = omega0 1e5 N m s) at which
  the worst utilisation stays below 1: tensions scale about as omega^2, so a first guess is
  omega / sqrt(u); then secant steps on log u against log omega until u is within 1 % of 1.
  A free deployment takes a time proportional to 1 / omega: its end time is stretched by the
  same factor.
- ``rupture``: the free web, the ramp web and the free arms at 8 pi rad/s with rupture on:
  when and where the first element breaks, how many break, the pieces at the end.
- ``figs``: ``docs/img/strength_*.png`` from the runs.

Writes ``benchmarks/results/strength.json`` (each stage updates its own entry) and the runs
into OUT/<name>/.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe import case as case_mod
from spinweb_fe.post.strength import pieces, where
from spinweb_fe.record.energy import energy_balance
from spinweb_fe.run.driver import run_case

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results" / "strength.json"
IMG = ROOT / "docs" / "img"
SIGMA_F = 5.8e9  # Pa, Zylon AS tensile strength
E_ZYLON = 180e9  # Pa
EPS_ZYLON = SIGMA_F / E_ZYLON
#: case -> (the key scanned, how the end time follows it)
SCANS = {"paper_free_web": "initial.omega", "paper_free_arms": "initial.omega",
         "paper_ramp_web": "control.omega_max", "paper_feedback_web": "control.omega0"}
RUPTURE = ("paper_free_web", "paper_ramp_web", "paper_free_arms")


def paper_cases(skip_stiff, only=None):
    names = sorted(p.stem for p in (ROOT / "cases").glob("paper_*.toml"))
    return [n for n in names if not (skip_stiff and n.endswith("_stiff"))
            and (not only or n in only)]


def failure_strain(name):
    case = case_mod.load(ROOT / "cases" / f"{name}.toml")
    return SIGMA_F / case.cable.youngs_modulus


def run(name, out, sets):
    """Run a paper case with overrides; (result file, wall seconds)."""
    case = case_mod.load(ROOT / "cases" / f"{name}.toml", sets)
    t0 = time.perf_counter()
    run_case(case, out, progress=False)
    return out / "results.h5", time.perf_counter() - t0


def margins_of(path) -> dict:
    """Worst utilisation, when and where, time above 1, energy error of a result file."""
    with h5py.File(path, "r") as h5:
        h = {k: h5["history"][k][()] for k in h5["history"]}
        k = int(np.argmax(h["utilisation"]))
        elem = int(h["max_strain_element"][k])
        m = h5["mesh"]
        nodes = m["elements"][elem]
        coords = m["node_arm_coord"][()][nodes]
        coord = float(np.nanmean(coords)) if np.isfinite(coords).any() else None
        edge = bool("elem_sets/boundary" in m and elem in set(m["elem_sets/boundary"][()]))
        info = {"where": where(h5, elem), "arm_length_m": float(m.attrs["arm_length"]),
                "root_coord_m": float(m.attrs["arm_root_coord"])}
        n_frames = h5["frames/time"].shape[0] if "frames" in h5 else 0
        broken = h5["frames/broken"][-1] > 0 if "frames/broken" in h5 else None
        if broken is not None and n_frames:
            info["pieces_at_end"] = pieces(m["elements"][()], broken,
                                           m["node_sets/hub_tied"][()], m["points"].shape[0])
    u = h["utilisation"]
    t = h["time"]
    over = np.flatnonzero(u > 1.0)
    e = energy_balance(h)
    scale = max(np.abs(h["kinetic_energy"]).max(), np.abs(h["torque_work"]).max())
    out = {"worst_utilisation": float(u[k]), "worst_strain": float(h["max_strain"][k]),
           "worst_time_s": float(t[k]), "worst_element": elem,
           "worst_arm": int(h["max_strain_arm"][k]), "worst_arm_coord_m": coord,
           "worst_on_edge": edge, "first_over_1_s": float(t[over[0]]) if len(over) else None,
           "time_over_1_s": float(len(over) * (t[1] - t[0])) if len(over) else 0.0,
           "max_tension_N": float(h["max_tension"].max()),
           "energy_error": float(np.abs(e - e[0]).max() / scale), **info}
    if "broken_elements" in h:
        nb = h["broken_elements"]
        first = int(np.argmax(nb > 0)) if nb[-1] > 0 else None
        out.update({"broken_elements": int(nb[-1]),
                    "first_break_s": float(t[first]) if first is not None else None,
                    "rupture_dissipation_J": float(h["rupture_dissipation"][-1])})
        if first is not None:
            with h5py.File(path, "r") as h5:
                out["first_break_where"] = where(h5, int(h["max_strain_element"][first]))
    return out


def stage_margins(args, results):
    res = results.setdefault("margins", {})
    for name in paper_cases(args.skip_stiff, args.cases):
        eps = failure_strain(name)
        path, wall = run(name, args.out / "margins" / name, [f"cable.failure_strain={eps}"])
        res[name] = {"failure_strain": eps, "wall_s": wall, **margins_of(path)}
        print(f"{name}: eps_f {eps:.4g}, worst utilisation {res[name]['worst_utilisation']:.3g} "
              f"at {res[name]['worst_time_s']:.3f} s, {res[name]['where']} ({wall:.1f} s)",
              flush=True)


def scan_value(name, key):
    case = case_mod.load(ROOT / "cases" / f"{name}.toml")
    table, field = key.split(".")
    return float(getattr(getattr(case, table), field)), float(case.time.end)


def scan_sets(name, key, value, w0, t_end):
    """Overrides of a scan point: the scanned key, what must follow it, a stretched end."""
    sets = [f"cable.failure_strain={EPS_ZYLON}", "output.frame_dt=0", f"{key}={value!r}"]
    if key == "initial.omega":
        sets.append(f"time.end={t_end * max(1.0, w0 / value)!r}")
    if key == "control.omega0":  # the paper's law: start at omega0, gain M0 = omega0 1e5
        sets += [f"initial.omega={value!r}", f"control.M0={value * 1e5!r}",
                 f"time.end={t_end * max(1.0, w0 / value)!r}"]
    return sets


def completed(path) -> bool:
    try:
        with h5py.File(path, "r") as h5:
            return h5.attrs.get("status") == "completed"
    except OSError:
        return False


def stage_scan(args, results):
    res = results.setdefault("scan", {})
    for name, key in SCANS.items():
        w0, t_end = scan_value(name, key)
        points = {}

        def evaluate(w):
            w = float(f"{w:.4f}")
            out = args.out / "scan" / f"{name}_{w:.4f}"
            if not completed(out / "results.h5"):  # a finished point is not run again
                run(name, out, scan_sets(name, key, w, w0, t_end))
            m = margins_of(out / "results.h5")
            points[w] = {"value": w, "worst_utilisation": m["worst_utilisation"],
                         "worst_time_s": m["worst_time_s"], "where": m["where"]}
            print(f"  {name} {key} = {w:.4f}: u = {m['worst_utilisation']:.4f} "
                  f"at {m['worst_time_s']:.3f} s, {m['where']}", flush=True)
            return m["worst_utilisation"]

        u0 = results.get("margins", {}).get(name, {}).get("worst_utilisation") or evaluate(w0)
        points.setdefault(w0, {"value": w0, "worst_utilisation": u0, "from": "margins"})
        # a bracket: secant steps on log u against log omega from the omega^2 guess
        w_prev, u_prev, w = w0, u0, w0 / math.sqrt(u0)
        for _ in range(4):
            u = evaluate(w)
            if any(p["worst_utilisation"] <= 1.0 for p in points.values()) and \
                    any(p["worst_utilisation"] > 1.0 for p in points.values()):
                break
            slope = math.log(u / u_prev) / math.log(w / w_prev)
            w_prev, u_prev, w = w, u, w * (1.0 / u) ** (1.0 / min(max(slope, 0.5), 4.0))
        # then halve it until it is 2 % wide: below lo within strength, above hi not
        while True:
            safe = [v for v, p in points.items() if p["worst_utilisation"] <= 1.0]
            lo = max(safe) if safe else None
            hi = min((v for v, p in points.items() if p["worst_utilisation"] > 1.0
                      and (lo is None or v > lo)), default=None)
            if lo is None or hi is None or (hi - lo) < 0.02 * lo:
                break
            evaluate(0.5 * (lo + hi))
        for folder in (args.out / "scan").glob(f"{name}_*"):  # points of earlier scans too
            try:
                w = float(folder.name.rsplit("_", 1)[1])
            except ValueError:
                continue
            if w not in points and completed(folder / "results.h5"):
                evaluate(w)
        # the limit: every sampled rate below ``lo`` is within strength, ``hi`` is not
        hi = min((v for v, p in points.items() if p["worst_utilisation"] > 1.0), default=None)
        lo = max((v for v, p in points.items() if p["worst_utilisation"] <= 1.0
                  and (hi is None or v < hi)), default=None)
        res[name] = {"key": key, "paper_value": w0,
                     "points": [points[v] for v in sorted(points)],
                     "largest_within_strength": lo, "smallest_beyond": hi,
                     "monotonic": bool(np.all(np.diff([int(points[v]["worst_utilisation"] > 1.0)
                                                       for v in sorted(points)]) >= 0))}
        print(f"{name}: {key} within strength up to {lo} (beyond at {hi})", flush=True)


def stage_steady(args, results):
    """The deployed web and the straight tethers spinning steadily (linear.steady, finite
    strains): the utilisation at 8 pi rad/s, where it peaks, and the rate at which it is 1."""
    from scipy.optimize import brentq

    from spinweb_fe.case.scene import deployed
    from spinweb_fe.linear.steady import solve_steady

    res = results.setdefault("steady", {})
    for name in ("paper_free_web", "paper_free_arms"):
        case = case_mod.load(ROOT / "cases" / f"{name}.toml")
        mesh, struct = deployed(case)
        eps = SIGMA_F / case.cable.youngs_modulus

        def util(w):
            return float(solve_steady(struct, w).strain.max()) / eps

        w0 = float(case.initial.omega)
        st = solve_steady(struct, w0)
        k = int(np.argmax(st.strain))
        nodes = mesh.elem_nodes[k]
        w1 = brentq(lambda w: util(w) - 1.0, 0.2 * w0, w0, xtol=1e-4)
        res[name] = {"omega": w0, "utilisation": float(st.strain[k]) / eps,
                     "element": k, "arm": int(max(mesh.node_arm[nodes])),
                     "arm_coord_m": float(np.mean(mesh.node_arm_coord[nodes])),
                     "on_edge": bool(k in set(mesh.elem_sets.get("boundary", []))),
                     "max_tension_N": float(st.tension.max()), "omega_at_1": w1}
        print(f"{name}: steady at {w0:.4g} rad/s: u = {res[name]['utilisation']:.3g} "
              f"(element {k}, l = {res[name]['arm_coord_m']:.1f} m); u = 1 at {w1:.4g} rad/s",
              flush=True)


def stage_damping(args, results):
    """How much of the free web's worst utilisation at 8 pi rad/s is snap loading that axial
    damping (a fraction of critical for the element mode) takes away."""
    res = results.setdefault("damping", {})
    for zeta in (0.05, 0.2):
        name = "paper_free_web"
        path, wall = run(name, args.out / "damping" / f"{name}_{zeta}",
                         [f"cable.failure_strain={EPS_ZYLON}", f"cable.damping_ratio={zeta}",
                          "output.frame_dt=0"])
        res[f"{name}_{zeta}"] = {"damping_ratio": zeta, "wall_s": wall, **margins_of(path)}
        r = res[f"{name}_{zeta}"]
        print(f"{name} damping {zeta}: worst u {r['worst_utilisation']:.3g} at "
              f"{r['worst_time_s']:.3f} s, {r['where']}", flush=True)


def stage_rupture(args, results):
    res = results.setdefault("rupture", {})
    for name in RUPTURE:
        eps = failure_strain(name)
        path, wall = run(name, args.out / "rupture" / name,
                         [f"cable.failure_strain={eps}", "cable.rupture=true",
                          "output.frame_dt=0.01"])
        res[name] = {"failure_strain": eps, "wall_s": wall, **margins_of(path)}
        r = res[name]
        print(f"{name}: {r['broken_elements']} broken, first at {r['first_break_s']} s "
              f"({r.get('first_break_where')}), {r.get('pieces_at_end')} pieces ({wall:.1f} s)",
              flush=True)


def frame_utilisation(h5, k, eps_f):
    """(E,) utilisation of frame k from its positions, and its broken flags (or None)."""
    pos = h5["frames/position"][k]
    el = h5["mesh/elements"][()]
    rest = h5["mesh/rest_length"][()]
    strain = np.linalg.norm(pos[el[:, 1]] - pos[el[:, 0]], axis=1) / rest - 1.0
    broken = h5["frames/broken"][k] > 0 if "frames/broken" in h5 else None
    return pos, el, np.maximum(strain, 0.0) / eps_f, broken


def margins_figure(results, out_dir, path):
    """Utilisation histories of the Zylon paper cases and the free web at its worst frame."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from spinweb_fe.post.strength import draw_web

    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(13, 5.6),
                                  gridspec_kw={"width_ratios": [1.25, 1]})
    for name, r in results["margins"].items():
        if name.endswith("_stiff"):
            continue
        with h5py.File(out_dir / "margins" / name / "results.h5", "r") as h5:
            t, u = h5["history/time"][()], h5["history/utilisation"][()]
        ax.semilogy(t, u, lw=0.8, label=f"{name.removeprefix('paper_')} (max {u.max():.3g})")
    ax.axhline(1.0, color="k", lw=1.2, ls="--")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("utilisation: max strain / failure strain (Zylon, 3.22 %)")
    ax.set_ylim(0.05, 30)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="lower right")
    with h5py.File(out_dir / "margins" / "paper_free_web" / "results.h5", "r") as h5:
        worst = max(range(h5["frames/time"].shape[0]),
                    key=lambda k: frame_utilisation(h5, k, EPS_ZYLON)[2].max())
        pos, el, util, _ = frame_utilisation(h5, worst, EPS_ZYLON)
        lc = draw_web(ax2, pos, el, util, hub_radius=float(h5["mesh"].attrs["hub_radius"]),
                      vmax=3.0)
        ax2.set_title(f"free web at t = {h5['frames/time'][worst]:.2f} s (rupture off)")
    fig.colorbar(lc, ax=ax2, label="utilisation (capped at 3)", shrink=0.8)
    ax2.set_xlabel("x [m]")
    ax2.set_ylabel("y [m]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def rupture_figure(path_h5, path):
    """Where the web tears: the web at the frames where 5 %, 35 % and 75 % of its broken
    elements have broken (broken elements left out, the others coloured by utilisation, the
    view holding 90 % of the nodes), and the flat web with each broken element coloured by
    the time it broke."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    from spinweb_fe.post.strength import draw_web

    with h5py.File(path_h5, "r") as h5:
        times = h5["frames/time"][()]
        count = (h5["frames/broken"][()] > 0).sum(axis=1)
        ks = [int(np.argmax(count >= f * count[-1])) for f in (0.05, 0.35, 0.75)]
        r0 = float(h5["mesh"].attrs["hub_radius"])
        fig, axes = plt.subplots(1, 4, figsize=(21, 5.4))
        for ax, k in zip(axes, ks):
            pos, el, util, broken = frame_utilisation(h5, k, EPS_ZYLON)
            lc = draw_web(ax, pos, el, util, broken, hub_radius=r0, vmax=1.0)
            half = 1.1 * float(np.percentile(np.hypot(pos[:, 0], pos[:, 1]), 90))
            ax.set_xlim(-half, half)
            ax.set_ylim(-half, half)
            ax.set_title(f"t = {times[k]:.2f} s: {int(broken.sum())} broken")
        fig.colorbar(lc, ax=axes[2], label="utilisation", shrink=0.8)
        ref = h5["mesh/reference_points"][()]
        broke = h5["frames/broken"][()] > 0
        gone = broke[-1]
        when = times[np.argmax(broke, axis=0)][gone]
        ax = axes[3]
        ax.add_collection(LineCollection(ref[el[~gone]][:, :, :2], colors="0.85",
                                         linewidths=0.6))
        lc = LineCollection(ref[el[gone]][:, :, :2], cmap="plasma", linewidths=1.8)
        lc.set_array(when)
        ax.add_collection(lc)
        ax.set_aspect("equal")
        ax.autoscale_view()
        fig.colorbar(lc, ax=ax, label="broken at t [s]", shrink=0.8)
        ax.set_title(f"the flat web: {int(gone.sum())} broken elements")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def stage_figs(args, results):
    IMG.mkdir(parents=True, exist_ok=True)
    margins_figure(results, args.out, IMG / "strength_margins.png")
    for name in ("paper_free_web", "paper_ramp_web"):
        rupture_figure(args.out / "rupture" / name / "results.h5",
                       IMG / f"strength_rupture_{name.removeprefix('paper_')}.png")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stages", nargs="*",
                    default=["margins", "steady", "damping", "scan", "rupture", "figs"])
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "strength")
    ap.add_argument("--skip-stiff", action="store_true")
    ap.add_argument("--cases", nargs="*", help="margins: only these paper cases")
    args = ap.parse_args(argv)
    results = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    results["machine"] = {"platform": platform.platform(), "python": platform.python_version(),
                          "date": time.strftime("%Y-%m-%d")}
    results["zylon"] = {"tensile_strength_Pa": SIGMA_F, "youngs_modulus_Pa": E_ZYLON,
                        "failure_strain": EPS_ZYLON,
                        "source": "Toyobo, PBO fiber ZYLON technical information (2005)"}
    stages = {"margins": stage_margins, "steady": stage_steady, "damping": stage_damping,
              "scan": stage_scan, "rupture": stage_rupture, "figs": stage_figs}
    for s in args.stages:
        stages[s](args, results)
        if s != "figs":
            RESULTS.parent.mkdir(parents=True, exist_ok=True)
            RESULTS.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
