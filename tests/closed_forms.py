"""Closed-form references shared by several tests."""

import numpy as np

from meshgen.mesh import lumped_mass
from spinweb_fe.linear.steady import Structure

ZYLON_E, ZYLON_RHO, PAPER_AREA = 180e9, 1540.0, 1.025e-5


def quadquad_line_tensions(mesh, omega, line_density):
    """(m,) [N] tensions of a spinning flat square grid: statically determinate, each mesh
    line carries the centrifugal pull of its own nodes beyond the element,
    t = omega^2 sum m_k |x_k| over the nodes of the line farther out than the element."""
    mass = lumped_mass(mesh, line_density)
    xy = mesh.node_ref[:, :2]
    out = np.empty(mesh.n_elems)
    for k, (i, j) in enumerate(mesh.elem_nodes):
        d = xy[j] - xy[i]
        ax = 0 if abs(d[0]) > abs(d[1]) else 1
        outer = j if abs(xy[j, ax]) > abs(xy[i, ax]) else i
        line = np.isclose(xy[:, 1 - ax], xy[outer, 1 - ax])
        beyond = line & (np.sign(xy[:, ax]) == np.sign(xy[outer, ax])) & (
            np.abs(xy[:, ax]) >= abs(xy[outer, ax]) - 1e-9)
        out[k] = omega ** 2 * np.sum(mass[beyond] * np.abs(xy[beyond, ax]))
    return out


def string_structure(m, E=1000 * ZYLON_E, length=50.0):
    """A uniform string of ``length`` rooted on the axis (node 0 at the origin, tied), m
    elements, no tip mass: its spinning modes are Legendre's, omega_l / Omega =
    sqrt(l (l + 1) / 2) out of the plane and sqrt(l (l + 1) / 2 - 1) in it, l odd."""
    x = np.linspace(0.0, length, m + 1)
    pos = np.column_stack([x, np.zeros(m + 1), np.zeros(m + 1)])
    elems = np.column_stack([np.arange(m), np.arange(1, m + 1)])
    mass = np.zeros(m + 1)
    np.add.at(mass, elems.ravel(), 0.5 * ZYLON_RHO * PAPER_AREA * length / m)
    return Structure(pos, mass, elems, np.full(m, length / m), np.full(m, E * PAPER_AREA),
                     np.array([0]), 1.0)
