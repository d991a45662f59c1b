"""The analytical model's rate payout: the free length L(t) prescribed by a payout law.

While the law holds the arm back ("paying"), each arm hangs from its departure point D,
which the payout moves back along the coil: D is wound over alpha(t) = (H - L(t)) / r0 from
the root R, at inertial angle theta_D = theta - w alpha (w = +1 for a trailing coil). The
arm is straight from D at the absolute angle chi; phi = chi - theta as in every regime, and
beta = phi + w alpha is its angle from the radial at D (beta = -w pi/2: tangent, the free
coiled regime). The free part is the outer L metres of the arm (the profile measured from
the tip), its material flows out of the coil at D at the rate L'. With u = theta_D' =
omega + w L'/r0 and the free part's moments m_f, S, I about D (:meth:`ArmParams.moments`),
rho0 = dm_f/dL the line density at D:

- total angular momentum about the axis (the coil turns with the hub, consistent model):
  K = J0 omega + n [r0 m_f L' (w + sin beta) + r0 S cos beta (Psi + u) + I Psi], K' = M;
- moment of momentum of the free part about the moving point D: the only force on it acts
  at D and the material enters at D, so H_D' + v_D x p = 0 with H_D = r0 S u cos beta +
  I Psi, v_D = r0 u e_theta(theta_D), p the free part's momentum:
  r0 S cos beta omega' + I Psi' = -(w S L'' cos beta + r0 S u^2 sin beta + 2 S L' Psi).

Both are linear in (omega', Psi'), like the other regimes (:mod:`models`). At beta = -w pi/2
they reduce to the coiled regime's K and E; at L = H (alpha = 0) to the pivoting regime's.
The law does work: the energy balance E - E0 = W_torque + W_restraint defines the
restraint's work, which is zero outside this regime. The laws here are piecewise linear in
t (L'' = 0 between the table's points, where the integration restarts).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from spinweb_fe.analytic.models import ArmParams


class Payout(NamedTuple):
    """A payout law: paid-out (free) length ``length`` [m] at times ``times`` [s], linear
    between the points and constant outside them."""

    times: np.ndarray
    length: np.ndarray

    def at(self, t: float) -> tuple[float, float]:
        """(L [m], L' [m/s]) at time t; L' is the slope of the segment starting at t."""
        ts, ls = self.times, self.length
        if t < ts[0] or t >= ts[-1] or len(ts) == 1:
            return float(np.interp(t, ts, ls)), 0.0
        q = int(np.searchsorted(ts, t, side="right")) - 1
        slope = (ls[q + 1] - ls[q]) / (ts[q + 1] - ts[q])
        return float(ls[q] + slope * (t - ts[q])), float(slope)

    def breaks(self, t_end: float) -> list:
        """The table's times inside (0, t_end): the law's slope changes there."""
        return [float(t) for t in self.times if 0.0 < t < t_end]


def _kin(p: ArmParams, phi, omega, L, Ld, w):
    alpha = (p.H - L) / p.r0
    beta = phi + w * alpha
    u = omega + w * Ld / p.r0
    m_f, S, I = p.moments(L)
    return beta, u, m_f, S, I, p.root_density(L)


def tangent_gap(p: ArmParams, phi, L, w) -> float:
    """eps = w beta + pi/2 [rad]: the arm's angle from its coil's tangent at D (0: tangent,
    pi/2: radial, pi: over its coil)."""
    return w * (phi + w * (p.H - L) / p.r0) + 0.5 * math.pi


def one_plus(p: ArmParams, phi, L, w) -> float:
    """1 + w sin(beta) = 2 sin^2(eps / 2), without the cancellation near the tangent (where
    the line's slip through D, L' (1 + w sin beta), vanishes)."""
    return 2.0 * math.sin(0.5 * tangent_gap(p, phi, L, w)) ** 2


def rows(p: ArmParams, phi, omega, psi, L, Ld, w):
    """Coefficients (a11, a12, b1, a21, a22, b2) of a11 omega' + a12 Psi' = b1 + M,
    a21 omega' + a22 Psi' = b2 in the paying regime (L'' = 0)."""
    beta, u, m_f, S, I, rho0 = _kin(p, phi, omega, L, Ld, w)
    n, r0 = p.n, p.r0
    cb, sb = math.cos(beta), math.sin(beta)
    r1 = n * (r0 * rho0 * Ld * Ld * w * one_plus(p, phi, L, w) + 2.0 * r0 * m_f * Ld * psi * cb
              - r0 * S * sb * (psi * psi - u * u) + 2.0 * S * Ld * psi)
    return (p.J0 + n * r0 * S * cb, n * (r0 * S * cb + I), -r1,
            r0 * S * cb, I, -(r0 * S * u * u * sb + 2.0 * S * Ld * psi))


def invariants(p: ArmParams, phi, omega, psi, L, Ld, w):
    """(E [J], K [N m s]) of hub, coil and free arms in the paying regime."""
    beta, u, m_f, S, I, _ = _kin(p, phi, omega, L, Ld, w)
    n, r0 = p.n, p.r0
    cb = math.cos(beta)
    opw = one_plus(p, phi, L, w)  # |v_D + L' u|^2 = r0^2 omega^2 + 2 L' opw (w r0 omega + L')
    E = (0.5 * (p.J_hub + n * (p.m_arm - m_f) * r0 * r0) * omega * omega
         + n * (0.5 * m_f * (r0 * r0 * omega * omega + 2.0 * Ld * opw * (w * r0 * omega + Ld))
                + 0.5 * I * psi * psi + r0 * u * psi * S * cb))
    K = p.J0 * omega + n * (r0 * m_f * Ld * w * opw + r0 * S * cb * (psi + u) + I * psi)
    return E, K


def tension(p: ArmParams, phi, omega, psi, omega_dot, L, Ld, w) -> float:
    """Arm tension N [N] at D: minus the along-arm part of the force on the free part,
    N = m_f r0 (u^2 cos beta - u' sin beta) + S Psi^2 - rho0 L'^2 (1 + w sin beta)."""
    beta, u, m_f, S, I, rho0 = _kin(p, phi, omega, L, Ld, w)
    cb, sb = math.cos(beta), math.sin(beta)
    return (m_f * p.r0 * (u * u * cb - omega_dot * sb) + S * psi * psi
            - rho0 * Ld * Ld * one_plus(p, phi, L, w))


def tip_rate(p: ArmParams, phi, omega, psi, L, Ld, w) -> float:
    """Angular rate of the tip position vector about the hub axis [rad/s]."""
    beta, u, _, _, _, _ = _kin(p, phi, omega, L, Ld, w)
    r0 = p.r0
    cb, sb = math.cos(beta), math.sin(beta)
    h = r0 * r0 * u + r0 * Ld * sb + r0 * L * (psi + u) * cb + L * L * psi
    return h / (r0 * r0 + L * L + 2.0 * r0 * L * cb)


class Brake(NamedTuple):
    """A brake law: force ``force`` [N] at times ``times`` [s], linear between the points
    and constant outside them."""

    times: np.ndarray
    force: np.ndarray

    def at(self, t: float) -> float:
        """The brake force [N] at time t."""
        return float(np.interp(t, self.times, self.force))

    def breaks(self, t_end: float) -> list:
        """The table's times inside (0, t_end): the force's slope changes there."""
        return [float(t) for t in self.times if 0.0 < t < t_end]


def line_tension(p: ArmParams, phi, omega, psi, omega_dot, L, Ld, Ldd, w) -> float:
    """The line's tension [N] just outside D: minus the along-arm force on the free part
    less the momentum its entering material brings, N = m_f r0 (u^2 cos beta - u' sin beta)
    - m_f L'' + S Psi^2 (u' = omega' + w L'' / r0): what the reel or the brake holds."""
    beta, u, m_f, S, I, _ = _kin(p, phi, omega, L, Ld, w)
    ud = omega_dot + w * Ldd / p.r0
    return m_f * p.r0 * (u * u * math.cos(beta) - ud * math.sin(beta)) - m_f * Ldd + S * psi * psi


def length_row(p: ArmParams, phi, omega, psi, L, Ld, w):
    """Lagrange's equation of the free length (per arm) without the device's force:
    a (omega', Psi', L'') = c - N opw, N the device's force against the slip (its power is
    -N L' opw, opw = 1 + w sin beta). From T = J0 omega^2/2 + n [m_f opw (w r0 omega L' +
    L'^2) + (r0 omega + w L') S cos beta Psi + I Psi^2/2] (docs/analytic.md 4c)."""
    beta, _, m_f, S, I, rho0 = _kin(p, phi, omega, L, Ld, w)
    r0 = p.r0
    cb = math.cos(beta)
    opw = one_plus(p, phi, L, w)
    a = (r0 * m_f * w * opw, w * S * cb, 2.0 * m_f * opw)
    c = (Ld * Ld * (cb * m_f / r0 - opw * rho0) + 2.0 * w * cb * m_f * Ld * (omega - psi)
         + psi * psi * S * opw + cb * m_f * omega * omega * r0)
    return a, c, opw


def device_force(p: ArmParams, phi, omega, psi, omega_dot, psi_dot, L, Ld, Ldd, w) -> float:
    """The force [N] a reel or brake at D exerts against the line's slip, from the free
    length's equation: its power is -N L' (1 + w sin beta) per arm (for a point mass on a
    massless line, the line's tension at D). On the coil's tangent, where the slip and the
    equation vanish together, the line's tension (:func:`line_tension`), its limit."""
    a, c, opw = length_row(p, phi, omega, psi, L, Ld, w)
    if opw < 1e-8:
        return line_tension(p, phi, omega, psi, omega_dot, L, Ld, Ldd, w)
    return (c - a[0] * omega_dot - a[1] * psi_dot - a[2] * Ldd) / opw


def slip_rows(p: ArmParams, phi, omega, psi, L, Ld, w, force):
    """(A (3, 3), b (3,)) of the slipping brake: A (omega', Psi', L'') = b + (M, 0, 0):
    the total angular momentum (K' = M), the moment of momentum of the free part about the
    moving D (H_D' + v_D x p = 0; both as the reel's, and Lagrange's) and Lagrange's
    equation of the free length with the brake's ``force`` against the slip, whose power
    is -force L' (1 + w sin beta): the energy balance holds whatever the line's mass
    (the line's tension at D equal to the force, the momentum balance of the free part
    along the line, lets the rigid arm's transverse force at D work on the material that
    enters there, and near the coil's tangent runs away; for a point mass on a massless
    line the two are the same; docs/analytic.md 4c)."""
    beta, u, m_f, S, I, rho0 = _kin(p, phi, omega, L, Ld, w)
    n, r0 = p.n, p.r0
    cb, sb = math.cos(beta), math.sin(beta)
    a, c, opw = length_row(p, phi, omega, psi, L, Ld, w)
    r1 = n * (r0 * rho0 * Ld * Ld * w * opw + 2.0 * r0 * m_f * Ld * psi * cb
              - r0 * S * sb * (psi * psi - u * u) + 2.0 * S * Ld * psi)
    A = np.array([[p.J0 + n * r0 * S * cb, n * (r0 * S * cb + I),
                   n * (r0 * m_f * w * opw + w * S * cb)],
                  [r0 * S * cb, I, w * S * cb],
                  a])
    b = np.array([-r1, -(r0 * S * u * u * sb + 2.0 * S * Ld * psi), c - force * opw])
    return A, b


def slip_accelerations(A, b, torque=None, omega_dot=None):
    """(omega', Psi', L'', M) of :func:`slip_rows`, given the hub torque M or its
    acceleration omega'."""
    if omega_dot is None:
        x = np.linalg.solve(A, b + np.array([torque, 0.0, 0.0]))
        return x[0], x[1], x[2], torque
    psi_dot, Ldd = np.linalg.solve(A[1:, 1:], b[1:] - A[1:, 0] * omega_dot)
    M = A[0, 0] * omega_dot + A[0, 1] * psi_dot + A[0, 2] * Ldd - b[0]
    return omega_dot, psi_dot, Ldd, M
