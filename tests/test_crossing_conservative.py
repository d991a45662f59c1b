"""The conservative crossing test (fe.contact.crossing.pair_crossings with a least
separation): pairs of elements planted in the configurations an exact volume test can miss
-- parallel and collinear elements passing through each other, a touch without passing
through, a crossing through an end, a crossing on a step boundary -- in random orientations
and positions at scales from 1e-3 to 1e3 m, are never missed; pairs that stay 100 times the
separation apart are never counted."""

import numpy as np
import pytest

from spinweb_fe.fe.contact.crossing import SEP
from support import loop_crossings

SCALES = (1e-3, 1e-1, 1.0, 1e1, 1e3)


def rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.diag(r))


def place(rng, scale, *points):
    """The points (each (3,), in units of the scale) turned by a random rotation, scaled and
    moved to a random place up to 10 scales from the origin (so coordinates carry
    round-off)."""
    R, shift = rotation(rng), rng.uniform(-10, 10, 3) * scale
    return [R @ (np.asarray(p, float) * scale) + shift for p in points]


def count(pts, scale, sep_factor=1.0):
    """Crossings pair_crossings reports for the 8 points (a0, a1, b0, b1, c0, c1, d0, d1)
    with the run's separation: SEP times the largest coordinate."""
    sep = SEP * max(np.abs(p).max() for p in pts) * sep_factor
    times, signs = np.empty(3), np.empty(3, np.int64)
    return loop_crossings(*pts, times, signs, sep)


@pytest.mark.parametrize("scale", SCALES)
def test_parallel_elements_passing_through_each_other(scale):
    """CD parallel to AB, their x ranges overlapping, moves through it (V = 0 all along):
    counted in every orientation, also with a tilt of 1e-13 rad."""
    rng = np.random.default_rng(1)
    for k in range(40):
        tilt = 1e-13 * (k % 3)
        pts = place(rng, scale, [0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0],
                    [0.3, 0, 0.5], [0.3, 0, -0.5], [1.3, tilt, 0.5], [1.3, tilt, -0.5])
        assert count(pts, scale) >= 1, (scale, k)


@pytest.mark.parametrize("scale", SCALES)
def test_collinear_elements_sliding_into_each_other(scale):
    """CD on AB's line slides into it (an overlap of collinear elements)."""
    rng = np.random.default_rng(2)
    for k in range(40):
        pts = place(rng, scale, [0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0],
                    [1.5, 0, 0], [0.5, 0, 0], [2.5, 0, 0], [1.5, 0, 0])
        assert count(pts, scale) >= 1, (scale, k)


@pytest.mark.parametrize("scale", SCALES)
def test_a_touch_without_passing_through(scale):
    """CD comes down onto AB across it, touches it at the step's end and goes back up in
    the next (V reaches zero without changing sign): counted in one of the two."""
    rng = np.random.default_rng(3)
    for k in range(40):
        # the ends move on straight lines within a step: the touch at the step's end, the
        # way back in the next step
        pts = place(rng, scale, [0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0],
                    [0.5, -0.5, 0.2], [0.5, -0.5, 0.0], [0.5, 0.5, 0.2], [0.5, 0.5, 0.0])
        there = count(pts, scale)
        back = count([pts[0], pts[1], pts[2], pts[3], pts[5], pts[4], pts[7], pts[6]], scale)
        assert there + back >= 1, (scale, k)


@pytest.mark.parametrize("scale", SCALES)
def test_a_crossing_through_an_end(scale):
    """CD passes through the node B that elements AB and BE share: counted by one of the
    two pairs at least."""
    rng = np.random.default_rng(4)
    for k in range(40):
        A, B, E, C0, C1, D0, D1 = place(rng, scale, [0, 0, 0], [1, 0, 0], [2, 0.3, 0],
                                        [1, -0.5, 0.3], [1, -0.5, -0.3],
                                        [1, 0.5, 0.3], [1, 0.5, -0.3])
        n = count([A, A, B, B, C0, C1, D0, D1], scale) + \
            count([B, B, E, E, C0, C1, D0, D1], scale)
        assert n >= 1, (scale, k)


@pytest.mark.parametrize("scale", SCALES)
def test_a_crossing_on_a_step_boundary(scale):
    """The crossing falls exactly at the end of one step (the start of the next): counted
    in one of the two steps."""
    rng = np.random.default_rng(5)
    for k in range(40):
        A, B, C0, C1, C2, D0, D1, D2 = place(rng, scale, [0, 0, 0], [1, 0, 0],
                                             [0.5, -0.5, 0.4], [0.5, -0.5, 0.0],
                                             [0.5, -0.5, -0.4], [0.5, 0.5, 0.4],
                                             [0.5, 0.5, 0.0], [0.5, 0.5, -0.4])
        n = count([A, A, B, B, C0, C1, D0, D1], scale) + \
            count([A, A, B, B, C1, C2, D1, D2], scale)
        assert n >= 1, (scale, k)


@pytest.mark.parametrize("scale", SCALES)
def test_pairs_apart_are_never_counted(scale):
    """Parallel elements sliding along each other 100 separations apart, and crossed ones
    passing 100 separations apart: no false alarm."""
    rng = np.random.default_rng(6)
    for k in range(40):
        gap = 100 * SEP * 18  # in scale units: 100 separations (coordinates below 18 scales)
        pts = place(rng, scale, [0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0],
                    [0.3, 0, gap], [0.6, 0, gap], [1.3, 0, gap], [1.6, 0, gap])
        assert count(pts, scale) == 0, (scale, k)
        pts = place(rng, scale, [0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0],
                    [1 + gap, -0.5, 1], [1 + gap, -0.5, -1], [1 + gap, 0.5, 1],
                    [1 + gap, 0.5, -1])
        assert count(pts, scale) == 0, (scale, k)  # past AB's end, 100 separations off


def test_the_exact_test_without_a_separation_misses_them():
    """What the separation buys: without it the parallel pass-through and the collinear
    slide are missed (the test's V stays 0)."""
    pts = [np.array(p, float) for p in ([0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0],
                                        [0.3, 0, 0.5], [0.3, 0, -0.5], [1.3, 0, 0.5],
                                        [1.3, 0, -0.5])]
    times, signs = np.empty(3), np.empty(3, np.int64)
    assert loop_crossings(*pts, times, signs) == 0
    assert count(pts, 1.0) == 1
