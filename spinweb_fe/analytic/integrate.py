"""Integration of the analytical model: the start state, the event-driven loop over the
regimes (:mod:`spinweb_fe.analytic.regimes`, :mod:`spinweb_fe.analytic.devices`) with
``scipy.integrate.solve_ivp``, and the result. Sampling: :mod:`spinweb_fe.analytic.sample`.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import solve_ivp

from spinweb_fe.analytic import devices  # noqa: F401  (registers the device regimes)
from spinweb_fe.analytic.models import HALF_PI, MODELS, ArmParams, invariants
from spinweb_fe.analytic.regimes import REGIMES, Ctx, captured_inertia
from spinweb_fe.analytic.sample import sample

log = logging.getLogger(__name__)

#: default start-up free length as a fraction of H (the fully coiled L = 0 is singular)
L0_FRACTION = 1e-4
#: guard against chattering between regimes
MAX_SEGMENTS = 20_000
#: switches without time passing before the model gives up (never seen: a guard)
MAX_STILL = 50
#: the brake's tangent band [rad] (docs/analytic.md 4c)
BAND = 1e-4


@dataclass
class AnalyticResult:
    """Sampled history (dict of arrays, names as in ``results.HISTORY_UNITS``) and run info."""

    history: dict
    params: ArmParams
    model: str
    switches: list = field(default_factory=list)   # (time, phi, new regime)
    stopped: str = ""                               # non-empty if stopped before t_end
    info: dict = field(default_factory=dict)


def _rate(control, t):
    return control.law.rate(control.params, t)


def start_state(p: ArmParams, control, coiled: bool, wrap: str, omega_init: float,
                spin: str, L0: float | None = None, model: str = "consistent"):
    """Start state (phi, omega, Psi, regime).

    Coiled start: L = 0 is singular, so the arm starts *captured* (wound and turning rigidly
    with the hub, Psi = omega) with a small free length L0 (default ``L0_FRACTION`` H),
    phi0 = -+(pi/2 + (H - L0)/r0) for a trailing/leading wrap; it is released as soon as
    the free-arm equations would unwind it. Straight start: phi0 = 0, L = H, pivoting.
    spin='all': the arms co-rotate with the hub (Psi = omega_init). spin='hub': a captured
    (coiled) arm is tied to the hub, so the start is a momentum-conserving inelastic
    coupling omega = J_hub omega_init / J_captured (the loss is reported); straight arms
    start non-rotating (Psi = 0). spin_ramp starts from omega = 0.
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
        omega = p.J_hub * omega_init / captured_inertia(model, p, L0)
        return phi0, omega, omega, regime
    return phi0, omega_init, 0.0, regime


def _full(ctx, y):
    """The state with (L_D, L') = (H, 0) appended where only a device integrates them (the
    error norm of solve_ivp averages over the integrated components: without a device the
    six of the free model are integrated alone, as before the devices)."""
    return y if len(y) == 8 else np.concatenate([y, (ctx.p.H, 0.0)])


def _rhs(ctx, regime, size):
    reg = REGIMES[regime]

    def rhs(t, y):
        y = _full(ctx, y)
        wd, pd, Ldd, M = reg.accel(ctx, t, y)
        # y = theta, phi, omega, Psi, torque work W, torque impulse P, L_D, L'
        return [y[2], y[3] - y[2], wd, pd, M * y[2], M, reg.rate(ctx, t, y), Ldd][:size]
    return rhs


def _event(ctx, ev, t0):
    """A solve_ivp event of ``ev``. A switch starts the next regime on the surface of the
    events that end it the other way (g = 0 up to round-off at t0): there g(t0) reads as
    'not yet crossed', so that only a later crossing fires, not the start itself."""
    def fn(t, y):
        g = ev.fn(t, _full(ctx, y))
        if t == t0 and g * ev.direction >= 0.0:
            return -ev.direction * 1e-300
        return g
    fn.terminal, fn.direction = True, ev.direction
    return fn


def _enter(ctx, regime, t, y, switches):
    """Apply the regime's entry check (a break in a law or a force) until it holds."""
    for _ in range(8):
        enter = REGIMES[regime].enter
        sw = enter(ctx, t, y) if enter is not None else None
        if sw is None:
            return regime, y
        regime, y = sw.regime, sw.y
        switches.append((t, y[1], regime))
    return regime, y


def integrate(p: ArmParams, control, *, model: str = "consistent", t_end: float,
              history_dt: float, coiled: bool = True, wrap: str = "trailing",
              omega_init: float = 8 * math.pi, spin: str = "all", L0: float | None = None,
              rtol: float = 1e-10, atol: float = 1e-10, method: str = "DOP853",
              payout=None, brake=None, band: float | None = None) -> AnalyticResult:
    """Integrate the model from t = 0 to ``t_end`` and sample the history.

    The regimes (docs/analytic.md): ``pivoting`` (|phi| <= pi/2, L = H), ``coiled``
    (|phi| > pi/2, L = H - r0 (|phi| - pi/2)), ``captured`` (a fully wound arm, L <= L0,
    turning rigidly with the hub; a coiled arm wound down to L0/2 is captured by a
    momentum-conserving inelastic impact, whose loss is ``contact_dissipation``), and those
    of a reel (``paying``, ``laid``) or a brake (``stick``, ``slip``, ``peel``), each ended
    exactly by solve_ivp events.

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
        solve_ivp tolerances; atol applies to angles [rad] and rates [rad/s], scaled for the
        torque work and impulse by the initial energy and momentum, for lengths by H.
    payout : Payout or None
        A reel (consistent model only): the free length never exceeds the law's.
    brake : Brake or None
        A brake at D (consistent model only; not with a payout). With a reel or a brake the
        history gains the device's ``brake_work``, ``brake_tension`` and ``payout_speed``.
    band : float, optional
        The brake's tangent band [rad] (default ``BAND``; docs/analytic.md 4c).

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
    ctx = Ctx(model, p, control, w, payout, brake, 0.5 * L_start,
              BAND if band is None else band)
    prescribed = control.law.prescribes_rate
    E_init = 0.5 * (p.J_hub if spin == "hub" and coiled and not prescribed
                    else 0.0) * omega_init ** 2
    E0, K0 = invariants(p, phi0, omega0, psi0, regime != "pivoting")
    breaks = control.law.breaks(control.params)
    w_law = (max(abs(_rate(control, t)[0]) for t in [b for b in breaks] + [t_end])
             if prescribed else 0.0)
    w_scale = max(abs(omega_init), w_law, 1.0)
    atol_v = np.array([atol, atol, atol * w_scale, atol * w_scale,
                       atol * max(E0, p.J0 * w_scale ** 2), atol * max(abs(K0), p.J0 * w_scale),
                       atol * p.H, atol * p.H * w_scale])
    y = np.array([0.0, phi0, omega0, psi0, 0.0, 0.0, L_start if brake is not None else p.H,
                  0.0])
    stops = sorted(set([b for b in breaks if b < t_end]
                       + (payout.breaks(t_end) if payout else [])
                       + (brake.breaks(t_end) if brake else []) + [t_end]))
    size = 8 if brake is not None or payout is not None else 6
    t, segments, switches, stopped, lost, still = 0.0, [], [], "", 0.0, 0
    while t < t_end and not stopped:
        if len(segments) > MAX_SEGMENTS:
            stopped = f"more than {MAX_SEGMENTS} regime switches by t = {t:.6g} s (chattering)"
            break
        regime, y = _enter(ctx, regime, t, y, switches)
        t_stop = next(b for b in stops if b > t)
        evs = REGIMES[regime].events(ctx, t, y)
        sol = solve_ivp(_rhs(ctx, regime, size), (t, t_stop), y[:size], method=method,
                        rtol=rtol, atol=atol_v[:size], dense_output=True,
                        events=[_event(ctx, ev, t) for ev in evs])
        segments.append((t, sol.t[-1], sol.sol, regime, lost))
        still = still + 1 if sol.t[-1] - t <= 1e-12 * max(t_end, 1.0) else 0
        if sol.status < 0:
            stopped = f"solve_ivp failed at t = {sol.t[-1]:.6g} s in the {regime} regime: " \
                      f"{sol.message}"
        t, y = sol.t[-1], _full(ctx, sol.y[:, -1].copy())
        if still > MAX_STILL:
            stopped = (f"the regimes switch {MAX_STILL} times at t = {t:.6g} s without time "
                       f"passing (last: {', '.join(s[2] for s in switches[-4:])})")
        if sol.status != 1 or stopped:
            continue
        hit = next(i for i, te in enumerate(sol.t_events) if len(te))
        sw = evs[hit].then(ctx, t, y)
        lost += sw.lost
        stopped = sw.stop
        if not stopped:
            regime, y = sw.regime, np.array(sw.y, dtype=float)
            switches.append((t, y[1], regime))
    hist = sample(ctx, [(*s[:2], (lambda tk, d=s[2]: _full(ctx, d(tk))), *s[3:])
                        for s in segments], history_dt, t_end)
    info = {"E0": E0, "K0": K0, "L0": L_start,
            "start_loss": E_init - E0 if E_init else 0.0, "contact_loss": lost,
            "regimes": sorted({s[3] for s in segments})}
    if stopped:
        log.warning("analytic model stopped early: %s", stopped)
    return AnalyticResult(hist, p, model, switches, stopped, info)
