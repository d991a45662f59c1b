"""The analytical model's brake (``[stowage] payout = "brake"``): the consistent model with a
brake at each arm's departure point D, the analytical twin of fe.coil.payout's brake.

The arm hangs from D, wound over alpha = (H - L) / r0 from the root, with its free length L
now a state (L, L') instead of a law: the equations of the paying regime
(:mod:`spinweb_fe.analytic.payout`: the total angular momentum K' = M and the moment of
momentum of the free part about the moving D) keep their L'' terms, and

- ``stick``: the brake holds the line, L' = L'' = 0; the arm pivots about D. It slips when
  the line's tension at D (:func:`spinweb_fe.analytic.payout.line_tension`) reaches the
  brake force;
- ``slip``: the line runs through D at the brake force, the tension equation closes the
  three (omega', Psi', L''). It sticks again when L' falls to zero.

A captured arm starts sticking when the stick equations swing it out (off its coil's
tangent); the regime ends fully paid out (L = H: pivoting about the root), or, unsupported
here, when the arm comes back to its coil's tangent or swings over its coil (the model stops
there and says so: the FE brake then holds the line along the hub).

The state is (theta, phi, omega, Psi, W, P, L, L'), W and P the torque's work and impulse.
"""

from __future__ import annotations

from spinweb_fe.analytic import payout as pay_mod
from spinweb_fe.analytic.models import HALF_PI, solve_rows

REGIMES = ("stick", "slip")


def _law(control, t, omega):
    """(torque, omega') of the control law: one of them None."""
    if control.law.prescribes_rate:
        return None, control.law.rate(control.params, t)[1]
    return control.law.torque(control.params, t, omega), None


def accel(p, control, regime, t, y, w, brake):
    """(omega', Psi', L'', M) of a stick or slip regime at state y."""
    phi, omega, psi, L, Ld = y[1], y[2], y[3], y[6], y[7]
    torque, omega_dot = _law(control, t, omega)
    if regime == "stick":
        wd, pd, M = solve_rows(pay_mod.rows(p, phi, omega, psi, L, 0.0, w), torque, omega_dot)
        return wd, pd, 0.0, M
    A, b = pay_mod.slip_rows(p, phi, omega, psi, L, Ld, w, brake.at(t))
    return pay_mod.slip_accelerations(A, b, torque, omega_dot)


def tension(p, control, regime, t, y, w, brake) -> float:
    """The line's tension at D [N] (the brake force while slipping)."""
    wd, _, Ldd, _ = accel(p, control, regime, t, y, w, brake)
    Ld = y[7] if regime == "slip" else 0.0
    return pay_mod.line_tension(p, y[1], y[2], y[3], wd, y[6], Ld, Ldd, w)


def rhs_factory(p, control, regime, brake, w):
    def rhs(t, y):
        wd, pd, Ldd, M = accel(p, control, regime, t, y, w, brake)
        Ld = y[7] if regime == "slip" else 0.0
        return [y[2], y[3] - y[2], wd, pd, M * y[2], M, Ld, Ldd if regime == "slip" else 0.0]
    return rhs


def released(p, control, t, y, w, brake) -> bool:
    """A captured arm (L = y[6]) starts sticking: the stick equations swing it off its
    coil's tangent (w beta'' > 0, beta' = Psi - omega while it sticks)."""
    wd, pd, _, _ = accel(p, control, "stick", t, y, w, brake)
    return w * (pd - wd) > 0.0


def events(p, control, regime, brake, w):
    """Terminal events: [stick: slips | slip: sticks, back to the tangent, over the coil,
    fully paid out] (their order is their meaning in the integrator)."""
    def beta(y):
        return y[1] + w * (p.H - y[6]) / p.r0

    if regime == "stick":
        def change(t, y):         # the tension reaches the brake force: it slips
            return tension(p, control, regime, t, y, w, brake) - brake.at(t)
        change.direction = 1.0
    else:
        def change(t, y):         # the line stops: the brake holds it
            return y[7]
        change.direction = -1.0

    def tangent(t, y):
        return w * beta(y) + HALF_PI

    def over(t, y):
        return w * beta(y) - HALF_PI

    def full(t, y):
        return y[6] - p.H * (1.0 - 1e-12)
    change.terminal = tangent.terminal = over.terminal = full.terminal = True
    tangent.direction, over.direction, full.direction = -1.0, 1.0, 1.0
    return [change, tangent, over, full]


def switch(regime, hit, t):
    """(next regime, why it stops or '') after event ``hit`` of :func:`events`."""
    if hit == 0:
        return ("slip" if regime == "stick" else "stick"), ""
    if hit == 3:
        return "pivoting", ""
    where = "comes back to its coil's tangent" if hit == 1 else "swings over its held coil"
    return regime, f"at t = {t:.6g} s the arm {where}: the analytical brake ends here"


def sample(p, control, regime, t, y, w, brake):
    """(E, K, tension at D, L, L', tip rate) of a stick or slip state for the history."""
    phi, omega, psi, L = y[1], y[2], y[3], y[6]
    Ld = y[7] if regime == "slip" else 0.0
    E, K = pay_mod.invariants(p, phi, omega, psi, L, Ld, w)
    N = tension(p, control, regime, t, y, w, brake)
    return E, K, N, L, Ld, pay_mod.tip_rate(p, phi, omega, psi, L, Ld, w)
