"""Flat (deployed) webs: the square QuadQuad grid, the hub cut-out and the area rule.

Node numbering of :func:`flat_quadquad` (see docs/mesh.md): first the kept grid nodes
(mesh nodes) row by row (y outer, x inner, both increasing), then the k-1 intermediate
nodes of each kept mesh segment, segment by segment (all x-direction segments, then all
y-direction segments, each in the order of its first node), from the segment's first to
its second node. Elements: the k elements of each segment, in the same segment order.
"""

from __future__ import annotations

import numpy as np

from meshgen.checks import MeshValueError
from meshgen.mesh import Mesh

def grid_count(side: float, mesh_width: float) -> int:
    """Number N = S/t of mesh widths per side; ValueError unless it is an integer >= 2."""
    ratio = side / mesh_width
    n = int(round(ratio))
    if n < 2 or abs(ratio - n) > 1e-9 * max(1.0, ratio):
        raise MeshValueError("mesh_width", f"the side {side:g} m must be an integer multiple "
                             f"(>= 2) of the mesh width {mesh_width:g} m "
                             f"(side/mesh_width = {ratio:.9g})")
    return n


def grid_coords(side: float, n: int) -> np.ndarray:
    """(N+1,) grid-line coordinates [m], exactly symmetric about 0 (x_i = (2i - N) a / N)."""
    a = 0.5 * side
    return (2.0 * np.arange(n + 1) - n) * a / n


def effective_cutout(side: float, mesh_width: float, hub_cutout: float) -> float:
    """Half-width c [m] of the cut-out actually removed: the smallest grid line at or
    outside ``hub_cutout`` (0 if ``hub_cutout`` is 0).

    Raises MeshValueError if the cut-out would leave no web (c >= S/2).
    """
    n = grid_count(side, mesh_width)
    if hub_cutout < 0:
        raise MeshValueError("hub_cutout", f"must be >= 0, got {hub_cutout:g} m")
    if hub_cutout == 0:
        return 0.0
    x = np.abs(grid_coords(side, n))
    tol = 1e-9 * mesh_width
    c = float(np.min(x[x >= hub_cutout - tol]))
    if c >= 0.5 * side - tol:
        raise MeshValueError("hub_cutout", f"the cut-out half-width {hub_cutout:g} m "
                             f"(rounded to the grid line {c:g} m) leaves no web of side {side:g} m")
    return c


def default_cutout(side: float, mesh_width: float, hub_radius: float) -> float:
    """Default cut-out half-width c [m]: the smallest grid line at or outside the hub
    radius (t * ceil(r0 / t) when S/t is even), so that no web node lies in the hub."""
    return effective_cutout(side, mesh_width, hub_radius)


def flat_quadquad(side: float, mesh_width: float, elements_per_segment: int = 1,
                  corner_mass: float = 0.0, hub_cutout: float = 0.0) -> Mesh:
    """Flat square web with a square mesh (QuadQuad), centred at the origin, in z = 0.

    Parameters
    ----------
    side : float [m]
        Side S = 2a.
    mesh_width : float [m]
        Grid spacing t; S/t must be an integer (else MeshValueError on ``mesh_width``).
    elements_per_segment : int
        Cable elements k per mesh segment (k - 1 intermediate nodes, rest length t/k).
    corner_mass : float [kg]
        Point mass at each of the 4 corners.
    hub_cutout : float [m]
        Half-width c of the central square removed for the hub, rounded outwards to a
        grid line: every node with max(|x|, |y|) < c and every segment touching one is
        removed (0: none).

    Returns
    -------
    Mesh
        ``node_pos = node_ref`` (flat). Node sets: ``mesh_nodes``, ``corners`` and
        ``tips`` (corners in arm order, arm k at angle pi/4 + k pi/2), ``boundary``
        (outer edge), ``hole_boundary`` (edge of the cut-out, empty without one).
        Element sets: ``grid`` (all), ``lines_x``, ``lines_y``, ``boundary``.
        Counts with q grid lines strictly inside the cut-out (q = 2c/t - 1 for even N):
        nodes (N+1)^2 - q^2 + (k-1) n_seg, elements k n_seg,
        n_seg = 2 N (N+1) - 2 q (q+1).
    """
    n = grid_count(side, mesh_width)
    ne = int(elements_per_segment)
    if ne < 1:
        raise MeshValueError("elements_per_segment", f"must be >= 1, got {elements_per_segment}")
    if corner_mass < 0:
        raise MeshValueError("corner_mass", f"must be >= 0, got {corner_mass:g} kg")
    a = 0.5 * side
    t = side / n
    c = effective_cutout(side, mesh_width, hub_cutout)
    g = grid_coords(side, n)
    X, Y = np.meshgrid(g, g)                      # [j, i]: y index j, x index i
    tol = 1e-9 * t
    keep = np.maximum(np.abs(X), np.abs(Y)) >= c - tol if c > 0 else np.ones_like(X, bool)
    index = np.full(X.shape, -1, np.int64)
    index[keep] = np.arange(int(keep.sum()))
    mesh_xy = np.column_stack([X[keep], Y[keep]])
    n_mesh = len(mesh_xy)

    seg_x = np.column_stack([index[:, :-1].ravel(), index[:, 1:].ravel()])
    seg_y = np.column_stack([index[:-1, :].ravel(), index[1:, :].ravel()])
    seg_x = seg_x[np.all(seg_x >= 0, axis=1)]
    seg_y = seg_y[np.all(seg_y >= 0, axis=1)]
    seg = np.vstack([seg_x, seg_y])
    n_seg = len(seg)

    # intermediate nodes p + (q - p) m / k, m = 1..k-1, and the chain p, n_1.., q
    frac = np.arange(1, ne) / ne
    p, q = mesh_xy[seg[:, 0]], mesh_xy[seg[:, 1]]
    inter = (p[:, None, :] + (q - p)[:, None, :] * frac[None, :, None]).reshape(-1, 2)
    chain = np.empty((n_seg, ne + 1), np.int64)
    chain[:, 0], chain[:, -1] = seg[:, 0], seg[:, 1]
    chain[:, 1:-1] = n_mesh + np.arange(n_seg * (ne - 1)).reshape(n_seg, ne - 1)
    elems = np.column_stack([chain[:, :-1].ravel(), chain[:, 1:].ravel()])

    xy = np.vstack([mesh_xy, inter])
    pos = np.column_stack([xy, np.zeros(len(xy))])
    rest = np.full(len(elems), t / ne)

    corners = np.array([index[n, n], index[n, 0], index[0, 0], index[0, n]], np.int64)
    pmass = np.zeros(len(pos))
    pmass[corners] = corner_mass
    radius_inf = np.max(np.abs(xy), axis=1)
    boundary = np.flatnonzero(np.abs(radius_inf - a) <= tol)
    hole = np.flatnonzero(np.abs(radius_inf - c) <= tol) if c > 0 else np.zeros(0, np.int64)
    on_edge = np.isin(elems, boundary).all(axis=1)
    e_x = np.arange(len(seg_x) * ne)
    return Mesh(
        node_pos=pos, node_ref=pos, elem_nodes=elems, elem_rest_len=rest,
        node_point_mass=pmass,
        node_sets={"mesh_nodes": np.arange(n_mesh), "corners": corners, "tips": corners,
                   "boundary": boundary, "hole_boundary": hole},
        elem_sets={"grid": np.arange(len(elems)), "lines_x": e_x,
                   "lines_y": np.arange(len(e_x), len(elems)),
                   "boundary": np.flatnonzero(on_edge)},
        arm_length=a)
