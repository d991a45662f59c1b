"""The line at a reel's or brake's departure point D (fe.coil.payout): its energy and the
leapfrog's pairing of kinetic and strain energy, from which each device's work is measured
(the energy its update changes, with the midpoint pairing the device's work is second
order in the step; docs/solver.md)."""

from __future__ import annotations

import numpy as np
from numba import njit

from spinweb_fe.fe.coil.payout import _frac, _hub_velocity3


@njit(inline="always")
def _pull(pos, q, at_front, s_f, s_dev, xd, t_elem, t_from, t_to, t_coord, rest_len, ea,
          inv_rest):
    """(the inner end's place, the force on the outer node), six floats, of the free
    element q (of the coil's test tables ``t_*``) of a level whose place on the coil is
    ``s_f``: from D (``xd``) at rest length phi L0 if the level is its arm's front
    (``at_front``; ``s_dev`` the line's coordinate at D), else from its held node at L0 (a
    spring of E A / L0 on its stretch). Arrays, not the coil's tuples: a tuple handed on
    costs a reference count per array, and this runs per element and step."""
    e, b = t_elem[q], t_to[q]
    ell = rest_len[e]
    a = t_from[q]
    xa0, xa1, xa2 = pos[a, 0], pos[a, 1], pos[a, 2]
    if at_front:
        ell *= _frac(t_coord[q], s_f, s_dev)
        xa0, xa1, xa2 = xd[0], xd[1], xd[2]
    r0, r1, r2 = pos[b, 0] - xa0, pos[b, 1] - xa1, pos[b, 2] - xa2
    d = np.sqrt(r0 ** 2 + r1 ** 2 + r2 ** 2 + 1e-300)
    c = -(ea[e] * inv_rest[e] * max(d - ell, 0.0) / d)
    return xa0, xa1, xa2, c * r0, c * r1, c * r2


@njit(inline="always")
def line_energy(coil, cs, k, elems, mv, lo, hi):
    """Kinetic energy of the nodes of arm k's levels lo - 1 .. hi (their masses now) and
    strain energy of the free elements of levels lo .. hi [J]: the device's elements (of
    the front level) from D at their rest length phi L0, the others at L0."""
    pos, vel, mass = mv.pos, mv.vel, mv.mass
    first, end = coil.arm_ptr[k], coil.arm_ptr[k + 1]
    level_ptr, level_nodes, test_ptr = coil.level_ptr, coil.level_nodes, coil.test_ptr
    t_elem, t_from, t_to, t_coord = coil.test_elem, coil.test_from, coil.test_to, \
        coil.test_to_coord
    rest_len, ea, inv_rest = elems.rest_len, elems.ea, elems.inv_rest
    front, s_dev, xd = first + cs.front[k], cs.s_dev[k], cs.dev_x[k]
    e_kin, e_str = 0.0, 0.0
    for lev in range(max(lo - 1, first), min(hi + 1, end)):
        for p in range(level_ptr[lev], level_ptr[lev + 1]):
            i = level_nodes[p]
            e_kin += 0.5 * mass[i] * (vel[i, 0] ** 2 + vel[i, 1] ** 2 + vel[i, 2] ** 2)
        if lev < lo:
            continue
        s_f = coil.level_coord[lev]
        for q in range(test_ptr[lev], test_ptr[lev + 1]):
            e = t_elem[q]
            _, _, _, f0, f1, f2 = _pull(pos, q, lev == front, s_f, s_dev, xd, t_elem, t_from,
                                        t_to, t_coord, rest_len, ea, inv_rest)
            n = np.sqrt(f0 ** 2 + f1 ** 2 + f2 ** 2)
            e_str += 0.5 * n * n / (ea[e] * inv_rest[e])
    return e_kin + e_str


@njit(inline="always")
def line_pairing(coil, cs, k, elems, mv, pose, lev, dt, steps):
    """sum f . (dx_b - dx_a) over the free elements of arm k's levels lev and lev + 1: the
    force on the outer node times the step's displacement of the outer node (dt v, from
    ``steps`` (T, 3), written on the first call: negative ``steps[0, 0]`` marks it unwritten)
    less its inner end's (dt times the hub's velocity at D or at the held node now). Half
    the change of this sum over the device's update is the part of the device's work the
    leapfrog credits to the step: with it the device's work is the midpoint rule."""
    out = 0.0
    j = 0
    hi = min(lev + 2, coil.arm_ptr[k + 1])
    fresh = steps[0, 0] < 0.0
    pos, vel, test_ptr = mv.pos, mv.vel, coil.test_ptr
    t_elem, t_from, t_to, t_coord = coil.test_elem, coil.test_from, coil.test_to, \
        coil.test_to_coord
    rest_len, ea, inv_rest = elems.rest_len, elems.ea, elems.inv_rest
    front, s_dev, xd = coil.arm_ptr[k] + cs.front[k], cs.s_dev[k], cs.dev_x[k]
    for lv in range(lev, hi):
        s_f = coil.level_coord[lv]
        for q in range(test_ptr[lv], test_ptr[lv + 1]):
            xa0, xa1, xa2, f0, f1, f2 = _pull(pos, q, lv == front, s_f, s_dev, xd, t_elem,
                                              t_from, t_to, t_coord, rest_len, ea, inv_rest)
            if fresh:
                for d in range(3):
                    steps[j + 1, d] = dt * vel[t_to[q], d]
            va0, va1, va2 = _hub_velocity3(pose, xa0, xa1, xa2)
            out += (f0 * (steps[j + 1, 0] - dt * va0) + f1 * (steps[j + 1, 1] - dt * va1)
                    + f2 * (steps[j + 1, 2] - dt * va2))
            j += 1
    steps[0, 0] = 1.0
    return out
