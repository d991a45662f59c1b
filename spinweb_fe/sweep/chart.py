"""``spinweb design``, the FE side and the outputs: the candidates of an analytical search
verified in FE on Dask (and refined on the FE where the two verdicts disagree), the chart
(the least value of one searched key, by bisection on the analytical model, against one
design input, with FE-checked points), and the files: design.csv / .json / .toml / .png,
chart.csv / .json / .png (docs/design.md).
"""

from __future__ import annotations

import csv
import dataclasses
import json
import logging
import math
import time
import tomllib
from pathlib import Path

import numpy as np

from spinweb_fe.errors import InputError
from spinweb_fe.sweep.design import (BOUNDS, METRICS, OBJECTIVES, Design, Evaluator, Point, _num, bisect,
                                     build_case, case_raw, check_cases, evaluate, judge_point,
                                     load_design, metrics_of)
from spinweb_fe.sweep.run import flatten

log = logging.getLogger(__name__)


def load_chart(path) -> Design:
    """:func:`load_design` for ``--chart``: one searched key and a [chart] table; every
    chart value's case validated."""
    d = load_design(path, chart=True)
    doc = tomllib.loads(d.text)
    key, values, fe, factor = _chart(d.source, doc.get("chart"), d.search, d.ties, d.sets)
    d = dataclasses.replace(d, chart_key=key, chart_values=values, chart_fe=fe,
                            chart_factor=factor)
    check_cases(d)
    return d


def _chart(src, table, search, ties, sets):
    """(key, values, FE-checked values, factor) of [chart]."""
    if not table:
        raise InputError(src, "chart", "missing: --chart needs a [chart] table with one "
                         "key and its values, e.g. \"initial.omega\" = [1.57, 6.28]")
    if len(search) != 1:
        raise InputError(src, "search", "a chart finds the least value of one searched key: "
                         f"{len(search)} given")
    opts = {k: table[k] for k in ("fe", "factor") if k in table}
    keys = flatten({k: v for k, v in table.items() if k not in opts})
    if len(keys) != 1:
        raise InputError(src, "chart", f"must hold exactly one key and its values, got "
                         f"{sorted(keys) or 'none'}")
    (key, values), = keys.items()
    if not isinstance(values, list) or not values:
        raise InputError(src, f"chart.{key}", "must be a non-empty list of values")
    values = tuple(_num(src, f"chart.{key}", v) for v in values)
    if key in search or key in ties or key in sets:
        raise InputError(src, f"chart.{key}", "also searched, tied or set: give it in one place")
    fe = opts.get("fe", [])
    fe = values if fe is True else fe
    if not isinstance(fe, (list, tuple)) or any(not any(math.isclose(_num(src, "chart.fe", x),
                                                                      v) for v in values)
                                                for x in fe):
        raise InputError(src, "chart.fe", "must be true or a list of chart values to check in FE")
    factor = _num(src, "chart.factor", opts.get("factor", 1.25))
    if not factor > 1.0:
        raise InputError(src, "chart.factor", f"must be > 1, got {factor!r}")
    return key, values, tuple(float(x) for x in fe), factor



def candidates(d: Design, points) -> list:
    """Up to ``d.candidates`` feasible points, best objective first, at least 2 % of the
    unit range apart."""
    feas = sorted((p for p in points if p.feasible and math.isfinite(p.objective)),
                  key=lambda p: (p.objective, -p.margin))
    out = []
    for p in feas:
        u = d.to_unit(p.values)
        if all(np.max(np.abs(u - d.to_unit(q.values))) > 0.02 for q in out):
            out.append(p)
        if len(out) == d.candidates:
            break
    return out


def safe_step(d: Design, p: Point, points, k: int) -> dict | None:
    """The point ``refine_step * 2**k`` of the unit range from ``p`` away from the nearest
    analytically infeasible point (None: no direction, or the step leaves the range)."""
    u = d.to_unit(p.values)
    bad = [d.to_unit(q.values) for q in points if not q.feasible]
    if not bad:
        return None
    near = min(bad, key=lambda b: float(np.linalg.norm(b - u)))
    step = u - near
    if not np.linalg.norm(step) > 0:
        return None
    nu = u + d.refine_step * 2 ** k * step / np.linalg.norm(step)
    if np.any(nu < -1e-12) or np.any(nu > 1 + 1e-12):
        return None
    return d.from_unit(nu)


def fe_point(d: Design, values: dict, row: dict, out_dir: Path, extra=None) -> Point:
    """Judge a finished FE run (sweep.run.run_one's ``row``) from its results.h5."""
    import h5py

    from spinweb_fe.io.mesh import read_mesh_group
    from spinweb_fe.record import verdict

    allv = {**values, **(extra or {})}
    path = out_dir / "results.h5"
    crits = None
    if path.is_file():
        with h5py.File(path, "r") as h5:
            crits = verdict.read_group(h5)
            if crits is not None:
                h = {k: h5["history"][k][()] for k in h5["history"]}
                mesh = read_mesh_group(h5["mesh"])
    if crits is None:
        return Point(allv, "fe", False, -1.0, math.nan, {}, ("error",),
                     status=row.get("status", "no results.h5") if row.get("status") != "ok"
                     else "no verdict in results.h5", run_dir=str(out_dir),
                     wall_s=row.get("wall_time_s", math.nan))
    frac = verdict.limits_of(build_case(d, values, extra, fe=True).verdict)["deployed_fraction"]
    m = metrics_of(h, crits, verdict.reach_of(mesh), mesh.hub_radius, frac)
    return judge_point(d, allv, "fe", crits, m, run_dir=str(out_dir), wall_s=row.get(
        "wall_time_s", math.nan), note="" if row.get("status", "ok") == "ok" else row["status"])


def run_fe(d: Design, client, jobs, out_dir: Path) -> list:
    """FE runs of ``jobs`` = [(name, values, extra)] on Dask, each in out_dir/fe/<name>;
    returns their Points in order."""
    from spinweb_fe.sweep.run import run_one

    futs = []
    for name, values, extra in jobs:
        task = {"raw": case_raw(d, values, extra, fe=True), "source": str(d.base),
                "mode": "fe", "model": "consistent", "out_dir": str(out_dir / "fe" / name)}
        futs.append(client.submit(run_one, task, pure=False, key=f"spinweb-design-{name}-"
                                  f"{time.monotonic_ns()}"))
    out = []
    for (name, values, extra), fut in zip(jobs, futs):
        try:
            row = fut.result()
        except Exception as exc:  # noqa: BLE001 - the worker died: a failed run
            row = {"status": f"{type(exc).__name__}: {exc}".splitlines()[0]}
        p = fe_point(d, values, row, out_dir / "fe" / name, extra)
        log.info("FE %s: %s (%.1f s)", name, p.verdict(), p.wall_s)
        out.append(p)
    return out


def slug(d: Design, values: dict) -> str:
    return "_".join(f"{k.split('.')[-1]}={v:.5g}" for k, v in values.items())


def verify(d: Design, client, cands, points, out_dir: Path) -> list:
    """FE runs of the candidates; while none passes, step the safest failed one toward the
    analytical safe side (``safe_step``, doubling) and run again; once a step passes,
    bisect between it and the last FE failure: ``d.refine`` FE runs at most after the
    candidates. Returns [(analytic point, FE point)] in the order run."""
    pairs = list(zip(cands, run_fe(d, client, [(f"{i:02d}_{slug(d, c.values)}", c.values, None)
                                               for i, c in enumerate(cands)], out_dir)))
    if any(f.feasible for _, f in pairs):
        return pairs
    bad = [q for q in points if not q.feasible]
    fail = max((a for a, _ in pairs), key=lambda a: min(
        (float(np.linalg.norm(d.to_unit(a.values) - d.to_unit(q.values))) for q in bad),
        default=0.0))
    ok = None
    for k in range(d.refine):
        if ok is None:
            nxt, what = safe_step(d, fail, points, k), "step to the safe side"
        else:
            u0, u1 = d.to_unit(fail.values), d.to_unit(ok.values)
            if np.max(np.abs(u1 - u0)) < 0.25 * d.refine_step:
                break
            nxt, what = d.from_unit(0.5 * (u0 + u1)), "bisect between FE fail and pass"
        if nxt is None:
            log.info("refine: no further step toward the safe side within the search range")
            break
        a = evaluate(d, nxt)
        points.append(a)
        if not a.feasible:
            log.info("refine: %s fails analytically (%s): stop", slug(d, nxt),
                     ",".join(a.failed))
            break
        log.info("refine %d (%s): %s", k + 1, what, slug(d, nxt))
        (f,) = run_fe(d, client, [(f"{len(pairs):02d}_refine_{slug(d, nxt)}", nxt, None)],
                      out_dir)
        a.note = f"refinement {k + 1}: {what}"
        pairs.append((a, f))
        if f.feasible:
            ok = a
        else:
            fail = a
    return pairs


def choose(pairs):
    """The FE-verified pair with the best FE objective (the analytic one where the FE's is
    not finite); None if the FE rejected all."""
    ok = [(a, f) for a, f in pairs if f.feasible]
    if not ok:
        return None
    return min(ok, key=lambda af: af[1].objective if math.isfinite(af[1].objective)
               else af[0].objective)


# -- the chart ----------------------------------------------------------------------------

def chart_row(d: Design, value: float) -> dict:
    """The least value of the searched key that passes, at chart value ``value`` (a Dask
    task): a scan of ``d.scan`` points upward to the first that passes, bisection between
    it and the one before (``d.rtol``), and one check a scan step above it (passing is
    assumed to hold above the least value; the large values, the costly stiff ones of a
    feedback law, are not solved)."""
    t0 = time.perf_counter()
    key = d.keys[0]
    ev = Evaluator(d, {d.chart_key: value})
    grid = np.linspace(0.0, 1.0, d.scan)
    prev = least = None
    note = "none passes in the search range"
    for i, u in enumerate(grid):
        p = ev(d.from_unit([u]))
        if p.feasible:
            least = bisect(d, ev, key, p, prev) if prev is not None else p
            note = "" if prev is not None else "the lower end of the search range passes"
            above = ev(d.from_unit([grid[i + 1]])) if i + 1 < len(grid) else p
            if not above.feasible:
                note = f"fails again at {key} = {above.values[key]:.4g} ({','.join(above.failed)})"
            break
        prev = p
    return {"value": value, "least": least.values[key] if least else math.nan, "point": least,
            "points": ev.points, "note": note, "wall_s": time.perf_counter() - t0}


def run_chart(d: Design, client, out_dir: Path) -> list:
    """Every chart row on Dask, then the FE checks: at each value of ``d.chart_fe`` one run
    at the least value times ``chart_factor`` (should pass) and one at it divided by the
    factor (should fail). Rows in chart order with ``fe_above`` / ``fe_below`` Points."""
    rows = client.gather(client.map(chart_row, [d] * len(d.chart_values), d.chart_values,
                                    pure=False))
    key, jobs = d.keys[0], []
    for r in rows:
        r["fe_above"] = r["fe_below"] = None
        if any(math.isclose(r["value"], v) for v in d.chart_fe) and math.isfinite(r["least"]):
            for side, x in (("above", r["least"] * d.chart_factor),
                            ("below", r["least"] / d.chart_factor)):
                jobs.append((r, side, f"{d.chart_key.split('.')[-1]}={r['value']:.5g}_{side}",
                             {key: x}))
        log.info("chart %s = %.5g: least %s = %.5g (%d solves, %.1f s)%s", d.chart_key,
                 r["value"], key, r["least"], len(r["points"]), r["wall_s"],
                 f": {r['note']}" if r["note"] else "")
    if jobs:
        pts = run_fe(d, client, [(name, vals, {d.chart_key: r["value"]})
                                 for r, _, name, vals in jobs], out_dir)
        for (r, side, _, _), p in zip(jobs, pts):
            r[f"fe_{side}"] = p
    return rows


# -- outputs ------------------------------------------------------------------------------

def _pt(p: Point | None) -> dict | None:
    return None if p is None else dataclasses.asdict(p)


def _json(path, obj):
    def clean(o):
        if isinstance(o, float) and not math.isfinite(o):
            return None if math.isnan(o) else ("inf" if o > 0 else "-inf")
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        return o
    Path(path).write_text(json.dumps(clean(obj), indent=1) + "\n")


def pair_table(d: Design, pairs) -> tuple[list, list]:
    """The side-by-side table of the verified points: (columns, rows)."""
    names = [d.minimise] + [b for b in d.bounds if b != d.minimise]
    cols = [*d.keys, "analytic_verdict", "fe_verdict"]
    cols += [f"{m}_{n}" for n in names for m in ("analytic", "fe")]
    cols += ["fe_wall_s", "run_dir", "note"]
    rows = []
    for a, f in pairs:
        row = [a.values[k] for k in d.keys] + [a.verdict(), f.verdict()]
        for n in names:
            get = (lambda p: p.objective) if n == d.minimise else (
                lambda p, n=n: p.metrics.get(n, math.nan))
            row += [get(a), get(f)]
        rows.append(row + [f.wall_s, f.run_dir, "; ".join(x for x in (a.note, f.note) if x)])
    return cols, rows


def _csv(path, cols, rows):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        w.writerows([[repr(v) if isinstance(v, float) else v for v in r] for r in rows])


def write_design(d: Design, points, pairs, chosen, out_dir: Path, timing: dict) -> dict:
    """design.csv (the verified points, both verdicts side by side), design.json (every
    point, the choice, the timing), design.toml (the chosen case, if any), design.png."""
    from spinweb_fe.case.load import dumps_toml

    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {n: out_dir / f"design.{n}" for n in ("csv", "json", "png")}
    _csv(paths["csv"], *pair_table(d, pairs))
    _json(paths["json"], {"design_file": str(d.source), "base": str(d.base),
                          "minimise": d.minimise, "bounds": d.bounds, "require": d.require,
                          "search": d.search, "analytic": [_pt(p) for p in points],
                          "verified": [[_pt(a), _pt(f)] for a, f in pairs],
                          "chosen": None if chosen is None else [_pt(chosen[0]), _pt(chosen[1])],
                          "timing_s": timing})
    if chosen is not None:
        raw = case_raw(d, chosen[0].values)
        raw.get("output", {}).pop("directory", None)
        a, f = chosen
        head = [f"# spinweb design {d.source.name}: the chosen design (base {d.base})",
                "# " + ", ".join(f"{k} = {v:.6g}" for k, v in a.values.items()),
                (f"# {d.minimise}: analytic {a.objective:.6g}, FE {f.objective:.6g} "
                 f"{OBJECTIVES[d.minimise][0]}; FE verified in {f.run_dir}")]
        if d.fe_sets:
            head.append("# the FE verification ran with " + ", ".join(
                f"{k} = {v!r}" for k, v in d.fe_sets.items()))
        paths["toml"] = out_dir / "design.toml"
        paths["toml"].write_text("\n".join(head) + "\n" + dumps_toml(raw))
    plot_design(d, points, pairs, chosen, paths["png"])
    return paths


def _axes(n):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, n, figsize=(4.6 * n, 3.8), squeeze=False)
    return plt, fig, axes[0]


def _log_x(ax):
    from matplotlib.ticker import NullFormatter

    ax.set_xscale("log")
    ax.xaxis.set_minor_formatter(NullFormatter())


def plot_design(d: Design, points, pairs, chosen, path):
    """The objective, every bound's metric and the verdict margin against the first
    searched key: analytical points (filled: pass, open: fail), FE points (square: pass,
    cross: fail), the bounds dashed, the design ringed."""
    key = d.keys[0]
    names = [n for n in dict.fromkeys([d.minimise, *d.bounds]) if n != "parameter"]
    plt, fig, axes = _axes(len(names) + 1)
    fe = [f for _, f in pairs]
    styles = ({"c": "C0", "marker": "o", "ls": "", "label": "analytic: pass"},
              {"mfc": "none", "c": "0.5", "marker": "o", "ls": "", "label": "analytic: fails"},
              {"c": "C2", "marker": "s", "ms": 8, "ls": "", "label": "FE: pass", "zorder": 4},
              {"c": "C3", "marker": "x", "ms": 9, "mew": 2, "ls": "", "label": "FE: fails"})
    for ax, n in zip(axes, [*names, "margin"]):
        def get(p, n=n):
            return p.margin if n == "margin" else p.metrics.get(n, math.nan)
        for group, style in zip(([p for p in points if p.feasible],
                                 [p for p in points if not p.feasible],
                                 [p for p in fe if p.feasible], [p for p in fe if not p.feasible]),
                                styles):
            pts = [p for p in group if math.isfinite(get(p))]
            if pts:
                ax.plot([p.values[key] for p in pts], [get(p) for p in pts], **style)
        if n in d.bounds or n == "margin":
            ax.axhline(d.bounds.get(n, 0.0), ls="--", c="k", lw=1, label="bound / zero")
        if chosen is not None and math.isfinite(get(chosen[1])):
            ax.plot(chosen[1].values[key], get(chosen[1]), "o", ms=16, mfc="none", mec="gold",
                    mew=2.5, label="design (FE)", zorder=5)
        if d.is_log(key):
            _log_x(ax)
        ys = [get(p) for p in points + fe if math.isfinite(get(p)) and get(p) > 0]
        if n != "margin" and ys and max(ys) / min(ys) > 30:
            ax.set_yscale("log")
        ax.set_xlabel(key)
        ax.set_ylabel("margin (< 0: fails)" if n == "margin" else f"{n} [{BOUNDS.get(n, OBJECTIVES.get(n))[0]}]")
        ax.grid(alpha=0.3)
    axes[-1].set_ylim(max(axes[-1].get_ylim()[0], -1.05), None)
    axes[0].legend(fontsize=7)
    fig.suptitle(d.title or f"spinweb design {d.source.name}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


#: the metrics at the least value (the registry's objectives), then the row's bookkeeping
CHART_METRICS = tuple(k for k, m in METRICS.items() if m.objective)
CHART_COLS = ("value", "least", *CHART_METRICS, "solves", "wall_s", "fe_above", "fe_below",
              "note")


def chart_table(d: Design, rows) -> list:
    out = []
    for r in rows:
        p = r["point"]
        m = p.metrics if p else {}
        out.append([r["value"], r["least"], *(m.get(k, math.nan) for k in CHART_METRICS),
                    len(r["points"]), r["wall_s"],
                    r["fe_above"].verdict() if r["fe_above"] else "",
                    r["fe_below"].verdict() if r["fe_below"] else "", r["note"]])
    return out


def write_chart(d: Design, rows, out_dir: Path) -> dict:
    """chart.csv, chart.json (every analytical point of every row) and chart.png."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {n: out_dir / f"chart.{n}" for n in ("csv", "json", "png")}
    cols = [d.chart_key, f"least {d.keys[0]}", *CHART_COLS[2:]]
    _csv(paths["csv"], cols, chart_table(d, rows))
    _json(paths["json"], {"design_file": str(d.source), "chart_key": d.chart_key,
                          "key": d.keys[0], "search": d.search, "require": d.require,
                          "rows": [{**{k: v for k, v in r.items() if k not in (
                              "point", "points", "fe_above", "fe_below")},
                              "point": _pt(r["point"]), "points": [_pt(p) for p in r["points"]],
                              "fe_above": _pt(r["fe_above"]), "fe_below": _pt(r["fe_below"])}
                              for r in rows]})
    plot_chart(d, rows, paths["png"])
    return paths


def plot_chart(d: Design, rows, path):
    """Least value against the chart key (FE checks above / below it), and the deployment
    time and peak torque at the least value."""
    key = d.keys[0]
    plt, fig, axes = _axes(2)
    x = [r["value"] for r in rows]
    axes[0].plot(x, [r["least"] for r in rows], "o-", c="C0", label="least passing (analytic)")
    for side, style in (("above", "^"), ("below", "v")):
        for r in rows:
            p = r[f"fe_{side}"]
            if p is not None:
                axes[0].plot(r["value"], p.values[key], style, ms=9, c="C2" if p.feasible
                             else "C3", mfc="C2" if p.feasible else "none")
    axes[0].plot([], [], "^", c="C2", label="FE: passes")
    axes[0].plot([], [], "v", c="C3", mfc="none", label="FE: fails")
    axes[0].set_ylabel(f"least {key}")
    m = [r["point"].metrics if r["point"] else {} for r in rows]
    axes[1].plot(x, [q.get("deploy_time", math.nan) for q in m], "o-", c="C1")
    axes[1].set_ylabel("deployment time at the least value [s]", color="C1")
    twin = axes[1].twinx()
    twin.plot(x, [q.get("peak_torque", math.nan) for q in m], "s--", c="C4")
    twin.set_ylabel("peak |hub torque| at the least value [N m]", color="C4")
    for ax in (axes[0], axes[1], twin):
        ys = [v for line in ax.get_lines() for v in line.get_ydata() if np.isfinite(v) and v > 0]
        if ys and (max(ys) / min(ys) > 30 or ax is axes[0] and d.is_log(key)):
            ax.set_yscale("log")
    for ax in axes:
        ax.set_xlabel(d.chart_key)
        if min(x) > 0 and max(x) / min(x) > 10:
            _log_x(ax)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(d.title or f"spinweb design --chart {d.source.name}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
