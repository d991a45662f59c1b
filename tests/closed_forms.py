"""Closed-form references shared by several tests."""

import numpy as np

from meshgen.mesh import lumped_mass


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
