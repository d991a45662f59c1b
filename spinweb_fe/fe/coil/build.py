"""The Coil of a coiled mesh: its levels (per arm, the coil nodes of one arm coordinate,
outer first), their free elements and the laws that release them (fe.coil.levels's kernels read
it)."""

from __future__ import annotations

import numpy as np

from spinweb_fe.fe.coil.levels import BUNDLES, Coil, no_coil
from spinweb_fe.fe.coil.payout import BY_CODE as PAYOUTS_BY_CODE


def _levels(mesh, coil_nodes):
    """Per arm, the coil's levels (outer first): [(arm, coord, nodes with the spine first)].
    Linear in the coil size apart from one sort."""
    arm, coord = mesh.node_arm[coil_nodes], np.round(mesh.node_arm_coord[coil_nodes], 9)
    spine = np.isin(coil_nodes, np.asarray(mesh.node_sets.get("boundary", []), np.int64))
    order = np.lexsort((coil_nodes, ~spine, -coord, arm))  # arm, outer first, spine first
    a, c, nodes = arm[order], coord[order], coil_nodes[order]
    cut = np.flatnonzero((np.diff(a) != 0) | (np.diff(c) != 0)) + 1
    return [(int(a[g[0]]), float(c[g[0]]), nodes[g])
            for g in np.split(np.arange(len(nodes)), cut)]


def _free_elements(elem_nodes, level_of, level_arm, level_coord, level_first):
    """Per level, its free elements (from a node of the level to a node of an outer level of
    the same arm), the one joining two spine nodes first: (ptr, elem, from, to)."""
    e = np.arange(len(elem_nodes))
    cols = []
    for a, b in ((elem_nodes[:, 0], elem_nodes[:, 1]), (elem_nodes[:, 1], elem_nodes[:, 0])):
        la, lb = level_of[a], level_of[b]
        ok = (la >= 0) & (lb >= 0)
        ok[ok] &= (level_arm[la[ok]] == level_arm[lb[ok]]) & (level_coord[lb[ok]]
                                                                > level_coord[la[ok]])
        cols.append((la[ok], e[ok], a[ok], b[ok]))
    la, el, fr, to = (np.concatenate(c) for c in zip(*cols))
    spine = (fr == level_first[la]) & (to == level_first[level_of[to]])
    order = np.lexsort((to, el, ~spine, la))
    la, el, fr, to = la[order], el[order], fr[order], to[order]
    ptr = np.searchsorted(la, np.arange(len(level_coord) + 1))
    return ptr.astype(np.int64), el, fr, to


BUNDLES_BY_CODE = {c.code: c for c in BUNDLES.values()}


def build_coil(mesh, elem_nodes, node_mass, coil_code=1, payout=(0, None), bundle=(0, 0.0),
               hold=None, elem_mass=None) -> Coil:
    """The Coil of a coiled mesh (``mesh.node_sets['coil']``), its levels and free elements.

    Parameters
    ----------
    mesh : meshgen.mesh.Mesh
    elem_nodes : (m, 2) int64
    node_mass : (n,) float64 [kg]
    coil_code : int
        See :data:`COILS`.
    payout : (code, None or ((P,) times [s], (P,) lengths [m]))
        The payout device (fe.coil.payout.PAYOUTS) and its law's paid-out length table.
    bundle : (code, value)
        See :data:`BUNDLES`.
    hold : None or (n_arms,) float64 [s]
        Times until which each arm's whole coil is held (None: none).
    elem_mass : None or (m,) float64 [kg]
        Each element's mass (the line density times its rest length; None: zeros, for a
        coil without a payout device).
    """
    coil_nodes = np.asarray(mesh.node_sets.get("coil", []), np.int64)
    if len(coil_nodes) == 0:
        return no_coil(mesh.n_arms)
    elem_nodes = np.asarray(elem_nodes, np.int64)
    levels = _levels(mesh, coil_nodes)
    level_arm = np.array([k for k, _, _ in levels], np.int64)
    coord = np.array([c for _, c, _ in levels])
    sizes = np.array([len(n) for _, _, n in levels])
    level_ptr = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    nodes = np.concatenate([n for _, _, n in levels])
    level_of = np.full(mesh.n_nodes, -1, np.int64)
    level_of[nodes] = np.repeat(np.arange(len(levels)), sizes)
    first = nodes[level_ptr[:-1]]
    test_ptr, t_el, t_from, t_to = _free_elements(elem_nodes, level_of, level_arm, coord, first)
    r = np.hypot(mesh.node_pos[:, 0], mesh.node_pos[:, 1])
    on_rim = np.abs(r - mesh.hub_radius) <= 1e-9 * mesh.hub_radius
    arm_ptr = np.searchsorted(level_arm, np.arange(mesh.n_arms + 1)).astype(np.int64)
    ends, bases = np.zeros(mesh.n_arms), np.zeros(mesh.n_arms)
    base_rim = np.zeros(mesh.n_arms, bool)
    for k in range(mesh.n_arms):
        mine = coord[arm_ptr[k]:arm_ptr[k + 1]]
        ends[k] = mine.max()
        below = np.flatnonzero((mesh.node_arm == k) & (mesh.node_arm_coord < mine.min() - 1e-9))
        step = np.min(-np.diff(mine)) if len(mine) > 1 else 0.0
        if len(below):
            top = below[mesh.node_arm_coord[below] >= mesh.node_arm_coord[below].max() - 1e-9]
            bases[k] = mesh.node_arm_coord[top[0]]
            base_rim[k] = bool(np.all(on_rim[top]))
        else:
            bases[k] = mine.min() - step
    t, L = (np.zeros(0), np.zeros(0)) if payout[1] is None else payout[1]
    return Coil(
        arm_ptr=arm_ptr, level_ptr=level_ptr, level_nodes=nodes,
        level_ref=np.ascontiguousarray(mesh.node_pos[nodes], np.float64), level_coord=coord,
        level_mass=np.add.reduceat(node_mass[nodes], level_ptr[:-1]),
        level_rim=np.logical_and.reduceat(on_rim[nodes], level_ptr[:-1]),
        test_ptr=test_ptr, test_elem=t_el, test_from=t_from, test_to=t_to,
        test_to_coord=coord[level_of[t_to]], arm_end=ends, arm_base=bases, base_rim=base_rim,
        coil_code=int(coil_code), payout_code=int(payout[0]),
        device=PAYOUTS_BY_CODE[int(payout[0])].device,
        length_law=PAYOUTS_BY_CODE[int(payout[0])].length_law,
        law_t=np.asarray(t, np.float64), law_v=np.asarray(L, np.float64),
        test_half=(np.zeros(len(t_el)) if elem_mass is None
                   else 0.5 * np.asarray(elem_mass, np.float64)[t_el]),
        bundle_code=int(bundle[0]), bundle_timed=BUNDLES_BY_CODE[int(bundle[0])].timed,
        bundle_value=float(bundle[1]),
        arm_hold=np.zeros(mesh.n_arms) if hold is None else np.asarray(hold, np.float64))
