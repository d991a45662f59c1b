"""The paper's analytical deployment model (Eqs. 4-8): case mapping and integration.

:func:`spinweb_fe.analytic.models.params_from_case` maps a tether or web scene to the parameters;
:func:`integrate` integrates the model with ``scipy.integrate.solve_ivp`` (DOP853, tight
tolerances), switching exactly between the coiled and pivoting regimes at the events
phi = +-pi/2, and samples the ``/history`` datasets of :mod:`spinweb_fe.record.history`
every ``history_dt``. :func:`solve_case` does both for a case. The control laws are those
of the solver's registry (:mod:`spinweb_fe.fe.control`), by their analytical forms.
Equations: :mod:`spinweb_fe.analytic.models`; derivation and start-up treatment:
docs/analytic.md.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from meshgen.registry import COILED_FOLDS
from spinweb_fe.analytic import braking
from spinweb_fe.analytic import payout as pay_mod
from spinweb_fe.analytic.models import (
    HALF_PI,
    MODELS,
    ArmParams,
    accelerations,
    invariants,
    params_from_case,
    root_tension,
    solve_rows,
    tip_rate,
)
from spinweb_fe.analytic.payout import Brake, Payout
from spinweb_fe.case.scene import control_from_case
from spinweb_fe.fe.control import Control
from spinweb_fe.fe.coil.payout import PAYOUTS, payout_table
from spinweb_fe.record import verdict

log = logging.getLogger(__name__)

#: default start-up free length as a fraction of H (the fully coiled L = 0 is singular)
L0_FRACTION = 1e-4
#: guard against chattering between regimes
MAX_SEGMENTS = 100_000


def _torque(control: Control, t: float, omega: float) -> float:
    """Applied torque [N m] of a torque law (the law's analytical form)."""
    return control.law.torque(control.params, t, omega)


def _rate(control: Control, t: float) -> tuple[float, float]:
    """Prescribed (omega [rad/s], omega_dot [rad/s^2]) of a rate law at time t."""
    return control.law.rate(control.params, t)


def _breaks(control: Control, t_end: float) -> list[float]:
    """Times at which the right-hand side is discontinuous (integration restarts there)."""
    return [b for b in control.law.breaks(control.params) if b < t_end]


@dataclass
class AnalyticResult:
    """Sampled history (dict of arrays, names as in ``results.HISTORY_UNITS``) and run info."""

    history: dict
    params: ArmParams
    model: str
    switches: list = field(default_factory=list)   # (time, phi, new regime)
    stopped: str = ""                               # non-empty if stopped before t_end
    info: dict = field(default_factory=dict)


def start_state(p: ArmParams, control: Control, coiled: bool, wrap: str, omega_init: float,
                  spin: str, L0: float | None = None, model: str = "consistent"):
    """Start state (phi, omega, Psi, regime).

    Coiled start: L = 0 is singular, so the arm starts *captured* (wound and turning rigidly
    with the hub, Psi = omega) with a small free length L0 (default ``L0_FRACTION`` H),
    phi0 = -+(pi/2 + (H - L0)/r0) for a trailing/leading wrap; it is released as soon as
    the free-arm equations would unwind it (see :func:`simulate`). Straight start: phi0 = 0,
    L = H, pivoting. spin='all': the arms co-rotate with the hub (Psi = omega_init).
    spin='hub': a captured (coiled) arm is tied to the hub, so the start is a momentum-
    conserving inelastic coupling omega = J_hub omega_init / J_captured (the loss is
    reported); straight arms start non-rotating (Psi = 0). spin_ramp starts from omega = 0.
    """
    if coiled:
        L0 = L0_FRACTION * p.H if L0 is None else L0
        if not 0.0 < L0 < p.H:
            raise ValueError(f"start-up free length L0 = {L0} m must be in (0, H)")
        sign = -1.0 if wrap == "trailing" else 1.0
        phi0, regime = sign * (HALF_PI + (p.H - L0) / p.r0), "captured"
    else:
        phi0, regime = 0.0, "pivoting"
    if control.law.prescribes_rate:
        omega = _rate(control, 0.0)[0]
        return phi0, omega, omega, regime
    if spin == "all":
        return phi0, omega_init, omega_init, regime
    if coiled:
        omega = p.J_hub * omega_init / _captured_inertia(model, p, L0)
        return phi0, omega, omega, regime
    return phi0, omega_init, 0.0, regime


def _captured_inertia(model, p, L):
    """Inertia of hub + captured arms (free part frozen in the coil) in each model."""
    m_f, S, I = p.moments(L)
    base = p.J0 if model == "consistent" else p.J_hub + p.n * p.r0 ** 2 * m_f
    return base + p.n * I


def _law(pay, p, t):
    """(L, L') of the payout law at t, L at most H."""
    L, Ld = pay.at(t)
    return (p.H, 0.0) if L >= p.H else (L, Ld)


def _accel(model, p, control, regime, t, phi, omega, psi, pay=None, w=1.0):
    """(omega', Psi', M) in any regime; captured arms turn with the hub (Psi = omega)."""
    if regime == "paying":
        coeffs = pay_mod.rows(p, phi, omega, psi, *_law(pay, p, t), w)
        if control.law.prescribes_rate:
            return solve_rows(coeffs, omega_dot=_rate(control, t)[1])
        return solve_rows(coeffs, torque=_torque(control, t, omega))
    coiled = regime != "pivoting"
    if regime == "captured":
        J = _captured_inertia(model, p, p.H - p.r0 * (abs(phi) - HALF_PI))
        if control.law.prescribes_rate:
            wd = _rate(control, t)[1]
            return wd, wd, J * wd
        M = _torque(control, t, omega)
        return M / J, M / J, M
    if control.law.prescribes_rate:
        return accelerations(model, p, phi, omega, psi, coiled, omega_dot=_rate(control, t)[1])
    return accelerations(model, p, phi, omega, psi, coiled, torque=_torque(control, t, omega))


def _release(model, p, control, t, y):
    """> 0 while a captured arm stays wound: sigma * phi'' of the free coiled equations."""
    phi, omega = y[1], y[2]
    wd, pd, _ = _accel(model, p, control, "coiled", t, phi, omega, omega)
    return math.copysign(1.0, phi) * (pd - wd)


def _rhs_factory(model, p, control, regime, pay, w, brake=None):
    if regime in braking.REGIMES:
        return braking.rhs_factory(p, control, regime, brake, w)
    tail = [] if brake is None else [0.0, 0.0]  # a brake's (L, L') wait in its state

    def rhs(t, y):
        omega_dot, psi_dot, M = _accel(model, p, control, regime, t, y[1], y[2], y[3], pay, w)
        # y = theta, phi, omega, Psi, torque work W, torque impulse P (, L, L')
        return [y[2], y[3] - y[2], omega_dot, psi_dot, M * y[2], M, *tail]
    return rhs


def _events(model, p, control, regime, phi_now, L_min, pay, w, t_now, brake=None):
    """Terminal events of a regime (their order is their meaning in :func:`integrate`)."""
    sigma = 1.0 if phi_now > 0 else -1.0
    if regime in braking.REGIMES:
        return braking.events(p, control, regime, brake, w)
    if regime == "captured" and brake is not None:
        def swings(t, y):         # the stick equations swing the arm off its coil
            wd, pd, _, _ = braking.accel(p, control, "stick", t, y, w, brake)
            return w * (pd - wd)
        swings.terminal, swings.direction = True, 1.0
        return [swings]
    if regime == "captured":
        if pay is not None and _law(pay, p, t_now)[0] < 2.0 * L_min:
            def allowed(t, y):     # the law lets the start-up length out
                return _law(pay, p, t)[0] - 2.0 * L_min
            allowed.terminal, allowed.direction = True, 1.0
            return [allowed]

        def release(t, y):
            return _release(model, p, control, t, y)
        release.terminal, release.direction = True, -1.0
        return [release]
    if regime == "coiled":
        def leave(t, y):           # |phi| back to pi/2: the arm starts pivoting
            return sigma * y[1] - HALF_PI

        def wound(t, y):           # free length down to L_min: captured by the hub
            return p.H - p.r0 * (sigma * y[1] - HALF_PI) - L_min
        leave.terminal = wound.terminal = True
        leave.direction = wound.direction = -1.0
        if pay is None:
            return [leave, wound]

        def binds(t, y):           # the free length reaches the law's: the law holds it
            return p.H - p.r0 * (sigma * y[1] - HALF_PI) - _law(pay, p, t)[0]
        binds.terminal, binds.direction = True, 1.0
        return [leave, wound, binds]
    if regime == "paying":
        def beta(t, y):
            return y[1] + w * (p.H - _law(pay, p, t)[0]) / p.r0

        def slack(t, y):           # back to the tangent: the arm pulls less than the law
            return w * beta(t, y) + HALF_PI

        def over(t, y):            # swings over its held coil
            return w * beta(t, y) - HALF_PI

        def full(t, y):            # everything paid out: pivoting about the root
            return _law(pay, p, t)[0] - p.H * (1.0 - 1e-12)
        slack.terminal = over.terminal = full.terminal = True
        slack.direction, over.direction, full.direction = -1.0, 1.0, 1.0
        return [slack, over, full]

    def up(t, y):
        return y[1] - HALF_PI

    def down(t, y):
        return y[1] + HALF_PI
    up.terminal = down.terminal = True
    up.direction, down.direction = 1.0, -1.0
    return [up, down]


def integrate(p: ArmParams, control: Control, *, model: str = "consistent", t_end: float,
             history_dt: float, coiled: bool = True, wrap: str = "trailing",
             omega_init: float = 8 * math.pi, spin: str = "all", L0: float | None = None,
             rtol: float = 1e-10, atol: float = 1e-10, method: str = "DOP853",
             payout: Payout | None = None, brake: Brake | None = None) -> AnalyticResult:
    """Integrate the model from t = 0 to ``t_end`` and sample the history.

    Three regimes, switched exactly by solve_ivp events: ``pivoting`` (|phi| <= pi/2, L = H),
    ``coiled`` (|phi| > pi/2, L = H - r0 (|phi| - pi/2)) and ``captured`` (a fully wound arm,
    L <= L0, turning rigidly with the hub). A captured arm is released when the coiled
    equations give sigma phi'' < 0 (it would unwind); a coiled arm whose free length falls to
    L0/2 is captured by a momentum-conserving inelastic impact, whose energy loss is
    recorded as ``contact_dissipation``.

    Parameters
    ----------
    p : ArmParams
    control : Control
    model : {'printed', 'consistent'}
    t_end, history_dt : float [s]
    coiled : bool
        Start fully coiled (True) or straight and radial (False).
    wrap : {'trailing', 'leading'}
        Coil direction relative to a positive spin.
    omega_init : float [rad/s]
        Initial hub rate (ignored by spin_ramp, which starts from 0).
    spin : {'all', 'hub'}
    L0 : float [m], optional
        Start-up free length of a coiled start (default ``L0_FRACTION`` H).
    rtol, atol : float
        solve_ivp tolerances; atol applies to angles [rad] and rates [rad/s], the torque
        work and impulse use atol scaled by the initial energy and momentum.
    payout : Payout or None
        A reel (consistent model only): the free length never exceeds the law's; while the
        law holds it the arm is ``paying`` (:mod:`spinweb_fe.analytic.payout`).
    brake : Brake or None
        A brake at D (consistent model only; not with a payout): the arm sticks or slips
        (:mod:`spinweb_fe.analytic.braking`). With a reel or a brake the history gains the
        device's ``brake_work``, ``brake_tension`` and ``payout_speed`` per arm.

    Returns
    -------
    AnalyticResult
    """
    if model not in MODELS:
        raise ValueError(f"unknown model '{model}' (valid: {', '.join(MODELS)})")
    if (payout is not None or brake is not None) and model != "consistent":
        raise ValueError("the payout devices are defined for the consistent model only")
    w = 1.0 if wrap == "trailing" else -1.0
    phi0, omega0, psi0, regime = start_state(p, control, coiled, wrap, omega_init, spin, L0,
                                             model)
    L_start = p.H - p.r0 * max(0.0, abs(phi0) - HALF_PI)
    L_min = 0.5 * L_start
    prescribed = control.law.prescribes_rate
    E_init = 0.5 * (p.J_hub if spin == "hub" and coiled and not prescribed
                    else 0.0) * omega_init ** 2
    E0, K0 = invariants(p, phi0, omega0, psi0, regime != "pivoting")
    w_law = (max(abs(_rate(control, t)[0]) for t in _breaks(control, math.inf) + [t_end])
             if prescribed else 0.0)
    w_scale = max(abs(omega_init), w_law, 1.0)
    atol_v = np.array([atol, atol, atol * w_scale, atol * w_scale,
                       atol * max(E0, p.J0 * w_scale ** 2), atol * max(abs(K0), p.J0 * w_scale)])
    y = np.array([0.0, phi0, omega0, psi0, 0.0, 0.0])
    if brake is not None:  # (L, L') of the brake's regimes
        y = np.concatenate([y, [L_start, 0.0]])
        atol_v = np.concatenate([atol_v, [atol * p.H, atol * p.H * w_scale]])
    t, segments, switches, stopped, lost = 0.0, [], [], "", 0.0
    stops = sorted(set(_breaks(control, t_end) + (payout.breaks(t_end) if payout else [])
                       + (brake.breaks(t_end) if brake else []) + [t_end]))
    while t < t_end and not stopped:
        if len(segments) > MAX_SEGMENTS:
            stopped = f"more than {MAX_SEGMENTS} regime switches by t = {t:.6g} s (chattering)"
            break
        if regime == "captured" and brake is not None and braking.released(
                p, control, t, y, w, brake):
            regime = "stick"
            switches.append((t, y[1], regime))
        elif regime == "captured" and brake is None and _release(
                model, p, control, t, y) < 0 and (
                payout is None or _law(payout, p, t)[0] >= 2.0 * L_min):
            regime = "coiled"
            switches.append((t, y[1], regime))
        t_stop = next(b for b in stops if b > t)
        sol = solve_ivp(_rhs_factory(model, p, control, regime, payout, w, brake), (t, t_stop),
                        y, method=method, rtol=rtol, atol=atol_v, dense_output=True,
                        events=_events(model, p, control, regime, y[1], L_min, payout, w, t,
                                       brake))
        if sol.status < 0:
            stopped = f"solve_ivp failed at t = {sol.t[-1]:.6g} s: {sol.message}"
        segments.append((t, sol.t[-1], sol.sol, regime, lost))
        t, y = sol.t[-1], sol.y[:, -1].copy()
        if sol.status != 1:
            continue
        hit = [i for i, te in enumerate(sol.t_events) if len(te)][0]
        if regime in braking.REGIMES:
            regime, stopped = braking.switch(regime, hit, t)  # pivoting: beta = phi
        elif regime == "captured" and brake is not None:
            regime = "stick"
        elif regime == "captured":
            if payout is None or _law(payout, p, t)[0] >= 2.0 * L_min:
                regime = "coiled"
        elif regime == "coiled" and hit == 2:     # the law holds the arm back
            regime = "paying"
        elif regime == "paying":
            if hit == 1:
                stopped = (f"at t = {t:.6g} s the arm swings over its held coil: the "
                           "analytical rate payout ends here")
                break
            regime = "coiled" if hit == 0 else "pivoting"
        elif regime == "coiled" and hit == 1:     # inelastic capture, K conserved
            E_before, K = invariants(p, y[1], y[2], y[3], True)
            m_f, S, I = p.moments(L_min)
            y[2] = y[3] = (K if model == "consistent" else
                           (p.J_hub + p.n * p.r0 ** 2 * m_f) * y[2] + p.n * I * y[3]) \
                / _captured_inertia(model, p, L_min)
            lost += E_before - invariants(p, y[1], y[2], y[3], True)[0]
            regime = "captured"
        else:
            y[1] = math.copysign(HALF_PI, y[1])
            regime = "pivoting" if regime == "coiled" else "coiled"
        switches.append((t, y[1], regime))
    hist = _sample(model, p, control, segments, history_dt, t_end, payout, w, brake)
    info = {"E0": E0, "K0": K0, "L0": L_start,
            "start_loss": E_init - E0 if E_init else 0.0, "contact_loss": lost}
    if stopped:
        log.warning("analytic model stopped early: %s", stopped)
    return AnalyticResult(hist, p, model, switches, stopped, info)


def _sample(model, p, control, segments, dt, t_end, pay=None, w=1.0, brake=None):
    n_out = int(math.floor(t_end / dt + 1e-9)) + 1
    times = np.arange(n_out) * dt
    times = times[times <= segments[-1][1] + 1e-12]
    names = ("hub_angle", "hub_omega", "hub_torque", "kinetic_energy", "torque_work",
             "angular_momentum", "max_tension", "L", "phi", "tip", "impulse", "lost",
             "device", "speed")
    cols = {k: np.empty(len(times)) for k in names}
    k = 0
    for i, (ta, tb, dense, regime, lost) in enumerate(segments):
        last = i == len(segments) - 1
        coiled = regime != "pivoting"
        while k < len(times) and (times[k] < tb or (last and times[k] <= tb + 1e-12)):
            tk = min(times[k], tb)
            y = dense(tk)
            theta, phi, omega, psi, work, imp = y[:6]
            if regime in braking.REGIMES:
                M = braking.accel(p, control, regime, tk, y, w, brake)[3]
                E, K, N, L, Ld, tip = braking.sample(p, control, regime, tk, y, w, brake)
                vals = (theta, omega, M, E, work, K, N, L, phi, tip, imp, lost, N, Ld)
            else:
                r = _sample_row(model, p, control, regime, tk, y, pay, w, coiled)
                vals = r[:11] + (lost,) + r[11:]
            for name, v in zip(names, vals):
                cols[name][k] = v
            k += 1
    n, zeros = p.n, np.zeros(len(times))

    def per_arm(v):
        return np.repeat(v[:, None], n, axis=1)
    out = {"time": times, "hub_angle": cols["hub_angle"], "hub_omega": cols["hub_omega"],
           "hub_torque": cols["hub_torque"], "kinetic_energy": cols["kinetic_energy"],
           "strain_energy": zeros, "torque_work": cols["torque_work"],
           "damping_dissipation": zeros.copy(), "contact_dissipation": cols["lost"],
           "angular_momentum": cols["angular_momentum"], "max_tension": cols["max_tension"],
           "arm_length": per_arm(cols["L"]), "arm_angle": per_arm(cols["phi"]),
           "tip_omega": per_arm(cols["tip"]), "torque_impulse": (cols["impulse"], "N m s")}
    if pay is not None or brake is not None:  # the device's work: E - E0 - W + losses
        out["brake_work"] = per_arm((cols["kinetic_energy"] + cols["lost"]
                                     - cols["kinetic_energy"][0] - cols["torque_work"]) / n)
        out["brake_tension"] = per_arm(cols["device"])
        out["payout_speed"] = per_arm(cols["speed"])
    return out


def _sample_row(model, p, control, regime, t, y, pay, w, coiled):
    """(theta, omega, M, E, W, K, N, L, phi, tip rate, impulse, N at the device, L') of a
    state of the coiled, captured, pivoting or paying regime."""
    theta, phi, omega, psi, work, imp = y[:6]
    wd, _, M = _accel(model, p, control, regime, t, phi, omega, psi, pay, w)
    if regime == "paying":
        L, Ld = _law(pay, p, t)
        E, K = pay_mod.invariants(p, phi, omega, psi, L, Ld, w)
        N = pay_mod.tension(p, phi, omega, psi, wd, L, Ld, w)
        tip = pay_mod.tip_rate(p, phi, omega, psi, L, Ld, w)
        dev = pay_mod.line_tension(p, phi, omega, psi, wd, L, Ld, 0.0, w)
        return theta, omega, M, E, work, K, N, L, phi, tip, imp, dev, Ld
    E, K = invariants(p, phi, omega, psi, coiled)
    L = p.H - p.r0 * max(0.0, abs(phi) - HALF_PI) if coiled else p.H
    N = root_tension(p, phi, omega, psi, wd, coiled)
    tip = tip_rate(p, phi, omega, psi, coiled)
    held = regime == "coiled"  # the coil holds the line at its tangent point
    speed = -p.r0 * math.copysign(1.0, phi) * (psi - omega) if held else 0.0
    return theta, omega, M, E, work, K, N, L, phi, tip, imp, N if held else 0.0, speed


def drifts(result: AnalyticResult) -> tuple[np.ndarray, np.ndarray]:
    """Relative balance errors over time: (K - K0 - torque impulse)/|K0| and
    (E - E0 - torque work)/E0 (with K0, E0 replaced by the current scale if they vanish)."""
    h = result.history
    K, E = h["angular_momentum"], h["kinetic_energy"]
    imp = h["torque_impulse"][0]
    K0, E0 = K[0], E[0]
    k_scale = max(abs(K0), np.max(np.abs(K)), 1e-300)
    e_scale = max(E0, np.max(E), 1e-300)
    lost = h["contact_dissipation"]
    return (K - K0 - imp) / k_scale, (E + lost - E0 - h["torque_work"]) / e_scale


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
    return integrate(p, control, model=model, t_end=case.time.end,
                     history_dt=case.output.history_dt, coiled=coiled, wrap=case.fold.wrap,
                     omega_init=case.initial.omega, spin=case.initial.spin, L0=L0,
                     rtol=rtol, atol=atol, payout=payout, brake=brake)


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
