"""``spinweb design --chart``: the least value of one searched key, by bisection on the
analytical model, against one design input, with FE-checked points (docs/design.md, "Design
charts"). Outputs: :mod:`spinweb_fe.sweep.outputs`."""

from __future__ import annotations

import dataclasses
import logging
import math
import time
import tomllib
from pathlib import Path

import numpy as np

from spinweb_fe.errors import InputError
from spinweb_fe.sweep.design import Design, Evaluator, _num, bisect, check_cases, load_design
from spinweb_fe.sweep.run import flatten
from spinweb_fe.sweep.verify import run_fe

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


def run_chart(d: Design, client, out_dir: Path, show: bool = False) -> list:
    """Every chart row on Dask, then the FE checks: at each value of ``d.chart_fe`` one run
    at the least value times ``chart_factor`` (should pass) and one at it divided by the
    factor (should fail). Rows in chart order with ``fe_above`` / ``fe_below`` Points;
    ``show``: a progress bar per stage."""
    from dask.distributed import as_completed

    from spinweb_fe.run.progress import Stage

    futs = client.map(chart_row, [d] * len(d.chart_values), d.chart_values, pure=False)
    order = {f.key: i for i, f in enumerate(futs)}
    rows = [None] * len(futs)
    with Stage("chart rows (analytic)", len(futs), show) as st:
        for fut in as_completed(futs):
            rows[order[fut.key]] = fut.result()
            st.update(note=f"{d.chart_key} = {rows[order[fut.key]]['value']:g}")
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
        with Stage("chart FE checks", len(jobs), show) as st:
            pts = run_fe(d, client, [(name, vals, {d.chart_key: r["value"]})
                                     for r, _, name, vals in jobs], out_dir, st)
        for (r, side, _, _), p in zip(jobs, pts):
            r[f"fe_{side}"] = p
    return rows


