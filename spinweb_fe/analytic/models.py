"""Equations of the rigid-arm deployment model (paper Eqs. 4-8): ``printed`` and ``consistent``.

A hub of radius r0 and inertia J_hub spins about +z (angle theta, rate omega). n identical
straight arms of length H are attached to the rim, each carrying a distributed mass (the
paper's Eq. 7 profile, zero at the tip, and/or a uniform tether) and a tip mass. Per arm
the generalised coordinate is the arm angle phi (from the outward radial at the root,
counter-clockwise positive). While |phi| > pi/2 the arm is wound on the hub over
alpha = |phi| - pi/2 and its free part, of length L = H - r0 alpha, leaves the hub
tangentially at the departure point; otherwise the arm pivots about its root (L = H).

The state used by the equations is (phi, omega, Psi) with Psi = omega + dphi/dt the absolute
angular rate of the free arm. Both models are linear in the accelerations,

    a11 omega' + a12 Psi' = b1 + M        (hub row)
    a21 omega' + a22 Psi' = b2            (arm row)

and :func:`accelerations` solves them either for (omega', Psi') given the hub torque M, or
for (Psi', M) given a prescribed omega'. The derivation is in docs/analytic.md. The
physical invariants (:func:`invariants`) are the same for both models: the ``printed``
model is judged by how well it conserves them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from meshgen.registry import TOPOLOGIES, cable_length_per_area

MODELS = ("printed", "consistent")
HALF_PI = 0.5 * math.pi


@dataclass(frozen=True)
class ArmParams:
    """Parameters of the hub-and-arms model (SI units).

    Parameters
    ----------
    n : int
        Number of arms (tethers), placed symmetrically.
    H : float [m]
        Arm length (free length when fully deployed).
    r0 : float [m]
        Hub radius (radius of the arm roots and of the coil).
    J_hub : float [kg m^2]
        Hub inertia about the spin axis (hub alone, no web).
    m_tip : float [kg]
        Point mass at each arm tip (corner mass).
    m_lin : float [kg]
        Web mass per arm with the paper's Eq. 7 profile: line density
        2 m_lin/H^2 (H - s) at arm coordinate s from the root (zero at the tip).
    m_uni : float [kg]
        Uniformly distributed mass per arm (a tether of line density m_uni/H).
    """

    n: int
    H: float
    r0: float
    J_hub: float
    m_tip: float
    m_lin: float = 0.0
    m_uni: float = 0.0

    def __post_init__(self):
        if self.n < 1 or self.H <= 0 or self.r0 <= 0 or self.J_hub <= 0:
            raise ValueError("need n >= 1, H > 0, r0 > 0, J_hub > 0")
        if min(self.m_tip, self.m_lin, self.m_uni) < 0 or self.m_arm <= 0:
            raise ValueError("arm masses must be >= 0 with a positive total")

    @property
    def m_arm(self) -> float:
        """Total mass of one arm, tip included [kg]."""
        return self.m_tip + self.m_lin + self.m_uni

    @property
    def J0(self) -> float:
        """Hub inertia plus every arm mass at the rim radius [kg m^2] (the fully coiled inertia)."""
        return self.J_hub + self.n * self.m_arm * self.r0 ** 2

    @property
    def phi_coiled(self) -> float:
        """|phi| of a fully coiled arm (L = 0) [rad]."""
        return HALF_PI + self.H / self.r0

    def moments(self, L: float) -> tuple[float, float, float]:
        """Mass, first and second moment about the free arm's base of the free part of length L.

        The free part is the outer (tip) end of the arm: the profile measured from the tip is
        fixed, so its moments are those of the last L metres.

        Returns
        -------
        m_f [kg], S [kg m], I [kg m^2]
        """
        H = self.H
        lin = self.m_lin / (H * H)   # Eq. 7: rho_L = 2 m_lin/H^2 (L - l), 0 <= l <= L
        uni = self.m_uni / H
        L2 = L * L
        m_f = lin * L2 + uni * L + self.m_tip
        S = lin * L2 * L / 3.0 + uni * L2 / 2.0 + self.m_tip * L
        I = lin * L2 * L2 / 6.0 + uni * L2 * L / 3.0 + self.m_tip * L2
        return m_f, S, I

    def root_density(self, L: float) -> float:
        """Line density [kg/m] at the base of a free part of length L: d m_f / dL."""
        return 2.0 * self.m_lin * L / (self.H * self.H) + self.m_uni / self.H


def geometry(p: ArmParams, phi: float, coiled: bool):
    """Free length and the effective angle of the free arm at its base.

    Returns
    -------
    L : float [m]
        Free arm length.
    c, s : float
        cos and sin of the free arm's angle from the radial at its base (0 and +-1 while
        coiled: the free part leaves tangentially).
    sigma : float
        +1 for a leading coil (phi > pi/2), -1 for a trailing coil (phi < -pi/2), 0 uncoiled.
    """
    if coiled:
        sigma = 1.0 if phi > 0 else -1.0
        return p.H - p.r0 * (sigma * phi - HALF_PI), 0.0, sigma, sigma
    return p.H, math.cos(phi), math.sin(phi), 0.0


def _rows(model, p: ArmParams, phi, omega, psi, coiled):
    """Coefficients (a11, a12, b1, a21, a22, b2) of the two equations of motion."""
    L, c, s, sigma = geometry(p, phi, coiled)
    m_f, S, I = p.moments(L)
    n, r0 = p.n, p.r0
    if model == "consistent":
        if coiled:   # Lagrange with T = J0 w^2/2 + n I(L) Psi^2/2, L = H - r0 alpha
            return (p.J0, 0.0, n * sigma * r0 * S * psi * psi,
                    0.0, I, -2.0 * sigma * r0 * S * psi * (omega - 0.5 * psi))
        # pivoting arm: moment balance about the root; root force acts on the hub
        return (p.J0, n * r0 * S * c, n * r0 * S * s * psi * psi,
                r0 * S * c, I, -r0 * S * s * omega * omega)
    if model == "printed":
        if coiled:   # Eqs. 4, 5/8a, 6/8b with omega -> omega + phi', phi -> +-pi/2, L' = -+ r0 phi'
            return (p.J_hub + n * r0 * r0 * m_f, 0.0, n * sigma * r0 * S * psi * psi,
                    0.0, S, -2.0 * sigma * r0 * m_f * psi * (omega - 0.5 * psi))
        # Eq. 4 with N from Eq. 5/8a; Eq. 6/8b (transverse force balance) with L' = 0
        return (p.J_hub + n * r0 * r0 * m_f * s * s, 0.0,
                n * r0 * s * (m_f * r0 * omega * omega * c + S * psi * psi),
                m_f * r0 * c, S, -m_f * r0 * s * omega * omega)
    raise ValueError(f"unknown model '{model}' (valid: {', '.join(MODELS)})")


def accelerations(model: str, p: ArmParams, phi: float, omega: float, psi: float,
                  coiled: bool, torque: float | None = None,
                  omega_dot: float | None = None) -> tuple[float, float, float]:
    """Hub and arm angular accelerations and the hub torque.

    Give exactly one of ``torque`` (hub torque M [N m], the hub rate is free) or
    ``omega_dot`` (prescribed hub acceleration [rad/s^2], the required torque is returned).

    Parameters
    ----------
    model : {'printed', 'consistent'}
    p : ArmParams
    phi : float [rad]
        Arm angle.
    omega : float [rad/s]
        Hub rate.
    psi : float [rad/s]
        Absolute rate of the free arm, omega + dphi/dt.
    coiled : bool
        Regime: True while the arm is wound on the hub (|phi| > pi/2).

    Returns
    -------
    omega_dot [rad/s^2], psi_dot [rad/s^2], torque [N m]
    """
    return solve_rows(_rows(model, p, phi, omega, psi, coiled), torque, omega_dot)


def solve_rows(coeffs, torque=None, omega_dot=None) -> tuple[float, float, float]:
    """(omega', Psi', M) from the coefficients (a11, a12, b1, a21, a22, b2) of
    a11 omega' + a12 Psi' = b1 + M, a21 omega' + a22 Psi' = b2, given the torque M or the
    hub acceleration omega'."""
    a11, a12, b1, a21, a22, b2 = coeffs
    if omega_dot is None:
        det = a11 * a22 - a12 * a21
        omega_dot = ((b1 + torque) * a22 - a12 * b2) / det
        psi_dot = (a11 * b2 - a21 * (b1 + torque)) / det
        return omega_dot, psi_dot, torque
    psi_dot = (b2 - a21 * omega_dot) / a22
    return omega_dot, psi_dot, a11 * omega_dot + a12 * psi_dot - b1


def invariants(p: ArmParams, phi: float, omega: float, psi: float, coiled: bool):
    """Kinetic energy and angular momentum of hub + arms (the physical ones, for both models).

    The wound part of each arm turns with the hub at radius r0; the free part moves with
    the velocity sigma r0 omega u + l Psi n while coiled (u along the arm, n normal to it)
    and r0 omega e_theta + l Psi n while pivoting about the root.

    Returns
    -------
    E [J], K [N m s]
    """
    L, c, s, sigma = geometry(p, phi, coiled)
    m_f, S, I = p.moments(L)
    n, r0 = p.n, p.r0
    E = 0.5 * p.J0 * omega * omega + n * (0.5 * I * psi * psi + r0 * S * c * omega * psi)
    K = p.J0 * omega + n * (I * psi + r0 * S * c * (omega + psi))
    return E, K


def root_tension(p: ArmParams, phi, omega, psi, omega_dot, coiled) -> float:
    """Arm tension N [N] at the root (pivoting) or at the departure point (coiled).

    N = m_f r0 (omega^2 cos - omega' sin) + S Psi^2: the along-arm momentum balance of the
    free part (Eq. 8a with the corner mass added; identical in both models).
    """
    L, c, s, sigma = geometry(p, phi, coiled)
    m_f, S, I = p.moments(L)
    return m_f * p.r0 * (omega * omega * c - omega_dot * s) + S * psi * psi


def tip_rate(p: ArmParams, phi, omega, psi, coiled) -> float:
    """Angular rate of the tip position vector about the hub axis, (r x v)_z / |r|^2 [rad/s]."""
    L, c, s, sigma = geometry(p, phi, coiled)
    r0 = p.r0
    h = r0 * r0 * omega + r0 * L * c * (omega + psi) + L * L * psi
    return h / (r0 * r0 + L * L + 2.0 * r0 * L * c)


def params_from_case(case, tether_mass: bool = True) -> ArmParams:
    """Map a case to the model parameters.

    Tether scene: n = tethers.count, H = tethers.length, tip mass, and (if ``tether_mass``)
    the tether's own mass: ``tethers.arm_mass`` with the Eq. 7 profile if given, else
    rho A H as a uniform arm mass (the FE tether has line density rho A). Web scene: n = 4 (square outlines) or 3 (triangular), H = side/2, and the web
    mass m_w = rho_A x web area with the paper's Eq. 7 profile, m_w/n per arm; rho_A is
    web.areal_density or the continuum value rho A lambda of the mesh (lambda = 2/t for a
    square mesh). The hub cut-out is not modelled (see docs/analytic.md).
    """
    hub = case.hub
    if case.scene == "tethers":
        t = case.tethers
        if t.arm_mass is not None:  # the paper's arm: Eq. 7 density, zero at the tip
            m_lin = t.arm_mass if tether_mass else 0.0
            return ArmParams(n=t.count, H=t.length, r0=hub.radius, J_hub=hub.inertia,
                             m_tip=case.tip_mass.mass, m_lin=m_lin)
        m_uni = case.cable.density * case.cable.area * t.length if tether_mass else 0.0
        return ArmParams(n=t.count, H=t.length, r0=hub.radius, J_hub=hub.inertia,
                         m_tip=case.tip_mass.mass, m_uni=m_uni)
    w = case.web
    rho_a = w.areal_density
    if rho_a is None:
        rho_a = case.cable.density * case.cable.area * cable_length_per_area(w.topology,
                                                                             w.mesh_width)
    n = TOPOLOGIES[w.topology].corners
    area = math.sqrt(3.0) / 4.0 * w.side ** 2 if n == 3 else w.side ** 2
    return ArmParams(n=n, H=0.5 * w.side, r0=hub.radius, J_hub=hub.inertia,
                     m_tip=case.tip_mass.mass, m_lin=rho_a * area / n)
