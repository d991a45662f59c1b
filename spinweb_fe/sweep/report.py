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
    cols = ["index", "name", *sweep.keys, *(m for m, _, _ in METRICS), "status", "run_dir"]
    out = []
    for run, row in zip(sweep.runs, rows):
        out.append([run.index, run.name, *(run.values[k] for k in sweep.keys),
                    *(row.get(m, math.nan) for m, _, _ in METRICS), row["status"],
                    f"runs/{run.name}"])
    return cols, out


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
    that vary independently of it; failed runs are left out, re-coiled runs ringed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    xkey = sweep.keys[0] if sweep.keys else "index"
    xs = [r.values[xkey] if sweep.keys else r.index for r in sweep.runs]
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in xs)
    cats = list(dict.fromkeys(map(str, xs)))
    series = _series_keys(sweep) if sweep.keys else []
    groups = {}
    for run, row, xv in zip(sweep.runs, rows, xs):
        groups.setdefault(_line_label(sweep, run, series), []).append(
            (xv if numeric else cats.index(str(xv)), row))
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    for ax, (metric, ylabel) in zip(axes.flat, PLOTTED.items()):
        for colour, (label, pts) in enumerate(groups.items()):
            pts = sorted(pts, key=lambda p: p[0])
            x = np.array([p[0] for p in pts], dtype=float)
            y = np.array([p[1].get(metric, math.nan) for p in pts], dtype=float)
            if np.all(np.isnan(y)):  # every run of this line failed
                continue
            ax.plot(x, y, "o-", color=f"C{colour % 10}", label=label or None)
            rec = np.array([p[1].get("recoiled") == 1.0 for p in pts])
            if rec.any():
                ax.plot(x[rec], y[rec], "o", ms=12, mfc="none", mec="red", mew=1.5)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    ticks = sorted(set(xs)) if numeric else []
    for ax in axes.flat:
        if not numeric:
            ax.set_xticks(range(len(cats)), cats, rotation=30)
            continue
        if min(xs) > 0 and max(xs) > 10 * min(xs):
            ax.set_xscale("log")
        if len(ticks) <= 8:  # label the swept values themselves
            ax.set_xticks(ticks, [f"{v:.4g}" for v in ticks])
            ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    for ax in axes[1]:
        ax.set_xlabel(_key_label(xkey))
    handles = {}
    for ax in axes.flat:  # one legend entry per line, whichever panel drew it
        handles.update(zip(*reversed(ax.get_legend_handles_labels())))
    top = 0.95
    if handles:
        fig.legend(handles.values(), handles.keys(), loc="upper center", fontsize=8,
                   ncol=min(3, len(handles)), bbox_to_anchor=(0.5, 0.955), frameon=False)
        top = 0.955 - 0.03 * math.ceil(len(handles) / 3)
    n_fail = sum(r["status"] != "ok" for r in rows)
    fig.suptitle(f"{sweep.title or sweep.source.name} ({sweep.mode}; "
                 f"{len(rows) - n_fail} ok, {n_fail} failed; red ring: re-coiled)", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, top))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
