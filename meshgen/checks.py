"""Mesh invariants and mass diagnostics.

:func:`check_mesh` lists every violated invariant of a :class:`~meshgen.mesh.Mesh`
(used by :func:`meshgen.build.build_mesh` and by the tests). :func:`arm_mass_profile`
and :func:`eq7_error` measure how well the folded web reproduces the paper's arm mass
density (Eq. 7), see docs/mesh.md.
"""

from __future__ import annotations

import numpy as np

from meshgen.mesh import POLYGON_TAN, Mesh


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


def arm_mass_profile(mesh: Mesh, node_mass: np.ndarray, arm: int, h: float | None = None):
    """Mass of one arm deposited on the grid l_i = i h of arm coordinates (cloud in cell).

    Each node of the arm gives its lumped mass to the two nearest grid points with linear
    (hat-function) weights, so nodes that lie between grid lines (``elements_per_segment
    > 1``, or any node of a mesh whose lines are not parallel to the half-axes) are split
    without ambiguity.

    Parameters
    ----------
    mesh : Mesh
        A mesh with arm data (``node_arm``, ``node_arm_coord``, ``arm_length``).
    node_mass : (n,) float64 [kg]
        Lumped node masses (cable only, or with point masses).
    arm : int
        Arm index.
    h : float or None [m]
        Grid spacing; None: the smallest spacing of the mesh lines of a QuadQuad web (the
        mesh width).

    Returns
    -------
    l : (K,) float64 [m]
        Grid points 0, h, ..., K h, K = round(arm_length / h).
    m : (K,) float64 [kg]
        Mass deposited on each grid point.
    """
    sel = mesh.node_arm == arm
    l = mesh.node_arm_coord[sel]
    H = mesh.arm_length
    h = _line_spacing(mesh) if h is None else float(h)
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


def arm_density(l: np.ndarray, arm_length: float, corner: float, areal_density: float,
                n_arms: int = 4) -> np.ndarray:
    """Line density rho_L(l) [kg/m] of a star-folded arm (docs/mesh.md).

    rho_L(l) = 2 rho_A cot(pi/n) (H - max(l, l_c)): Eq. 7 of the paper (linear, zero at
    the tip, m_w / n per arm for the whole web) for l >= l_c, and constant in the root
    region l < l_c gathered on the hub frame, where the outline-shaped hole of inradius
    c = l_c / tan(pi/n) is cut out. Square web: 2 rho_A (a - max(l, c)).

    Parameters
    ----------
    l : (K,) float64 [m]
    arm_length, corner : float [m]
        H = S/2 and l_c (c for the square web, c sqrt(3) for the triangular web).
    areal_density : float [kg/m^2]
    n_arms : {3, 4}
    """
    cot = 1.0 / POLYGON_TAN[n_arms]
    rho = 2.0 * areal_density * cot * (arm_length - np.maximum(l, corner))
    return np.where((l >= 0) & (l <= arm_length), rho, 0.0)


def eq7_reference(l: np.ndarray, h: float, arm_length: float, corner: float,
                  areal_density: float, n_arms: int = 4) -> np.ndarray:
    """Exact hat-weighted arm mass on the grid l_i for :func:`arm_density`.

    Each half-hat [l_i - h, l_i], [l_i, l_i + h], clipped to [0, H], is split at the
    kink l_c; on each piece the integrand is a quadratic polynomial, which 2-point
    Gauss-Legendre integrates exactly.

    Parameters
    ----------
    l : (K,) float64 [m]
        Grid points 0, h, ..., K h.
    h : float [m]
    arm_length, corner : float [m]
        H and l_c.
    areal_density : float [kg/m^2]
    n_arms : {3, 4}

    Returns
    -------
    (K,) float64 [kg]
    """
    H = arm_length
    g = 1.0 / np.sqrt(3.0)
    out = np.zeros(len(l))
    for lo, hi, rising in ((-h, 0.0, True), (0.0, h, False)):
        a, b = np.clip(l + lo, 0.0, H), np.clip(l + hi, 0.0, H)
        m = np.clip(corner, a, b)
        for x0, x1 in ((a, m), (m, b)):
            mid, half = 0.5 * (x0 + x1), 0.5 * (x1 - x0)
            for x in (mid - g * half, mid + g * half):
                w = (x - (l - h)) / h if rising else (l + h - x) / h
                out += half * w * arm_density(x, H, corner, areal_density, n_arms)
    return out


def eq7_error(mesh: Mesh, node_mass: np.ndarray, areal_density: float,
              cutout: float, beyond_root: bool = False, h: float | None = None) -> float:
    """Relative L1 error of the arms' deposited mass against the exact density.

    Returns ``sum_i |m_i - m_i,exact| / sum_i m_i,exact`` over all arms (cable mass only
    should be passed in ``node_mass``); ``cutout`` is the hole inradius c, ``h`` the grid
    spacing (:func:`arm_mass_profile`). With ``beyond_root`` only grid points whose hat
    lies entirely in l >= l_c count: there the reference is Eq. 7 itself.
    """
    err = tot = 0.0
    n = mesh.n_arms
    corner = cutout * POLYGON_TAN[n]
    for k in range(n):
        l, m = arm_mass_profile(mesh, node_mass, k, h)
        step = l[1] - l[0]
        ref = eq7_reference(l, step, mesh.arm_length, corner, areal_density, n)
        use = l >= corner + step - 1e-9 * step if beyond_root else np.ones(len(l), bool)
        err += np.abs(m - ref)[use].sum()
        tot += ref[use].sum()
    return err / tot
