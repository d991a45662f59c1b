"""Lattices of the flat webs other than quadquad and their clipping to the web's outline
(meshgen.topologies): triangular, square and hexagonal node lattices about the centroid,
nodes snapped onto the outline, lattice edges cut where they leave it, close boundary
points merged, the boundary closed by its cable.
"""

from __future__ import annotations

import math

import numpy as np

_SQ3 = math.sqrt(3.0)


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
