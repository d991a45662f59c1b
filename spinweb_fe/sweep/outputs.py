"""``spinweb design`` outputs: design.csv / .json / .toml / .png and chart.csv / .json /
.png (docs/design.md)."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from spinweb_fe.record.criteria import required
from spinweb_fe.sweep.design import BOUNDS, METRICS, OBJECTIVES, Design, Point, case_raw

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


def write_design(d: Design, points, pairs, chosen, out_dir: Path, info: dict) -> dict:
    """design.csv (the verified points, both verdicts side by side), design.json (every
    point, the choice, its Monte-Carlo record, the stages, why there is no design), and for
    a chosen design design.toml (its case, with the criteria it was verified for in
    ``[verdict] require`` and its bounds and perturbations in the header) and, for a robust
    one, design_check.toml (the sweep of its members: ``spinweb sweep`` reproduces the pass
    rate), design.png."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {n: out_dir / f"design.{n}" for n in ("csv", "json", "png")}
    _csv(paths["csv"], *pair_table(d, pairs))
    robust = info.get("robust", {})
    _json(paths["json"], {"design_file": str(d.source), "base": str(d.base),
                          "minimise": d.minimise, "bounds": d.bounds,
                          "require": list(required(d.require)), "search": d.search,
                          "members": d.members, "seed": d.seed, "pass_rate": d.pass_rate,
                          "random": [f"{x.key} ~ {x.describe()}" for x in d.draws],
                          "analytic": [_pt(p) for p in points],
                          "verified": [[_pt(a), _pt(f), robust.get(i)]
                                       for i, (a, f) in enumerate(pairs)],
                          "chosen": None if chosen is None else [_pt(chosen[0]), _pt(chosen[1])],
                          **{k: v for k, v in info.items() if k != "robust"}})
    if chosen is not None:
        paths.update(_design_files(d, chosen, info, out_dir))
    plot_design(d, points, pairs, chosen, paths["png"])
    return paths


def _design_files(d: Design, chosen, info, out_dir: Path) -> dict:
    from spinweb_fe.case.load import dumps_toml

    raw = case_raw(d, chosen[0].values)
    raw.get("output", {}).pop("directory", None)
    raw.setdefault("verdict", {})["require"] = list(required(d.require))
    a, f = chosen
    head = [f"# spinweb design {d.source.name}: the chosen design (base {d.base})",
            "# " + ", ".join(f"{k} = {v:.6g}" for k, v in a.values.items()),
            (f"# {d.minimise}: analytic {a.objective:.6g}, FE {f.objective:.6g} "
             f"{OBJECTIVES[d.minimise][0]}; FE verified in {f.run_dir}"),
            "# verified for: [verdict] require below, and the bounds " + (", ".join(
                f"{k} <= {v:g}" for k, v in d.bounds.items()) or "(none)")]
    rec = info.get("chosen_robust")
    if rec:
        head.append(f"# robust: {rec['passes']} of {rec['members']} Monte-Carlo members pass "
                    f"({100 * rec['rate']:.0f} %, 95 % interval {100 * rec['low']:.0f} .. "
                    f"{100 * rec['high']:.0f} %; required {d.pass_rate}); perturbations: "
                    + "; ".join(f"{x.key} ~ {x.describe()}" for x in d.draws)
                    + "; spinweb sweep design_check.toml runs them again")
    if d.fe_sets:
        head.append("# the FE verification ran with " + ", ".join(
            f"{k} = {v!r}" for k, v in d.fe_sets.items()))
    out = {"toml": out_dir / "design.toml"}
    out["toml"].write_text("\n".join(head) + "\n" + dumps_toml(raw))
    if d.members:
        lines = [f"# the Monte-Carlo members of spinweb design {d.source.name}'s design",
                 f'title = "members of {d.title or d.source.stem}"', 'base = "design.toml"',
                 f"members = {d.members}", f"seed = {d.seed}", "", "[random]"]
        lines += [f'"{x.key}" = {{dist = "{x.dist}", '
                  + ", ".join(f"{k} = {_toml_value(v)}" for k, v in x.params.items()) + "}"
                  for x in d.draws]
        if d.fe_sets:
            lines += ["", "[set]"] + [f'"{k}" = {_toml_value(v)}' for k, v in d.fe_sets.items()]
        out["check"] = out_dir / "design_check.toml"
        out["check"].write_text("\n".join(lines) + "\n")
    return out


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return repr(float(v)) if isinstance(v, float) else repr(v)


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
