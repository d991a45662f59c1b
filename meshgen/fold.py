"""Star fold of the square web and coiling of arms on the hub [reconstructed].

Three pure stages, each returning a new :class:`~meshgen.mesh.Mesh` (see docs/mesh.md):

1. :func:`assign_arms` -- the flat web split into 4 arms (arm coordinate
   l = min(|x'|, |y'|) in quadrant coordinates), the hub-tied nodes and the arm metadata;
   positions unchanged (this is the ``flat`` fold pattern).
2. :func:`star_fold` -- every node with the same (arm, leg, l) is gathered onto one point:
   the cross halves onto their tied points T_j, the root legs (l < c) along a path from
   T_j in to the rim and round it to the merge point M_k, and the arm beyond (l >= c)
   straight and radial from M_k (a star of 4 arms).
3. :func:`coil` -- every straight radial arm is wound onto the hub rim, trailing or
   leading. Generic: also used for tethers.

Every stage maps the arm coordinate 1-Lipschitz onto the plane, so no element is ever
longer than its rest length (checked by :func:`meshgen.checks.check_mesh`).
"""

from __future__ import annotations

import math

import numpy as np

from meshgen.checks import MeshValueError
from meshgen.mesh import Mesh

WRAP_SIGN = {"trailing": 1, "leading": -1}

# local quadrant coordinates (x', y') = R(-k pi/2) (x, y): rows are (x', y') as
# combinations of (x, y) for k = 0..3
_ROT = np.array([[[1, 0], [0, 1]], [[0, 1], [-1, 0]],
                 [[-1, 0], [0, -1]], [[0, -1], [1, 0]]], dtype=np.float64)


def _classify(ref: np.ndarray, tol: float):
    """Quadrant decomposition of a flat square web centred at the origin.

    Returns
    -------
    arm : (n,) int64
        Quadrant / arm k of each node, -1 on the central cross.
    cross : (n,) int64
        Cross half j (angle j pi/2) of cross nodes, -1 elsewhere.
    half : (n,) int64
        Cross half j the node's leg hangs from: k for x' > y' (y' = 0 side), k+1 for
        x' < y' (x' = 0 side); -1 on the diagonal x' = y' and on the cross.
    l : (n,) float64 [m]
        Arm coordinate min(|x'|, |y'|) (0 on the cross).
    """
    x, y = ref[:, 0], ref[:, 1]
    on_x, on_y = np.abs(y) <= tol, np.abs(x) <= tol
    cross_node = on_x | on_y
    cross = np.full(len(x), -1, np.int64)
    cross[on_x & (x > 0)] = 0
    cross[on_y & (y > 0)] = 1
    cross[on_x & (x < 0)] = 2
    cross[on_y & (y < 0)] = 3
    arm = np.where(x > 0, np.where(y > 0, 0, 3), np.where(y > 0, 1, 2)).astype(np.int64)
    arm[cross_node] = -1
    k = np.maximum(arm, 0)
    xl = _ROT[k, 0, 0] * x + _ROT[k, 0, 1] * y
    yl = _ROT[k, 1, 0] * x + _ROT[k, 1, 1] * y
    l = np.where(cross_node, 0.0, np.minimum(xl, yl))
    half = np.where(xl > yl + tol, k, np.where(yl > xl + tol, (k + 1) % 4, -1))
    half[cross_node] = -1
    return arm, cross, half, l


def assign_arms(mesh: Mesh, hub_radius: float) -> Mesh:
    """Arm decomposition of a flat square web and its hub ties (the ``flat`` pattern).

    Quadrant k holds arm k, whose tip is the corner at psi_k = pi/4 + k pi/2. A node's
    arm coordinate is l = min(|x'|, |y'|) in the quadrant's local coordinates. Nodes on
    the central cross (x = 0 or y = 0) belong to no arm (``node_arm = -1``, arm coordinate
    NaN; node set ``cross``). The cut-out half-width c is the smallest max(|x|, |y|) of the
    web; the tied nodes are the 4 innermost cross nodes T_j = c (cos j pi/2, sin j pi/2).

    Parameters
    ----------
    mesh : Mesh
        Flat QuadQuad web with an even number of mesh widths per side (the central
        cross must be a pair of mesh lines) and a cut-out c >= hub_radius.
    hub_radius : float [m]

    Returns
    -------
    Mesh
        Same positions; ``node_arm``, ``node_arm_coord``, ``arm_root_angle`` (psi_k),
        ``arm_length`` = a, ``arm_root_coord`` = c, ``hub_radius``, ``wrap`` = 0, node
        sets ``hub_tied`` (T_0..T_3), ``cross``, ``root_region`` (arm nodes with l < c).
    """
    ref = mesh.node_ref
    rest_min = float(np.min(mesh.elem_rest_len))
    tol = 1e-6 * rest_min
    a = float(np.max(np.abs(ref[:, :2])))
    c = float(np.min(np.max(np.abs(ref[:, :2]), axis=1)))
    if hub_radius <= 0:
        raise MeshValueError("hub_radius", f"must be > 0, got {hub_radius:g} m")
    if c < hub_radius - tol:
        raise MeshValueError("hub_cutout", f"the web's cut-out half-width {c:g} m is smaller "
                             f"than the hub radius {hub_radius:g} m: the tied nodes would lie "
                             "inside the hub (leave web.hub_cutout unset or make it >= r0)")
    arm, cross, half, l = _classify(ref, tol)
    tied = []
    for j in range(4):
        target = c * np.array([math.cos(j * math.pi / 2), math.sin(j * math.pi / 2)])
        hit = np.flatnonzero((cross == j) & (np.abs(ref[:, :2] - target).max(axis=1) <= tol))
        if len(hit) != 1:
            raise MeshValueError("mesh_width", "the star fold needs the central cross x = 0, "
                                 "y = 0 to be mesh lines: side/mesh_width must be even")
        tied.append(hit[0])
    coord = np.where(arm >= 0, l, np.nan)
    sets = dict(mesh.node_sets)
    sets.update(hub_tied=np.array(tied, np.int64), cross=np.flatnonzero(cross >= 0),
                root_region=np.flatnonzero((arm >= 0) & (l < c - tol)))
    psi = math.pi / 4 + np.arange(4) * math.pi / 2
    return mesh.replace(node_arm=arm, node_arm_coord=coord, arm_root_angle=psi,
                        arm_length=a, arm_root_coord=c, hub_radius=float(hub_radius),
                        wrap=0, node_sets=sets)


def leg_path(l: np.ndarray, beta: np.ndarray, sigma: np.ndarray, c: float,
             r0: float) -> np.ndarray:
    """Points P(l) [m] of the root-leg paths, 0 <= l <= c.

    The path runs from T = c (cos beta, sin beta) radially in to the rim, then along the
    rim by pi/4 in the direction ``sigma`` (+1 counter-clockwise) to the merge point;
    its length c - r0 + r0 pi/4 is covered proportionally to l (speed <= 1), so
    P(0) = T and P(c) = the merge point.

    Parameters
    ----------
    l, beta, sigma : (p,) float64
        Arm coordinate [m], angle of the cross half [rad], rim direction [-].
    c, r0 : float [m]
        Cut-out half-width and hub radius.

    Returns
    -------
    (p, 2) float64 [m]
    """
    l_rad = c - r0
    s = l * (l_rad + r0 * math.pi / 4) / c
    radial = s <= l_rad
    r = np.where(radial, c - s, r0)
    ang = np.where(radial, beta, beta + sigma * (s - l_rad) / r0)
    return np.column_stack([r * np.cos(ang), r * np.sin(ang)])


def star_fold(mesh: Mesh) -> Mesh:
    """Star fold of a QuadQuad web with arm data (:func:`assign_arms`), arms uncoiled.

    - Cross half j (all its nodes): at its tied point T_j (zero-length elements).
    - Root legs, 0 <= l < c: the leg of arm k that hangs from cross half j (j = k or
      k+1) on :func:`leg_path` from T_j to M_k = r0 (cos psi_k, sin psi_k).
    - l >= c (both legs and the diagonal): straight and radial,
      (r0 + l - c) (cos psi_k, sin psi_k).

    Nodes with equal (arm, leg, l) coincide: the transverse mesh lines are gathered
    (concertina) into zero-length elements. The map is 1-Lipschitz in l, and |l| changes
    by at most an element's rest length along any element, so no element is stretched.

    Returns
    -------
    Mesh
        New ``node_pos`` (z = 0); everything else unchanged.
    """
    if mesh.n_arms != 4 or len(mesh.node_sets["hub_tied"]) != 4:
        raise MeshValueError("pattern", "star fold is implemented for quadquad only "
                             "(call assign_arms first)")
    ref = mesh.node_ref
    tol = 1e-6 * float(np.min(mesh.elem_rest_len))
    arm, cross, half, l = _classify(ref, tol)
    c, r0, psi = mesh.arm_root_coord, mesh.hub_radius, mesh.arm_root_angle
    xy = np.zeros((mesh.n_nodes, 2))
    is_cross = cross >= 0
    beta_c = cross[is_cross] * (math.pi / 2)
    xy[is_cross] = c * np.column_stack([np.cos(beta_c), np.sin(beta_c)])
    leg = (arm >= 0) & (l < c)
    k = arm[leg]
    j = half[leg]
    sigma = np.where(j == k, 1.0, -1.0)         # from beta_k ccw, from beta_(k+1) cw
    beta = np.where(j == k, k, k + 1) * (math.pi / 2)
    xy[leg] = leg_path(l[leg], beta, sigma, c, r0)
    out = (arm >= 0) & ~leg
    r = r0 + l[out] - c
    ang = psi[arm[out]]
    xy[out] = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    xy[mesh.node_sets["hub_tied"]] = ref[mesh.node_sets["hub_tied"], :2]
    pos = np.column_stack([xy, np.zeros(mesh.n_nodes)])
    return mesh.replace(node_pos=pos)


def coil(mesh: Mesh, wrap: str = "trailing") -> Mesh:
    """Wind every arm that is straight and radial beyond its root onto the hub rim.

    A node of arm k with arm coordinate l >= l_root (``arm_root_coord``) moves from
    (r0 + l - l_root) (cos psi_k, sin psi_k) to the rim point at angle
    psi_k - w (l - l_root) / r0, w = +1 (trailing: clockwise, against a positive spin
    about +z) or -1 (leading). Arc length is preserved, chords are shorter: no element is
    stretched. Successive turns overlap (no cable-cable contact is modelled).

    Parameters
    ----------
    mesh : Mesh
        Mesh with arm data, ``hub_radius > 0``, arms straight and radial beyond the root.
    wrap : {'trailing', 'leading'}

    Returns
    -------
    Mesh
        New ``node_pos`` and ``wrap`` (+1 / -1).
    """
    if wrap not in WRAP_SIGN:
        raise MeshValueError("wrap", f"unknown wrap '{wrap}' (valid: {', '.join(WRAP_SIGN)})")
    r0 = mesh.hub_radius
    if r0 <= 0:
        raise MeshValueError("hub_radius", "coiling needs a hub radius > 0")
    w = WRAP_SIGN[wrap]
    l0 = mesh.arm_root_coord
    sel = np.flatnonzero(mesh.node_arm >= 0)
    sel = sel[mesh.node_arm_coord[sel] >= l0]
    ang = mesh.arm_root_angle[mesh.node_arm[sel]] - w * (mesh.node_arm_coord[sel] - l0) / r0
    pos = np.array(mesh.node_pos)
    pos[sel] = np.column_stack([r0 * np.cos(ang), r0 * np.sin(ang), np.zeros(len(sel))])
    return mesh.replace(node_pos=pos, wrap=w)


def fold_web(mesh: Mesh, hub_radius: float, pattern: str = "star",
             wrap: str = "trailing") -> Mesh:
    """Flat QuadQuad web -> arms + ties (``flat``) or star fold + coil (``star``)."""
    if pattern not in ("star", "flat"):
        raise MeshValueError("pattern", f"unknown web fold '{pattern}' (valid: star, flat)")
    web = assign_arms(mesh, hub_radius)
    if pattern == "flat":
        return web
    return coil(star_fold(web), wrap)
