"""Per-arm measures of the FE state, defined as in the analytical model.

For each arm (tether) with root on the hub rim at hub-frame angle theta_R and tip at p:
- uncoiled (the straight root-to-tip chord leaves the hub outwards): L = |p - R|,
  phi = angle of p - R from the outward radial at R, counter-clockwise positive;
- coiled over a wound angle alpha (the free part leaves the rim tangentially at the
  departure point D): L = sqrt(|p|^2 - r0^2) (tangent length from D to the tip),
  phi = -(pi/2 + alpha) for a trailing coil (wound clockwise from the root), +(pi/2 + alpha)
  for a leading one. alpha is tracked continuously in time, so several turns and re-coiling
  the other way are followed.
- omega_tip = (p x v)_z / |p|^2: the rate of the tip's polar angle about the hub axis.
"""

from __future__ import annotations

import math

import numpy as np


class ArmTracker:
    """Turns recorded tip positions / velocities into L, phi, omega_tip (continuous alpha).

    Parameters
    ----------
    root_angle : (n_arms,) [rad]   hub-frame angle of each arm's root on the rim
    r0 : float [m]                 hub radius
    alpha0 : (n_arms,) [rad]       initial signed wound angle (+ trailing, - leading, 0 free)
    """

    def __init__(self, root_angle, r0, alpha0):
        self.root = np.asarray(root_angle, dtype=float)
        self.r0 = float(r0)
        self.alpha = np.asarray(alpha0, dtype=float).copy()
        self.phi = np.where(self.alpha > 0, -1.0, np.where(self.alpha < 0, 1.0, 0.0))

    def _one(self, k, x, y):
        r0 = self.r0
        c, s = math.cos(self.root[k]), math.sin(self.root[k])
        xl, yl = c * x + s * y, -s * x + c * y  # tip in the root frame (root at (r0, 0))
        qx, qy = xl - r0, yl
        a_prev = self.alpha[k]
        if abs(a_prev) < 0.5 * math.pi and qx >= 0.0:
            self.alpha[k] = 0.0
            phi = math.atan2(qy, qx)
            self.phi[k] = phi
            return math.hypot(qx, qy), phi
        rho2 = xl * xl + yl * yl
        length = math.sqrt(max(rho2 - r0 * r0, 0.0))
        gamma = math.atan2(length, r0)
        beta = math.atan2(yl, xl)
        sign = 1.0 if (a_prev > 0 or (a_prev == 0 and self.phi[k] <= 0)) else -1.0
        a = -sign * beta - gamma  # |alpha| modulo 2 pi
        a += 2 * math.pi * round((abs(a_prev) - a) / (2 * math.pi))  # branch nearest alpha_prev
        a = max(a, 0.0)
        self.alpha[k] = sign * a
        phi = -sign * (0.5 * math.pi + a)
        self.phi[k] = phi
        return length, phi

    def update(self, tip_pos, tip_vel, hub_angle):
        """(T, n, 3) tip positions and velocities (inertial) and (T,) hub angle ->
        (L, phi, omega_tip), each (T, n)."""
        T, n = tip_pos.shape[:2]
        L = np.empty((T, n))
        phi = np.empty((T, n))
        for t in range(T):
            c, s = math.cos(hub_angle[t]), math.sin(hub_angle[t])
            for k in range(n):
                x, y = tip_pos[t, k, 0], tip_pos[t, k, 1]
                L[t, k], phi[t, k] = self._one(k, c * x + s * y, -s * x + c * y)
        px, py = tip_pos[..., 0], tip_pos[..., 1]
        r2 = np.maximum(px * px + py * py, 1e-300)
        omega_tip = (px * tip_vel[..., 1] - py * tip_vel[..., 0]) / r2
        return L, phi, omega_tip


def initial_alpha(mesh) -> np.ndarray:
    """Signed wound angle of each arm in the initial mesh: wrap * (free arm length) / r0 for a
    coiled mesh, 0 otherwise."""
    n = mesh.n_arms
    if mesh.wrap == 0 or mesh.hub_radius <= 0:
        return np.zeros(n)
    free = mesh.arm_length - mesh.arm_root_coord
    return np.full(n, mesh.wrap * free / mesh.hub_radius)
