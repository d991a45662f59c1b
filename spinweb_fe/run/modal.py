"""A case's modes and design sweeps: the spin rate of a case, the steady state and the
lowest modes of its deployed web, and their dependence on the spin rate or the corner mass.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass

import numpy as np

from spinweb_fe.case.scene import NO_SPIN, deployed, spin_rate  # noqa: F401 (spin_rate: cli)
from spinweb_fe.errors import InputError, RunError
from spinweb_fe.linear.modes import Modes, compute_modes
from spinweb_fe.linear.steady import SteadyState, Structure, check_mechanism, solve_steady

log = logging.getLogger(__name__)

#: swept parameter -> (unit, what it changes)
SWEEP_PARAMS = {"omega": ("rad/s", "spin rate"), "tip_mass": ("kg", "corner (tip) mass")}
MAX_SWEEP_POINTS = 200


@dataclass(frozen=True)
class Analysis:
    """The steady state and lowest modes of a case's deployed web at one spin rate."""

    mesh: object  # meshgen.mesh.Mesh, the flat mesh
    structure: Structure
    steady: SteadyState
    modes: Modes


def analyse(case, omega: float, count: int, hub: str = "driven", built=None) -> Analysis:
    """Steady state (Newton) and the ``count`` lowest modes of the case's deployed web.

    Parameters
    ----------
    case : spinweb_fe.case.Case
    omega : float [rad/s]
    count : int
    hub : {'driven', 'coasting'}
    built : (mesh, Structure) or None
        The deployed web, if already built (:func:`spinweb_fe.case.scene.deployed`).

    Raises
    ------
    RunError
        No steady state, or slack elements make it a mechanism.
    """
    mesh, s = deployed(case) if built is None else built
    st = solve_steady(s, omega)
    check_mechanism(s, st)
    return Analysis(mesh, s, st, compute_modes(s, st, count, hub))


def parse_sweep(text: str):
    """'name=A:B:N' -> (name, (N,) float64 values from A to B); InputError if malformed."""
    name, sep, rng = str(text).partition("=")
    name = name.strip()
    if not sep or name not in SWEEP_PARAMS:
        raise InputError("--sweep", "", f"expected NAME=A:B:N with NAME one of "
                         f"{', '.join(SWEEP_PARAMS)}, got '{text}'")
    parts = rng.split(":")
    try:
        a, b, n = float(parts[0]), float(parts[1]), int(parts[2])
    except (IndexError, ValueError):
        raise InputError("--sweep", name, f"expected A:B:N (two numbers and a count), got "
                         f"'{rng}'") from None
    if len(parts) != 3 or not (math.isfinite(a) and math.isfinite(b)):
        raise InputError("--sweep", name, f"expected A:B:N with finite A, B, got '{rng}'")
    if not 1 <= n <= MAX_SWEEP_POINTS:
        raise InputError("--sweep", name, f"N must be in 1..{MAX_SWEEP_POINTS}, got {n}")
    values = np.linspace(a, b, n)
    if name == "omega" and np.any(values == 0.0):
        raise InputError("--sweep", name, f"the range {a:g}:{b:g}:{n} holds omega = 0: "
                         f"{NO_SPIN}")
    if name == "omega" and np.any(np.sign(values) != np.sign(values[0])):
        raise InputError("--sweep", name, "the range must not cross omega = 0")
    if name == "tip_mass" and np.any(values < 0):
        raise InputError("--sweep", name, f"masses must be >= 0, got {a:g}:{b:g}")
    return name, values


@dataclass(frozen=True)
class SweepPoint:
    """One value of a sweep: the spin rate and tip mass used, and the result (None when
    there is no steady state there; ``error`` says why)."""

    value: float
    omega: float
    tip_mass: float
    steady: SteadyState | None
    modes: Modes | None
    error: str = ""


def sweep(case, name: str, values, omega: float, count: int, hub: str = "driven") -> list:
    """Modes against the spin rate (``name`` = 'omega') or the corner mass ('tip_mass').

    Parameters
    ----------
    case : spinweb_fe.case.Case
    name : {'omega', 'tip_mass'}
    values : (p,) float64 [rad/s] or [kg]
    omega : float [rad/s]
        The spin rate of a tip_mass sweep.
    count : int
    hub : {'driven', 'coasting'}

    Returns
    -------
    list of SweepPoint
        A value without a steady state (RunError) is kept with ``modes`` None.

    Raises
    ------
    RunError
        If no value of the sweep has a steady state.
    """
    built = deployed(case) if name == "omega" else None
    points = []
    for v in np.asarray(values, float):
        c, w = case, omega
        if name == "omega":
            w = float(v)
        else:
            c = dataclasses.replace(case, tip_mass=dataclasses.replace(case.tip_mass,
                                                                       mass=float(v)))
        try:
            res = analyse(c, w, count, hub, built)
            points.append(SweepPoint(float(v), w, c.tip_mass.mass, res.steady, res.modes))
        except RunError as exc:
            log.warning("%s = %g: %s", name, v, exc)
            points.append(SweepPoint(float(v), w, c.tip_mass.mass, None, None, str(exc)))
        log.debug("sweep %s = %g done", name, v)
    if all(p.modes is None for p in points):
        raise RunError(f"no steady state at any {name} of the sweep: {points[0].error}")
    return points
