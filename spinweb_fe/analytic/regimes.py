"""The analytical model's regimes without a payout device: ``captured``, ``coiled`` and
``pivoting`` (docs/analytic.md, sections 3-4), and what every regime shares.

A regime is a :class:`Regime`: its accelerations, the rate of the device's free length
L_D, its terminal events (each with what happens when it fires) and what the history
records of a state. :mod:`spinweb_fe.analytic.devices` adds the reel's and the brake's
regimes; :mod:`spinweb_fe.analytic.integrate` switches between them.

The state is ``y = (theta, phi, omega, Psi, W, P, L_D, L')``: hub angle and rate, arm angle
and absolute rate, the torque's work and impulse, the free length held at the device's point
D (the brake's, or H once everything is out: no device) and the line's speed through a
slipping brake.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, NamedTuple

from spinweb_fe.analytic.models import (HALF_PI, ArmParams, accelerations, invariants,
                                        root_tension, tip_rate)

#: a state's observables for the history: E [J], K [N m s], arm tension N [N], free length
#: L [m], tip rate [rad/s], hub torque M [N m], tension at the device [N], payout speed [m/s]
Observed = tuple


@dataclass(frozen=True)
class Ctx:
    """What every regime needs: the model, its parameters and control law, the wrap
    (w = +1 trailing, -1 leading), the devices (a reel's ``pay`` or a ``brake``, or
    neither), the capture length, and the brake's regularisation (docs/analytic.md 4c):
    the tangent band ``band`` [rad]."""

    model: str
    p: ArmParams
    control: object
    w: float
    pay: object = None
    brake: object = None
    L_min: float = 0.0
    band: float = 1e-4

    def law(self, t: float, omega: float):
        """(torque [N m] or None, omega' [rad/s^2] or None) of the control law at t."""
        law = self.control.law
        if law.prescribes_rate:
            return None, law.rate(self.control.params, t)[1]
        return law.torque(self.control.params, t, omega), None

    def law_length(self, t: float) -> tuple[float, float]:
        """(L, L') of the reel's law at t, L at most H (L' = 0 there)."""
        L, Ld = self.pay.at(t)
        return (self.p.H, 0.0) if L >= self.p.H else (L, Ld)

    def force(self, t: float) -> float:
        """The brake's force [N] at t."""
        return self.brake.at(t)


class Switch(NamedTuple):
    """What an event does: the next regime, the state it starts from, why the model stops
    there ('' if it goes on) and the kinetic energy an impact took [J]."""

    regime: str
    y: object
    stop: str = ""
    lost: float = 0.0


class Event(NamedTuple):
    """A terminal event: ``fn(t, y)`` crossing zero in ``direction``; ``then(ctx, t, y)``
    returns the :class:`Switch`."""

    fn: Callable
    direction: float
    then: Callable


class Regime(NamedTuple):
    """One regime: ``accel(ctx, t, y) -> (omega', Psi', L'', M)``, ``rate(ctx, t, y)``
    (dL_D/dt), ``events(ctx, t0, y0) -> [Event]``, ``observe(ctx, t, y) -> Observed`` and
    ``enter(ctx, t, y) -> Switch or None``: where the regime cannot go on from a state (a
    law's or a brake force's break changed what holds), the switch to take at once."""

    accel: Callable
    rate: Callable
    events: Callable
    observe: Callable
    enter: Callable | None = None


def sigma_of(phi: float) -> float:
    """+1 for an arm wound counter-clockwise (phi > 0), -1 clockwise."""
    return 1.0 if phi > 0 else -1.0


def wound_length(p: ArmParams, phi: float) -> float:
    """Free length [m] of an arm wound on the hub at angle phi (|phi| >= pi/2)."""
    return p.H - p.r0 * (abs(phi) - HALF_PI)


def captured_inertia(model: str, p: ArmParams, L: float) -> float:
    """Inertia of hub + captured arms (free part frozen in the coil) in each model."""
    m_f, S, I = p.moments(L)
    base = p.J0 if model == "consistent" else p.J_hub + p.n * p.r0 ** 2 * m_f
    return base + p.n * I


def no_rate(ctx, t, y) -> float:
    return 0.0


# -- the free regimes ---------------------------------------------------------------------

def _captured_accel(ctx, t, y):
    J = captured_inertia(ctx.model, ctx.p, wound_length(ctx.p, y[1]))
    torque, wd = ctx.law(t, y[2])
    if wd is not None:
        return wd, wd, 0.0, J * wd
    return torque / J, torque / J, 0.0, torque


def _free_accel(coiled):
    def accel(ctx, t, y):
        torque, wd = ctx.law(t, y[2])
        a = accelerations(ctx.model, ctx.p, y[1], y[2], y[3], coiled, torque=torque,
                          omega_dot=wd)
        return a[0], a[1], 0.0, a[2]
    return accel


coiled_accel = _free_accel(True)


def unwinding(ctx, t, y) -> float:
    """w_s (Psi - omega) of a wound arm (its free length grows at r0 times it, w_s the wrap
    direction -sigma), or, where that is zero, the same of its accelerations (a captured arm
    that turns with the hub: would the free equations unwind it?)."""
    s = -sigma_of(y[1])
    r = s * (y[3] - y[2])
    if abs(r) > 1e-12 * max(abs(y[2]), 1.0):
        return r
    wd, pd, _, _ = coiled_accel(ctx, t, y)
    return s * (pd - wd)


def release(ctx, t, y) -> float:
    """> 0 when the coiled equations, evaluated with Psi = omega, unwind a captured arm."""
    wd, pd, _, _ = coiled_accel(ctx, t, (*y[:3], y[2], *y[4:]))
    return -sigma_of(y[1]) * (pd - wd)


def _captured_events(ctx, t0, y0):
    """Released when the free equations unwind the arm (a device's regimes replace this)."""
    if release(ctx, t0, y0) > 0.0:
        return []
    return [Event(lambda t, y: release(ctx, t, y), 1.0, lambda c, t, y: Switch("coiled", y))]


def _capture(ctx, t, y):
    """Inelastic, momentum-conserving capture of an arm wound down to L_min."""
    p, y = ctx.p, y.copy()
    E_before, K = invariants(p, y[1], y[2], y[3], True)
    m_f, S, I = p.moments(ctx.L_min)
    y[2] = y[3] = (K if ctx.model == "consistent" else
                   (p.J_hub + p.n * p.r0 ** 2 * m_f) * y[2] + p.n * I * y[3]) \
        / captured_inertia(ctx.model, p, ctx.L_min)
    lost = E_before - invariants(p, y[1], y[2], y[3], True)[0]
    return Switch("captured", y, lost=lost)


def coiled_events(ctx, t0, y0):
    """Leaving the coil (pivoting) and capture by the hub."""
    p = ctx.p
    s = sigma_of(y0[1])

    def leave(t, y):        # |phi| back to pi/2: pivoting about the root
        return s * y[1] - HALF_PI

    def wound(t, y):        # free length down to L_min: captured by the hub
        return wound_length(p, y[1]) - ctx.L_min

    def to_pivoting(ctx, t, y):
        y = y.copy()
        y[1] = math.copysign(HALF_PI, y[1])
        y[6] = p.H
        return Switch("pivoting", y)
    return [Event(leave, -1.0, to_pivoting), Event(wound, -1.0, _capture)]


def _pivoting_events(ctx, t0, y0):
    def up(t, y):
        return y[1] - HALF_PI

    def down(t, y):
        return y[1] + HALF_PI

    def to_coiled(ctx, t, y):
        y = y.copy()
        y[1] = math.copysign(HALF_PI, y[1])
        return Switch("coiled", y)
    return [Event(up, 1.0, to_coiled), Event(down, -1.0, to_coiled)]


def observe_free(ctx, t, y, regime, held_tension=False, speed_rate=False) -> Observed:
    """Observables of a captured, coiled or pivoting state; ``held_tension``: the device
    holds the line at D (its tension is the arm's), ``speed_rate``: D moves with the free
    length (the payout speed is L')."""
    p, coiled = ctx.p, regime != "pivoting"
    phi, omega, psi = y[1], y[2], y[3]
    wd, _, _, M = REGIMES[regime].accel(ctx, t, y)
    E, K = invariants(p, phi, omega, psi, coiled)
    L = wound_length(p, phi) if coiled else p.H
    N = root_tension(p, phi, omega, psi, wd, coiled)
    speed = -p.r0 * sigma_of(phi) * (psi - omega) if speed_rate else 0.0
    return E, K, N, L, tip_rate(p, phi, omega, psi, coiled), M, \
        N if held_tension else 0.0, speed


def _observe(regime):
    def observe(ctx, t, y):
        return observe_free(ctx, t, y, regime, held_tension=regime == "coiled",
                            speed_rate=regime == "coiled")
    return observe


#: the regimes by name; :mod:`spinweb_fe.analytic.devices` adds its own and gives the
#: captured and coiled ones the events and columns of a device
REGIMES = {
    "captured": Regime(_captured_accel, no_rate, _captured_events, _observe("captured")),
    "coiled": Regime(coiled_accel, no_rate, coiled_events, _observe("coiled")),
    "pivoting": Regime(_free_accel(False), no_rate, _pivoting_events, _observe("pivoting")),
}
