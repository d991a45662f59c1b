"""Separation certificates: which listed pairs cannot meet this step, from what each node
moved, so that the exact test and the penalty run only on the pairs whose gap the step's
motion could have closed (issue #42).

Each listed pair keeps a certificate, a proven lower bound of its elements' distance: its
exact distance when the list was built or the pair was last looked at, less what they
could have closed since. Over a step each node moves on a straight line
(x(t) = x_n + t (x_{n+1} - x_n)); seen in a frame turning about +z by theta(t) = theta_n +
t dtheta (any rigid frame keeps distances), a node's displacement from its place at the
step's start is at most

    m_i = |y_i(1) - y_i(0)| + rho_i (dtheta^2 / 8 + |dtheta|^3 / 3) + |dtheta| |x_{n+1} - x_n| / 4,

the chord of its path in the frame plus the path's largest departure from the chord (rho_i
its distance from the axis at the step's start; the rotation's departure from its chord,
to third order, and the turn of its own displacement). A point of an element is a convex
combination of its ends at every instant, so it moves by at most the larger m of its two
ends (``elem``), and two elements close by at most the sum of theirs, or, finer, by at most
the largest |y_i(1) - y_i(0) - (y_j(1) - y_j(0))| + dev_i + dev_j over an end i of one and
an end j of the other (:func:`pair_motion`). A pair whose bound less that stays above the
least separation cannot meet during the step; the others are tested exactly and get their
exact distance at the step's end as their new bound.

So that a step need not write a certificate that still holds, each element's bounds are
summed over the steps (``cum``: from the list's build to the step's end; ``cum0``: to its
start), and a pair keeps its ``level`` K = d + cum_e + cum_f at the step it was last
looked at (d its bound then): its bound at the end of any later step is K - cum_e - cum_f,
read without a write. Only a pair whose elements' sum reaches its level is looked at: by
its own relative motion first (a new level if that still holds), then exactly.

The frame follows the web, not the hub: each step turns it by the rotation that fits the
nodes' displacements best (dtheta = sum(x dy - y dx) / sum(x^2 + y^2)), so that a web
spinning at its own rate stands as still in it as the held coil does while it turns with
the hub (a deployed web that turns 8 rad/s slower than a driven hub moves its tips 400 m/s
through the hub's frame: the list would be rebuilt every 20 steps).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

#: relative round-off allowed for in a computed distance (its bound is lowered by this
#: times the largest coordinate)
ROUND = 1e-13
#: the certificates of a whole list (the audit's, fe.contact.touch.certified_blocks; the
#: fail-safe's first pass, fe.contact.failsafe.certified_candidates) run on the step's threads
#: for a list of at least this many pairs (below it the threads' start costs more than the
#: pass), cut into this many blocks a thread (a block's exact tests are uneven: more blocks
#: than threads even the load)
THREAD_MIN_PAIRS = 20000
BLOCKS_PER_THREAD = 4


class StepMotion(NamedTuple):
    """What the nodes moved over the step, in the frame that follows the web
    (:func:`step_motion`).

    dy (n, 3) [m]: the chord of each node's path; dev (n,) [m]: the path's largest
    departure from its chord; elem (m,) [m]: each element's largest displacement bound
    (the larger of its ends' |dy| + dev); cum0, cum (m,) [m]: ``elem`` summed from the
    list's build to the step's start and to its end; theta (2,) [rad]: the frame's angle at
    the step's start and end; scale (1,) [m]: the largest coordinate magnitude at either end (the
    least separation and the round-off follow it).
    """

    dy: np.ndarray
    dev: np.ndarray
    elem: np.ndarray
    cum0: np.ndarray
    cum: np.ndarray
    theta: np.ndarray
    scale: np.ndarray


class Certified(NamedTuple):
    """What the contact's passes know of the audit's list besides its pairs: ``level`` (P,)
    [m], each pair's certificate level (its bound at the step's start is level - cum0_e -
    cum0_f); the step's ``motion``;
    ``adj``, the pairs of each node (fe.contact.zones.Adjacency, filled when first needed);
    ``active`` (m,) int8, the elements the list takes (fe.contact.broad); ``clock`` (11,)
    int64 [cycle-counter ticks] and ``tally`` (15,) int64: the profile of the contact's
    passes (fe.contact.clock's C_ and N_ slots; added to only, no part of a checkpoint:
    :func:`contact_profile` makes them)."""

    level: np.ndarray
    motion: StepMotion
    adj: tuple
    active: np.ndarray
    clock: np.ndarray
    tally: np.ndarray


def contact_profile() -> tuple:
    """A zeroed ``(clock, tally)`` pair for :class:`Certified`."""
    return np.zeros(11, np.int64), np.zeros(15, np.int64)


def no_motion(n_nodes: int, n_elems: int) -> StepMotion:
    """A :class:`StepMotion` of zeros for ``n_nodes`` nodes and ``n_elems`` elements."""
    return StepMotion(np.zeros((n_nodes, 3)), np.zeros(n_nodes), np.zeros(n_elems),
                      np.zeros(n_elems), np.zeros(n_elems), np.zeros(2), np.zeros(1))


@njit(cache=True)
def step_motion(mo, elem_nodes, active, pos0, pos1):
    """Fill ``mo`` (a :class:`StepMotion` whose ``theta[0]`` holds the frame's angle at the
    step's start) for the step from ``pos0`` to ``pos1``: the frame's turn that fits the
    displacements best, then each node's and each ``active`` element's motion in it."""
    num, den = 0.0, 0.0
    for i in range(pos0.shape[0]):
        x0, y0 = pos0[i, 0], pos0[i, 1]
        num += x0 * (pos1[i, 1] - y0) - y0 * (pos1[i, 0] - x0)
        den += x0 * x0 + y0 * y0
    mo.theta[1] = mo.theta[0] + (num / den if den > 0.0 else 0.0)
    c0, s0, c1, s1, turn, own = frame_turn(mo)
    big = 0.0
    for i in range(pos0.shape[0]):
        mo.dy[i, 0], mo.dy[i, 1], mo.dy[i, 2], mo.dev[i], size = node_motion(
            pos0, pos1, i, c0, s0, c1, s1, turn, own)
        big = max(big, size)
    mo.scale[0] = big
    slack = 4.0 * ROUND * big  # the frame's turn of coordinates of this size
    for e in range(elem_nodes.shape[0]):
        if not active[e]:
            continue
        a, b = elem_nodes[e, 0], elem_nodes[e, 1]
        ma = math.sqrt(mo.dy[a, 0] ** 2 + mo.dy[a, 1] ** 2 + mo.dy[a, 2] ** 2) + mo.dev[a]
        mb = math.sqrt(mo.dy[b, 0] ** 2 + mo.dy[b, 1] ** 2 + mo.dy[b, 2] ** 2) + mo.dev[b]
        mo.elem[e] = max(ma, mb) + slack
        mo.cum[e] = mo.cum0[e] + mo.elem[e]


@njit(inline="always")
def node_motion(pos0, pos1, i, c0, s0, c1, s1, turn, own):
    """Node i's chord in the frame (cos, sin of its angle at the step's start and end), its
    path's departure from the chord (``turn``: dtheta^2 / 8 + |dtheta|^3 / 3, ``own``:
    |dtheta| / 4) and its largest coordinate magnitude at either end [m]:
    (dy_x, dy_y, dy_z, dev, size)."""
    x0, y0, z0 = pos0[i, 0], pos0[i, 1], pos0[i, 2]
    x1, y1, z1 = pos1[i, 0], pos1[i, 1], pos1[i, 2]
    u = math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2 + (z1 - z0) ** 2)
    size = max(max(max(abs(x0), abs(y0)), max(abs(z0), abs(x1))), max(abs(y1), abs(z1)))
    return ((c1 * x1 + s1 * y1) - (c0 * x0 + s0 * y0), (c1 * y1 - s1 * x1) - (c0 * y0 - s0 * x0),
            z1 - z0, math.sqrt(x0 * x0 + y0 * y0) * turn + own * u, size)


@njit(inline="always")
def frame_turn(mo):
    """The frame's (cos, sin) at the step's start and end and the path terms ``turn`` and
    ``own`` of :func:`node_motion`, from ``mo.theta``."""
    th0, th1 = mo.theta[0], mo.theta[1]
    dth = th1 - th0
    return (math.cos(th0), math.sin(th0), math.cos(th1), math.sin(th1),
            dth * dth / 8.0 + abs(dth) ** 3 / 3.0, abs(dth) / 4.0)


@njit(inline="always")
def _apart_by(p, q):
    """The bound of two nodes' relative motion from their :func:`node_motion` tuples."""
    return math.sqrt((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2) \
        + p[3] + q[3]


@njit(inline="always")
def moved_pair_motion(mo, pos0, pos1, a, b, c, d, frame):
    """:func:`pair_motion` from the four nodes' positions as they stand (the chords and
    departures computed afresh, ``frame`` from :func:`frame_turn`; the round-off slack from
    the larger of the step's scale and the four nodes' coordinates): valid after impulses
    moved a node's x_{n+1} since :func:`step_motion`."""
    c0, s0, c1, s1, turn, own = frame
    pa = node_motion(pos0, pos1, a, c0, s0, c1, s1, turn, own)
    pb = node_motion(pos0, pos1, b, c0, s0, c1, s1, turn, own)
    pc = node_motion(pos0, pos1, c, c0, s0, c1, s1, turn, own)
    pd = node_motion(pos0, pos1, d, c0, s0, c1, s1, turn, own)
    big = max(max(mo.scale[0], max(pa[4], pb[4])), max(pc[4], pd[4]))
    out = max(max(_apart_by(pa, pc), _apart_by(pa, pd)),
              max(_apart_by(pb, pc), _apart_by(pb, pd)))
    return out + 8.0 * ROUND * big


@njit(inline="always")
def pair_motion(mo, a, b, c, d):
    """How much elements ab and cd can close over the step [m]: the largest relative
    chord of an end of one against an end of the other, with both paths' departures."""
    dy, dev = mo.dy, mo.dev
    out = 0.0
    for i in (a, b):
        for j in (c, d):
            x = math.sqrt((dy[i, 0] - dy[j, 0]) ** 2 + (dy[i, 1] - dy[j, 1]) ** 2
                          + (dy[i, 2] - dy[j, 2]) ** 2) + dev[i] + dev[j]
            out = max(out, x)
    return out + 8.0 * ROUND * mo.scale[0]


@njit(inline="always")
def bound_now(level, mo, p, e, f):
    """A pair's proven least distance at the step's start [m] (its ``level`` less its
    elements' sums to then)."""
    return level[p] - mo.cum0[e] - mo.cum0[f]


@njit(inline="always")
def bound_after(level, mo, p, e, f):
    """A pair's proven least distance over the whole step [m] (its ``level`` less its
    elements' sums to the step's end)."""
    return level[p] - mo.cum[e] - mo.cum[f]


@njit(inline="always")
def set_level(level, mo, p, e, f, d):
    """Certify a pair at least ``d`` [m] apart at the step's end: its new level."""
    level[p] = d + mo.cum[e] + mo.cum[f]
