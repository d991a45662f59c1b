"""Flat webs other than the square web with a square mesh (the paper's Fig. 2).

The paper considers webs with n = 3 or 4 corners (an equilateral triangle or a square of
side S) and meshes with mu = 3, 4 or 6 cables per node (triangular, square or hexagonal
cells). ``quadquad`` lives in :mod:`meshgen.flat`; this module builds the other five:

============  =================  ===================
topology      web outline        mesh cell
============  =================  ===================
``tritri``    triangle           triangle
``triquad``   triangle           square
``trihex``    triangle           hexagon
``quadtri``   square             triangle
``quadhex``   square             hexagon
============  =================  ===================

Conventions (see also docs/prestress.md):

* The mesh width t is the edge length of a mesh cell (triangle side, square side or
  hexagon side). Every web is centred on the origin (its centroid) in the plane z = 0.
* Triangular web: equilateral, one corner on +y at (0, 2h/3), the base at y = -h/3,
  h = S sqrt(3)/2. Square web: sides parallel to the axes.
* The lattice is placed symmetrically about the centroid (C3 for the triangle, both mirror
  axes for the square), with one cell family aligned with the base: triangles have
  horizontal edges, hexagons are pointy-topped (vertical edges).
* Mesh lines are clipped to the outline and the outline itself is a cable, so the web
  boundary is a closed cable polygon through the n corners. Lattice nodes within
  ``snap * t`` of the outline are moved onto it; a lattice edge that leaves the web is cut
  where it crosses the outline, and the cut point becomes a boundary node. Boundary points
  closer than ``snap * t`` are merged (a corner wins). A boundary node that no mesh line
  reaches is dropped (the boundary cable passes straight through it), and so is an interior
  node left with a single cable. For a hexagonal mesh this keeps whole cells where the
  outline passes through cell centres (side S = sqrt(3) j t for the triangle) and closes
  the cut cells with the boundary cable; other sizes give a ragged but symmetric edge.
* The tri web with a tri mesh is exact when S / t is an integer (nodes on the sides, one at
  each corner).
* Optional central cut-out: the nodes strictly inside the disc of radius ``hub_cutout``
  are removed with their cables; the remaining nodes that lost a cable form
  ``node_sets['hub_tied']`` (the rim of the hole, tied to the hub).
"""

from __future__ import annotations

import math

import numpy as np

from meshgen.checks import MeshValueError
from meshgen.mesh import Mesh
from meshgen.registry import TOPOLOGIES as REGISTRY

#: the topologies built here (every one but quadquad, see meshgen.flat)
TOPOLOGIES = tuple(name for name in REGISTRY if name != "quadquad")
SNAP = 0.3
_SQ3 = math.sqrt(3.0)


def web_outline(shape: str, side: float) -> np.ndarray:
    """(n, 2) corners [m] of the web outline, counter-clockwise, centroid at the origin.

    ``shape`` is 'tri' (corners at 330, 90 and 210 degrees, i.e. one corner on +y) or
    'quad' (corners at 225, 315, 45 and 135 degrees).
    """
    if shape == "tri":
        h = side * _SQ3 / 2
        return np.array([[-side / 2, -h / 3], [side / 2, -h / 3], [0.0, 2 * h / 3]])
    a = side / 2
    return np.array([[-a, -a], [a, -a], [a, a], [-a, a]])


# --- lattices ------------------------------------------------------------------------

def _grid(a1, a2, offset, radius, steps):
    """Nodes offset + i a1 + j a2 within ``radius``, and edges along the given steps."""
    k = int(math.ceil(radius / min(np.linalg.norm(a1), np.linalg.norm(a2)) * 2)) + 2
    ii, jj = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
    pts = offset + ii[..., None] * a1 + jj[..., None] * a2
    inside = np.hypot(pts[..., 0], pts[..., 1]) <= radius
    index = np.full(ii.shape, -1)
    index[inside] = np.arange(inside.sum())
    edges = [np.zeros((0, 2), np.int64)]
    for di, dj in steps:
        ni, nj = ii + di, jj + dj
        ok = inside & (ni >= -k) & (ni <= k) & (nj >= -k) & (nj <= k)
        b = index[ni[ok] + k, nj[ok] + k]
        edges.append(np.column_stack([index[ok], b])[b >= 0])
    return pts[inside], np.concatenate(edges)


def _tri_lattice(t, offset, radius):
    return _grid(np.array([t, 0.0]), np.array([t / 2, t * _SQ3 / 2]), offset, radius,
                 [(1, 0), (0, 1), (-1, 1)])


def _quad_lattice(t, offset, radius):
    return _grid(np.array([t, 0.0]), np.array([0.0, t]), offset, radius, [(1, 0), (0, 1)])


def _hex_lattice(t, offset, radius):
    """Pointy-topped honeycomb of edge t; ``offset`` is the position of one cell centre."""
    centres, _ = _grid(np.array([_SQ3 * t, 0.0]), np.array([_SQ3 * t / 2, 1.5 * t]),
                       offset, radius + t, [])
    ang = np.deg2rad(30.0 + 60.0 * np.arange(6))
    corners = t * np.column_stack([np.cos(ang), np.sin(ang)])
    pts = (centres[:, None, :] + corners[None]).reshape(-1, 2)
    local = np.arange(len(centres))[:, None] * 6
    edges = np.stack([local + np.arange(6), local + (np.arange(6) + 1) % 6], -1).reshape(-1, 2)
    rep = _merge_close(pts, 1e-6 * t)
    pts, edges = _compact(pts, edges, rep)
    return pts, edges


def _merge_close(pts, tol, priority=None):
    """(n,) representative index of each point; points closer than ``tol`` share one.

    The representative of a cluster is its member with the lowest ``priority`` value
    (then the lowest index).
    """
    # imported here: scipy costs 0.2-0.3 s of start-up, and the square web never comes here
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    pairs = cKDTree(pts).query_pairs(tol, output_type="ndarray")
    n = len(pts)
    g = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(g, directed=False)
    prio = np.zeros(n) if priority is None else np.asarray(priority, float)
    order = np.lexsort((np.arange(n), prio, label))
    first = np.ones(n, bool)
    first[1:] = label[order][1:] != label[order][:-1]
    rep_of_label = np.empty(label.max() + 1, np.int64)
    rep_of_label[label[order][first]] = order[first]
    return rep_of_label[label]


def _compact(pts, edges, rep):
    """Keep the representatives, renumber, drop degenerate and duplicate edges."""
    keep = np.unique(rep)
    new = np.full(len(pts), -1)
    new[keep] = np.arange(len(keep))
    e = new[rep[edges]]
    e = np.sort(e[e[:, 0] != e[:, 1]], axis=1)
    return pts[keep], np.unique(e, axis=0)


# --- clipping to the outline ---------------------------------------------------------

def _nearest_on_outline(pts, corners, delta):
    """Nearest outline point (n,2), distance (n,), inside and to-corner flags (n,).

    The outline is a convex polygon. A point within ``delta`` of two adjacent sides goes
    to their common corner (so that a node on a symmetry axis near a corner is not pushed
    to one side).
    """
    a = corners
    nc = len(corners)
    d = np.roll(corners, -1, axis=0) - corners
    rel = pts[:, None, :] - a[None]
    u = np.clip(np.einsum("nkj,kj->nk", rel, d) / np.einsum("kj,kj->k", d, d), 0.0, 1.0)
    q = a[None] + u[..., None] * d[None]
    dist = np.linalg.norm(pts[:, None, :] - q, axis=2)
    k = np.argmin(dist, axis=1)
    normal = np.column_stack([d[:, 1], -d[:, 0]])
    signed = np.einsum("nkj,kj->nk", rel, normal)
    inside = np.all(signed <= 1e-12 * np.abs(normal).max() * np.abs(corners).max(), axis=1)
    idx = np.arange(len(pts))
    near, best = q[idx, k], dist[idx, k]
    to_corner = np.zeros(len(pts), bool)
    for c in range(nc):  # corner c joins sides c-1 and c
        both = (dist[:, c] <= delta) & (dist[:, c - 1] <= delta)
        near[both] = corners[c]
        to_corner |= both
    return near, best, inside, to_corner


def _exit_point(p, r, corners):
    """Where the segments p -> r (p inside, r outside) leave the convex polygon."""
    d = np.roll(corners, -1, axis=0) - corners
    normal = np.column_stack([d[:, 1], -d[:, 0]])
    num = np.einsum("kj,kj->k", corners, normal)[None] - p @ normal.T
    den = (r - p) @ normal.T
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(den > 0, num / den, np.inf)
    return p + np.min(s, axis=1)[:, None] * (r - p)


def _on_sides(pts, corners, tol):
    """(n, k) bool: point lies on side k of the outline."""
    a = corners
    d = np.roll(corners, -1, axis=0) - corners
    rel = pts[:, None, :] - a[None]
    len2 = np.einsum("kj,kj->k", d, d)
    u = np.einsum("nkj,kj->nk", rel, d) / len2
    cross = (rel[..., 0] * d[None, :, 1] - rel[..., 1] * d[None, :, 0]) / np.sqrt(len2)
    return (np.abs(cross) <= tol) & (u >= -1e-9) & (u <= 1 + 1e-9)


def _clip(pts, edges, corners, t, snap, hole=None):
    """Clip a lattice to the outline (and out of an optional convex ``hole``).

    Returns nodes, edges, edge label (-1 mesh cable, 0 outline cable, 1 hole-outline
    cable) and the node ids of the outline corners followed by the hole corners.
    """
    delta = snap * t
    q, dist, inside, to_corner = _nearest_on_outline(pts, corners, delta)
    near = (dist <= delta) | to_corner
    keep = inside | near
    pos = np.where(near[:, None], q, pts)
    in_hole = np.zeros(len(pts), bool)
    hole = np.zeros((0, 2)) if hole is None else np.asarray(hole, float)
    if len(hole):
        qh, dist_h, inside_h, to_corner_h = _nearest_on_outline(pts, hole, delta)
        near_h = (dist_h <= delta) | to_corner_h
        pos = np.where(near_h[:, None], qh, pos)
        in_hole = inside_h & ~near_h
        keep &= ~in_hole
        near |= near_h
    interior = keep & ~near
    a, b = edges[:, 0], edges[:, 1]
    kept = keep[a] & keep[b]
    if len(hole):   # a chord between two points of the hole's rim crosses the hole
        mid = 0.5 * (pos[a[kept]] + pos[b[kept]])
        _, dist_m, inside_m, _ = _nearest_on_outline(mid, hole, 0.0)
        kept[np.flatnonzero(kept)[inside_m & (dist_m > 1e-9 * t)]] = False
    kept_edges = edges[kept]
    cut = (interior[a] & ~keep[b]) | (interior[b] & ~keep[a])
    p_in = np.where(interior[a[cut]], a[cut], b[cut])
    p_out = np.where(interior[a[cut]], b[cut], a[cut])
    x_cut = _exit_point(pts[p_in], pts[p_out], corners)
    into = in_hole[p_out]          # an edge entering the hole is cut where it enters
    if into.any():
        x_cut[into] = _exit_point(pts[p_out[into]], pts[p_in[into]], hole)
    n0 = len(pts)
    all_pts = np.vstack([pos, x_cut, corners, hole])
    all_edges = np.vstack([kept_edges, np.column_stack([p_in, n0 + np.arange(len(x_cut))])])
    n_new = len(x_cut) + len(corners) + len(hole)
    alive = np.concatenate([keep, np.ones(n_new, bool)])
    # merge boundary points closer than delta: corners first, then lattice nodes
    prio = np.concatenate([np.ones(n0), 2 * np.ones(len(x_cut)),
                           np.zeros(len(corners) + len(hole))])
    on_bnd = np.concatenate([near, np.ones(n_new, bool)])
    rep = np.arange(len(all_pts))
    bidx = np.flatnonzero(on_bnd & alive)
    rep[bidx] = bidx[_merge_close(all_pts[bidx], delta, prio[bidx])]
    rep[~alive] = -1
    all_edges = all_edges[(rep[all_edges] >= 0).all(axis=1)]
    corner_old = n0 + len(x_cut) + np.arange(len(corners) + len(hole))
    keep_idx = np.unique(rep[rep >= 0])
    new = np.full(len(all_pts), -1)
    new[keep_idx] = np.arange(len(keep_idx))
    e = new[rep[all_edges]]
    e = np.unique(np.sort(e[e[:, 0] != e[:, 1]], axis=1), axis=0)
    polygons = [corners] + ([hole] if len(hole) else [])
    return _close_boundary(all_pts[keep_idx], e, polygons, new[rep[corner_old]], t)


def _close_boundary(pts, edges, polygons, corner_ids, t):
    """Replace cables along each polygon (outline, hole) by one boundary chain per side;
    prune loose nodes. Returns nodes, edges, edge label (-1 or polygon index), corners."""
    sides = np.hstack([_on_sides(pts, poly, 1e-7 * t) for poly in polygons])
    starts = np.vstack(polygons)
    d = np.vstack([np.roll(poly, -1, axis=0) - poly for poly in polygons])
    owner = np.concatenate([np.full(len(poly), i) for i, poly in enumerate(polygons)])
    alive = np.ones(len(pts), bool)
    shared = (sides[edges[:, 0]] & sides[edges[:, 1]]).any(axis=1)
    inner = edges[~shared]
    is_corner = np.zeros(len(pts), bool)
    is_corner[corner_ids] = True
    on_bnd = sides.any(axis=1)
    while True:
        inner = inner[alive[inner].all(axis=1)]
        deg = np.bincount(inner.ravel(), minlength=len(pts))
        drop = alive & ~is_corner & ((on_bnd & (deg == 0)) | (~on_bnd & (deg <= 1)))
        if not drop.any():
            break
        alive &= ~drop
    chains, labels = [], [np.full(len(inner), -1)]
    for k in range(len(starts)):
        ids = np.flatnonzero(sides[:, k] & alive)
        u = (pts[ids] - starts[k]) @ d[k]
        ids = ids[np.argsort(u)]
        chains.append(np.column_stack([ids[:-1], ids[1:]]))
        labels.append(np.full(len(ids) - 1, owner[k]))
    all_edges = np.vstack([inner] + chains)
    new = np.full(len(pts), -1)
    new[alive] = np.arange(alive.sum())
    return pts[alive], new[all_edges], np.concatenate(labels), new[corner_ids]


# --- assembly ------------------------------------------------------------------------

def _lattice_for(topology, side, t):
    """Lattice nodes/edges covering the web, placed symmetrically about the centroid."""
    shape, cell = ("tri", topology[3:]) if topology.startswith("tri") else ("quad", topology[4:])
    corners = web_outline(shape, side)
    radius = np.linalg.norm(corners, axis=1).max() + 2 * t
    if topology == "tritri":
        frac = (max(1, round(side / t)) / 3.0) % 1.0
        offset = -frac * np.array([1.5 * t, t * _SQ3 / 2])
        pts, edges = _tri_lattice(t, offset, radius)
    elif topology == "quadtri":
        pts, edges = _tri_lattice(t, np.zeros(2), radius)
    elif topology == "triquad":
        ox = 0.5 * t * (round(side / t) % 2)
        oy = (corners[0, 1] / t - math.floor(corners[0, 1] / t)) * t
        pts, edges = _quad_lattice(t, np.array([ox, oy]), radius)
    elif topology == "trihex":
        base = corners[0, 1]
        choices = [0.0, t, -t]  # cell centre, or a vertex above / below one, at the origin
        miss = [abs((base - c) / (1.5 * t) - round((base - c) / (1.5 * t))) for c in choices]
        pts, edges = _hex_lattice(t, np.array([0.0, choices[int(np.argmin(miss))]]), radius)
    elif topology == "quadhex":
        pts, edges = _hex_lattice(t, np.zeros(2), radius)
    else:
        raise MeshValueError("topology", f"unknown topology '{topology}' "
                             f"(valid: {', '.join(TOPOLOGIES)})")
    return pts, edges, corners


def _subdivide(pts, edges, k):
    """Split every segment into k elements; returns nodes, elements, parent segment."""
    if k == 1:
        return pts, edges, np.arange(len(edges))
    s = (np.arange(1, k) / k)[None, :, None]
    a, b = pts[edges[:, 0]], pts[edges[:, 1]]
    mid = (a[:, None] + s * (b - a)[:, None]).reshape(-1, 2)
    ids = len(pts) + np.arange(len(mid)).reshape(len(edges), k - 1)
    chain = np.column_stack([edges[:, :1], ids, edges[:, 1:]])
    elems = np.stack([chain[:, :-1], chain[:, 1:]], -1).reshape(-1, 2)
    return np.vstack([pts, mid]), elems, np.repeat(np.arange(len(edges)), k)


def _web_inradius(topology: str, side: float) -> float:
    """Inradius [m] of the web outline: S / (2 sqrt 3) for the triangle (h/3), S/2 for the
    square."""
    return side / (2 * _SQ3) if topology.startswith("tri") else side / 2


def outline_hole(topology: str, side: float, inradius: float) -> np.ndarray:
    """(n, 2) corners [m] of a hole shaped like the web outline, of inradius ``inradius``
    (the hub frame of the star fold: sides parallel to the web's sides)."""
    corners = web_outline("tri" if topology.startswith("tri") else "quad", side)
    return corners * (inradius / _web_inradius(topology, side))


def outline_cutout(topology: str, side: float, mesh_width: float, hub_cutout: float) -> float:
    """Inradius c [m] of the outline-shaped hole actually cut for a star fold.

    ``tritri`` with S/t an integer: rounded outwards to the nearest mesh line, so that the
    hole's sides are cables of the mesh (c = h/3 - i t sqrt(3)/2, h = S sqrt(3)/2); other
    topologies: ``hub_cutout`` itself (the hole outline becomes a cable that clips the
    mesh, as the web outline does).
    """
    if hub_cutout <= 0:
        raise MeshValueError("hub_cutout", f"the star fold needs a hub cut-out > 0, "
                             f"got {hub_cutout:g} m")
    n = side / mesh_width
    if topology == "tritri" and abs(n - round(n)) <= 1e-9 * n:
        top = _web_inradius(topology, side)           # h/3
        step = mesh_width * _SQ3 / 2
        i = math.floor((top - hub_cutout) / step + 1e-9)
        return top - i * step
    return float(hub_cutout)


def flat_other(topology: str, side: float, mesh_width: float, elements_per_segment: int = 1,
               corner_mass: float = 0.0, hub_cutout: float | None = 0.0,
               snap: float = SNAP, hole: str = "disc") -> Mesh:
    """A flat web of one of the paper's Fig. 2 configurations (not ``quadquad``).

    Parameters
    ----------
    topology : {'tritri', 'triquad', 'trihex', 'quadtri', 'quadhex'}
        Web outline (tri: equilateral triangle, quad: square) and mesh cell.
    side : float [m]
        Web side S.
    mesh_width : float [m]
        Mesh width t: edge length of a mesh cell.
    elements_per_segment : int
        Cable elements between two mesh nodes (collinear subdivision).
    corner_mass : float [kg]
        Point mass at each web corner.
    hub_cutout : float or None [m]
        Size of the central hole (0 or None: no hole): the radius of a disc whose nodes
        are removed (``hole='disc'``), or the inradius of a hole shaped like the web
        outline (``hole='outline'``, see :func:`outline_hole`).
    snap : float
        Fraction of t within which lattice nodes are moved onto the outline and boundary
        points are merged.
    hole : {'disc', 'outline'}
        ``disc``: the nodes left on the rim (those that lost a cable) form ``hub_tied``.
        ``outline``: the hole is clipped like the outline, its boundary is a cable
        polygon through its corners, and every node on it (subdivision nodes included)
        forms ``hub_tied`` and ``hole_boundary``: the rigid hub frame of the star fold.

    Raises
    ------
    MeshValueError
        For a bad parameter (named as in this signature).

    Returns
    -------
    Mesh
        z = 0, ``node_pos == node_ref``; node sets ``corners`` = ``tips`` (sorted by polar
        angle in [0, 2 pi)), ``boundary``, ``hub_tied`` (and ``hole_boundary``,
        ``hole_corners`` for an outline hole); element sets ``boundary`` (the outline
        cable) and ``hole_boundary``.
    """
    if not 0 < mesh_width <= side / 2:
        raise MeshValueError("mesh_width", f"need 0 < mesh_width <= side/2, got "
                             f"{mesh_width:g} m for a side of {side:g} m")
    if int(elements_per_segment) < 1:
        raise MeshValueError("elements_per_segment",
                             f"must be >= 1, got {elements_per_segment}")
    if corner_mass < 0:
        raise MeshValueError("corner_mass", f"must be >= 0, got {corner_mass:g} kg")
    if hole not in ("disc", "outline"):
        raise MeshValueError("hole", f"unknown hole shape '{hole}' (valid: disc, outline)")
    t = float(mesh_width)
    lat, lat_edges, corners = _lattice_for(topology, float(side), t)
    hole_xy = None
    if hole == "outline" and hub_cutout:
        if hub_cutout > _web_inradius(topology, side) - t:
            raise MeshValueError("hub_cutout", f"a hole of inradius {hub_cutout:g} m leaves "
                                 f"less than one mesh width ({t:g} m) of web beside it")
        hole_xy = outline_hole(topology, side, hub_cutout)
    pts, edges, label, corner_ids = _clip(lat, lat_edges, corners, t, snap, hole_xy)
    hole_ids, corner_ids = corner_ids[len(corners):], corner_ids[:len(corners)]
    hub_tied = np.zeros(0, np.int64)
    if hub_cutout and hole_xy is None:
        r = np.hypot(pts[:, 0], pts[:, 1])
        gone = r < hub_cutout * (1 - 1e-12)
        if gone[corner_ids].any():
            raise MeshValueError("hub_cutout", f"{hub_cutout:g} m removes a web corner")
        hit = gone[edges].any(axis=1)
        hub_tied = np.setdiff1d(np.unique(edges[hit]), np.flatnonzero(gone))
        new = np.full(len(pts), -1)
        new[~gone] = np.arange((~gone).sum())
        pts, edges, label = pts[~gone], new[edges[~hit]], label[~hit]
        corner_ids, hub_tied = new[corner_ids], new[hub_tied]
    # deterministic node order: by row (y), then x
    order = np.lexsort((pts[:, 0], np.round(pts[:, 1] / t, 6)))
    rank = np.empty(len(pts), np.int64)
    rank[order] = np.arange(len(pts))
    pts, edges = pts[order], np.sort(rank[edges], axis=1)
    corner_ids, hub_tied, hole_ids = rank[corner_ids], np.sort(rank[hub_tied]), rank[hole_ids]
    ang = np.mod(np.arctan2(pts[corner_ids, 1], pts[corner_ids, 0]), 2 * np.pi)
    corner_ids = corner_ids[np.argsort(ang)]
    boundary_nodes = np.unique(edges[label == 0])
    nodes2, elems, parent = _subdivide(pts, edges, int(elements_per_segment))
    seg_len = np.linalg.norm(pts[edges[:, 1]] - pts[edges[:, 0]], axis=1)
    rest = seg_len[parent] / int(elements_per_segment)
    xyz = np.column_stack([nodes2, np.zeros(len(nodes2))])
    mass = np.zeros(len(nodes2))
    mass[corner_ids] = corner_mass
    node_sets = {"corners": corner_ids, "tips": corner_ids, "boundary": boundary_nodes}
    hole_elems = np.flatnonzero(label[parent] == 1)
    if hole_xy is not None:
        hub_tied = np.unique(elems[hole_elems])
        node_sets.update(hole_boundary=hub_tied, hole_corners=hole_ids)
    node_sets["hub_tied"] = hub_tied
    return Mesh(node_pos=xyz, node_ref=xyz.copy(), elem_nodes=elems, elem_rest_len=rest,
                node_point_mass=mass, node_sets=node_sets,
                elem_sets={"boundary": np.flatnonzero(label[parent] == 0),
                           "hole_boundary": hole_elems})
