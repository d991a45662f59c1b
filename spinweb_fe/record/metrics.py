"""The registry of run metrics: the one definition of what a sweep's summary tabulates and
what a design minimises or bounds (name, sweep column, unit, what it measures, whether it
can be an objective or a bound), and :func:`compute`, which takes them all from a run's
history and verdict (FE and analytical alike). docs/design.md's table of metrics is
:func:`markdown` (tests/test_criteria.py holds them equal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from spinweb_fe.record import verdict


@dataclass(frozen=True)
class MetricDef:
    """One metric: its ``name`` (design files, design.csv), its sweep summary ``column``,
    ``unit``, what it ``measures``, whether a design may minimise it (``objective``) or
    bound it from above (``bound``), and the axis label of summary.png (``plot``, or '')."""

    name: str
    column: str
    unit: str
    measures: str
    objective: bool = True
    bound: bool = True
    plot: str = ""


METRICS = {m.name: m for m in (
    MetricDef("deploy_time", "deploy_time_s", "s", "the verdict's deployment time: the first "
              "history time from which every tip stays at least `verdict.deployed_fraction` "
              "of its deployed distance from the hub axis to the end (inf: not deployed)",
              plot="time to full deployment [s]"),
    MetricDef("peak_torque", "peak_hub_torque_Nm", "N m", "largest abs(hub torque) (for a "
              "prescribed rate, the torque it takes)", plot="peak |hub torque| [N m]"),
    MetricDef("peak_power", "peak_power_W", "W", "largest abs(hub torque x hub rate)"),
    MetricDef("swing", "swing_rad", "rad", "the verdict's in-plane swing after deployment "
              "(NaN: not deployed)", bound=False),
    MetricDef("max_tension", "max_tension_N", "N", "largest tension (analytic: at the arm's "
              "root or departure point; FE: any element)", plot="max tension [N]"),
    MetricDef("brake_force", "brake_force_N", "N", "largest tension at the payout device, "
              "reel or brake (`brake_tension`; NaN without one)"),
    MetricDef("strength", "utilisation", "1", "the largest utilisation, strain / "
              "`cable.failure_strain` (as a bound: `strength = true` is at most 1; analytic: "
              "tethers only, root tension / (E A eps_f); NaN without a failure strain)",
              objective=False),
    MetricDef("final_hub_omega", "final_hub_omega_rad_s", "rad/s", "hub rate at the end of "
              "the run", objective=False, bound=False, plot="final hub rate [rad/s]"),
)}
#: the objectives a design may minimise, and 'parameter' (the searched value itself)
OBJECTIVES = {**{k: (m.unit, m.measures) for k, m in METRICS.items() if m.objective},
              "parameter": ("", "the searched value itself (one searched key): the least M0")}
#: the metrics a design may bound from above (strength: a flag, utilisation <= 1)
BOUNDS = {k: (m.unit, m.measures) for k, m in METRICS.items() if m.bound}


def compute(h: dict, crits, reach, hub_radius: float, fraction: float,
            ea_fail: float | None = None) -> dict:
    """Every metric of a run (by name) from its history ``h`` and criteria ``crits``.

    Parameters
    ----------
    h : dict
        ``time``, ``hub_torque``, ``hub_omega``, ``max_tension``, and ``tip_position`` (FE)
        or ``arm_length``, ``arm_angle`` (analytical); ``brake_tension`` with a device.
    crits : list of record.verdict.Criterion
    reach : (n,) or float [m]
        Each tip's deployed distance from the axis (FE: verdict.reach_of; analytic r0 + H).
    hub_radius : float [m]
    fraction : float
        The case's verdict.deployed_fraction.
    ea_fail : float or None [N]
        E A eps_f of the cable: the analytical strength where the verdict has no
        utilisation (a rigid arm's root tension over it).
    """
    by = {c.name: c for c in crits}
    t = np.asarray(h["time"], float)
    M, w = np.asarray(h["hub_torque"], float), np.asarray(h["hub_omega"], float)
    radius = verdict.tip_radius(h, hub_radius)
    reach = np.broadcast_to(np.asarray(reach, float), radius.shape[1:])
    dep = verdict.deploy_time(t, radius, reach, fraction)
    tension = float(np.max(h["max_tension"]))
    sw, ov = by.get("swing"), by.get("overstrain")
    util = ov.value if ov is not None and ov.passed is not None else (
        tension / ea_fail if ea_fail else math.nan)
    return {"deploy_time": dep if math.isfinite(dep) else math.inf,
            "peak_torque": float(np.max(np.abs(M))), "peak_power": float(np.max(np.abs(M * w))),
            "swing": sw.value if sw is not None and sw.passed is not None else math.nan,
            "max_tension": tension,
            "brake_force": float(np.max(h["brake_tension"])) if "brake_tension" in h
            else math.nan,
            "strength": util, "final_hub_omega": float(w[-1])}


def columns(values: dict) -> dict:
    """The sweep summary's columns of :func:`compute`'s metrics."""
    return {METRICS[k].column: v for k, v in values.items()}


def markdown() -> str:
    """The table of metrics of docs/design.md."""
    rows = ["| metric (`minimise`, `[bounds]`) | sweep column | unit | objective | bound | "
            "measures |", "|---|---|---|---|---|---|"]
    for m in METRICS.values():
        rows.append(f"| `{m.name}` | `{m.column}` | {m.unit} | {'yes' if m.objective else '-'}"
                    f" | {'yes' if m.bound else '-'} | {m.measures} |")
    return "\n".join(rows)
