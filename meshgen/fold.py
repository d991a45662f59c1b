"""Star fold of the square web and coiling of arms on the hub [reconstructed].

Three pure stages, each returning a new :class:`~meshgen.mesh.Mesh` (see docs/mesh.md):

1. :func:`assign_arms` -- the flat web split into 4 arms (arm coordinate
   l = min(|x'|, |y'|) in quadrant coordinates), the hub-tied nodes and the arm metadata;
   positions unchanged (this is the ``flat`` fold pattern). Two hub attachments
   (``ties``): ``frame`` (default) ties every node of the cut-out's boundary, a rigid
   square frame of half-width c >= r0; ``axes`` ties only the 4 cross nodes T_j.
2. :func:`star_fold` -- every node with the same (arm, leg, l) is gathered onto one point:
   the cross halves onto their tied points T_j; the root legs (l < c) onto the frame edge
   they attach to (``frame``) or along a path from T_j in to the rim and round it to the
   merge point M_k (``axes``); the arm beyond (l >= c) straight and radial, from the frame
   corner (``frame``) or from M_k (``axes``): a star of 4 arms.
3. :func:`coil` -- every straight radial arm is wound onto the hub rim, trailing or
   leading (``frame``: first folded back radially from the frame corner in to the rim).
   Generic: also used for tethers.

Every stage maps the arm coordinate 1-Lipschitz onto the plane, so no element is ever
longer than its rest length (checked by :func:`meshgen.checks.check_mesh`).
"""

from __future__ import annotations

import math

import numpy as np

from meshgen.checks import MeshValueError
from meshgen.mesh import Mesh

WRAP_SIGN = {"trailing": 1, "leading": -1}
#: hub attachments of the star-folded web: the whole hole boundary, or the 4 axis nodes
TIES = ("frame", "axes")

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


def _cutout(ref: np.ndarray) -> float:
    """Cut-out half-width c [m] of a flat square web: the smallest max(|x|, |y|)."""
    return float(np.min(np.max(np.abs(ref[:, :2]), axis=1)))


def _frame_nodes(ref: np.ndarray, c: float, tol: float) -> np.ndarray:
    """Nodes on the square loop max(|x|, |y|) = c (the hole boundary), sorted."""
    return np.flatnonzero(np.abs(np.max(np.abs(ref[:, :2]), axis=1) - c) <= tol)


def tie_mode(mesh: Mesh) -> str:
    """``'frame'`` or ``'axes'``: the hub attachment of a web from :func:`assign_arms`.

    ``frame`` if the hub-tied nodes are exactly the nodes of the cut-out's boundary loop,
    ``axes`` if they are 4 nodes; MeshValueError otherwise (no arm data).
    """
    tied = np.sort(np.asarray(mesh.node_sets.get("hub_tied", ()), np.int64))
    if mesh.n_arms == 4 and len(tied) > 4 and mesh.n_elems:
        tol = 1e-6 * float(np.min(mesh.elem_rest_len))
        ref = mesh.node_ref
        if np.array_equal(tied, _frame_nodes(ref, _cutout(ref), tol)):
            return "frame"
    if mesh.n_arms == 4 and len(tied) == 4:
        return "axes"
    raise MeshValueError("pattern", "star fold is implemented for quadquad only "
                         "(call assign_arms first)")


def frame_lead_in(c: float, r0: float) -> float:
    """Length d0 = c sqrt(2) - r0 [m] of the radial spoke from the frame corner (radius
    c sqrt(2)) in to the rim, where the coil of a ``frame``-tied arm starts."""
    return c * math.sqrt(2.0) - r0


def assign_arms(mesh: Mesh, hub_radius: float, ties: str = "frame") -> Mesh:
    """Arm decomposition of a flat square web and its hub ties (the ``flat`` pattern).

    Quadrant k holds arm k, whose tip is the corner at psi_k = pi/4 + k pi/2. A node's
    arm coordinate is l = min(|x'|, |y'|) in the quadrant's local coordinates. Nodes on
    the central cross (x = 0 or y = 0) belong to no arm (``node_arm = -1``, arm coordinate
    NaN; node set ``cross``). The cut-out half-width c is the smallest max(|x|, |y|) of the
    web. Tied nodes: ``frame`` -- every node of the hole boundary max(|x|, |y|) = c
    (subdivision nodes included: 8 c k / t nodes), a rigid square frame around the hub;
    ``axes`` -- the 4 innermost cross nodes T_j = c (cos j pi/2, sin j pi/2).

    Parameters
    ----------
    mesh : Mesh
        Flat QuadQuad web with an even number of mesh widths per side (the central
        cross must be a pair of mesh lines) and a cut-out c >= hub_radius.
    hub_radius : float [m]
    ties : {'frame', 'axes'}

    Returns
    -------
    Mesh
        Same positions; ``node_arm``, ``node_arm_coord``, ``arm_root_angle`` (psi_k),
        ``arm_length`` = a, ``arm_root_coord`` (where the coil meets the rim:
        c + c sqrt(2) - r0 for ``frame``, c for ``axes``), ``hub_radius``, ``wrap`` = 0,
        node sets ``hub_tied``, ``cross``, ``root_region`` (arm nodes with l < c).
    """
    if ties not in TIES:
        raise MeshValueError("ties", f"unknown hub ties '{ties}' (valid: {', '.join(TIES)})")
    ref = mesh.node_ref
    rest_min = float(np.min(mesh.elem_rest_len))
    tol = 1e-6 * rest_min
    a = float(np.max(np.abs(ref[:, :2])))
    c = _cutout(ref)
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
    root = c
    if ties == "frame":
        tied = _frame_nodes(ref, c, tol)
        root = c + frame_lead_in(c, hub_radius)
    coord = np.where(arm >= 0, l, np.nan)
    sets = dict(mesh.node_sets)
    sets.update(hub_tied=np.array(tied, np.int64), cross=np.flatnonzero(cross >= 0),
                root_region=np.flatnonzero((arm >= 0) & (l < c - tol)))
    psi = math.pi / 4 + np.arange(4) * math.pi / 2
    return mesh.replace(node_arm=arm, node_arm_coord=coord, arm_root_angle=psi,
                        arm_length=a, arm_root_coord=root, hub_radius=float(hub_radius),
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
    - Root legs, 0 <= l < c, of arm k:
      ``frame`` -- gathered onto the frame edge they attach to: in local quadrant
      coordinates the leg node (x', l) with x' > l (hanging from the y' = 0 side) at the
      tied frame node (c, l), the node (l, y') with y' > l at (l, c);
      ``axes`` -- the leg hanging from cross half j (j = k or k+1) on :func:`leg_path`
      from T_j to M_k = r0 (cos psi_k, sin psi_k).
    - l >= c (both legs and the diagonal): straight and radial,
      (r_c + l - c) (cos psi_k, sin psi_k), from the frame corner r_c = c sqrt(2)
      (``frame``) or from the rim point M_k, r_c = r0 (``axes``).

    Nodes with equal (arm, leg, l) coincide: the transverse mesh lines are gathered
    (concertina) into zero-length elements. The map is 1-Lipschitz in l, and |l| changes
    by at most an element's rest length along any element, so no element is stretched.
    The tie mode is read from the mesh (:func:`tie_mode`).

    Returns
    -------
    Mesh
        New ``node_pos`` (z = 0); everything else unchanged.
    """
    ties = tie_mode(mesh)
    ref = mesh.node_ref
    tol = 1e-6 * float(np.min(mesh.elem_rest_len))
    arm, cross, half, l = _classify(ref, tol)
    r0, psi = mesh.hub_radius, mesh.arm_root_angle
    c = _cutout(ref)
    xy = np.zeros((mesh.n_nodes, 2))
    is_cross = cross >= 0
    beta_c = cross[is_cross] * (math.pi / 2)
    xy[is_cross] = c * np.column_stack([np.cos(beta_c), np.sin(beta_c)])
    leg = (arm >= 0) & (l < c)
    k = arm[leg]
    j = half[leg]
    if ties == "frame":
        # local (x', y') -> (c, l) on the y' = 0 side, (l, c) on the x' = 0 side
        loc = np.where((j == k)[:, None], np.column_stack([np.full(len(k), c), l[leg]]),
                       np.column_stack([l[leg], np.full(len(k), c)]))
        rot = _ROT[k]                                   # global -> local; transpose back
        xy[leg] = np.einsum("pji,pj->pi", rot, loc)
        r_c = c * math.sqrt(2.0)
    else:
        sigma = np.where(j == k, 1.0, -1.0)         # from beta_k ccw, from beta_(k+1) cw
        beta = np.where(j == k, k, k + 1) * (math.pi / 2)
        xy[leg] = leg_path(l[leg], beta, sigma, c, r0)
        r_c = r0
    out = (arm >= 0) & ~leg
    r = r_c + l[out] - c
    ang = psi[arm[out]]
    xy[out] = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    xy[mesh.node_sets["hub_tied"]] = ref[mesh.node_sets["hub_tied"], :2]
    pos = np.column_stack([xy, np.zeros(mesh.n_nodes)])
    return mesh.replace(node_pos=pos)


def _lead_in(mesh: Mesh) -> float:
    """Radial lead-in of the coil: d0 = c sqrt(2) - r0 for a ``frame``-tied web, else 0."""
    try:
        if tie_mode(mesh) == "frame":
            return mesh.arm_root_coord - _cutout(mesh.node_ref)
    except MeshValueError:
        pass
    return 0.0


def coil(mesh: Mesh, wrap: str = "trailing", lead_in: float | None = None) -> Mesh:
    """Wind every arm that is straight and radial beyond its root onto the hub rim.

    With l0 = ``arm_root_coord`` (where the coil meets the rim) and d = ``lead_in``: a
    node of arm k with l0 - d <= l < l0 moves onto the spoke at radius r0 + (l0 - l),
    angle psi_k (radially in to the rim), and a node with l >= l0 to the rim point at
    angle psi_k - w (l - l0) / r0, w = +1 (trailing: clockwise, against a positive spin
    about +z) or -1 (leading). Arc length is preserved, chords are shorter: no element is
    stretched. Successive turns overlap (no cable-cable contact is modelled).

    The input arm is straight and radial from radius r0 + d at l = l0 - d outwards
    (:func:`star_fold`; tethers and the ``axes`` web: d = 0, the arm starts on the rim;
    the ``frame`` web: d = c sqrt(2) - r0, the arm starts at the frame corner and the
    coil folds its first d back in to the rim).

    Parameters
    ----------
    mesh : Mesh
        Mesh with arm data, ``hub_radius > 0``, arms straight and radial beyond the root.
    wrap : {'trailing', 'leading'}
    lead_in : float or None [m]
        d; None: c sqrt(2) - r0 for a ``frame``-tied web (:func:`tie_mode`), else 0.

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
    d = _lead_in(mesh) if lead_in is None else float(lead_in)
    l0 = mesh.arm_root_coord
    sel = np.flatnonzero(mesh.node_arm >= 0)
    sel = sel[mesh.node_arm_coord[sel] >= l0 - d]
    sel = np.setdiff1d(sel, mesh.node_sets["hub_tied"])   # tied nodes never move
    lk = mesh.node_arm_coord[sel]
    psi = mesh.arm_root_angle[mesh.node_arm[sel]]
    spoke = lk < l0
    r = np.where(spoke, r0 + (l0 - lk), r0)
    ang = np.where(spoke, psi, psi - w * (lk - l0) / r0)
    pos = np.array(mesh.node_pos)
    pos[sel] = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros(len(sel))])
    return mesh.replace(node_pos=pos, wrap=w)


def fold_web(mesh: Mesh, hub_radius: float, pattern: str = "star",
             wrap: str = "trailing", ties: str = "frame") -> Mesh:
    """Flat QuadQuad web -> arms + ties (``flat``) or star fold + coil (``star``);
    ``ties`` = ``frame`` (the whole hole boundary, default) or ``axes`` (4 nodes)."""
    if pattern not in ("star", "flat"):
        raise MeshValueError("pattern", f"unknown web fold '{pattern}' (valid: star, flat)")
    web = assign_arms(mesh, hub_radius, ties)
    if pattern == "flat":
        return web
    return coil(star_fold(web), wrap)
