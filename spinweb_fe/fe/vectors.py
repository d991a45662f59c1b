"""The vector rows of the step loop: momentum vectors, the hub's pose and the web's distance
from the hub plane, recorded by runs that can leave the plane (a free hub, a perturbation).

A row is laid out as :data:`spinweb_fe.fe.layout.VECTOR` (the kernels take its slots). The
momenta are those of the row's step n: the mean of the half-step values, as the scalar
columns; positions at x_n. After a node pass x_{n+1} x v_{n+1/2} = x_n x v_{n+1/2}, so the
second half of the momentum sum is taken after the pass.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def node_momenta(pos, vel, mass, inv_mass, row, w, vs):
    """w sum m v and w sum m x x v over the free nodes, added to the row's slots
    ``vs.linear_momentum`` and ``vs.angular_momentum_vector``."""
    px = py = pz = lx = ly = lz = 0.0
    for i in range(pos.shape[0]):
        if inv_mass[i] > 0.0:
            m = mass[i]
            vx, vy, vz = m * vel[i, 0], m * vel[i, 1], m * vel[i, 2]
            px += vx
            py += vy
            pz += vz
            lx += pos[i, 1] * vz - pos[i, 2] * vy
            ly += pos[i, 2] * vx - pos[i, 0] * vz
            lz += pos[i, 0] * vy - pos[i, 1] * vx
    p, a = vs.linear_momentum, vs.angular_momentum_vector
    row[p] += w * px
    row[p + 1] += w * py
    row[p + 2] += w * pz
    row[a] += w * lx
    row[a + 1] += w * ly
    row[a + 2] += w * lz


@njit(cache=True)
def plane_stats(pos, model_inv_mass, centre, axis, row, vs):
    """RMS and largest |(x - centre) . axis| [m] over the web's nodes (those the model does
    not tie to the hub) into the row's slots ``vs.out_of_plane_rms`` and ``_max``."""
    s = 0.0
    big = 0.0
    count = 0
    for i in range(pos.shape[0]):
        if model_inv_mass[i] > 0.0:
            d = ((pos[i, 0] - centre[0]) * axis[0] + (pos[i, 1] - centre[1]) * axis[1]
                 + (pos[i, 2] - centre[2]) * axis[2])
            s += d * d
            big = max(big, abs(d))
            count += 1
    row[vs.out_of_plane_rms] = np.sqrt(s / max(count, 1))
    row[vs.out_of_plane_max] = big
