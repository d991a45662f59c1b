"""The quantities of interest of a convergence study: their names, units, and their values
from a result file (docs/converge.md).

Names: ``COLUMN@T`` a history column at time T (linear between rows; per-arm columns
averaged over the arms, vectors by their length), ``COLUMN@max|min|end|mean`` over the
window, ``tip_radius`` (the tips' distance from the axis) as a column, ``deploy_time`` (the
first time every tip is at the verdict's deployed share of its reach, between rows),
``peak_tension``, ``peak_utilisation``, ``margin.<criterion>`` (the verdict's margin:
1 - value/limit, for ``deployed`` value/limit - 1; negative fails).
"""

from __future__ import annotations

import math
import tomllib

import numpy as np

from spinweb_fe.errors import InputError
from spinweb_fe.fe.layout import VECTOR
from spinweb_fe.record import verdict
from spinweb_fe.record.history import COLUMNS

#: named quantities: name -> (units, meaning)
NAMED = {"deploy_time": ("s", "first time every tip is at the verdict's deployed share of "
                              "its reach (NaN: never)"),
         "peak_tension": ("N", "largest max_tension of the run"),
         "peak_utilisation": ("1", "largest utilisation (strain / failure strain)")}
REDUCE = ("max", "min", "end", "mean")
DERIVED = {"tip_radius": ("m", "the tips' distance from the hub axis")}
#: the history's vector columns (one vector per row)
VECTORS = tuple(c.name for c in VECTOR if c.width > 1)


def default_quantities(case, times) -> tuple:
    """Hub rate (the hub torque where the law prescribes the rate) and mean arm length at
    ``times`` and their means over the window, deployment time, peak tension (and
    utilisation with a failure strain), and the margins of the verdict's criteria."""
    from spinweb_fe.fe.control import LAWS

    hub = "hub_torque" if LAWS[case.control.law].prescribes_rate else "hub_omega"
    out = [f"{hub}@{t:g}" for t in times] + [f"arm_length@{t:g}" for t in times]
    out += [f"{hub}@mean", "arm_length@mean", "deploy_time", "peak_tension"]
    if case.cable.failure_strain is not None:
        out += ["peak_utilisation", "margin.overstrain"]
    from spinweb_fe.record.criteria import GENERAL

    out += [f"margin.{c}" for c in GENERAL]
    return tuple(out)

def parse_quantity(name: str) -> tuple:
    """(kind, column or criterion, at) of a quantity name; InputError if unknown."""
    if name in NAMED:
        return "named", name, None
    if name.startswith("margin."):
        crit = name.split(".", 1)[1]
        if crit not in verdict.CRITERIA or crit == "completed":
            valid = ", ".join(c for c in verdict.CRITERIA if c != "completed")
            raise InputError("--quantity", name, f"no criterion '{crit}' (valid: {valid})")
        return "margin", crit, None
    col, sep, at = name.partition("@")
    if not sep or (col not in COLUMNS and col not in DERIVED):
        raise InputError("--quantity", name, "unknown: give COLUMN@TIME or COLUMN@max|min|"
                         f"end|mean (a history column), or one of {', '.join(NAMED)}, "
                         "margin.<criterion>")
    if at in REDUCE:
        return "column", col, at
    try:
        return "column", col, float(at)
    except ValueError:
        raise InputError("--quantity", name, f"'{at}' is neither a time [s] nor one of "
                         f"{', '.join(REDUCE)}") from None


def units_of(name: str) -> str:
    kind, what, _ = parse_quantity(name)
    if kind == "named":
        return NAMED[what][0]
    if kind == "margin":
        return "1"
    return (DERIVED.get(what) or COLUMNS[what])[0]


# -- on the worker ------------------------------------------------------------------------

def _series(h: dict, col: str, hub_radius: float):
    """(T,) the column as one number per row: per-arm columns averaged over the arms,
    vectors by their length (per arm, then averaged); None if the run has no such column."""
    if col == "tip_radius":
        x = verdict.tip_radius(h, hub_radius)
    elif col in h:
        x = np.asarray(h[col], dtype=float)
    else:
        return None
    if x.ndim == 3 or (x.ndim == 2 and col in VECTORS):
        x = np.linalg.norm(x, axis=-1)
    return x.mean(axis=1) if x.ndim == 2 else x


def _margin(c) -> float:
    if c is None or c.passed is None or not (math.isfinite(c.value) and c.limit > 0):
        return math.nan
    if c.name == "deployed" and c.units == "1":
        return c.value / c.limit - 1.0
    return 1.0 - c.value / c.limit


def quantities_of(path, names) -> tuple:
    """({name: value}, {criterion: passed or None}) of a result file ``results.h5``."""
    import h5py

    from spinweb_fe.io.mesh import read_mesh_group

    with h5py.File(path, "r") as h5:
        mesh = read_mesh_group(h5["mesh"])
        case = tomllib.loads(str(h5.attrs.get("case", "")))
        h = {k: h5["history"][k][()] for k in h5["history"]}
        crits = verdict.read_group(h5) or []
        info = {"dt": float(h5.attrs.get("dt", math.nan)),
                "steps": int(h5.attrs.get("steps", 0)), "elements": int(mesh.n_elems)}
    by = {c.name: c for c in crits}
    t = np.asarray(h["time"], dtype=float)
    out = {}
    for name in names:
        kind, what, at = parse_quantity(name)
        if kind == "margin":
            out[name] = _margin(by.get(what))
        elif what == "deploy_time":
            frac = verdict.limits_of(case.get("verdict"))["deployed_fraction"]
            share = verdict.tip_radius(h, mesh.hub_radius) / verdict.reach_of(mesh)
            out[name] = first_crossing(t, share.min(axis=1) - frac)
        elif kind == "named":
            col = "max_tension" if what == "peak_tension" else "utilisation"
            out[name] = float(np.max(h[col])) if col in h else math.nan
        else:
            x = _series(h, what, mesh.hub_radius)
            out[name] = math.nan if x is None else _reduce(t, x, at)
    passed = {c.name: c.passed for c in crits}
    return out, passed, info


def first_crossing(t, x) -> float:
    """[s] the first time ``x`` reaches 0 from below, linear between the rows (not the
    history's row: a time quantised to the row interval has no order); NaN: never."""
    above = np.flatnonzero(x >= 0.0)
    if len(above) == 0:
        return math.nan
    i = int(above[0])
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (t[i] - t[i - 1]) * (-x[i - 1]) / (x[i] - x[i - 1]))


def _reduce(t, x, at) -> float:
    if at == "max":
        return float(np.max(x))
    if at == "min":
        return float(np.min(x))
    if at == "end":
        return float(x[-1])
    if at == "mean":
        return float(np.trapezoid(x, t) / (t[-1] - t[0])) if t[-1] > t[0] else float(x[0])
    if not t[0] - 1e-9 <= at <= t[-1] + 1e-9:
        return math.nan
    return float(np.interp(at, t, x))
