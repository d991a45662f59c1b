"""The gravity gradient of a circular orbit about the Earth (``[environment]``).

The frame of the run is inertial (not rotating), its origin the orbit point O, which moves
on a circular orbit of radius a about the Earth with mean motion n = sqrt(mu / a^3). Relative
to O a mass at x feels, to first order in |x| / a (1e-5 for a 100 m web in low orbit), the
tidal acceleration

    g(x, t) = n^2 (3 (e . x) e - x),    e(t) = cos(n t) e1 + sin(n t) e2,

e the unit vector from the Earth to O (the local vertical), e1, e2 the orbit plane. The field
turns with the orbit, so it does work: ``gravity_gradient_work`` is the sum over the steps of
dt g . (v_{n-1/2} + v_{n+1/2}) / 2 m on every free node, and the same for the body (force
M g(X) at its centre of mass, torque 3 n^2 e x (I_s e) about it, the sum over its points of
m (x - X) x g: the field is linear). This inertial frame keeps the solver, the rigid hub and
the momentum histories as they are; the orbiting (Hill) frame would add Coriolis and
centrifugal terms to every node and turn the spin axis at -n.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

MU_EARTH = 3.986004418e14  # [m^3/s^2] gravitational parameter (EGM96 / WGS84)
R_EARTH = 6.371e6  # [m] mean radius


class Environment(NamedTuple):
    """The tidal field (fixed during a run).

    Attributes
    ----------
    n : float [rad/s]
        Mean motion of the orbit (0: no gravity gradient).
    e1, e2 : (3,) float64
        Orthonormal basis of the orbit plane: the local vertical is e1 at t = 0 and turns
        towards e2.
    """

    n: float
    e1: np.ndarray
    e2: np.ndarray


def no_environment() -> Environment:
    """No gravity gradient."""
    return Environment(0.0, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))


def orbit(radius: float, tilt: float = 0.0) -> Environment:
    """A circular orbit of ``radius`` [m] about the Earth whose normal is the spin axis +z
    turned by ``tilt`` [rad] about +x: e1 = x, e2 = (0, cos tilt, sin tilt)."""
    return Environment(math.sqrt(MU_EARTH / radius ** 3), np.array([1.0, 0.0, 0.0]),
                       np.array([0.0, math.cos(tilt), math.sin(tilt)]))


@njit(cache=True)
def vertical(env, t):
    """e(t): the unit vector from the Earth to the orbit point."""
    c = np.cos(env.n * t)
    s = np.sin(env.n * t)
    return c * env.e1 + s * env.e2


@njit(cache=True)
def tidal_accel(n2, e, x0, x1, x2):
    """g(x) = n^2 (3 (e . x) e - x) [m/s^2]."""
    ex = 3.0 * (e[0] * x0 + e[1] * x1 + e[2] * x2)
    return n2 * (ex * e[0] - x0), n2 * (ex * e[1] - x1), n2 * (ex * e[2] - x2)


@njit(cache=True)
def body_tidal(env, t, mass, X, inertia_s):
    """(F, T): the tidal force M g(X) on a body of mass M centred at X and its torque
    3 n^2 e x (I_s e) about X (I_s: the inertial inertia tensor about X)."""
    e = vertical(env, t)
    n2 = env.n * env.n
    gx, gy, gz = tidal_accel(n2, e, X[0], X[1], X[2])
    F = np.array([mass * gx, mass * gy, mass * gz])
    Ie = inertia_s @ e
    T = 3.0 * n2 * np.array([e[1] * Ie[2] - e[2] * Ie[1], e[2] * Ie[0] - e[0] * Ie[2],
                             e[0] * Ie[1] - e[1] * Ie[0]])
    return F, T


@njit(cache=True)
def node_tidal(env, t, pos, mass, force, tidal):
    """tidal[i] = m_i g(x_i, t) [N] of every node (``mass``: the model's masses, the nodes
    that move with a fixed axis included), added to ``force`` (n, 3)."""
    e = vertical(env, t)
    n2 = env.n * env.n
    for i in range(pos.shape[0]):
        m = mass[i]
        gx, gy, gz = tidal_accel(n2, e, pos[i, 0], pos[i, 1], pos[i, 2])
        tidal[i, 0] = m * gx
        tidal[i, 1] = m * gy
        tidal[i, 2] = m * gz
        force[i, 0] += tidal[i, 0]
        force[i, 1] += tidal[i, 1]
        force[i, 2] += tidal[i, 2]


@njit(cache=True)
def tidal_power(tidal, vel, inv_mass):
    """sum tidal_i . v_i [W] over the nodes with active mass (1/m > 0)."""
    p = 0.0
    for i in range(tidal.shape[0]):
        if inv_mass[i] > 0.0:
            p += tidal[i, 0] * vel[i, 0] + tidal[i, 1] * vel[i, 1] + tidal[i, 2] * vel[i, 2]
    return p


@njit(cache=True)
def axis_hub_tidal(env, t, hub):
    """3 n^2 e x (I e) [N m]: the tidal torque on an axisymmetric hub on the fixed axis +z
    (I = diag(I_t, I_t, J) about its centre, the origin)."""
    e = vertical(env, t)
    n2 = env.n * env.n
    ie = np.array([hub.transverse * e[0], hub.transverse * e[1], hub.inertia * e[2]])
    return 3.0 * n2 * np.array([e[1] * ie[2] - e[2] * ie[1], e[2] * ie[0] - e[0] * ie[2],
                                e[0] * ie[1] - e[1] * ie[0]])
