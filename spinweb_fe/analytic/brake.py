"""The analytical brake's regimes (consistent model; docs/analytic.md 4c), and what the
reel's share with them on the coil's tangent (:mod:`spinweb_fe.analytic.devices`).

The brake (:class:`~spinweb_fe.analytic.payout.Brake`, a force F(t) against the line's
slip through D):

- ``stick``: the brake holds, the arm pivots about D (L' = 0); it slips when the line's
  tension at D reaches F;
- ``slip``: the line runs through D against F (L a state; Lagrange's equation of the
  free length, whose power balance is the brake's -F L' (1 + w sin beta));
- ``peel``: at its coil's tangent, pulling at least F, the line leaves D along the coil
  without passing the brake (its slip L' (1 + w sin beta) vanishes there): the coil pays
  out as the free coil does, D moving with its departure point, until it stops unwinding
  or pulls ``GRIP`` less than F (then the brake holds it again);
- ``coiled``: the arm wraps back over the hub beyond D, which stays.

Near the tangent the slip's equations are singular (the line's inertia along itself,
m_f (1 + w sin beta), vanishes: D runs back along the coil, L' growing as 1/eps, eps the
angle from the tangent, while no material moves fast): a slipping arm that comes within
``Ctx.band`` of its tangent is put on it (rotated about D by at most ``band``, K and E kept
exactly), and a sticking arm whose line reaches F within twice the band peels instead.
docs/analytic.md 4c measures the band's error. An arm that swings over its held coil
(beta past the other tangent) leaves the model's validity: it stops there and says so.
"""

from __future__ import annotations

import math

import numpy as np

from spinweb_fe.analytic import payout as pay_mod
from spinweb_fe.analytic.models import HALF_PI, root_tension, solve_rows
from spinweb_fe.analytic.regimes import (REGIMES, Event, Regime, Switch, coiled_accel,
                                         no_rate, observe_free, sigma_of)

#: the peel ends when the line pulls this share below the brake's force (hysteresis)
GRIP = 1e-3


def _gap(ctx, y, L) -> float:
    return pay_mod.tangent_gap(ctx.p, y[1], L, ctx.w)


def _over(ctx, t, why_L):
    """The event 'the arm swings over its held coil' (eps = pi) with the stop message."""
    def fn(t, y):
        return _gap(ctx, y, why_L(t, y)) - math.pi

    def then(ctx, t, y):
        return Switch("stopped", y, f"at t = {t:.6g} s the arm swings over its held coil, "
                      "where its line would lie on the coil: beyond the analytical model")
    return Event(fn, 1.0, then)


def _on_tangent(ctx, y, L):
    """y with the arm exactly on its coil's tangent at free length L (phi = -w (pi/2 +
    alpha)), L' = 0."""
    y = y.copy()
    y[1] = -ctx.w * (HALF_PI + (ctx.p.H - L) / ctx.p.r0)
    y[6], y[7] = L, 0.0
    return y


def to_tangent(ctx, y):
    """Put a slipping (or sticking) arm within the band on its tangent at D, keeping the
    angular momentum and the kinetic energy: at the tangent E = J0 omega^2/2 + n I Psi^2/2
    and K = J0 omega + n I Psi, solved for (omega, Psi) next to the state's."""
    p = ctx.p
    L = y[6]
    E, K = pay_mod.invariants(p, y[1], y[2], y[3], L, y[7], ctx.w)
    nI = p.n * p.moments(L)[2]
    J0 = p.J0
    a, b, c = J0 * (J0 + nI), -2.0 * K * J0, K * K - 2.0 * nI * E
    disc = max(b * b - 4.0 * a * c, 0.0)
    roots = [(-b + s * math.sqrt(disc)) / (2.0 * a) for s in (1.0, -1.0)]
    omega = min(roots, key=lambda r: abs(r - y[2]))
    y = _on_tangent(ctx, y, L)
    y[2], y[3] = omega, (K - J0 * omega) / nI
    return y


def stop_line(ctx, y, Ld):
    """The line runs out to its end (L = H at the speed ``Ld``) and stops: an impact at the
    root, whose impulse keeps the total angular momentum and the arm's moment of momentum
    about the root; the kinetic energy it takes is the device's (its work)."""
    p, w = ctx.p, ctx.w
    _, K = pay_mod.invariants(p, y[1], y[2], y[3], p.H, Ld, w)
    _, S, I = p.moments(p.H)
    cb = math.cos(y[1])
    h = p.r0 * S * cb * (y[2] + w * Ld / p.r0) + I * y[3]
    A = np.array([[p.J0 + p.n * p.r0 * S * cb, p.n * (p.r0 * S * cb + I)], [p.r0 * S * cb, I]])
    y = y.copy()
    y[2], y[3] = np.linalg.solve(A, [K, h])
    y[6], y[7] = p.H, 0.0
    return y


# -- the brake ----------------------------------------------------------------------------

def _stick_accel(ctx, t, y):
    torque, wd = ctx.law(t, y[2])
    a = solve_rows(pay_mod.rows(ctx.p, y[1], y[2], y[3], y[6], 0.0, ctx.w), torque, wd)
    return a[0], a[1], 0.0, a[2]


def _slip_accel(ctx, t, y):
    torque, wd = ctx.law(t, y[2])
    A, b = pay_mod.slip_rows(ctx.p, y[1], y[2], y[3], y[6], y[7], ctx.w, ctx.force(t))
    try:
        return pay_mod.slip_accelerations(A, b, torque, wd)
    except np.linalg.LinAlgError:  # a trial stage on the tangent: solve_ivp shortens its step
        return (math.nan,) * 4


def _line(ctx, t, y, regime) -> float:
    """The brake's force at D [N]: in a stick state the line's tension just outside D (what
    the brake holds, finite up to the tangent; the FE brake's measure), in a slip state the
    force against the slip (:func:`spinweb_fe.analytic.payout.device_force`, F: its power
    is -F L' (1 + w sin beta)); the two are one for a point mass on a massless line."""
    wd, pd, Ldd, _ = REGIMES[regime].accel(ctx, t, y)
    if regime == "slip":
        return pay_mod.device_force(ctx.p, y[1], y[2], y[3], wd, pd, y[6], y[7], Ldd, ctx.w)
    return pay_mod.line_tension(ctx.p, y[1], y[2], y[3], wd, y[6], 0.0, 0.0, ctx.w)


def _coil_pull(ctx, t, y) -> float:
    """The free coil's tension at its departure point [N]."""
    wd = coiled_accel(ctx, t, y)[0]
    return root_tension(ctx.p, y[1], y[2], y[3], wd, True)


def _pull(ctx, t, y) -> float:
    """What an arm on its tangent at D asks of the brake [N]: the larger of the free coil's
    pull at its departure point and the tension that holds it there (equal while it does
    not move along its coil)."""
    return max(_coil_pull(ctx, t, y), _line(ctx, t, y, "stick"))


def _to_peel(ctx, t, y):
    """Peel from a state on the tangent; y[7] (unused while peeling) keeps the pull below
    which the brake holds the line again: ``GRIP`` below the smaller of the force and the
    pull now (a sticking arm within the band can ask F where the peel asks a little less:
    without the margin the two would hand over at once, again and again)."""
    y = y.copy()
    y[7] = (1.0 - GRIP) * min(ctx.force(t), _pull(ctx, t, y))
    return Switch("peel", y)


def brake_fold(ctx, t, y):
    """The regime of an arm at its coil's tangent at D (L = y[6]). About to unwind (moving,
    or at rest with the accelerations unwinding it), it peels off if it pulls at least the
    brake's force: the line leaves D along the coil, where its slip through the brake,
    L' (1 + w sin beta), vanishes; pulling less, the brake holds it (stick: the arm swings
    off its coil). Winding back, it wraps over the hub beyond D (coiled)."""
    y = _on_tangent(ctx, y, y[6])
    s = -sigma_of(y[1])
    r = s * (y[3] - y[2])
    if abs(r) <= 1e-12 * max(abs(y[2]), 1.0):  # at rest: what the accelerations do
        wd, pd, _, _ = coiled_accel(ctx, t, y)
        r = s * (pd - wd)
    if r <= 0.0:
        return Switch("coiled", y)
    return _to_peel(ctx, t, y) if _pull(ctx, t, y) >= ctx.force(t) else Switch("stick", y)


def _slips(ctx, t, y):
    """The tension at D reaches the force: the line slips; within twice the band of the
    tangent (where a slip would be put on it again at the band) it peels off, or wraps
    back, instead."""
    if _gap(ctx, y, y[6]) >= 2.0 * ctx.band:
        y = y.copy()
        y[7] = 0.0
        return Switch("slip", y)
    return _band_fold(ctx, t, y)


def _band_fold(ctx, t, y):
    """An arm within the band of its tangent whose line holds F: put on the tangent
    (:func:`to_tangent`), it peels if it unwinds (it pulls F), else wraps back."""
    sw = brake_fold(ctx, t, to_tangent(ctx, y))
    return _to_peel(ctx, t, sw.y) if sw.regime == "stick" else sw


def _stick_events(ctx, t0, y0):
    LD = lambda t, y: y[6]  # noqa: E731 - D's free length
    slips = Event(lambda t, y: _line(ctx, t, y, "stick") - ctx.force(t), 1.0, _slips)
    fold = Event(lambda t, y: _gap(ctx, y, y[6]), -1.0, brake_fold)
    return [slips, fold, _over(ctx, t0, LD)]


def _stick_enter(ctx, t, y):
    return _slips(ctx, t, y) if _line(ctx, t, y, "stick") > ctx.force(t) else None


def _slip_events(ctx, t0, y0):
    def stops(ctx, t, y):
        y = y.copy()
        y[7] = 0.0
        return Switch("stick", y)

    def arrest(ctx, t, y):  # within the band of its tangent, at F: it peels if it unwinds
        return _band_fold(ctx, t, y)

    def full(ctx, t, y):
        return Switch("pivoting", stop_line(ctx, y, y[7]))
    return [Event(lambda t, y: y[7], -1.0, stops),
            Event(lambda t, y: _gap(ctx, y, y[6]) - ctx.band, -1.0, arrest),
            Event(lambda t, y: y[6] - ctx.p.H, 1.0, full),
            _over(ctx, t0, lambda t, y: y[6])]


def _peel_rate(ctx, t, y) -> float:
    return -sigma_of(y[1]) * ctx.p.r0 * (y[3] - y[2])


def _peel_events(ctx, t0, y0):
    def leave(t, y):            # the coil is out: pivoting about the root
        return sigma_of(y0[1]) * y[1] - HALF_PI

    def out(ctx, t, y):
        y = y.copy()
        y[1] = math.copysign(HALF_PI, y[1])
        y[6], y[7] = ctx.p.H, 0.0
        return Switch("pivoting", y)
    holds = Event(lambda t, y: _pull(ctx, t, y) - y[7], -1.0,
                  lambda c, t, y: Switch("stick", _on_tangent(c, y, y[6])))
    stops = Event(lambda t, y: _peel_rate(ctx, t, y), -1.0, brake_fold)
    return [holds, stops, Event(leave, -1.0, out)]


def _peel_enter(ctx, t, y):
    if _pull(ctx, t, y) < min(y[7], (1.0 - GRIP) * ctx.force(t)):
        return Switch("stick", _on_tangent(ctx, y, y[6]))
    return None


def _brake_observe(regime):
    def observe(ctx, t, y):
        p, w = ctx.p, ctx.w
        wd, _, _, M = REGIMES[regime].accel(ctx, t, y)
        L, Ld = y[6], (y[7] if regime == "slip" else 0.0)
        E, K = pay_mod.invariants(p, y[1], y[2], y[3], L, Ld, w)
        N = _line(ctx, t, y, regime)
        return E, K, N, L, pay_mod.tip_rate(p, y[1], y[2], y[3], L, Ld, w), M, N, Ld
    return observe


def _peel_observe(ctx, t, y):
    return observe_free(ctx, t, y, "peel", held_tension=True, speed_rate=True)


REGIMES.update({
    "stick": Regime(_stick_accel, no_rate, _stick_events, _brake_observe("stick"),
                    _stick_enter),
    "slip": Regime(_slip_accel, lambda ctx, t, y: y[7], _slip_events, _brake_observe("slip")),
    "peel": Regime(coiled_accel, _peel_rate, _peel_events, _peel_observe, _peel_enter),
})
