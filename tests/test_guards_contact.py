"""Guards of the crossing test and the separation certificates (issue #47): a crossing
exactly through the node two elements share is counted once (the half-open ends), with and
without the conservative test's separation; a node's path in the frame that follows the
web departs from its chord by no more than the certificate's bound, which is tight where
one term alone decides (a node at rest while the frame turns; a node moving fast along its
radius)."""

import math

import numpy as np
import pytest

from spinweb_fe.fe.contact.bounds import no_motion, step_motion
from spinweb_fe.fe.contact.crossing import SEP
from support import loop_crossings


def _count(ab, cd, sep):
    """Crossings of the static element ab (its two ends) with cd ((2, 2, 3): each end's
    start and end of the step)."""
    times, signs = np.empty(3), np.empty(3, np.int64)
    (a, b), (c, d) = ab, cd
    return loop_crossings(a, a, b, b, c[0], c[1], d[0], d[1], times, signs, sep)


@pytest.mark.parametrize("sep", [0.0, SEP * 2.0])
@pytest.mark.parametrize("down", [True, False])
def test_a_crossing_through_a_shared_node_is_counted_once(sep, down):
    """AB = (0,0,0)-(1,0,0) and BE = (1,0,0)-(2,0,0) share B; CD, across the x axis at
    x = 1 (y from -0.5 to 0.5), moves from z = 0.3 to -0.3 (or back up) and passes
    exactly through B at mid-step. The two pairs count 1 crossing between them, not 2
    (the end s = 1 of AB is BE's s = 0): exact, with sep 0 and with the run's separation."""
    A, B, E = np.array([0.0, 0, 0]), np.array([1.0, 0, 0]), np.array([2.0, 0, 0])
    z = (0.3, -0.3) if down else (-0.3, 0.3)
    cd = (np.array([[1.0, -0.5, z[0]], [1.0, -0.5, z[1]]]),
          np.array([[1.0, 0.5, z[0]], [1.0, 0.5, z[1]]]))
    n_ab, n_be = _count((A, B), cd, sep), _count((B, E), cd, sep)
    assert n_ab + n_be == 1
    assert n_be == 1  # the shared node belongs to the element it starts
    # the same crossing through an inner point of AB: counted by AB alone
    cd_mid = tuple(p - np.array([0.5, 0, 0]) for p in cd)
    assert _count((A, B), cd_mid, sep) == 1 and _count((B, E), cd_mid, sep) == 0


def _departure(x0, x1, th0, th1, samples=4001):
    """The largest distance [m] of a node's path in the turning frame from its chord:
    x(t) = x0 + t (x1 - x0), frame angle th0 + t (th1 - th0), sampled."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    x = x0 + t * (x1 - x0)
    th = th0 + t[:, 0] * (th1 - th0)
    c, s = np.cos(th), np.sin(th)
    y = np.column_stack([c * x[:, 0] + s * x[:, 1], c * x[:, 1] - s * x[:, 0], x[:, 2]])
    chord = y[0] + t * (y[-1] - y[0])
    return np.linalg.norm(y - chord, axis=1).max()


def test_the_certificates_bound_each_nodes_departure_from_its_chord():
    """Twenty nodes on a ring of 10 m turn rigidly by 0.1 rad over the step (the frame
    follows them); node 0 stays where it is (its path in the frame is an arc: departure
    rho (1 - cos(dtheta / 2)), the bound's turn term rho (dtheta^2 / 8 + |dtheta|^3 / 3)
    is 1 + 8 |dtheta| / 3 = 1.26x that at the frame's fitted dtheta = 0.097), node 1
    moves 5 m out along its radius while turning (the bound's own-displacement term
    |dtheta| u / 4 is the larger). Every node's
    sampled departure is within its bound (dev); for nodes 0 and 1 the bound is within
    1.3x and 1.2x of the departure (measured 1.26 and 1.14: a halved turn term leaves node
    0's bound at 0.76 of its departure, a dropped own term node 1's at 0.12)."""
    n = 20
    ang = 2 * np.pi * np.arange(n) / n
    pos0 = np.column_stack([10 * np.cos(ang), 10 * np.sin(ang), np.zeros(n)])
    dth = 0.1
    c, s = math.cos(dth), math.sin(dth)
    pos1 = np.column_stack([c * pos0[:, 0] - s * pos0[:, 1], s * pos0[:, 0] + c * pos0[:, 1],
                            np.zeros(n)])
    pos1[0] = pos0[0]
    pos1[1] = pos1[1] * 1.5
    pos1[2, 2] = 0.3  # one node leaves the plane
    elems = np.array([[i, (i + 1) % n] for i in range(n)], dtype=np.int64)
    mo = no_motion(n, n)
    step_motion(mo, elems, np.ones(n, np.int8), pos0, pos1)
    th0, th1 = mo.theta
    assert 0.08 < th1 - th0 < 0.1
    dep = np.array([_departure(pos0[i], pos1[i], th0, th1) for i in range(n)])
    assert np.all(dep <= mo.dev)
    assert mo.dev[0] < 1.3 * dep[0]
    assert mo.dev[1] < 1.2 * dep[1]
    # an element moves by at most the larger bound of its ends (chord + departure)
    move = np.linalg.norm(mo.dy, axis=1) + mo.dev
    assert np.all(mo.elem >= np.maximum(move[elems[:, 0]], move[elems[:, 1]]))
    assert np.allclose(mo.cum, mo.elem) and np.all(mo.elem > 0)
