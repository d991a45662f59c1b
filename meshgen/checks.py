"""Mesh invariants and mass diagnostics.

:func:`check_mesh` lists every violated invariant of a :class:`~meshgen.mesh.Mesh`
(used by :func:`meshgen.build.build_mesh` and by the tests). :func:`arm_mass_profile`
and :func:`eq7_error` measure how well the folded web reproduces the paper's arm mass
density (Eq. 7), see docs/mesh.md.
"""

from __future__ import annotations

import numpy as np

from meshgen.mesh import Mesh


class MeshValueError(ValueError):
    """Invalid mesh-generation input.

    Parameters
    ----------
    param : str
        Name of the generator parameter at fault (``side``, ``mesh_width``,
        ``hub_cutout``, ``hub_radius``, ``topology``, ``pattern``, ...);
        :func:`meshgen.build.build_mesh` maps it to a case key.
    reason : str
        What is wrong, in one line.
    """

    def __init__(self, param, reason):
        self.param = param
        self.reason = reason
        super().__init__(f"{param}: {reason}")


def check_mesh(mesh: Mesh, tol: float = 1e-9) -> list[str]:
    """Violated mesh invariants, one message per kind (empty list: the mesh is valid).

    Checked: finite arrays; element and node-set indices in range; no element joining a
    node to itself; rest lengths > 0 and equal to the reference (flat) lengths; no element
    longer than its rest length in ``node_pos`` (relative ``tol``); point masses >= 0;
    with a hub (``hub_radius > 0``): no free node strictly inside the hub cylinder and no
    tied node inside the rim (radius in the x-y plane, relative ``tol``); arm indices in
    ``[-1, n_arms)``.

    Parameters
    ----------
    mesh : Mesh
    tol : float
        Relative tolerance [-].

    Returns
    -------
    list of str
    """
    bad = []
    n = mesh.n_nodes
    for name in ("node_pos", "node_ref", "elem_rest_len", "node_point_mass", "arm_root_angle"):
        if not np.all(np.isfinite(getattr(mesh, name))):
            bad.append(f"{name} has non-finite values")
    en = mesh.elem_nodes
    if en.size and (en.min() < 0 or en.max() >= n):
        bad.append("elem_nodes index out of range")
        return bad
    if np.any(en[:, 0] == en[:, 1]):
        bad.append(f"{int(np.sum(en[:, 0] == en[:, 1]))} elements join a node to itself")
    for name, idx in mesh.node_sets.items():
        if idx.size and (idx.min() < 0 or idx.max() >= n):
            bad.append(f"node set '{name}' index out of range")
    for name, idx in mesh.elem_sets.items():
        if idx.size and (idx.min() < 0 or idx.max() >= mesh.n_elems):
            bad.append(f"element set '{name}' index out of range")
    rest = mesh.elem_rest_len
    if np.any(rest <= 0):
        bad.append(f"{int(np.sum(rest <= 0))} rest lengths are not positive")
    ref = mesh.elem_length(mesh.node_ref)
    dev = np.abs(ref - rest) > tol * rest
    if np.any(dev):
        bad.append(f"{int(dev.sum())} rest lengths differ from the reference (flat) lengths")
    cur = mesh.elem_length()
    over = cur > rest * (1.0 + tol)
    if np.any(over):
        i = int(np.argmax(cur / rest))
        bad.append(f"{int(over.sum())} elements are longer than their rest length "
                   f"(worst: element {i}, strain {cur[i] / rest[i] - 1:.3e})")
    if np.any(mesh.node_point_mass < 0):
        bad.append("negative point masses")
    if mesh.node_arm.size and (mesh.node_arm.min() < -1 or mesh.node_arm.max() >= mesh.n_arms):
        bad.append("node_arm out of range")
    r0 = mesh.hub_radius
    if r0 > 0:
        r = np.hypot(mesh.node_pos[:, 0], mesh.node_pos[:, 1])
        tied = np.zeros(n, bool)
        tied[mesh.node_sets["hub_tied"]] = True
        inside = r < r0 * (1.0 - tol)
        if np.any(inside & ~tied):
            bad.append(f"{int(np.sum(inside & ~tied))} free nodes are inside the hub "
                       f"(smallest radius {r[~tied].min():.6g} m < r0 = {r0:.6g} m)")
        if np.any(inside & tied):
            bad.append(f"{int(np.sum(inside & tied))} hub-tied nodes are inside the rim")
    return bad


def arm_mass_profile(mesh: Mesh, node_mass: np.ndarray, arm: int):
    """Mass of one arm deposited on the grid l_i = i h of arm coordinates (cloud in cell).

    Each node of the arm gives its lumped mass to the two nearest grid points with linear
    (hat-function) weights, so nodes that lie between grid lines (``elements_per_segment
    > 1``) are split without ambiguity.

    Parameters
    ----------
    mesh : Mesh
        A mesh with arm data (``node_arm``, ``node_arm_coord``, ``arm_length``).
    node_mass : (n,) float64 [kg]
        Lumped node masses (cable only, or with point masses).
    arm : int
        Arm index.

    Returns
    -------
    l : (K,) float64 [m]
        Grid points 0, h, ..., arm_length with h the smallest spacing of the arm's
        mesh lines (the mesh width).
    m : (K,) float64 [kg]
        Mass deposited on each grid point.
    """
    sel = mesh.node_arm == arm
    l = mesh.node_arm_coord[sel]
    H = mesh.arm_length
    h = _line_spacing(mesh)
    K = int(round(H / h))
    x = l / h
    i0 = np.clip(np.floor(x).astype(np.int64), 0, K - 1)
    w1 = x - i0
    m = np.zeros(K + 1)
    np.add.at(m, i0, (1.0 - w1) * node_mass[sel])
    np.add.at(m, i0 + 1, w1 * node_mass[sel])
    return np.arange(K + 1) * h, m


def _line_spacing(mesh: Mesh) -> float:
    """Mesh width t of a square web: spacing of the distinct reference x coordinates of
    the grid's mesh lines (rest length times elements per segment)."""
    nodes = mesh.node_sets.get("mesh_nodes")
    x = np.unique(np.round(mesh.node_ref[nodes, 0], 9))
    return float(np.min(np.diff(x)))


def eq7_reference(l: np.ndarray, h: float, half_side: float, cutout: float,
                  areal_density: float) -> np.ndarray:
    """Exact hat-weighted arm mass on the grid l_i for the density of docs/mesh.md.

    rho_L(l) = 2 rho_A (a - max(l, c)): Eq. 7 (with H = a) for l >= c, and constant in
    the gathered root region l < c where the central square of half-width c is cut out.
    The kink at l = c is a grid point, so each half-hat integrates a linear function.

    Parameters
    ----------
    l : (K,) float64 [m]
        Grid points 0, h, ..., a.
    h : float [m]
    half_side, cutout : float [m]
        a = S/2 and c.
    areal_density : float [kg/m^2]

    Returns
    -------
    (K,) float64 [kg]
    """
    a, c, rA = half_side, cutout, areal_density
    rho = 2.0 * rA * (a - np.maximum(l, c))
    g_left = np.where(l > c + 1e-9 * h, -2.0 * rA, 0.0)    # slope on [l - h, l]
    g_right = np.where(l >= c - 1e-9 * h, -2.0 * rA, 0.0)  # slope on [l, l + h]
    left = np.where(l > 0.5 * h, rho * h / 2 - g_left * h * h / 6, 0.0)
    right = np.where(l < a - 0.5 * h, rho * h / 2 + g_right * h * h / 6, 0.0)
    return left + right


def eq7_error(mesh: Mesh, node_mass: np.ndarray, areal_density: float,
              cutout: float, beyond_root: bool = False) -> float:
    """Relative L1 error of the arms' deposited mass against the exact density.

    Returns ``sum_i |m_i - m_i,exact| / sum_i m_i,exact`` over all arms (cable mass only
    should be passed in ``node_mass``). With ``beyond_root`` only grid points whose hat
    lies entirely in l >= c count: there the reference is Eq. 7 itself.
    """
    err = tot = 0.0
    for k in range(mesh.n_arms):
        l, m = arm_mass_profile(mesh, node_mass, k)
        h = l[1] - l[0]
        ref = eq7_reference(l, h, mesh.arm_length, cutout, areal_density)
        use = l >= cutout + h - 1e-9 * h if beyond_root else np.ones(len(l), bool)
        err += np.abs(m - ref)[use].sum()
        tot += ref[use].sum()
    return err / tot
