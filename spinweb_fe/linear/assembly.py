"""Assembly of the linear analyses of a flat pin-jointed web (in-plane): the free-dof
projection, the equilibrium matrix and the geometric stiffness."""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix


def free_dof_basis(xy, fixed_nodes, roller=None):
    """Sparse projection P (dof, 2n) onto the free in-plane dof.

    Parameters
    ----------
    xy : (n, 2) float64 [m]
    fixed_nodes : int array
        Nodes fixed in both directions.
    roller : tuple (node, direction) or None
        A node that may move only along the unit vector ``direction``.
    """
    n = len(xy)
    fixed = set(int(i) for i in fixed_nodes)
    rows, cols, vals = [], [], []
    dof = 0
    for i in range(n):
        if roller is not None and i == roller[0]:
            rows += [dof, dof]
            cols += [2 * i, 2 * i + 1]
            vals += [float(roller[1][0]), float(roller[1][1])]
            dof += 1
        elif i not in fixed:
            rows += [dof, dof + 1]
            cols += [2 * i, 2 * i + 1]
            vals += [1.0, 1.0]
            dof += 2
    return csr_matrix((vals, (rows, cols)), shape=(dof, 2 * n))


def equilibrium_matrix(xy, bars):
    """Full equilibrium matrix (2n, b): column k holds the unit pulls of bar k on its nodes.

    Sign convention: ``A t = f`` with t > 0 a tension and f the external load.
    """
    n = len(xy)
    a, b = bars[:, 0], bars[:, 1]
    d = xy[a] - xy[b]
    e = d / np.linalg.norm(d, axis=1)[:, None]
    A = np.zeros((2 * n, len(bars)))
    k = np.arange(len(bars))
    for c in range(2):
        A[2 * a + c, k] += e[:, c]   # node a is pulled towards b: -t e balances +f
        A[2 * b + c, k] -= e[:, c]
    return A


def geometric_stiffness(xy, bars, tension):
    """(2n, 2n) geometric stiffness [N/m] of bars with the given tensions."""
    n = len(xy)
    d = xy[bars[:, 1]] - xy[bars[:, 0]]
    length = np.linalg.norm(d, axis=1)
    e = d / length[:, None]
    g = (tension / length)[:, None, None] * (np.eye(2)[None] - e[:, :, None] * e[:, None, :])
    K = np.zeros((n, 2, n, 2))
    i, j = bars[:, 0], bars[:, 1]
    for a, b, sign in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
        np.add.at(K, (a, slice(None), b), sign * g)
    return K.reshape(2 * n, 2 * n)
