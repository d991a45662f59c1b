"""Continuous crossing detection of cable elements (fe/contact/crossing.py): two segments passing
through each other at 1 to 200 m/s, at several angles and offsets, over steps of the
paper web's size, are counted exactly once (and not at all when they pass beside each
other); the count is invariant under rotation and translation; the broad phase lists
exactly the pairs that a brute-force box test does."""

import math

import numpy as np
import pytest

from spinweb_fe.fe.contact.broad import RIGID, candidate_pairs, carried, sift_pairs
from spinweb_fe.fe.contact.crossing import step_crossings
from spinweb_fe.fe.contact.distance import segment_distance
from support import loop_crossings

DT = 4.6e-5  # the paper web's step at cfl 0.2 [s]


def rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def passing(speed, angle, offset, z0, steps, R=np.eye(3), shift=np.zeros(3)):
    """Segment AB fixed on the x axis (from -1 to 1 m), segment CD of 2 m at ``angle`` to
    it in a plane z = const, centred over x = ``offset``, moving down at ``speed`` from
    z0 for ``steps`` steps of DT: the crossings counted step by step (times, signs)."""
    A, B = np.array([-1.0, 0, 0]), np.array([1.0, 0, 0])
    u = np.array([math.cos(angle), math.sin(angle), 0.0])
    centre = np.array([offset, 0.0, 0.0])
    out = []
    times, signs = np.empty(3), np.empty(3, np.int64)
    for n in range(steps):
        z_a, z_b = z0 - speed * DT * n, z0 - speed * DT * (n + 1)
        c0, d0 = centre - u + [0, 0, z_a], centre + u + [0, 0, z_a]
        c1, d1 = centre - u + [0, 0, z_b], centre + u + [0, 0, z_b]
        pts = [R @ p + shift for p in (A, A, B, B, c0, c1, d0, d1)]
        k = loop_crossings(*pts, times, signs)
        out += [(n + times[i], int(signs[i])) for i in range(k)]
    return out


@pytest.mark.parametrize("speed", [1.0, 10.0, 100.0, 200.0])
@pytest.mark.parametrize("angle", [0.2, math.pi / 4, math.pi / 2, 2.5])
def test_a_crossing_is_counted_exactly_once_at_any_speed(speed, angle):
    z0 = 0.3 * speed * DT + 2.5 * speed * DT  # crosses z = 0 in the third step
    hits = passing(speed, angle, 0.3, z0, 6)
    assert len(hits) == 1
    t, sign = hits[0]
    assert t == pytest.approx(z0 / (speed * DT), abs=1e-9)  # the step fraction of z = 0
    # the other way up: the same crossing, the other sign
    back = passing(-speed, angle, 0.3, -z0, 6)
    assert len(back) == 1 and back[0][1] == -sign


@pytest.mark.parametrize("speed", [1.0, 200.0])
def test_a_crossing_on_a_step_boundary_is_counted_once(speed):
    hits = passing(speed, math.pi / 3, -0.4, 3 * speed * DT, 6)  # z = 0 exactly at n = 3
    assert len(hits) == 1 and hits[0][0] == pytest.approx(3.0, abs=1e-9)


@pytest.mark.parametrize("offset", [1.2, -1.5, 3.0])
def test_segments_passing_beside_each_other_do_not_cross(offset):
    """CD centred beyond A or B (at 90 degrees it misses AB): no crossing, although the
    lines cross."""
    assert passing(100.0, math.pi / 2, offset, 2.5 * 100 * DT, 6) == []


def test_the_count_is_invariant_under_rotation_and_translation():
    rng = np.random.default_rng(4)
    base = passing(50.0, 1.0, 0.2, 2.5 * 50 * DT, 6)
    for _ in range(5):
        R = rot(rng.normal(size=3), rng.uniform(0, 2 * math.pi))
        moved = passing(50.0, 1.0, 0.2, 2.5 * 50 * DT, 6, R, rng.normal(size=3) * 100.0)
        assert len(moved) == 1 and moved[0][1] == base[0][1]
        assert moved[0][0] == pytest.approx(base[0][0], abs=1e-6)


def dense_crossings(a0, a1, b0, b1, c0, c1, d0, d1, samples=20001):
    """The same count by brute force: V sampled at ``samples`` times of the step, each
    sign change whose segments meet (closest points inside both) at the later sample."""
    t = np.linspace(0.0, 1.0, samples)[:, None]
    A, B = a0 + t * (a1 - a0), b0 + t * (b1 - b0)
    C, D = c0 + t * (c1 - c0), d0 + t * (d1 - d0)
    V = np.einsum("ij,ij->i", B - A, np.cross(C - A, D - A))
    out = []
    for i in np.flatnonzero((V[1:] >= 0) != (V[:-1] >= 0)) + 1:
        d1_, d2_, r = B[i] - A[i], D[i] - C[i], A[i] - C[i]
        a, b, c = d1_ @ d1_, d1_ @ d2_, d2_ @ d2_
        den = a * c - b * b
        s_ = (b * (d2_ @ r) - c * (d1_ @ r)) / den
        u_ = (a * (d2_ @ r) - b * (d1_ @ r)) / den
        if -1e-3 <= s_ <= 1 + 1e-3 and -1e-3 <= u_ <= 1 + 1e-3:
            out.append((float(t[i, 0]), 1 if V[i] >= 0 else -1))
    return out


def test_against_dense_sampling_including_two_crossings_in_one_step():
    """400 random pairs of unit-size segments whose ends move by up to 3 m in the step
    (a tumbling element): the crossings found equal those of a dense sampling of the step
    (times within its spacing, the same signs), some pairs crossing twice."""
    rng = np.random.default_rng(3)
    times, signs = np.empty(3), np.empty(3, np.int64)
    twice = 0
    for _ in range(400):
        p = rng.uniform(-1, 1, size=(4, 3))
        q = p + rng.uniform(-3, 3, size=(4, 3))
        k = loop_crossings(p[0], q[0], p[1], q[1], p[2], q[2], p[3], q[3], times, signs)
        ref = dense_crossings(p[0], q[0], p[1], q[1], p[2], q[2], p[3], q[3])
        assert k == len(ref)
        for i in range(k):
            assert times[i] == pytest.approx(ref[i][0], abs=1e-4) and signs[i] == ref[i][1]
        twice += k >= 2
    assert twice >= 3


@pytest.mark.parametrize("with_rigid, lattice", [(False, False), (True, False), (True, True)])
def test_broad_phase_lists_what_a_brute_force_box_test_lists(with_rigid, lattice):
    """The hash grid against every pair's box test; with elements marked RIGID (moving with
    the hub, in a grid of their own), no pair of two of them and every other pair as
    before, in the same (code) order. ``lattice``: the nodes on a grid of quarter metres
    and no skin, so that boxes touch each other and end on the hash grid's cell faces
    (the cell is the longest box; a pair is taken in one cell only, the one of the larger
    low corner: a touching pair must be found there, and once)."""
    rng = np.random.default_rng(11)
    n = 300
    pos = rng.uniform(0, 6, size=(n, 3))
    if lattice:
        pos = np.round(pos * 4) / 4
    elems = np.array([(i, (i + 1) % n) for i in range(0, n, 1)] +
                     [(i, int(j)) for i, j in zip(range(0, n, 3), rng.integers(0, n, n // 3))
                      if i != j])
    elems = elems[np.linalg.norm(pos[elems[:, 0]] - pos[elems[:, 1]], axis=1) < 3.0]
    active = np.ones(len(elems), np.int8)
    active[::7] = 0
    if with_rigid:
        active[1::3] = RIGID
    skin = 0.0 if lattice else 0.2
    listed = candidate_pairs(pos, elems, active, skin)
    codes = listed[:, 0] * len(elems) + listed[:, 1]
    assert np.all(np.diff(codes) > 0)
    got = {tuple(p) for p in listed}
    lo = np.minimum(pos[elems[:, 0]], pos[elems[:, 1]]) - skin
    hi = np.maximum(pos[elems[:, 0]], pos[elems[:, 1]]) + skin
    want = set()
    for e in range(len(elems)):
        for f in range(e + 1, len(elems)):
            if not (active[e] and active[f]) or set(elems[e]) & set(elems[f]):
                continue
            if active[e] == active[f] == RIGID:
                continue
            if np.all(lo[e] <= hi[f]) and np.all(lo[f] <= hi[e]):
                want.add((e, f))
    assert want and got == want


@pytest.mark.parametrize("fresh", [True, False])
def test_the_list_sifted_leaves_out_touching_pairs_as_set_operations_do(fresh):
    """sift_pairs (one pass, two merges) against the same rule by numpy's set operations:
    a pair entering the list closer than ``touch`` is left out, a pair left out before stays
    out while within ``keep``; the kept pairs, their codes and distances (the segments'
    least distance: segment_distance's, within a dense sampling's step of it) and the codes
    left out."""
    rng = np.random.default_rng(5)
    n = 80
    pos = rng.uniform(0, 3, size=(n, 3))
    elems = np.array([(i, i + 1) for i in range(n - 1)])
    m = len(elems)
    pairs = candidate_pairs(pos, elems, np.ones(m, np.int8), 0.3)
    code = pairs[:, 0] * m + pairs[:, 1]
    old = np.zeros(0, np.int64) if fresh else np.sort(rng.choice(code, len(code) // 2,
                                                                  replace=False))
    ignored = np.sort(rng.choice(code, len(code) // 4, replace=False))
    keep, touch = 0.3, 0.25
    codes, kept, kept_codes, kept_dist, left = sift_pairs(pairs, elems, pos, old, fresh,
                                                          ignored, keep, touch)
    ends = pos[elems[pairs]]  # (P, 2 elements, 2 ends, 3)
    dist = np.array([segment_distance(*q[0], *q[1]) for q in ends])
    s = np.linspace(0.0, 1.0, 41)[None, :, None]
    pa = ends[:, 0, :1] + s * (ends[:, 0, 1:] - ends[:, 0, :1])  # (P, 41, 3)
    pb = ends[:, 1, :1] + s * (ends[:, 1, 1:] - ends[:, 1, :1])
    dense = np.linalg.norm(pa[:, :, None] - pb[:, None, :], axis=3).min(axis=(1, 2))
    assert np.all(dist <= dense + 1e-12) and np.all(dist >= dense - 3.0 * 3 ** 0.5 / 40)
    entering = np.ones(len(code), bool) if fresh else ~np.isin(code, old)
    want_left = np.union1d(np.intersect1d(ignored, code[dist <= keep]),
                           code[entering & (dist <= touch)])
    assert np.array_equal(codes, code)
    assert 0 < len(left) < len(code) and np.array_equal(left, want_left)
    out = np.isin(code, left)
    assert np.array_equal(kept, pairs[~out]) and np.array_equal(kept_codes, code[~out])
    assert np.array_equal(kept_dist, dist[~out])


def test_a_new_list_carries_what_its_pairs_had_in_the_old():
    """carried (a merge of two ascending code lists) against numpy's searchsorted: a code
    in both lists takes its old value, a new one its fresh value; an empty old list keeps
    the fresh values."""
    rng = np.random.default_rng(3)
    codes = np.sort(rng.choice(10_000, 600, replace=False))
    old_codes = np.sort(np.concatenate([rng.choice(codes, 300, replace=False),
                                        rng.choice(np.setdiff1d(np.arange(10_000), codes),
                                                   100, replace=False)]))
    fresh, old = rng.uniform(0, 1, len(codes)), rng.uniform(2, 3, len(old_codes))
    got = carried(codes, fresh, old_codes, old)
    i = np.minimum(np.searchsorted(old_codes, codes), len(old_codes) - 1)
    same = old_codes[i] == codes
    assert same.sum() == 300 and np.array_equal(got, np.where(same, old[i], fresh))
    assert np.array_equal(carried(codes, fresh, np.zeros(0, np.int64), np.zeros(0)), fresh)


def test_step_crossings_of_a_net_falling_through_a_line():
    """A 3 x 3 grid of 1 m cells (12 elements) falls at 150 m/s through a line above it at
    an angle: the line crosses every element of the grid it passes over, once each."""
    xs = np.arange(4.0)
    nodes = np.array([(x, y, 0.0) for y in xs for x in xs])
    idx = lambda i, j: j * 4 + i  # noqa: E731
    elems = [(idx(i, j), idx(i + 1, j)) for j in range(4) for i in range(3)] + \
            [(idx(i, j), idx(i, j + 1)) for j in range(3) for i in range(4)]
    line = np.array([(-1.0, 0.5, 0.0), (4.0, 2.6, 0.0)])  # y = 0.5 + 0.42 (x + 1)
    pos = np.vstack([nodes, line])
    elems = np.array(elems + [(16, 17)])
    drop = np.zeros_like(pos)
    drop[:16, 2] = -150.0 * DT
    pos0 = pos.copy()
    pos0[:16, 2] += 0.5 * 150 * DT  # the grid starts half a step above the line
    pos1 = pos0 + drop
    pairs = candidate_pairs(pos0, elems, np.ones(len(elems), np.int8), 150 * DT)
    out = [np.empty(64), np.empty(64, np.int64), np.empty(64, np.int64), np.empty(64, np.int64)]
    n = step_crossings(pairs, elems, pos0, pos1, *out)
    crossed = sorted(int(out[1][i]) for i in range(n))
    # the elements the line's projection meets: by their own segment-segment test in 2-D
    want = []
    p, r = line[0, :2], line[1, :2] - line[0, :2]
    for e, (a, b) in enumerate(elems[:-1]):
        q, s = nodes[a, :2], nodes[b, :2] - nodes[a, :2]
        den = r[0] * s[1] - r[1] * s[0]
        if den == 0:
            continue
        t = ((q - p)[0] * s[1] - (q - p)[1] * s[0]) / den
        u = ((q - p)[0] * r[1] - (q - p)[1] * r[0]) / den
        if 0 <= t <= 1 and 0 <= u < 1:
            want.append(e)
    assert crossed == sorted(want) and len(want) >= 5
    assert all(0.49 < out[0][i] < 0.51 for i in range(n))


def test_closest_points_of_an_element_of_no_length():
    """A folded web can hold an element whose ends coincide: its closest points are those
    of a point (no division by its zero length)."""
    from spinweb_fe.fe.contact.distance import closest_points

    p = np.array([0.5, 1.0, 0.0])
    s, t, d = closest_points(p, p, np.array([0.0, 0.0, 0.0]), np.array([2.0, 0.0, 0.0]))
    assert (s, t, d) == (0.0, 0.25, 1.0)
    s, t, d = closest_points(np.array([0.0, 0.0, 0.0]), np.array([2.0, 0.0, 0.0]), p, p)
    assert (s, t, d) == (0.25, 0.0, 1.0)
    assert closest_points(p, p, p + 1.0, p + 1.0)[2] == np.sqrt(3.0)
