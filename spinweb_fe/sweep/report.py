"""Sweep outputs: the summary table as ``summary.csv`` and ``summary.h5`` and the plot
``summary.png`` (metrics against the first swept key). See docs/sweep.md."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from spinweb_fe.sweep.run import METRICS, PLOTTED, Sweep


def table(sweep: Sweep, rows) -> tuple[list, list]:
    """(column names, list of row lists): index, name, swept keys, metrics, status, dir."""
    member = ["member"] if sweep.members else []
    cols = ["index", "name", *member, *sweep.keys, *(m for m, _, _ in METRICS), "failed",
            "status", "run_dir"]
    out = []
    for run, row in zip(sweep.runs, rows):
        out.append([run.index, run.name, *([run.member] if member else []),
                    *(run.values[k] for k in sweep.keys),
                    *(row.get(m, math.nan) for m, _, _ in METRICS), row.get("failed", ""),
                    row["status"], f"runs/{run.name}"])
    return cols, out


def groups(sweep: Sweep) -> dict:
    """{label: [positions of its runs]}: the runs of one grid point and [[runs]] entry (the
    Monte-Carlo members of one design) together; one group '' without a grid or entries."""
    drawn = {d.key for d in sweep.draws}
    out = {}
    for pos, run in enumerate(sweep.runs):
        fixed = [(k, v) for k, v in run.values.items() if k not in drawn]
        label = ", ".join([run.label] * bool(run.label) + [
            f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}" for k, v in fixed])
        out.setdefault(label, []).append(pos)
    return out


def pass_rate(sweep: Sweep, rows, positions=None) -> dict:
    """The verdicts of a sweep's runs (or of those at ``positions``): n, passes, rate, its
    Wilson interval (sweep.draws, 95 %), the count of each failed criterion, and the worst
    run (largest verdict severity; a run that failed to run is the worst) with the command
    that runs it alone."""
    from spinweb_fe.sweep.draws import CONFIDENCE, wilson

    positions = range(len(rows)) if positions is None else positions
    sel = [rows[i] for i in positions]
    n = len(sel)
    passes = sum(r.get("passed") == 1.0 for r in sel)
    low, high = wilson(passes, n)
    counts = {}
    for r in sel:
        for name in filter(None, str(r.get("failed", "")).split(",")):
            counts[name] = counts.get(name, 0) + 1

    def badness(i):
        sev = rows[i].get("severity", math.nan)
        return math.inf if rows[i]["status"] != "ok" or sev != sev else sev
    worst = max(positions, key=badness) if n else None
    out = {"n": n, "passes": passes, "rate": passes / n if n else math.nan, "low": low,
           "high": high, "confidence": CONFIDENCE, "failed_counts": counts}
    if worst is not None:
        run = sweep.runs[worst]
        out.update(worst=run.name, worst_severity=badness(worst),
                   worst_failed=rows[worst].get("failed", ""),
                   rerun=f"spinweb sweep {sweep.source} --only {run.name}")
    return out


def rate_lines(sweep: Sweep, rows) -> list:
    """Lines of a sweep's pass rates for the terminal: one block per group of runs
    (:func:`groups`)."""
    lines = []
    what = "Monte-Carlo members" if sweep.members else "runs"
    for label, positions in groups(sweep).items():
        pr = pass_rate(sweep, rows, positions)
        head = f"verdicts{' (' + label + ')' if label else ''}: "
        lines.append(f"{head}{pr['passes']} of {pr['n']} {what if pr['n'] > 1 else 'run'} "
                     f"pass ({100 * pr['rate']:.1f} %, {100 * pr['confidence']:.0f} % "
                     f"interval {100 * pr['low']:.1f} .. {100 * pr['high']:.1f} %)")
        if pr["failed_counts"]:
            lines.append("  failed criteria: " + ", ".join(
                f"{k} {v}" for k, v in sorted(pr["failed_counts"].items(),
                                              key=lambda kv: -kv[1])))
        if pr.get("worst") is not None and pr["n"] > 1:
            why = pr["worst_failed"] or "passes"
            lines.append(f"  worst: {pr['worst']} (severity {pr['worst_severity']:.3g}: "
                         f"{why}); run it alone: {pr['rerun']} -o DIR")
    return lines


def write_summary(sweep: Sweep, rows, out_dir) -> dict:
    """Write ``summary.csv``, ``summary.h5`` (``/runs/<column>`` datasets with ``units``)
    and ``summary.png``; return their paths."""
    import h5py

    from spinweb_fe import __version__

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    cols, data = table(sweep, rows)
    paths = {"csv": out_dir / "summary.csv", "h5": out_dir / "summary.h5",
             "png": out_dir / "summary.png"}
    with open(paths["csv"], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        w.writerows([["" if v is None else repr(v) if isinstance(v, float) else v for v in r]
                     for r in data])
    units = {m: u for m, u, _ in METRICS}
    docs = {m: d for m, _, d in METRICS}
    with h5py.File(paths["h5"], "w") as h5:
        h5.attrs.update({"sweep": sweep.text, "sweep_file": str(sweep.source),
                         "base": str(sweep.base), "mode": sweep.mode, "model": sweep.model,
                         "swept_keys": list(sweep.keys) or [""], "spinweb_version": __version__,
                         "n_runs": len(data),
                         "n_failed": sum(r[cols.index("status")] != "ok" for r in data)})
        pr = pass_rate(sweep, rows)
        by_group = {label: pass_rate(sweep, rows, pos) for label, pos in groups(sweep).items()}
        h5.attrs.update({"groups": list(by_group) or [""],
                         "group_passes": [p["passes"] for p in by_group.values()],
                         "group_runs": [p["n"] for p in by_group.values()],
                         "group_pass_rate_low": [p["low"] for p in by_group.values()],
                         "group_pass_rate_high": [p["high"] for p in by_group.values()]})
        h5.attrs.update({"members": sweep.members, "seed": sweep.seed,
                         "random": [f"{d.key} ~ {d.describe()}" for d in sweep.draws] or [""],
                         "passes": pr["passes"], "pass_rate": pr["rate"],
                         "pass_rate_low": pr["low"], "pass_rate_high": pr["high"],
                         "pass_rate_confidence": pr["confidence"],
                         "worst_run": pr.get("worst", ""), "worst_rerun": pr.get("rerun", "")})
        g = h5.create_group("runs")
        g.attrs["columns"] = cols  # the table's column order
        for j, name in enumerate(cols):
            vals = [r[j] for r in data]
            if name == "index":
                ds = g.create_dataset(name, data=np.asarray(vals, dtype=np.int64))
            elif all(isinstance(v, (int, float)) and not isinstance(v, bool)
                     for v in vals if v is not None):  # None: key unset in that run
                ds = g.create_dataset(name, data=np.array(
                    [math.nan if v is None else v for v in vals], dtype=float))
            else:
                ds = g.create_dataset(name, data=["" if v is None else str(v) for v in vals],
                                      dtype=h5py.string_dtype())
            ds.attrs["units"] = units.get(name) or _key_unit(name) or (
                "1" if name == "index" else "")
            if name in docs:
                ds.attrs["description"] = docs[name]
    plot_summary(sweep, rows, paths["png"])
    return paths


def _series_keys(sweep: Sweep):
    """Other swept keys that vary independently of the first one (lines of the plot)."""
    x, others = sweep.keys[0], sweep.keys[1:]
    keep = []
    for k in others:
        seen = {}
        for run in sweep.runs:
            seen.setdefault(repr(run.values[x]), set()).add(repr(run.values[k]))
        if any(len(s) > 1 for s in seen.values()):
            keep.append(k)
    return keep


def _key_unit(key: str) -> str:
    """SI unit of a dotted case key ('initial.omega' -> 'rad/s'; '' if none or unknown)."""
    from spinweb_fe.case.schema import SCHEMA

    table, _, name = key.partition(".")
    field = SCHEMA.get(table, {}).get(name)
    return field.unit if field is not None else ""


def _key_label(key: str) -> str:
    unit = _key_unit(key)
    return f"{key} [{unit}]" if unit else key


def _line_label(sweep: Sweep, run, series) -> str:
    """Legend of the line a run belongs to: its [[runs]] name (when a [[runs]] key splits
    the lines) and the grid keys among ``series``, as 'key = value'."""
    def kv(k):
        v = run.values[k]
        return f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}"

    if run.label and any(k not in sweep.grid for k in series):
        return ", ".join([run.label] + [kv(k) for k in series if k in sweep.grid])
    return ", ".join(kv(k) for k in series)


def plot_summary(sweep: Sweep, rows, path):
    """Metrics against the first swept key, one line per combination of the other keys
    that vary independently of it, each run's point green when its verdict passes and red
    when it fails; failed runs are left out, re-coiled runs ringed. A metric no run has
    (nothing deployed) gives its panel to the verdict's severity."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    from spinweb_fe.post.axes import untangle_ticks

    if sweep.members:
        return plot_members(sweep, rows, path)
    xkey = sweep.keys[0] if sweep.keys else "index"
    xs = [r.values[xkey] if sweep.keys else r.index for r in sweep.runs]
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in xs)
    cats = list(dict.fromkeys(map(str, xs)))
    series = _series_keys(sweep) if sweep.keys else []
    groups = {}
    for run, row, xv in zip(sweep.runs, rows, xs):
        groups.setdefault(_line_label(sweep, run, series), []).append(
            (xv if numeric else cats.index(str(xv)), row))
    shown = _panels(rows)
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    for ax, metric in zip(axes.flat, shown):
        for colour, (label, pts) in enumerate(groups.items()):
            pts = sorted(pts, key=lambda p: p[0])
            x = np.array([p[0] for p in pts], dtype=float)
            y = np.array([p[1].get(metric, math.nan) for p in pts], dtype=float)
            if np.all(np.isnan(y)):  # every run of this line failed
                continue
            ax.plot(x, y, "-", color=f"C{colour % 10}", label=label or None)
            verdicts = np.array([p[1].get("passed", math.nan) for p in pts], dtype=float)
            for value, mark, name in ((1.0, "tab:green", "verdict passes"),
                                      (0.0, "tab:red", "verdict fails")):
                sel = verdicts == value
                ax.plot(x[sel], y[sel], "o", color=mark, ms=6, label=name)
            rec = np.array([p[1].get("recoiled") == 1.0 for p in pts])
            if rec.any():
                ax.plot(x[rec], y[rec], "o", ms=12, mfc="none", mec="red", mew=1.5)
        if metric == "severity":
            ax.axhline(1.0, color="0.3", ls="--", lw=1.0)
        ax.set_ylabel(SHOWN.get(metric, PLOTTED.get(metric, metric)))
        ax.grid(alpha=0.3)
    bottom = _bottom(axes, len(shown))
    ticks = sorted(set(xs)) if numeric else []
    for ax in axes.flat[:len(shown)]:
        if not numeric:
            ax.set_xticks(range(len(cats)), cats)
            continue
        if min(xs) > 0 and max(xs) > 10 * min(xs):
            ax.set_xscale("log")
        if len(ticks) <= 8:  # label the swept values themselves
            ax.set_xticks(ticks, [f"{v:.4g}" for v in ticks])
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    for ax in bottom:
        ax.set_xlabel(_key_label(xkey))
    handles = {}
    for ax in axes.flat[:len(shown)]:  # one legend entry per line, whichever panel drew it
        handles.update(zip(*reversed(ax.get_legend_handles_labels())))
    top = 0.95
    if handles:
        fig.legend(handles.values(), handles.keys(), loc="upper center", fontsize=8,
                   ncol=min(3, len(handles)), bbox_to_anchor=(0.5, 0.955), frameon=False)
        top = 0.955 - 0.03 * math.ceil(len(handles) / 3)
    n_fail = sum(r["status"] != "ok" for r in rows)
    fig.suptitle(f"{sweep.title or sweep.source.name} ({sweep.mode}; "
                 f"{len(rows) - n_fail} ok, {n_fail} failed; red ring: re-coiled)", fontsize=11)
    for _ in range(2):  # the labels fitted to the laid-out panels, the layout to the labels
        fig.tight_layout(rect=(0, 0, 1, top))
        for ax in bottom:
            untangle_ticks(fig, ax, rotation=0.0 if numeric else 30.0)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


#: the panel that replaces a metric no run has
SHOWN = {"severity": "verdict severity (above 1: fails)"}


def _bottom(axes, n) -> list:
    """The 2 x 2 ``axes`` cut to ``n`` panels (the rest removed: no empty panel); returns
    the lowest panel of each column, which show the x tick labels."""
    for ax in axes.flat[n:]:
        ax.remove()
    bottom = {4: [axes[1, 0], axes[1, 1]], 3: [axes[1, 0], axes[0, 1]],
              2: [axes[0, 0], axes[0, 1]], 1: [axes[0, 0]]}[n]
    for ax in bottom:
        ax.tick_params(labelbottom=True)
    return bottom


def _panels(rows) -> list:
    """The metrics of :data:`PLOTTED` that some run has, then the verdict's severity in place
    of those none has (at least one panel)."""
    has = [m for m in PLOTTED if any(math.isfinite(_num(r.get(m))) for r in rows)]
    return has + ["severity"] if len(has) < len(PLOTTED) else has


def plot_members(sweep: Sweep, rows, path):
    """A Monte-Carlo sweep: the metrics against its first continuous drawn key (else its
    first numeric one, else the member), each member a point,
    green when its verdict passes, red when it fails (failed runs left out)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from spinweb_fe.post.axes import untangle_ticks

    numeric = [d.key for d in sweep.draws if all(
        _num(r.values[d.key]) == _num(r.values[d.key]) for r in sweep.runs)]
    spread = [d.key for d in sweep.draws if d.dist != "choice" and d.key in numeric]
    xkey = (spread or numeric or [None])[0]  # a continuous draw first
    x = np.array([_num(r.values[xkey]) if xkey else r.member for r in sweep.runs])
    ok = np.array([row.get("passed") == 1.0 for row in rows])
    marks = "osD^v<>"
    shown = _panels(rows)
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    for ax, metric in zip(axes.flat, shown):
        ylabel = SHOWN.get(metric, PLOTTED.get(metric, metric))
        y = np.array([row.get(metric, math.nan) for row in rows], dtype=float)
        for g, (label, pos) in enumerate(groups(sweep).items()):
            sel = np.zeros(len(rows), bool)
            sel[pos] = True
            m = marks[g % len(marks)]
            name = f"{label}: " if label else ""
            ax.plot(x[sel & ok], y[sel & ok], m, color="tab:green", ms=5, mfc="none" if g
                    else "tab:green", label=f"{name}passes")
            ax.plot(x[sel & ~ok], y[sel & ~ok], m, color="tab:red", ms=5, mfc="none" if g
                    else "tab:red", label=f"{name}fails")
        if metric == "severity":
            ax.axhline(1.0, color="0.3", ls="--", lw=1.0)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    bottom = _bottom(axes, len(shown))
    for ax in bottom:
        ax.set_xlabel(_key_label(xkey) if xkey else "member")
    axes.flat[0].legend(fontsize=7)
    rates = []
    for label, pos in groups(sweep).items():
        pr = pass_rate(sweep, rows, pos)
        rates.append(f"{label + ': ' if label else ''}{pr['passes']} of {pr['n']} pass "
                     f"[{100 * pr['low']:.0f}, {100 * pr['high']:.0f}] %")
    fig.suptitle(f"{sweep.title or sweep.source.name} ({sweep.mode})\n" + "; ".join(rates),
                 fontsize=10)
    for _ in range(2):
        fig.tight_layout(rect=(0, 0, 1, 0.95))
        for ax in bottom:
            untangle_ticks(fig, ax)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _num(v):
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan
