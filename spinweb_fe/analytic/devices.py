"""The payout devices' regimes (consistent model; docs/analytic.md 4b-4c).

The reel (:class:`~spinweb_fe.analytic.payout.Payout`, the free length prescribed):

- ``paying``: the arm hangs from D, which the law moves back along the coil;
- ``laid``: the arm lies along its coil's tangent at D while D moves at the law's rate (the
  coil supports it and the reel holds it back at once: the sliding state between paying and
  the free coil, which an event-based switch between those two alone would chatter on);
- ``coiled`` (of :mod:`~spinweb_fe.analytic.regimes`): the free length is below the law's
  (the line leaves the coil ahead of D, or wraps back over the hub beyond it).

The brake's regimes (``stick``, ``slip``, ``peel``) are :mod:`spinweb_fe.analytic.brake`.
"""

from __future__ import annotations

import math

import numpy as np

from spinweb_fe.analytic import payout as pay_mod
from spinweb_fe.analytic.brake import _gap, _on_tangent, _over, brake_fold, stop_line
from spinweb_fe.analytic.models import solve_rows
from spinweb_fe.analytic.regimes import (REGIMES, Event, Regime, Switch, coiled_accel,
                                         coiled_events, no_rate, release, sigma_of,
                                         wound_length)


# -- captured -----------------------------------------------------------------------------

def captured_events(ctx, t0, y0):
    """A captured arm: released when the free equations unwind it; under a reel also when
    the law lets its free length out."""
    out = [] if release(ctx, t0, y0) > 0.0 else [  # (unwinding already: waits for its law)
        Event(lambda t, y: release(ctx, t, y), 1.0, on_release)]
    if ctx.pay is not None and ctx.law_length(t0)[0] < wound_length(ctx.p, y0[1]):
        out.append(Event(lambda t, y: ctx.law_length(t)[0] - wound_length(ctx.p, y[1]), 1.0,
                         on_allowed))
    return out


def on_release(ctx, t, y):
    """The captured arm starts to unwind (under a device that has not paid everything
    out; after that, and coiled the other way, it is the free model's)."""
    if ctx.brake is not None and y[6] < ctx.p.H:
        return brake_fold(ctx, t, y)
    if ctx.pay is not None and ctx.law_length(t)[0] < ctx.p.H:
        L, Lc = ctx.law_length(t)[0], wound_length(ctx.p, y[1])
        if L < Lc * (1.0 - 1e-9):
            return Switch("captured", y)        # waits for its law
        return reel_fold(ctx, t, y) if L <= Lc * (1.0 + 1e-9) else Switch("coiled", y)
    return Switch("coiled", y)


def on_allowed(ctx, t, y):
    """The reel's law reaches the captured free length."""
    if release(ctx, t, y) >= 0.0:
        return reel_fold(ctx, t, y)
    return Switch("captured", y)


def _captured_enter(ctx, t, y):
    if release(ctx, t, y) > 0.0:
        sw = on_release(ctx, t, y)
        return None if sw.regime == "captured" else sw
    return None


# -- the reel -----------------------------------------------------------------------------

def _paying_accel(ctx, t, y):
    L, Ld = ctx.law_length(t)
    torque, wd = ctx.law(t, y[2])
    a = solve_rows(pay_mod.rows(ctx.p, y[1], y[2], y[3], L, Ld, ctx.w), torque, wd)
    return a[0], a[1], 0.0, a[2]


def _laid_accel(ctx, t, y):
    """The arm on its tangent at D moving at the law: K = J0 omega + n I Psi, Psi = omega +
    w L'/r0, so (J0 + n I) omega' = M - 2 n S L' Psi (L'' = 0 on a law's segment)."""
    p = ctx.p
    L, Ld = ctx.law_length(t)
    _, S, I = p.moments(L)
    torque, wd = ctx.law(t, y[2])
    J, drag = p.J0 + p.n * I, 2.0 * p.n * S * Ld * y[3]
    if wd is None:
        wd = (torque - drag) / J
        return wd, wd, 0.0, torque
    return wd, wd, 0.0, J * wd + drag


def _lifts(ctx, t, y) -> float:
    """w beta'' of the paying equations at a state on the tangent (> 0: the arm swings off
    the coil)."""
    wd, pd, _, _ = _paying_accel(ctx, t, y)
    return ctx.w * (pd - wd)


def _outruns(ctx, t, y) -> float:
    """L'' of the free coil at a state on the tangent (> 0: it would unwind faster than the
    law, which holds it; the law's L'' is 0)."""
    wd, pd, _, _ = coiled_accel(ctx, t, y)
    return -sigma_of(y[1]) * ctx.p.r0 * (pd - wd)


def reel_fold(ctx, t, y):
    """The regime of an arm at its coil's tangent with the law's free length: paying if it
    swings off the coil, the free coil if it unwinds slower than the law, laid if neither
    (the coil supports it and the reel holds it)."""
    p = ctx.p
    L, Ld = ctx.law_length(t)
    if L >= p.H:
        return Switch("coiled", y)
    y = _on_tangent(ctx, y, L)
    y[6] = p.H
    bp = -sigma_of(y[1]) * (y[3] - y[2]) - Ld / p.r0   # w beta' of the paying arm
    y[7] = Ld  # the law's speed in force (a jump in it is an impact: _reel_enter)
    if abs(bp) > 1e-9 * max(abs(y[2]), Ld / p.r0, 1e-300):
        return Switch("paying" if bp > 0 else "coiled", y)
    if _lifts(ctx, t, y) > 0.0:
        return Switch("paying", y)
    if _outruns(ctx, t, y) <= 0.0:
        return Switch("coiled", y)
    y[3] = y[2] + ctx.w * Ld / p.r0
    return Switch("laid", y)


def _jerk(ctx, y, L, Ld_old, Ld_new):
    """The reel's speed jumps from Ld_old to Ld_new (a corner of its law): an impulse at D
    that keeps the total angular momentum and the free part's moment of momentum about D
    (y[7] keeps the speed in force)."""
    p, w, n = ctx.p, ctx.w, ctx.p.n
    m_f, S, I = p.moments(L)
    beta = y[1] + w * (p.H - L) / p.r0
    cb, opw = math.cos(beta), pay_mod.one_plus(p, y[1], L, w)
    _, K = pay_mod.invariants(p, y[1], y[2], y[3], L, Ld_old, w)
    h = p.r0 * S * cb * (y[2] + w * Ld_old / p.r0) + I * y[3]
    A = np.array([[p.J0 + n * p.r0 * S * cb, n * (p.r0 * S * cb + I)], [p.r0 * S * cb, I]])
    rhs = [K - n * Ld_new * w * (p.r0 * m_f * opw + S * cb), h - S * cb * w * Ld_new]
    y = y.copy()
    y[2], y[3] = np.linalg.solve(A, rhs)
    y[7] = Ld_new
    return y


def _paying_enter(ctx, t, y):
    L, Ld = ctx.law_length(t)
    if Ld != y[7] and L < ctx.p.H:
        return Switch("paying", _jerk(ctx, y, L, y[7], Ld))
    return None


def _law_L(ctx):
    return lambda t, y: ctx.law_length(t)[0]


def _full(ctx):
    """The law reaches H: the arm pivots about its root."""
    def fn(t, y):
        return ctx.law_length(t)[0] - ctx.p.H * (1.0 - 1e-12)

    def then(ctx, t, y):
        return Switch("pivoting", stop_line(ctx, y, ctx.law_length(t - 1e-12)[1]))
    return Event(fn, 1.0, then)


def _paying_events(ctx, t0, y0):
    L = _law_L(ctx)
    slack = Event(lambda t, y: _gap(ctx, y, L(t, y)), -1.0, reel_fold)
    return [slack, _over(ctx, t0, L), _full(ctx)]


def _laid_events(ctx, t0, y0):
    return [Event(lambda t, y: _lifts(ctx, t, y), 1.0, lambda c, t, y: Switch("paying", y)),
            Event(lambda t, y: _outruns(ctx, t, y), -1.0, lambda c, t, y: Switch("coiled", y)),
            _full(ctx)]


def _reel_observe(regime):
    def observe(ctx, t, y):
        p, w = ctx.p, ctx.w
        L, Ld = ctx.law_length(t)
        wd, _, _, M = REGIMES[regime].accel(ctx, t, y)
        E, K = pay_mod.invariants(p, y[1], y[2], y[3], L, Ld, w)
        N = pay_mod.tension(p, y[1], y[2], y[3], wd, L, Ld, w)
        dev = pay_mod.line_tension(p, y[1], y[2], y[3], wd, L, Ld, 0.0, w)
        return E, K, N, L, pay_mod.tip_rate(p, y[1], y[2], y[3], L, Ld, w), M, dev, Ld
    return observe


def _laid_enter(ctx, t, y):
    L, Ld = ctx.law_length(t)
    if Ld != y[7] and L < ctx.p.H:
        y = _jerk(ctx, y, L, y[7], Ld)
    sw = reel_fold(ctx, t, y)
    return None if sw.regime == "laid" and Ld == y[7] else sw


# -- the free regimes under a device ------------------------------------------------------

def _coiled_events(ctx, t0, y0):
    """The coiled regime's events and those a device adds: under a brake, the arm winding
    off back to D (y[6] < H); under a reel, the free length reaching the law's (law below
    H)."""
    p, out = ctx.p, coiled_events(ctx, t0, y0)
    if ctx.brake is not None and y0[6] < p.H:
        out.append(Event(lambda t, y: wound_length(p, y[1]) - y[6], 1.0, brake_fold))
    elif ctx.pay is not None and ctx.law_length(t0)[0] < p.H:
        out.append(Event(lambda t, y: wound_length(p, y[1]) - ctx.law_length(t)[0], 1.0,
                         reel_fold))
    return out


def _free_observe(regime):
    """The free regimes' observables with a device's columns (tension at D, payout speed):
    a reel pays its law out whatever the arm does below it, a brake holds a coiled arm."""
    observe = REGIMES[regime].observe

    def view(ctx, t, y):
        out = observe(ctx, t, y)
        if ctx.pay is not None:
            return (*out[:6], 0.0, ctx.law_length(t)[1])
        if ctx.brake is not None:
            return (*out[:6], out[6] if regime == "coiled" else 0.0, 0.0)
        return out
    return view


REGIMES.update({
    "paying": Regime(_paying_accel, no_rate, _paying_events, _reel_observe("paying"),
                     _paying_enter),
    "laid": Regime(_laid_accel, no_rate, _laid_events, _reel_observe("laid"), _laid_enter),
})
REGIMES.update({
    "captured": REGIMES["captured"]._replace(events=captured_events, enter=_captured_enter,
                                             observe=_free_observe("captured")),
    "coiled": REGIMES["coiled"]._replace(events=_coiled_events,
                                         observe=_free_observe("coiled")),
    "pivoting": REGIMES["pivoting"]._replace(observe=_free_observe("pivoting")),
})
