"""The stowed coil: nodes held on the hub until the peel front of their arm releases them,
at a free or a prescribed pace, and bundles that move an arm's gathered levels as one.

A coiled scene's coil (the nodes that ``meshgen.fold.coil`` wound on the rim, and the web's
lead-in from the frame corner in to the rim) is cut into *levels*: per arm, the coil nodes of
one arm coordinate, ordered from the outer end of the coil (the tip) towards the root. Per arm
a *front* counts the levels released so far; the levels behind it are *held*: they move with
the hub like tied nodes, their mass in the hub's inertia. At the start only the tip level is
free. After a step the front level is released when its free element (to a released level)
is taut and points outward from the hub surface at the front node (the free part pulls it
off), and, under a rate payout, when the paid-out length would not exceed the law's. A
released node keeps the hub's velocity at its position, so momentum and energy are
continuous at each release.

While an arm is *bundled*, each of its released levels moves as one point: the level's first
node (its spine node) carries the level's summed mass and force, the others copy it. The
bundles open (each node keeps the bundle's velocity) when the arm has paid out a given
fraction of its length, or at a given time.

Registries of the choices: :data:`COILS`, :data:`BUNDLES` (and the payout devices,
:data:`spinweb_fe.fe.coil.payout.PAYOUTS`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from spinweb_fe.fe.choice import Choice, Param, registry
from spinweb_fe.fe.hub.rigid import turn_node


def _release_fraction(tables):
    if tables["stowage"]["bundle_release"] > 1.0:
        return "stowage.bundle_release", ("a fraction of the arm length in (0, 1], got "
                                          f"{tables['stowage']['bundle_release']:g}")
    return None


COILS = registry(
    Choice("loose", 0, "the coil lies on the hub with nothing holding it (contact only)"),
    Choice("held", 1, "every coil node moves with the hub until its arm's peel front releases "
                      "it", analytic="the coil turns with the hub (every regime)"),
)
@dataclass(frozen=True)
class Bundle(Choice):
    """A bundle law: ``timed`` if its bundles open at a time (else at a paid-out length;
    the kernel reads it as ``Coil.bundle_timed``)."""

    timed: bool = False


BUNDLES = registry(
    Bundle("none", 0, "every node moves on its own",
           analytic="the arm model: each arm a line of its own"),
    Bundle("until_length", 1, "levels move as one until the arm has paid out bundle_release "
                              "times its length",
           keys=(Param("bundle_release", "1", "pos", "bundles open at this fraction of the "
                       "arm length (until_length) or time (until_time)"),),
           need=(("bundle_release",),), check=_release_fraction),
    Bundle("until_time", 2, "levels move as one until t = bundle_release",
           keys=(Param("bundle_release", "s", "pos", "bundles open at this fraction of the "
                       "arm length (until_length) or time (until_time)"),),
           need=(("bundle_release",),), timed=True),
)


class Coil(NamedTuple):
    """The levels of the coil and the laws that release them (fixed during a run).

    Attributes
    ----------
    arm_ptr : (n_arms + 1,) int64
        Levels of arm k: arm_ptr[k] .. arm_ptr[k+1]-1, outer end first.
    level_ptr : (L + 1,) int64
        Nodes of level l: level_nodes[level_ptr[l] .. level_ptr[l+1]-1], its spine node first.
    level_nodes : (K,) int64
    level_ref : (K, 3) float64 [m]
        Hub-frame position of each level node (held nodes sit there).
    level_coord : (L,) float64 [m]
        Arm coordinate of each level.
    level_mass : (L,) float64 [kg]
        Mass of each level (a bundle's mass).
    level_rim : (L,) bool
        The level lies on the hub rim (the lead-in does not).
    test_ptr : (L + 1,) int64
        Free elements of level l: test_elem/test_from/test_to[test_ptr[l] .. test_ptr[l+1]-1],
        each joining a node of level l (from) to a node of an outer level (to), the one
        joining the spine nodes of two levels first.
    test_elem, test_from, test_to : (T,) int64
    test_to_coord : (T,) float64 [m]
        Arm coordinate of the ``to`` node.
    arm_end : (n_arms,) float64 [m]
        Arm coordinate of the tip: free length = arm_end - front coordinate.
    arm_base : (n_arms,) float64 [m]
        Arm coordinate where the arm is attached once all its levels are released.
    base_rim : (n_arms,) bool
        The arm's base lies on the hub rim (tethers) or not (the web's frame corner).
    coil_code : int
        The coil (:data:`COILS`): 1 held, 0 loose.
    payout_code : int
        The payout (fe.coil.payout.PAYOUTS): 0 free, 1 gate, 2 reel ('rate'), 3 brake.
    device : bool
        The payout is a device at each arm's departure point (a reel or brake: the
        registry entry's ``device``).
    length_law : bool
        A law limits the paid-out length (gate, reel: the entry's ``length_law``).
    law_t, law_v : (P,) float64 [s], [m] or [N]
        The device's law, linear between points, constant outside them (empty: none): the
        paid-out length (gate, reel) or the brake force (brake).
    test_half : (T,) float64 [kg]
        Half the mass of each free element (its share of each end node).
    bundle_code : int
        0 none, 1 until_length, 2 until_time (:data:`BUNDLES`).
    bundle_timed : bool
        The bundles open at a time, not at a length (the entry's ``timed``).
    bundle_value : float
        Fraction of the arm length, or the time [s].
    arm_hold : (n_arms,) float64 [s]
        Each arm's coil is held whole (its tip level too) until this time (0: released as
        usual from the start; a delayed arm, ``[perturbation] delay``).
    """

    arm_ptr: np.ndarray
    level_ptr: np.ndarray
    level_nodes: np.ndarray
    level_ref: np.ndarray
    level_coord: np.ndarray
    level_mass: np.ndarray
    level_rim: np.ndarray
    test_ptr: np.ndarray
    test_elem: np.ndarray
    test_from: np.ndarray
    test_to: np.ndarray
    test_to_coord: np.ndarray
    arm_end: np.ndarray
    arm_base: np.ndarray
    base_rim: np.ndarray
    coil_code: int
    payout_code: int
    device: bool
    length_law: bool
    law_t: np.ndarray
    law_v: np.ndarray
    test_half: np.ndarray
    bundle_code: int
    bundle_timed: bool
    bundle_value: float
    arm_hold: np.ndarray


class CoilState(NamedTuple):
    """Per arm: ``front`` (n_arms,) int64, the levels released; ``bundled`` (n_arms,) bool;
    and a payout device's (fe.coil.payout; zero without a reel or brake), each (n_arms,):

    ``s_dev`` [m], the arm coordinate of the line at the device D (free length arm_end -
    s_dev); ``dev_rest`` [kg], the mass held at D (the front level's free elements' outer
    halves still in the device); ``dev_ref`` (n_arms, 3) [m], D's hub-frame position;
    ``dev_x`` (n_arms, 3) [m], D in the world now; ``dev_work`` [J], the device's work so
    far (negative: energy it took); ``dev_tension`` [N], the line tension at D;
    ``dev_speed`` [m/s], the payout speed of the last step; and ``dev_moment`` (3,) [N m],
    the moment that carries the device forces from the held front nodes to D;
    ``dev_friction`` [J], a brake's N x summed over its slips (the least it must have
    dissipated)."""

    front: np.ndarray
    bundled: np.ndarray
    s_dev: np.ndarray
    dev_rest: np.ndarray
    dev_ref: np.ndarray
    dev_x: np.ndarray
    dev_work: np.ndarray
    dev_tension: np.ndarray
    dev_speed: np.ndarray
    dev_moment: np.ndarray
    dev_friction: np.ndarray


def no_coil(n_arms: int = 0) -> Coil:
    """A scene without a coil (every kernel of this module then does nothing)."""
    i0, f0 = np.zeros(1, np.int64), np.zeros(0)
    return Coil(np.zeros(n_arms + 1, np.int64), i0, np.zeros(0, np.int64), np.zeros((0, 3)), f0,
                f0, np.zeros(0, bool), i0, np.zeros(0, np.int64), np.zeros(0, np.int64),
                np.zeros(0, np.int64), f0, np.zeros(n_arms), np.zeros(n_arms),
                np.zeros(n_arms, bool), 0, 0, False, False, f0, f0, f0, 0, False, 0.0,
                np.zeros(n_arms))


def coil_start(coil: Coil) -> CoilState:
    """Fronts at the start: a held coil (``coil_code`` 1) has only its tip level free (none
    while the arm is held whole, ``arm_hold`` > 0); a loose one all."""
    n_arms = len(coil.arm_ptr) - 1
    counts = np.diff(coil.arm_ptr)
    held = coil.coil_code == COILS["held"].code
    front = np.where(coil.arm_hold > 0, 0, np.minimum(counts, 1)) if held else counts.copy()
    z = np.zeros(n_arms)
    bundled = coil.bundle_code != BUNDLES["none"].code
    return CoilState(front.astype(np.int64), np.full(n_arms, bundled),
                     coil.arm_end.copy(), z.copy(), np.zeros((n_arms, 3)), np.zeros((n_arms, 3)),
                     z.copy(), z.copy(), z.copy(), np.zeros(3), z.copy())


# The kernels the initial state calls from Python (level_masses, place_held, held_inertia)
# and held_moment take the coil's arrays, not its tuple (Coil, 23 arrays): numba types and
# unpacks every array of every tuple a kernel takes, 0.2-0.3 s of compile for each such
# kernel on a cold start (docs/performance.md).


@njit(cache=True)
def level_masses(level_ptr, level_nodes, level_mass, node_mass, node_inv_mass, mass, inv_mass,
                 lo, hi, bundled):
    """Active masses of the nodes of levels lo..hi-1 once released: their own
    (``node_mass``, ``node_inv_mass``: the model's), or (bundled) the level's mass on its
    spine node and none on the others. ``level_*``: the Coil's."""
    for lev in range(lo, hi):
        a, b = level_ptr[lev], level_ptr[lev + 1]
        for p in range(a, b):
            i = level_nodes[p]
            if bundled:
                first = p == a
                mass[i] = level_mass[lev] if first else 0.0
                inv_mass[i] = 1.0 / level_mass[lev] if first else 0.0
            else:
                mass[i] = node_mass[i]
                inv_mass[i] = node_inv_mass[i]


@njit(cache=True)
def held_inertia(arm_ptr, front, level_ptr, level_nodes, level_ref, node_mass):
    """sum m (x^2 + y^2) [kg m^2] of the held nodes, from their hub-frame positions
    (``front`` the CoilState's, ``node_mass`` the model's, the rest the Coil's)."""
    j = 0.0
    for k in range(arm_ptr.shape[0] - 1):
        for lev in range(arm_ptr[k] + front[k], arm_ptr[k + 1]):
            for p in range(level_ptr[lev], level_ptr[lev + 1]):
                i = level_nodes[p]
                j += node_mass[i] * (level_ref[p, 0] ** 2 + level_ref[p, 1] ** 2)
    return j


@njit(cache=True, no_cpython_wrapper=True)
def any_held(arm_ptr, front):
    """Whether some arm still has levels on the hub (the held coil's kernels have work);
    ``arm_ptr`` the coil's, ``front`` the CoilState's (arrays, not the tuples: the step
    loops call this every step)."""
    for k in range(arm_ptr.shape[0] - 1):
        if arm_ptr[k] + front[k] < arm_ptr[k + 1]:
            return True
    return False


@njit(cache=True)
def place_levels(arm_ptr, front, level_ptr, level_nodes, level_ref, pos, vel, theta, omega,
                 k, lo, hi):
    """The held nodes of arm k's levels lo..hi (those at or behind its front) move with
    the hub, as :func:`place_held` moves them all."""
    c = np.cos(theta)
    s = np.sin(theta)
    a = max(lo, arm_ptr[k] + front[k])
    b = min(hi + 1, arm_ptr[k + 1])
    for p in range(level_ptr[a] if a < b else 0, level_ptr[b] if a < b else 0):
        turn_node(pos, vel, level_nodes[p], level_ref[p], c, s, omega)


@njit(cache=True)
def place_held(arm_ptr, front, level_ptr, level_nodes, level_ref, pos, vel, theta, omega):
    """Held nodes move with the hub: x = R(theta) x_hub, v = omega z x x (``front`` the
    CoilState's, the rest the Coil's)."""
    for k in range(arm_ptr.shape[0] - 1):
        place_levels(arm_ptr, front, level_ptr, level_nodes, level_ref, pos, vel, theta,
                     omega, k, 0, arm_ptr[k + 1])


@njit(cache=True)
def held_moment(arm_ptr, front, level_ptr, level_nodes, pos, force):
    """z-moment of the element forces ``force`` (n, 3) on the held nodes (``front`` the
    CoilState's, the rest the Coil's: arrays, see :func:`level_masses`)."""
    tau = 0.0
    for k in range(arm_ptr.shape[0] - 1):
        a = level_ptr[arm_ptr[k] + front[k]]
        for p in range(a, level_ptr[arm_ptr[k + 1]]):
            i = level_nodes[p]
            tau += pos[i, 0] * force[i, 1] - pos[i, 1] * force[i, 0]
    return tau


@njit(cache=True)
def law_value(tt, vv, t):
    """The value at time t of a law given at times ``tt`` (increasing) by ``vv``: linear
    between the points, constant outside them."""
    if t <= tt[0]:
        return vv[0]
    for q in range(1, tt.shape[0]):
        if t <= tt[q]:
            return vv[q - 1] + (vv[q] - vv[q - 1]) * (t - tt[q - 1]) / (tt[q] - tt[q - 1])
    return vv[-1]


@njit(cache=True)
def payout_allowed(coil, t):
    """Paid-out length [m] a gate or a reel allows at time t (inf: no such law)."""
    if not coil.length_law:
        return np.inf
    return law_value(coil.law_t, coil.law_v, t)


@njit(cache=True, no_cpython_wrapper=True)
def free_length(coil, cs, k):
    """Paid-out length [m] of arm k: from its front level (or its base) to the tip."""
    lev = coil.arm_ptr[k] + cs.front[k]
    if lev < coil.arm_ptr[k + 1]:
        return coil.arm_end[k] - coil.level_coord[lev]
    return coil.arm_end[k] - coil.arm_base[k]


@njit(cache=True)
def pulls(coil, elems, pos, lev, broken=None, frame=None):
    """True if a free element of level ``lev`` is taut and points outward from the hub at
    its node of this level: the free part pulls the level off the hub (a ``broken`` element,
    fe.rupture, pulls nothing). Outward is along the node's radial from the hub axis:
    ``frame`` None for the fixed axis (+z through the origin), else (2, 3) the hub centre
    and unit axis (a free hub, which moves and tilts)."""
    for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
        e, a, b = coil.test_elem[q], coil.test_from[q], coil.test_to[q]
        if broken is not None and broken.shape[0] > 0 and broken[e]:
            continue
        dx = pos[b, 0] - pos[a, 0]
        dy = pos[b, 1] - pos[a, 1]
        dz = pos[b, 2] - pos[a, 2]
        taut = (dx * dx + dy * dy + dz * dz) * elems.inv_rest[e] ** 2 > 1.0
        if frame is None:
            out = dx * pos[a, 0] + dy * pos[a, 1]
        else:  # d . r, r the node's radial: x - c less its part along the axis
            c, ax = frame[0], frame[1]
            rx, ry, rz = pos[a, 0] - c[0], pos[a, 1] - c[1], pos[a, 2] - c[2]
            h = rx * ax[0] + ry * ax[1] + rz * ax[2]
            out = dx * (rx - h * ax[0]) + dy * (ry - h * ax[1]) + dz * (rz - h * ax[2])
        if taut and out > 0.0:
            return True
    return False


@njit(cache=True)
def release_fronts(coil, cs, elems, nodes, pos, mass, inv_mass, inertia, t, broken=None,
                   frame=None):
    """After a step: release the front level of every arm whose free part pulls it off the
    hub and whose paid-out length would then not exceed the payout law's at time t (broken
    elements and the hub's ``frame``: see :func:`pulls`); an arm held whole until
    ``arm_hold`` releases its tip level then. Returns the hub's effective inertia without the
    released nodes [kg m^2]. (A reel or a brake releases its levels itself: fe.coil.payout.)"""
    if coil.device:
        return inertia
    allowed = payout_allowed(coil, t)
    for k in range(coil.arm_ptr.shape[0] - 1):
        lev = coil.arm_ptr[k] + cs.front[k]
        end = coil.arm_ptr[k + 1]
        if lev >= end:
            continue
        if t < coil.arm_hold[k]:  # a delayed arm: its whole coil waits on the hub
            continue
        after = coil.arm_end[k] - (coil.level_coord[lev + 1] if lev + 1 < end
                                   else coil.arm_base[k])
        tip = cs.front[k] == 0  # a delayed arm's tip level goes when the wait is over
        if not tip and (after > allowed or not pulls(coil, elems, pos, lev, broken, frame)):
            continue
        for p in range(coil.level_ptr[lev], coil.level_ptr[lev + 1]):
            i = coil.level_nodes[p]
            inertia -= nodes.mass[i] * (coil.level_ref[p, 0] ** 2 + coil.level_ref[p, 1] ** 2)
        level_masses(coil.level_ptr, coil.level_nodes, coil.level_mass, nodes.mass,
                     nodes.inv_mass, mass, inv_mass, lev, lev + 1, cs.bundled[k])
        cs.front[k] += 1
    return inertia


@njit(cache=True, no_cpython_wrapper=True)
def front_row(coil, cs, k, t):
    """Arm k's held coil at time t: (front coordinate, next outer level's coordinate, 1 if
    the pinned node lies on the rim, 1 if the payout law holds the front back) [m, m, -, -].
    Under a reel or a brake the front is the device's line coordinate. Once every level is
    released the front is the arm's base."""
    lo, end = coil.arm_ptr[k], coil.arm_ptr[k + 1]
    lev = lo + cs.front[k]
    if lev >= end:
        s_n = coil.level_coord[end - 1] if end > lo else coil.arm_base[k]
        return coil.arm_base[k], s_n, 1.0 if coil.base_rim[k] else 0.0, 0.0
    q = coil.test_ptr[lev]
    s_f = coil.level_coord[lev]
    if coil.device:  # a reel or brake: the line leaves at its device
        s_f = cs.s_dev[k]
    s_n = coil.test_to_coord[q] if q < coil.test_ptr[lev + 1] else s_f
    after = coil.arm_end[k] - (coil.level_coord[lev + 1] if lev + 1 < end else coil.arm_base[k])
    bound = 1.0 if after > payout_allowed(coil, t) else 0.0
    return s_f, s_n, 1.0 if coil.level_rim[lev] else 0.0, bound
