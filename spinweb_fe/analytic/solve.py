"""The paper's analytical deployment model (Eqs. 4-8) for a case: mapping, integration,
the result file and its verdict.

:func:`spinweb_fe.analytic.models.params_from_case` maps a tether or web scene to the
parameters, :func:`devices_from_case` its payout device; :func:`solve_case` integrates the
model (:func:`spinweb_fe.analytic.integrate.integrate`: solve_ivp, DOP853, the regimes of
:mod:`spinweb_fe.analytic.regimes` and :mod:`spinweb_fe.analytic.devices` switched exactly
at events) and :func:`write` writes ``analytic.h5``. The control laws are those of the
solver's registry (:mod:`spinweb_fe.fe.control`), by their analytical forms. Derivation and
start-up treatment: docs/analytic.md.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from meshgen.registry import COILED_FOLDS
from spinweb_fe.analytic.integrate import (L0_FRACTION, MAX_SEGMENTS, AnalyticResult,  # noqa: F401
                                           integrate, start_state)
from spinweb_fe.analytic.models import params_from_case
from spinweb_fe.analytic.payout import Brake, Payout
from spinweb_fe.analytic.sample import drifts  # noqa: F401
from spinweb_fe.case.scene import control_from_case
from spinweb_fe.fe.coil.payout import PAYOUTS, payout_table
from spinweb_fe.record import verdict

log = logging.getLogger(__name__)


def _rate(control, t):
    return control.law.rate(control.params, t)


def solve_case(case, model: str = "consistent", tether_mass: bool = True,
               L0: float | None = None, rtol: float = 1e-10, atol: float = 1e-10) -> AnalyticResult:
    """Map a case, integrate the chosen model to ``time.end`` and return the result."""
    p = params_from_case(case, tether_mass=tether_mass)
    control = control_from_case(case)
    payout, brake = devices_from_case(case)
    if control.law.prescribes_rate and case.initial.omega != _rate(control, 0.0)[0]:
        log.info("%s starts from its own rate at t = 0: initial.omega = %g is not used",
                 control.law.name, case.initial.omega)
    coiled = case.fold.pattern in COILED_FOLDS
    res = integrate(p, control, model=model, t_end=case.time.end,
                    history_dt=case.output.history_dt, coiled=coiled, wrap=case.fold.wrap,
                    omega_init=case.initial.omega, spin=case.initial.spin, L0=L0,
                    rtol=rtol, atol=atol, payout=payout, brake=brake)
    eps_f = case.cable.failure_strain
    if eps_f and case.scene == "tethers":  # a tether's strain: its root tension over E A
        strain = res.history["max_tension"] / (case.cable.youngs_modulus * case.cable.area)
        res.history.update(max_strain=strain, utilisation=strain / eps_f)
    return res


def devices_from_case(case) -> tuple:
    """(Payout or None, Brake or None): the case's reel (its paid-out length law) or brake
    (its force law), fe.coil.payout.PAYOUTS; (None, None) for a free payout or a case without a
    coil.

    Raises
    ------
    ValueError
        For a gate, which has no analytical counterpart (a latch that does no work).
    """
    st = case.stowage
    code = None if st.payout is None else PAYOUTS[st.payout].code
    if code is None or code == PAYOUTS["free"].code:
        return None, None
    if code == PAYOUTS["gate"].code:
        raise ValueError("stowage.payout = 'gate' has no analytical counterpart (a latch "
                         "that does no work): use 'rate' (a reel) or 'brake'")
    table = payout_table(dataclasses.asdict(st))
    if code == PAYOUTS["rate"].code:
        return Payout(*table), None
    return None, Brake(*table)


def write(path, case, result: AnalyticResult, rtol: float, atol: float):
    """Write ``analytic.h5``: root attributes (model, tolerances, ...) and ``/history``."""
    import h5py

    from spinweb_fe.io.h5 import write_history, write_root_attrs

    p = result.params
    with h5py.File(path, "w") as h5:
        write_root_attrs(h5, case, model=result.model, rtol=rtol, atol=atol,
                         solver="scipy.integrate.solve_ivp DOP853",
                         arms=p.n, arm_length_H=p.H, hub_radius=p.r0, hub_inertia=p.J_hub,
                         tip_mass=p.m_tip, arm_mass_eq7=p.m_lin, arm_mass_uniform=p.m_uni,
                         start_length_L0=result.info["L0"],
                         start_energy_loss=result.info["start_loss"],
                         stopped=result.stopped,
                         switch_times=np.array([s[0] for s in result.switches], dtype=float))
        write_history(h5, result.history)
        verdict.write_group(h5, judge(case, result))


def judge(case, result: AnalyticResult) -> list:
    """The verdict of an analytical run (record.verdict): the criteria that a rigid arm
    model has (deployed, re-coil, swing, energy, momentum; not slack, strength, flatness)."""
    p = result.params
    # the model has no gravity gradient: its momentum audit holds whatever the case says
    terms = {**verdict.case_terms(case.to_dict()), "gravity": False}
    return verdict.judge(result.history, np.full(p.n, p.r0 + p.H), p.r0,
                         status=f"stopped: {result.stopped}" if result.stopped else "completed",
                         **terms)
