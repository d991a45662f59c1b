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
from meshgen.clip import _tri_lattice, _quad_lattice, _hex_lattice, _clip
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

# --- clipping to the outline ---------------------------------------------------------

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
