"""The vector rows of the step loops: momentum vectors, the hub's pose and the web's distance
from the hub plane, recorded by runs that can leave the plane (a free hub, a perturbation).

A row is :data:`VEC_WIDTH` numbers laid out as :data:`VEC_LAYOUT` (history name, width). The
momenta are those of the row's step n: the mean of the half-step values, as the scalar
columns; positions at x_n. After a node pass x_{n+1} x v_{n+1/2} = x_n x v_{n+1/2}, so the
second half of the momentum sum is taken after the pass.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: (history name, width) of the vector table's columns, in order
VEC_LAYOUT = (("linear_momentum", 3), ("angular_momentum_vector", 3), ("hub_position", 3),
              ("hub_quaternion", 4), ("hub_axis", 3), ("hub_angular_velocity", 3),
              ("out_of_plane_rms", 1), ("out_of_plane_max", 1), ("gravity_gradient_work", 1))
VEC_WIDTH = sum(w for _, w in VEC_LAYOUT)
I_HUB = 6  # first column of the hub's pose
I_RMS = 19  # out-of-plane RMS, then max, then the gravity-gradient work
I_GRAVITY = 21


@njit(cache=True)
def node_momenta(pos, vel, mass, inv_mass, row, w):
    """row[0:3] += w sum m v, row[3:6] += w sum m x x v over the free nodes."""
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
    row[0] += w * px
    row[1] += w * py
    row[2] += w * pz
    row[3] += w * lx
    row[4] += w * ly
    row[5] += w * lz


@njit(cache=True)
def plane_stats(pos, model_inv_mass, centre, axis, row):
    """RMS and largest |(x - centre) . axis| [m] over the web's nodes (those the model does
    not tie to the hub) into row[I_RMS], row[I_RMS + 1]."""
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
    row[I_RMS] = np.sqrt(s / max(count, 1))
    row[I_RMS + 1] = big


@njit(cache=True)
def _add_spin(i, mass, pos, acc):
    """acc += m_i (-y, x, z x, z y) of node i (the sums of :func:`fixed_hub_row`)."""
    m = mass[i]
    acc[0] -= m * pos[i, 1]
    acc[1] += m * pos[i, 0]
    acc[2] += m * pos[i, 2] * pos[i, 0]
    acc[3] += m * pos[i, 2] * pos[i, 1]


@njit(cache=True)
def fixed_hub_row(hub, coil, cs, nodes, pos, theta, w, j_eff, row):
    """The fixed-axis hub's part of a row: the tied and held nodes (model masses) turning at
    w about z, the hub's own spin, and its pose (at the origin, axis +z, angle theta)."""
    acc = np.zeros(4)  # sum m (-y, x, z x, z y) over the tied and held nodes
    for k in range(hub.tied_idx.shape[0]):
        _add_spin(hub.tied_idx[k], nodes.mass, pos, acc)
    for k in range(coil.arm_ptr.shape[0] - 1):
        for p in range(coil.level_ptr[coil.arm_ptr[k] + cs.front[k]],
                       coil.level_ptr[coil.arm_ptr[k + 1]]):
            _add_spin(coil.level_nodes[p], nodes.mass, pos, acc)
    px, py, sx, sy = acc[0], acc[1], acc[2], acc[3]
    row[0] += w * px  # sum m w z x x
    row[1] += w * py
    row[3] -= w * sx  # sum m x x (w z x x) = w sum m ((x^2 + y^2) z - z (x, y, 0))
    row[4] -= w * sy
    row[5] += j_eff * w  # J_eff counts the tied and held m (x^2 + y^2)
    for d in range(3):
        row[I_HUB + d] = 0.0
    row[9] = np.cos(0.5 * theta)
    row[10] = 0.0
    row[11] = 0.0
    row[12] = np.sin(0.5 * theta)
    row[13] = 0.0
    row[14] = 0.0
    row[15] = 1.0
    row[16] = 0.0
    row[17] = 0.0
    row[18] = w
