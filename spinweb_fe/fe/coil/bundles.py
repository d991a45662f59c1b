"""Bundles (``[stowage] bundle``): while an arm is bundled, each of its released levels moves
as one point, its first node (the spine node) carrying the level's summed mass and force
and the others copying it, until the bundles open at a paid-out length or a time
(fe.coil.levels.BUNDLES). ``coil`` None: no bundles (numba compiles none of this).
"""

from __future__ import annotations

from numba import njit

from spinweb_fe.fe.coil.levels import free_length, level_masses


@njit(cache=True)
def gather_bundles(coil, cs, force):
    """The force (n, 3) on each released level of a bundled arm, summed on its spine node
    (the other nodes' rows are cleared). ``coil`` None: a scene without bundles (numba
    compiles nothing of it)."""
    if coil is None:
        return
    for k in range(coil.arm_ptr.shape[0] - 1):
        if not cs.bundled[k]:
            continue
        for lev in range(coil.arm_ptr[k], coil.arm_ptr[k] + cs.front[k]):
            a, b = coil.level_ptr[lev], coil.level_ptr[lev + 1]
            m = coil.level_nodes[a]
            for p in range(a + 1, b):
                i = coil.level_nodes[p]
                for d in range(3):
                    force[m, d] += force[i, d]
                    force[i, d] = 0.0


@njit(cache=True)
def scatter_bundles(coil, cs, pos, vel):
    """The other nodes of each bundle take its spine node's position and velocity (``coil``
    None: no bundles)."""
    if coil is None:
        return
    for k in range(coil.arm_ptr.shape[0] - 1):
        if not cs.bundled[k]:
            continue
        for lev in range(coil.arm_ptr[k], coil.arm_ptr[k] + cs.front[k]):
            a, b = coil.level_ptr[lev], coil.level_ptr[lev + 1]
            m = coil.level_nodes[a]
            for p in range(a + 1, b):
                i = coil.level_nodes[p]
                for d in range(3):
                    pos[i, d] = pos[m, d]
                    vel[i, d] = vel[m, d]


@njit(cache=True)
def open_bundles(coil, cs, nodes, mass, inv_mass, t):
    """Open the bundles of the arms that reached the release (length fraction or time):
    every node keeps the bundle's position and velocity and gets its own mass back
    (``coil`` None: no bundles)."""
    if coil is None:
        return
    for k in range(coil.arm_ptr.shape[0] - 1):
        if not cs.bundled[k]:
            continue
        if coil.bundle_timed:
            due = t >= coil.bundle_value
        else:
            span = coil.arm_end[k] - coil.arm_base[k]
            due = free_length(coil, cs, k) >= coil.bundle_value * span - 1e-12 * span
        if due:
            cs.bundled[k] = False
            level_masses(coil.level_ptr, coil.level_nodes, coil.level_mass, nodes.mass,
                         nodes.inv_mass, mass, inv_mass, coil.arm_ptr[k],
                         coil.arm_ptr[k] + cs.front[k], cs.bundled[k])
