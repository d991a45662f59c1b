"""The outputs of a mesh convergence study: each quantity's estimate (sweep.gci), the
verdicts across the grids, ``converge.json``, ``converge.csv``, ``converge.png`` and the
printed table (docs/converge.md)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np

from spinweb_fe.record.verdict import CRITERIA
from spinweb_fe.sweep import gci
from spinweb_fe.sweep.converge import Plan
from spinweb_fe.sweep.quantities import units_of


def analyse(p: Plan, rows, safety: float = gci.SAFETY) -> dict:
    """The study's result (the content of ``converge.json``).

    Returns
    -------
    dict
        ``grids`` (coarsest first: name, h [m], the refined key's value, elements, dt [s],
        steps, status, wall time [s], passed, failed criteria); ``quantities`` (name, units,
        values per grid, and the :class:`gci.Estimate` fields with ``error_bar`` per grid in
        the grids' order); ``verdicts`` (per criterion: pass / fail per grid and the
        coarsest width from which on it no longer changes).
    """
    hs = [m.h for m in p.members]
    grids = []
    for m, r in zip(p.members, rows):
        info = r.get("info", {})
        passed = r.get("passed", {})
        ok = r["status"] == "ok"
        grids.append({"name": m.name, "h": m.h, "value": m.value,
                      "elements": info.get("elements"), "dt": info.get("dt"),
                      "steps": info.get("steps"), "status": r["status"],
                      "wall_time_s": r.get("wall_time_s"),
                      "passed": (all(v is not False for v in passed.values()) if ok else None),
                      "failed": [k for k, v in passed.items() if v is False]})
    quantities = []
    for q in p.quantities:
        vals = [r["values"].get(q, math.nan) for r in rows]
        none = all(not math.isfinite(v) for v in vals) and all(r["status"] == "ok" for r in rows)
        if none and q.startswith("margin."):
            continue  # the criterion does not apply to this case
        est = gci.study(hs, vals, safety)
        d = est.as_dict()
        if none:
            d["note"] = "no grid has a value: the event does not happen within the window"
        by_h = dict(zip(est.h, est.error_bar))  # finest first -> the grids' order
        d.update(error_bar=[by_h.get(h, math.nan) for h in hs],
                 used=[hs.index(est.h[i]) for i in est.used])
        del d["h"], d["phi"]
        quantities.append({"name": q, "units": units_of(q), "values": vals, **d})
    verdicts = []
    for c in CRITERIA:
        per = [r.get("passed", {}).get(c) if r["status"] == "ok" else None for r in rows]
        if all(v is None for v in per):
            continue
        verdicts.append({"criterion": c, "passed": per, "stable_from": gci.stable_from(hs, per)})
    overall = [g["passed"] for g in grids]
    verdicts.append({"criterion": "verdict", "passed": overall,
                     "stable_from": gci.stable_from(hs, overall)})
    ratios = [a / b for a, b in zip(hs, hs[1:])]
    return {"case": str(p.source), "title": p.title, "scene": p.scene, "key": p.key,
            "end": p.end, "times": list(p.times), "safety": safety, "ratios": ratios,
            "grids": grids, "quantities": quantities, "verdicts": verdicts}


def _clean(x):
    """JSON without NaN / infinity (null instead)."""
    if isinstance(x, dict):
        return {k: _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def write(result: dict, out_dir) -> dict:
    """Write ``converge.json``, ``converge.csv`` and ``converge.png`` into ``out_dir``;
    return their paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    paths = {k: out_dir / f"converge.{k}" for k in ("json", "csv", "png")}
    paths["json"].write_text(json.dumps(_clean(result), indent=1) + "\n")
    hs = [g["h"] for g in result["grids"]]
    head = ["quantity", "units", "kind", "order", "extrapolated", "gci_fine", "low", "high"]
    head += [f"value@{h:.6g}" for h in hs] + [f"error_bar@{h:.6g}" for h in hs]
    with open(paths["csv"], "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(head)
        for q in result["quantities"]:
            w.writerow([q["name"], q["units"], q["kind"]] + [
                repr(float(q[k])) for k in ("order", "extrapolated", "gci_fine", "low", "high")]
                + [repr(float(v)) for v in q["values"]] + [repr(float(v)) for v in q["error_bar"]])
    plot(result, paths["png"])
    return paths


def _fmt(v, digits=4) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.{digits}g}"


def lines(result: dict) -> list:
    """The printed report: one line per quantity, then the verdicts."""
    hs = [g["h"] for g in result["grids"]]
    out = ["grids: " + ", ".join(f"{g['name']} ({g['status']}"
                                 + (f", {g['elements']} elements" if g["elements"] else "")
                                 + ")" for g in result["grids"]),
           f"{'quantity':<22} " + " ".join(f"{'h=' + _fmt(h):>11}" for h in hs)
           + f"  {'kind':<11} {'order':>6} {'extrapolated':>12} {'GCI fine':>9}  "
           + "error bar at each h"]
    for q in result["quantities"]:
        gci_pc = f"{100 * q['gci_fine']:.3g} %" if math.isfinite(q["gci_fine"]) else "-"
        bars = ", ".join(_fmt(b, 3) for b in q["error_bar"])
        tail = (f"  range [{_fmt(q['low'])}, {_fmt(q['high'])}]" if q["kind"] in (
            "oscillatory", "divergent") else f"  ({q['note']})" if q["note"] and q["kind"]
            == "monotone" else "")
        out.append(f"{q['name']:<22} " + " ".join(f"{_fmt(v):>11}" for v in q["values"])
                   + f"  {q['kind']:<11} {_fmt(q['order'], 3):>6} "
                   f"{_fmt(q['extrapolated'], 6):>12} {gci_pc:>9}  {bars} [{q['units']}]"
                   + tail)
    for v in result["verdicts"]:
        marks = " ".join({True: "pass", False: "FAIL", None: "n/a"}[x] for x in v["passed"])
        out.append(f"{v['criterion']:<11} {marks}: the same from h = {_fmt(v['stable_from'])} "
                   "m on" if math.isfinite(v["stable_from"]) else f"{v['criterion']:<11} "
                   f"{marks}")
    return out


def plot(result: dict, path):
    """One panel per quantity: its values against the mesh size with their error bars,
    the fitted h^p curve, the extrapolated value at h = 0 and the finest grid's band
    (shaded; without an order the values' range)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    qs = result["quantities"]
    n = max(1, len(qs))
    cols = min(4, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 2.9 * rows), squeeze=False)
    hs = np.array([g["h"] for g in result["grids"]])
    for ax, q in zip(axes.flat, qs):
        v = np.array(q["values"], float)
        bar = np.array(q["error_bar"], float)
        ok = np.isfinite(v)
        if not ok.any():
            ax.text(0.5, 0.5, "no value on any grid", ha="center", va="center",
                    transform=ax.transAxes, fontsize=8)
        ax.errorbar(hs[ok], v[ok], yerr=np.where(np.isfinite(bar), bar, 0.0)[ok], fmt="o",
                    color="C0", capsize=3, label="grids")
        if math.isfinite(q["low"]) and math.isfinite(q["high"]):
            ax.axhspan(q["low"], q["high"], color="C1", alpha=0.2,
                       label="finest grid's band" if q["kind"] == "monotone" else "range")
        if q["kind"] == "monotone":
            f1, h1 = v[q["used"][0]], hs[q["used"][0]]
            x = np.linspace(0.0, hs.max(), 100)
            c = (f1 - q["extrapolated"]) / h1 ** q["order"]
            ax.plot(x, q["extrapolated"] + c * x ** q["order"], "C0--", lw=1)
            ax.plot([0.0], [q["extrapolated"]], "*", color="C3", ms=10, label="extrapolated")
        title = (f"p = {q['order']:.2f}, GCI {100 * q['gci_fine']:.2g} %"
                 if q["kind"] == "monotone" else q["kind"])
        ax.set_title(f"{q['name']} [{q['units']}]\n{title}", fontsize=8)
        ax.set_xlim(left=0.0)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("mesh size h [m]", fontsize=7)
    for ax in list(axes.flat)[len(qs):]:
        ax.axis("off")
    if qs:
        axes.flat[0].legend(fontsize=6)
    fig.suptitle(f"{result['title'] or result['case']}: mesh convergence to "
                 f"t = {result['end']:g} s", fontsize=9)
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.97))
    fig.savefig(path, dpi=110)
    plt.close(fig)
