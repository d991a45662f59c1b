"""Star fold of a web and coiling of its arms on the hub [reconstructed].

Three pure stages, each returning a new :class:`~meshgen.mesh.Mesh` (see docs/mesh.md).
They work for a web with n = 4 corners (the square web, any mesh) or n = 3 (the
triangular web), centred on the hub, with a central hole shaped like the web outline.
The n half-axes, from the centre through the side midpoints (angles psi_k -+ pi/n from
the corner k at psi_k), split the web into n kites; kite k becomes arm k.

1. :func:`assign_arms` -- the flat web split into n arms (arm coordinate l = distance to
   the nearer half-axis line of the kite), the hub-tied nodes and the arm metadata;
   positions unchanged (the ``flat`` fold pattern). Two hub attachments (``ties``):
   ``frame`` (default) ties every node of the hole boundary, a rigid polygon of inradius
   c >= r0 around the hub; ``axes`` (square web with a square mesh only) ties the 4
   nodes T_j where the half-axes leave the hole.
2. :func:`star_fold` -- ``frame``: every node goes to its nearest point on the frame
   polygon, and nodes in the normal cone of a frame corner (l >= l_c = c tan(pi/n)) go on
   radially from that corner by l - l_c: the half-axes collapse onto the points
   T_j = c u_j, the root strips onto the frame edges, and the arms beyond are straight
   and radial -- a star of n arms. ``axes``: the root legs are led from T_j in to the rim
   and round it to the merge point (:func:`leg_path`).
3. :func:`coil` -- every straight radial arm is wound onto the hub rim, trailing or
   leading (``frame``: first folded back radially from the frame corner in to the rim).
   Generic: also used for tethers.

Each stage is 1-Lipschitz (a nearest-point projection onto a convex set is, and l is),
so no element is ever longer than its rest length (checked by
:func:`meshgen.checks.check_mesh`). With ``layer_gap`` g > 0 (:mod:`meshgen.layers`) the
gathered layers stand in columns along z and the coil rises along the hub axis, so that no
two elements that share no node start closer than g; the radial run is then shortened by
the factor s that keeps every tilted element within its rest length.
"""

from __future__ import annotations

import math

import numpy as np

from meshgen.checks import MeshValueError
from meshgen.layers import (check_clearance, check_columns, check_gap, column_height,
                            layer_plan)
from meshgen.mesh import POLYGON_COS, POLYGON_TAN, Mesh
from meshgen.registry import TIES, WEB_FOLDS, WRAP_SIGN



def _unit(angle: np.ndarray) -> np.ndarray:
    """(k, 2) unit vectors at ``angle``, with components within 1e-15 of 0 or +-1 snapped
    (so that the square web's axes are exact)."""
    u = np.column_stack([np.cos(angle), np.sin(angle)])
    u[np.abs(u) < 1e-15] = 0.0
    unit = np.abs(np.abs(u) - 1.0) < 1e-15
    u[unit] = np.sign(u[unit])
    return u


def corner_angles(mesh: Mesh) -> np.ndarray:
    """(n,) angles psi_k [rad] of the web corners (the ``tips`` set, in arm order), made
    exactly regular: psi_k = psi_0 + 2 pi k / n."""
    tips = mesh.node_sets["tips"]
    n = len(tips)
    if n not in POLYGON_COS:
        raise MeshValueError("topology", f"the star fold needs a web with 3 or 4 corners, "
                             f"this one has {n}")
    p0 = mesh.node_ref[tips[0], :2]
    psi0 = math.atan2(p0[1], p0[0])
    return psi0 + 2 * math.pi * np.arange(n) / n


def half_axes(psi: np.ndarray) -> np.ndarray:
    """(n, 2) unit vectors u_j of the half-axes, at angles psi_j - pi/n: arm k lies
    between half-axes k and k+1 (mod n)."""
    return _unit(psi - math.pi / len(psi))


def _classify(ref: np.ndarray, psi: np.ndarray, tol: float):
    """Kite decomposition of a flat web centred at the origin.

    Returns
    -------
    arm : (n_nodes,) int64
        Kite / arm k of each node, -1 on a half-axis (and at the centre).
    cross : (n_nodes,) int64
        Half-axis j of the nodes on one, -1 elsewhere.
    half : (n_nodes,) int64
        Half-axis j the node's leg hangs from: k if nearer half-axis k, k+1 (mod n) if
        nearer half-axis k+1; -1 on the kite's bisector and on the half-axes.
    l : (n_nodes,) float64 [m]
        Arm coordinate: distance to the nearer half-axis line (0 on a half-axis).
    gauge : (n_nodes,) float64 [m]
        max_j P.u_j: the inradius of the outline-shaped polygon through the node.
    """
    n = len(psi)
    u = half_axes(psi)
    xy = ref[:, :2]
    side = xy[:, None, 1] * u[None, :, 0] - xy[:, None, 0] * u[None, :, 1]   # u_j x P
    along = xy @ u.T
    on = (np.abs(side) <= tol) & (along > tol)
    cross = np.where(on.any(axis=1), np.argmax(on, axis=1), -1)
    arm = np.full(len(xy), -1, np.int64)
    d_lo = np.zeros(len(xy))
    d_hi = np.zeros(len(xy))
    for k in range(n):
        inside = (side[:, k] > tol) & (side[:, (k + 1) % n] < -tol)
        arm[inside] = k
        d_lo[inside], d_hi[inside] = side[inside, k], -side[inside, (k + 1) % n]
    arm[cross >= 0] = -1
    l = np.where(arm >= 0, np.minimum(d_lo, d_hi), 0.0)
    half = np.where(d_lo < d_hi - tol, arm, np.where(d_hi < d_lo - tol, (arm + 1) % n, -1))
    half[arm < 0] = -1
    return arm, cross.astype(np.int64), half.astype(np.int64), l, along.max(axis=1)


def _tol(mesh: Mesh) -> float:
    """Geometric tolerance [m] of the fold: 1e-6 of the shortest rest length."""
    return 1e-6 * float(np.min(mesh.elem_rest_len))


def _hole(mesh: Mesh, tol: float):
    """(psi, c, parts): corner angles, hole inradius c = the smallest gauge, and the
    :func:`_classify` arrays (arm, cross, half, l, gauge) of the reference positions."""
    psi = corner_angles(mesh)
    parts = _classify(mesh.node_ref, psi, tol)
    return psi, float(parts[4].min()), parts


def _frame_hole(mesh: Mesh) -> float | None:
    """Hole inradius c [m] if the hub-tied nodes are exactly the hole boundary (more than
    one per arm: tethers, tied by one root node each, never are), else None."""
    tied = np.sort(np.asarray(mesh.node_sets.get("hub_tied", ()), np.int64))
    n = mesh.n_arms
    if n in POLYGON_COS and len(mesh.node_sets["tips"]) == n and len(tied) > n and mesh.n_elems:
        tol = _tol(mesh)
        _, c, parts = _hole(mesh, tol)
        if np.array_equal(tied, np.flatnonzero(np.abs(parts[4] - c) <= tol)):
            return c
    return None


def frame_lead_in(c: float, r0: float, n: int = 4) -> float:
    """Length d0 = c / cos(pi/n) - r0 [m] of the radial spoke from a frame corner in to
    the rim, where the coil of a ``frame``-tied arm starts (c sqrt(2) - r0 for the
    square web, 2c - r0 for the triangular web)."""
    return c / POLYGON_COS[n] - r0


def corner_coord(c: float, n: int = 4) -> float:
    """Arm coordinate l_c = c tan(pi/n) [m] of a frame corner: where the arm leaves the
    frame (c for the square web, c sqrt(3) for the triangular web)."""
    return c * POLYGON_TAN[n]


def tie_mode(mesh: Mesh) -> str:
    """``'frame'`` or ``'axes'``: the hub attachment of a web from :func:`assign_arms`.

    ``frame`` if the hub-tied nodes are exactly the nodes of the hole boundary (more
    than one per arm: tethers, tied by one root node each, are never ``frame``),
    ``axes`` if they are 4 nodes; MeshValueError otherwise (no arm data).
    """
    if _frame_hole(mesh) is not None:
        return "frame"
    if mesh.n_arms == 4 and len(mesh.node_sets.get("hub_tied", ())) == 4:
        return "axes"
    raise MeshValueError("pattern", "no star-fold arm data on this mesh (call assign_arms "
                         "first on a web with an outline-shaped hole)")


def assign_arms(mesh: Mesh, hub_radius: float, ties: str = "frame") -> Mesh:
    """Arm decomposition of a flat web and its hub ties (the ``flat`` pattern).

    Kite k holds arm k, whose tip is the corner at psi_k (the ``tips`` set). A node's arm
    coordinate l is its distance to the nearer of the kite's two half-axis lines; the
    tip has l = S/2 (the half sides from the side midpoints to the corner become the
    arm). Nodes on a half-axis belong to no arm (``node_arm = -1``, arm coordinate NaN;
    node set ``cross``). The hole inradius c is the smallest gauge max_j P.u_j of the
    web's nodes. Tied nodes: ``frame`` -- every node of the hole boundary (gauge = c,
    subdivision nodes included), a rigid polygon around the hub; ``axes`` (4 corners
    only) -- the 4 innermost half-axis nodes T_j = c u_j.

    Parameters
    ----------
    mesh : Mesh
        Flat web with 3 or 4 corners centred at the origin, with a central hole shaped
        like its outline (:func:`meshgen.flat.flat_quadquad` with a cut-out, or
        :func:`meshgen.topologies.flat_other` with ``hole='outline'``) of inradius
        c >= hub_radius. ``axes`` needs the half-axes to be mesh lines (QuadQuad with an
        even number of mesh widths per side).
    hub_radius : float [m]
    ties : {'frame', 'axes'}

    Returns
    -------
    Mesh
        Same positions; ``node_arm``, ``node_arm_coord``, ``arm_root_angle`` (psi_k),
        ``arm_length`` (the tips' arm coordinate, S/2), ``arm_root_coord`` (where the
        coil meets the rim: l_c + c / cos(pi/n) - r0 for ``frame``, c for ``axes``),
        ``hub_radius``, ``wrap`` = 0, node sets ``hub_tied``, ``cross``, ``root_region``
        (arm nodes with l < l_c).
    """
    if ties not in TIES:
        raise MeshValueError("ties", f"unknown hub ties '{ties}' (valid: {', '.join(TIES)})")
    if hub_radius <= 0:
        raise MeshValueError("hub_radius", f"must be > 0, got {hub_radius:g} m")
    tol = _tol(mesh)
    psi, c, (arm, cross, _, l, gauge) = _hole(mesh, tol)
    n = len(psi)
    if c < hub_radius - tol:
        raise MeshValueError("hub_cutout", f"the web's cut-out inradius {c:g} m is smaller "
                             f"than the hub radius {hub_radius:g} m: the tied nodes would lie "
                             "inside the hub (leave web.hub_cutout unset or make it >= r0)")
    l_c = corner_coord(c, n)
    if ties == "axes":
        if n != 4:
            raise MeshValueError("ties", "ties = 'axes' needs a square web; use 'frame'")
        u = half_axes(psi)
        tied = []
        for j in range(4):
            hit = np.flatnonzero((cross == j)
                                 & (np.abs(mesh.node_ref[:, :2] - c * u[j]).max(axis=1) <= tol))
            if len(hit) != 1:
                raise MeshValueError("mesh_width", "ties = 'axes' needs the central cross "
                                     "x = 0, y = 0 to be mesh lines: side/mesh_width must be even")
            tied.append(hit[0])
        root = c
    else:
        tied = np.flatnonzero(np.abs(gauge - c) <= tol)
        if len(tied) <= n:
            raise MeshValueError("hub_cutout", f"the hole (inradius {c:g} m) has only "
                                 f"{len(tied)} boundary nodes: make it larger than a mesh cell")
        root = l_c + frame_lead_in(c, hub_radius, n)
    coord = np.where(arm >= 0, l, np.nan)
    tips = mesh.node_sets["tips"]
    if not np.array_equal(arm[tips], np.arange(n)):
        raise MeshValueError("topology", "the web's corners are not in arm order")
    sets = dict(mesh.node_sets)
    sets.update(hub_tied=np.array(tied, np.int64), cross=np.flatnonzero(cross >= 0),
                root_region=np.flatnonzero((arm >= 0) & (l < l_c - tol)))
    return mesh.replace(node_arm=arm, node_arm_coord=coord, arm_root_angle=psi,
                        arm_length=float(np.mean(l[tips])), arm_root_coord=root,
                        hub_radius=float(hub_radius), wrap=0, node_sets=sets)


def leg_path(l: np.ndarray, beta: np.ndarray, sigma: np.ndarray, c: float,
             r0: float) -> np.ndarray:
    """Points P(l) [m] of the root-leg paths of the ``axes`` fold, 0 <= l <= c.

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


def star_fold(mesh: Mesh, layer_gap: float = 0.0) -> Mesh:
    """Star fold of a web with arm data (:func:`assign_arms`), arms uncoiled.

    - Half-axis j (all its nodes): at T_j = c u_j (zero-length elements).
    - Root legs, 0 <= l < l_c, of arm k:
      ``frame`` -- the leg hanging from half-axis j at T_j + l e_kj on the frame edge
      through T_j, e_kj the unit vector from T_j to the frame corner K_k (for the square
      web in local quadrant coordinates: (x', l) -> (c, l));
      ``axes`` -- on :func:`leg_path` from T_j to M_k = r0 (cos psi_k, sin psi_k).
    - l >= l_c (both legs and the bisector): straight and radial,
      (r_c + l - l_c) (cos psi_k, sin psi_k), from the frame corner r_c = c / cos(pi/n)
      (``frame``) or from the rim point M_k, r_c = r0 (``axes``, l_c = c).

    For ``frame`` this is the nearest-point projection onto the frame polygon plus the
    radial run-out in the corners' normal cones: 1-Lipschitz, so no element is
    stretched. Nodes with equal (arm, leg, l) coincide: the mesh lines are gathered
    (concertina) across the arm. The tie mode is read from the mesh (:func:`tie_mode`).

    ``layer_gap`` g > 0 (``frame`` ties, square mesh: :mod:`meshgen.layers`, docs/mesh.md
    2.9) stacks the gathered layers in columns along z, g apart, centred on the hub plane,
    and shortens the radial run by the plan's factor s: (r_c + s (l - l_c)).

    Returns
    -------
    Mesh
        New ``node_pos`` (z = 0 without a gap); everything else unchanged.
    """
    g = check_gap(layer_gap)
    ties = tie_mode(mesh)
    if g > 0 and ties != "frame":
        raise MeshValueError("layer_gap", "stacked layers need fold.ties = 'frame' (the axes "
                             "fold lays its root legs on the rim, under the coil)")
    ref = mesh.node_ref
    tol = _tol(mesh)
    if g > 0:
        check_columns(mesh, tol)
    psi, c, (arm, cross, half, l, _) = _hole(mesh, tol)
    n = len(psi)
    r0 = mesh.hub_radius
    u, u_psi = half_axes(psi), _unit(psi)
    xy = np.zeros((mesh.n_nodes, 2))
    is_cross = cross >= 0
    xy[is_cross] = c * u[cross[is_cross]]
    l_c = corner_coord(c, n) if ties == "frame" else c
    leg = (arm >= 0) & (l < l_c)
    k, j = arm[leg], half[leg]
    if ties == "frame":
        r_c = c / POLYGON_COS[n]
        e = (r_c * u_psi[k] - c * u[j]) / l_c
        xy[leg] = c * u[j] + l[leg, None] * e
    else:
        sigma = np.where(j == k, 1.0, -1.0)         # from beta_k ccw, from beta_(k+1) cw
        beta = np.where(j == k, k, k + 1) * (math.pi / 2)
        xy[leg] = leg_path(l[leg], beta, sigma, c, r0)
        r_c = r0
    out = (arm >= 0) & ~leg
    if g > 0:
        plan = layer_plan(mesh, g, l_c, columns=True)
        r = r_c + plan.arc(l[out]) - l_c
        z = column_height(mesh, c, plan.eta)
    else:
        r = r_c + l[out] - l_c
        z = np.zeros(mesh.n_nodes)
    xy[out] = r[:, None] * u_psi[arm[out]]
    xy[mesh.node_sets["hub_tied"]] = ref[mesh.node_sets["hub_tied"], :2]
    pos = np.column_stack([xy, z])
    return mesh.replace(node_pos=pos)


def _lead_in(mesh: Mesh) -> float:
    """Radial lead-in of the coil: d0 = c / cos(pi/n) - r0 for a ``frame``-tied web,
    else 0."""
    c = _frame_hole(mesh)
    return 0.0 if c is None else mesh.arm_root_coord - corner_coord(c, mesh.n_arms)


def coil(mesh: Mesh, wrap: str = "trailing", lead_in: float | None = None,
         layer_gap: float = 0.0) -> Mesh:
    """Wind every arm that is straight and radial beyond its root onto the hub rim.

    With l0 = ``arm_root_coord`` (where the coil meets the rim) and d = ``lead_in``: a
    node of arm k with l0 - d <= l < l0 moves onto the spoke at radius r0 + (l0 - l),
    angle psi_k (radially in to the rim), and a node with l >= l0 to the rim point at
    angle psi_k - w (l - l0) / r0, w = +1 (trailing: clockwise, against a positive spin
    about +z) or -1 (leading). Arc length is preserved, chords are shorter: no element is
    stretched. Without a layer gap successive turns overlap (no cable-cable contact is
    modelled); with ``layer_gap`` g > 0 (:mod:`meshgen.layers`, docs/mesh.md 2.9) l is
    replaced by the in-plane arc q(l) of the plan and the coil rises along z (each node
    keeps the z of its layer and adds the rise Z), so that the passes clear each other,
    the spokes and the layers by at least g.

    The input arm is straight and radial from radius r0 + d at l = l0 - d outwards
    (:func:`star_fold`; tethers and the ``axes`` web: d = 0, the arm starts on the rim;
    the ``frame`` web: d = c / cos(pi/n) - r0, the arm starts at the frame corner and the
    coil folds its first d back in to the rim).

    Parameters
    ----------
    mesh : Mesh
        Mesh with arm data, ``hub_radius > 0``, arms straight and radial beyond the root.
    wrap : {'trailing', 'leading'}
    lead_in : float or None [m]
        d; None: c / cos(pi/n) - r0 for a ``frame``-tied web (:func:`tie_mode`), else 0.
    layer_gap : float [m]
        g >= 0, as given to :func:`star_fold` (webs: ``frame`` ties only).

    Returns
    -------
    Mesh
        New ``node_pos``, ``wrap`` (+1 / -1) and the node set ``coil`` (every node moved onto
        the spoke or the rim).
    """
    if wrap not in WRAP_SIGN:
        raise MeshValueError("wrap", f"unknown wrap '{wrap}' (valid: {', '.join(WRAP_SIGN)})")
    r0 = mesh.hub_radius
    if r0 <= 0:
        raise MeshValueError("hub_radius", "coiling needs a hub radius > 0")
    w = WRAP_SIGN[wrap]
    g = check_gap(layer_gap)
    d = _lead_in(mesh) if lead_in is None else float(lead_in)
    l0 = mesh.arm_root_coord
    sel = np.flatnonzero(mesh.node_arm >= 0)
    sel = sel[mesh.node_arm_coord[sel] >= l0 - d]
    sel = np.setdiff1d(sel, mesh.node_sets["hub_tied"])   # tied nodes never move
    lk = mesh.node_arm_coord[sel]
    qk, z = lk, np.zeros(len(sel))
    if g > 0:
        c = _frame_hole(mesh)
        if c is None and "cross" in mesh.node_sets:
            raise MeshValueError("layer_gap", "stacked layers need fold.ties = 'frame'")
        plan = layer_plan(mesh, g, l0 - d, columns=c is not None)
        if c is not None:
            check_clearance(c, r0, plan)
        qk, z = plan.arc(lk), mesh.node_pos[sel, 2] + plan.lift(lk)
    psi = mesh.arm_root_angle[mesh.node_arm[sel]]
    spoke = qk < l0
    r = np.where(spoke, r0 + (l0 - qk), r0)
    ang = np.where(spoke, psi, psi - w * (qk - l0) / r0)
    pos = np.array(mesh.node_pos)
    pos[sel] = np.column_stack([r * np.cos(ang), r * np.sin(ang), z])
    sets = dict(mesh.node_sets)
    sets["coil"] = sel  # what the stowage holds: the lead-in and the turns on the rim
    return mesh.replace(node_pos=pos, wrap=w, node_sets=sets)


def fold_web(mesh: Mesh, hub_radius: float, pattern: str = "star",
             wrap: str = "trailing", ties: str = "frame", layer_gap: float = 0.0) -> Mesh:
    """Flat web with an outline-shaped hole -> arms + ties (``flat``) or star fold + coil
    (``star``); ``ties`` = ``frame`` (the whole hole boundary, default) or ``axes``
    (4 nodes, square web only); ``layer_gap`` g > 0 stacks the layers and the coil's
    passes g apart (``star``, ``frame``, square mesh; docs/mesh.md 2.9)."""
    if pattern not in WEB_FOLDS:
        raise MeshValueError("pattern", f"unknown web fold '{pattern}' "
                             f"(valid: {', '.join(WEB_FOLDS)})")
    g = check_gap(layer_gap)
    web = assign_arms(mesh, hub_radius, ties)
    if pattern == "flat":
        if g > 0:
            raise MeshValueError("layer_gap", "the flat web has no layers (fold.pattern = "
                                 "'flat')")
        return web
    return coil(star_fold(web, g), wrap, layer_gap=g)
