"""The cable element law, one piece per stage, shared by the element loops of fe.forces (the
step's block pass), fe.rupture (with the strength check) and fe.step (the plain scatter loop
of frames and the start). Inlined into the loops at numba IR level (``inline="always"``), so a
loop is the code it would be written out by hand."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(inline="always")
def length_strain(dx, dy, dz, inv_rest_e):
    """(1/L, strain) of an element with end difference (dx, dy, dz): the tension-only strain
    max(L/L0 - 1, 0) as a branch-free max; a zero length gets 1e-300 under the root."""
    ln = np.sqrt(dx * dx + dy * dy + dz * dz + 1e-300)
    inv = 1.0 / ln
    return inv, max(ln * inv_rest_e - 1.0, 0.0)


@njit(inline="always")
def stretch(pos, i, j, inv_rest_e):
    """(dx, dy, dz, 1/L, strain) of the element i -> j (see :func:`length_strain`)."""
    dx = pos[j, 0] - pos[i, 0]
    dy = pos[j, 1] - pos[i, 1]
    dz = pos[j, 2] - pos[i, 2]
    inv, strain = length_strain(dx, dy, dz, inv_rest_e)
    return dx, dy, dz, inv, strain


@njit(inline="always")
def rate(dx, dy, dz, inv, du, dv, dw):
    """dL/dt [m/s] of an element with end differences (dx, dy, dz) and (du, dv, dw) of the
    velocities."""
    return inv * (dx * du + dy * dv + dz * dw)


@njit(inline="always")
def lengthening(vel, i, j, dx, dy, dz, inv):
    """dL/dt [m/s] of the element i -> j."""
    return rate(dx, dy, dz, inv, vel[j, 0] - vel[i, 0], vel[j, 1] - vel[i, 1],
                vel[j, 2] - vel[i, 2])


@njit(inline="always")
def damped_tension(n_el, strain, cdamp_e, ldot):
    """N_el + c dL/dt while taut, never negative [N]."""
    taut = 1.0 if strain > 0.0 else 0.0
    return max(n_el + taut * cdamp_e * ldot, 0.0)
