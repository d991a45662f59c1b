"""Linking numbers of closed loops (record/linking.py, issue #26 item 3): the segment pair's
closed form against the Gauss integral by quadrature and against Klenin & Langowski's
arcsine form; Hopf links +-1 with orientation, unlinked rings 0, torus links T(2, 2k) =
k; invariant under rigid motions and under deformations that cross nothing; a segment
pushed through a loop changes Lk by exactly the sign that fe/contact/crossing.py's detector
reports (times the orientations); the web's cells: a flat web links nothing."""

import math

import numpy as np
import pytest
from numpy.polynomial.legendre import leggauss

from meshgen.build import flat_web
from meshgen.mesh import Mesh
from spinweb_fe.fe.contact.crossing import step_crossings
from spinweb_fe.record.linking import (box_pairs, cell_loops, linked_pairs, linking_number,
                                       loops_from, segment_linking)
from support import loop_crossings


def rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k


def ring(n, centre, e1, e2, r=1.0):
    """n-gon of radius r about ``centre`` in the plane (e1, e2), counter-clockwise about
    e1 x e2."""
    th = 2 * np.pi * (np.arange(n) + 0.5) / n
    return (np.asarray(centre, float) + r * np.cos(th)[:, None] * np.asarray(e1, float)
            + r * np.sin(th)[:, None] * np.asarray(e2, float))


def torus_link(q, n=96, R=2.0, r=1.0):
    """The two components of the torus link T(2, q), q even: each goes once round the
    axis and q/2 times round the tube."""
    t = 2 * np.pi * np.arange(n) / n
    out = []
    for j in range(2):
        v = q / 2 * t + j * np.pi
        out.append(np.column_stack([(R + r * np.cos(v)) * np.cos(t),
                                    (R + r * np.cos(v)) * np.sin(t), r * np.sin(v)]))
    return out


def hopf():
    """A counter-clockwise about +z in the plane z = 0; B in the plane y = 0 through A's
    centre, passing it downwards (-z): Lk = -1 by the right-hand rule."""
    return ring(16, [0, 0, 0], [1, 0, 0], [0, 1, 0]), ring(16, [1, 0, 0], [1, 0, 0], [0, 0, 1])


def klenin_langowski(p1, p2, p3, p4):
    """A segment pair's share of Lk by Klenin & Langowski (2000), Eq. 15-16: four arcsines
    of the normals of the tetrahedron's faces, signed by (r34 x r12) . r13."""
    r13, r14, r23, r24 = p3 - p1, p4 - p1, p3 - p2, p4 - p2
    n = [np.cross(u, v) for u, v in ((r13, r14), (r14, r24), (r24, r23), (r23, r13))]
    n = [v / np.linalg.norm(v) for v in n]
    omega = sum(math.asin(np.clip(n[k] @ n[(k + 1) % 4], -1, 1)) for k in range(4))
    return omega * np.sign(np.cross(p4 - p3, p2 - p1) @ r13) / (4 * math.pi)


def gauss_quadrature(p1, p2, p3, p4, order=60):
    """The Gauss integral of two segments by Gauss-Legendre quadrature, over 4 pi."""
    x, w = leggauss(order)
    x, w = (x + 1) / 2, w / 2
    a = p1 + x[:, None, None] * (p2 - p1)
    b = p3 + x[None, :, None] * (p4 - p3)
    u = a - b
    f = (u @ np.cross(p2 - p1, p4 - p3)) / np.linalg.norm(u, axis=-1) ** 3
    return float(w @ f @ w) / (4 * math.pi)


def test_a_segment_pair_is_its_gauss_integral():
    """Random segment pairs: the closed form equals the Gauss integral by quadrature (pairs
    apart, where 60 x 60 points converge) and Klenin & Langowski's arcsines (any pair)."""
    rng = np.random.default_rng(1)
    apart = 0
    for _ in range(60):
        p = rng.normal(size=(4, 3))
        p[2:] += 2.5 * rng.normal(size=3)
        if np.linalg.norm(p[2:].mean(0) - p[:2].mean(0)) < 2.0:
            continue
        apart += 1
        got = segment_linking(*p)
        assert got == pytest.approx(gauss_quadrature(*p), abs=1e-10)
        assert got == pytest.approx(klenin_langowski(*p), abs=1e-12)
    assert apart >= 30
    for _ in range(40):
        p = rng.normal(size=(4, 3))
        assert segment_linking(*p) == pytest.approx(klenin_langowski(*p), abs=1e-9)


def test_hopf_link_is_plus_or_minus_one_with_orientation():
    A, B = hopf()
    lk = linking_number(A, B)
    assert lk == pytest.approx(-1.0, abs=1e-12)
    assert linking_number(B, A) == pytest.approx(lk, abs=1e-12)
    assert linking_number(A, B[::-1]) == pytest.approx(1.0, abs=1e-12)
    assert linking_number(A[::-1], B) == pytest.approx(1.0, abs=1e-12)
    assert linking_number(A[::-1], B[::-1]) == pytest.approx(-1.0, abs=1e-12)
    assert linking_number(A, B * [1, 1, -1]) == pytest.approx(1.0, abs=1e-12)  # mirror
    # a coarse polygon is as exact: a triangle and a square
    tri = np.array([[-1.0, -1, 0], [2, -1, 0], [-1, 2, 0]])
    sq = np.array([[0.0, 0, 1], [0, 0, -1], [5, 0, -1], [5, 0, 1]])  # down through tri
    assert linking_number(tri, sq) == pytest.approx(-1.0, abs=1e-13)


def test_unlinked_rings_give_zero():
    A = ring(16, [0, 0, 0], [1, 0, 0], [0, 1, 0])
    beside = ring(16, [2.5, 0, 0], [1, 0, 0], [0, 0, 1])       # through A's plane outside it
    stacked = ring(16, [0.2, 0, 0.3], [1, 0, 0], [0, 1, 0])   # parallel planes
    far = ring(12, [10, -4, 3], [0, 1, 0], [0, 0, 1])
    for B in (beside, stacked, far):
        assert abs(linking_number(A, B)) < 1e-13
    # coplanar loops: exactly 0, also when they overlap in their plane (undefined there)
    assert linking_number(A, ring(9, [0.5, 0, 0], [1, 0, 0], [0, 1, 0])) == 0.0


def smooth_torus_lk(q, n=400, R=2.0, r=1.0):
    """Lk of the smooth T(2, q) by the trapezoidal rule on the Gauss integral (periodic and
    analytic: exponentially convergent), independent of the polygon formula."""
    t = 2 * np.pi * np.arange(n) / n
    curves = []
    for j in range(2):
        v, dv = q / 2 * t + j * np.pi, q / 2
        rho, drho = R + r * np.cos(v), -r * np.sin(v) * dv
        x = np.column_stack([rho * np.cos(t), rho * np.sin(t), r * np.sin(v)])
        dx = np.column_stack([drho * np.cos(t) - rho * np.sin(t),
                              drho * np.sin(t) + rho * np.cos(t), r * np.cos(v) * dv])
        curves.append((x, dx))
    (x, dx), (y, dy) = curves
    u = x[:, None, :] - y[None, :, :]
    f = np.einsum("ijk,ijk->ij", u, np.cross(dx[:, None, :], dy[None, :, :]))
    f /= np.linalg.norm(u, axis=-1) ** 3
    return f.sum() * (2 * np.pi / n) ** 2 / (4 * np.pi)


@pytest.mark.parametrize("q", [2, 4, 6])
def test_torus_link_t2q_links_q_over_2(q):
    """|Lk| = q/2, the sign that of the smooth link (here negative: the components turn
    round the tube counter-clockwise while going round the axis counter-clockwise, a
    left-handed twist), and the mirror image the other sign."""
    smooth = smooth_torus_lk(q)
    assert smooth == pytest.approx(-(q // 2), abs=1e-6)
    P, Q = torus_link(q)
    assert linking_number(P, Q) == pytest.approx(-(q // 2), abs=1e-10)
    assert linking_number(P * [1, 1, -1], Q * [1, 1, -1]) == pytest.approx(q // 2, abs=1e-10)


def test_rigid_motions_keep_lk_and_a_mirror_flips_it():
    rng = np.random.default_rng(5)
    cases = [hopf(), torus_link(4)]
    for P, Q in cases:
        base = linking_number(P, Q)
        for _ in range(5):
            R = rot(rng.normal(size=3), rng.uniform(0, 2 * np.pi))
            t = rng.normal(size=3) * 1e3
            assert linking_number(P @ R.T + t, Q @ R.T + t) == pytest.approx(base, abs=1e-9)
            M = R @ np.diag([1.0, 1.0, -1.0])
            assert linking_number(P @ M.T + t, Q @ M.T + t) == pytest.approx(-base, abs=1e-9)


def all_crossings(P0, P1, Q0, Q1):
    """Every crossing of a segment of loop P with one of loop Q while their nodes move
    from *0 to *1 (each segment in its loop's direction): [(i, j, sign)]."""
    times, signs = np.empty(3), np.empty(3, np.int64)
    out = []
    n, m = len(P0), len(Q0)
    for i in range(n):
        a, b = i, (i + 1) % n
        for j in range(m):
            c, d = j, (j + 1) % m
            k = loop_crossings(P0[a], P1[a], P0[b], P1[b], Q0[c], Q1[c], Q0[d], Q1[d],
                               times, signs)
            out += [(i, j, int(signs[r])) for r in range(k)]
    return out


def test_a_deformation_that_crosses_nothing_keeps_lk():
    rng = np.random.default_rng(7)
    for P, Q in (hopf(), torus_link(4, n=48), torus_link(6, n=48)):
        base = round(linking_number(P, Q))
        for _ in range(10):
            P1 = P + rng.normal(scale=0.03, size=P.shape)
            Q1 = Q + rng.normal(scale=0.03, size=Q.shape)
            assert all_crossings(P, P1, Q, Q1) == []
            assert linking_number(P1, Q1) == pytest.approx(base, abs=1e-9)


def square_through_ring(x_from, x_to):
    """B: the square of side 2 about the origin in z = 0, counter-clockwise about +z. A: a
    square in the plane y = 0, its left side at x = ``x_from`` (from z = 1 down to -1),
    its right side at x = 3; the left side moves to ``x_to`` in one step."""
    B = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    A0 = np.array([[x_from, 0, -1.0], [3, 0, -1], [3, 0, 1], [x_from, 0, 1]])
    A1 = A0.copy()
    A1[[0, 3], 0] = x_to
    return A0, A1, B


@pytest.mark.parametrize("x_from,x_to", [(1.5, 0.5), (0.5, 1.5), (1.3, -0.2)])
def test_pushing_a_segment_through_a_loop_changes_lk_by_the_crossing_sign(x_from, x_to):
    """A's left side passes through B's right side: one crossing; Lk changes by exactly
    its sign s (each element taken along its loop), by -s with A's element taken the other
    way; the same after any rigid motion."""
    rng = np.random.default_rng(13)
    A0, A1, B = square_through_ring(x_from, x_to)
    for trial in range(4):
        R = np.eye(3) if trial == 0 else rot(rng.normal(size=3), rng.uniform(0, 2 * np.pi))
        t = np.zeros(3) if trial == 0 else rng.normal(size=3) * 50
        a0, a1, b = A0 @ R.T + t, A1 @ R.T + t, B @ R.T + t
        hits = all_crossings(a0, a1, b, b)
        assert len(hits) == 1 and hits[0][:2] == (3, 1)  # A's side 3 -> 0, B's side 1 -> 2
        s = hits[0][2]
        before, after = linking_number(a0, b), linking_number(a1, b)
        assert round(after) - round(before) == s
        assert abs(after - before - s) < 1e-9
        # the element stored the other way round (0 -> 3): the detector's sign flips
        times, signs = np.empty(3), np.empty(3, np.int64)
        k = loop_crossings(a0[0], a1[0], a0[3], a1[3], b[1], b[1], b[2], b[2], times, signs)
        assert k == 1 and signs[0] == -s
    # the geometry's own answer: A's side goes down through B's inside, so Lk = -1 there
    assert round(linking_number(A1 if x_to < 1 else A0, B)) == -1


def test_a_loop_caught_at_its_crossing_is_halfway_and_a_suspect():
    """At the crossing the two loops meet: V = 0 there, the pair counts 0, and Lk is the
    mean of before and after; linked_pairs reports the pair as a suspect, not a link."""
    A0, _, _ = square_through_ring(1.0, 1.0)  # A's left side on B's right side, and B
    B = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [2, 1.5, 0], [-1, 1.5, 0]])  # wider
    # a micrometre either side (round-off grows as 1e-16 times size over distance)
    assert linking_number(A0 + [1e-6, 0, 0], B) == pytest.approx(0.0, abs=1e-9)
    assert linking_number(A0 - [1e-6, 0, 0], B) == pytest.approx(-1.0, abs=1e-9)
    assert linking_number(A0, B) == pytest.approx(-0.5, abs=1e-12)
    pos = np.vstack([A0, B])
    res = linked_pairs(pos, loops_from([[0, 1, 2, 3], [4, 5, 6, 7, 8]]))
    assert res.links.shape == (0, 3) and res.suspect.tolist() == [[0, 1]]
    assert res.worst == pytest.approx(0.5, abs=1e-12)


def two_strips():
    """Two webs of two cells each, as one Mesh. W1: 2 x 3 nodes, flat in its reference,
    placed upright in the plane y = 0 (rows at z = -0.7, 0.3, 1.3); its middle row, the
    element e = (2, 3) from x = -0.5 to 0.5, borders both its cells. W2: 3 x 2 nodes in
    z = 0, its middle column, the element f = (7, 10) from y = -1 to 1 at x = 0. Moving
    e's nodes down to z = -0.3 passes e through f, and nothing else through anything."""
    ref = [(x, y) for y in range(3) for x in range(2)] + [(5 + x, y) for y in range(2)
                                                         for x in range(3)]
    ref = np.array([(x, y, 0.0) for x, y in ref])
    pos = np.vstack([[(x - 0.5, 0.0, 0.3 + y - 1) for x, y, _ in ref[:6]],
                     [(x - 6.0, 2.0 * y - 1, 0.0) for x, y, _ in ref[6:]]])
    elems = np.array([(0, 1), (2, 3), (4, 5), (0, 2), (2, 4), (1, 3), (3, 5),
                      (6, 7), (7, 8), (9, 10), (10, 11), (6, 9), (7, 10), (8, 11)])
    mesh = Mesh(node_pos=pos, node_ref=ref, elem_nodes=elems,
                elem_rest_len=np.linalg.norm(ref[elems[:, 1]] - ref[elems[:, 0]], axis=1),
                node_point_mass=np.zeros(len(ref)))
    pos1 = pos.copy()
    pos1[[2, 3], 2] = -0.3
    return mesh, pos1


def along(loop, a, b):
    """+1 if the loop runs a -> b, -1 if b -> a."""
    nxt = dict(zip(loop.tolist(), np.roll(loop, -1).tolist()))
    return 1 if nxt.get(a) == b else -1 if nxt.get(b) == a else 0


def test_one_crossing_of_two_web_elements_changes_four_cell_pairs():
    """e borders two cells of W1 (run once each way), f two of W2: the crossing changes
    Lk(P, Q) of the four pairs by s eps_e(P) eps_f(Q), s the detector's sign for e and f
    as stored, eps = +-1 whether the cell runs the element in its stored order."""
    mesh, pos1 = two_strips()
    loops = cell_loops(mesh)
    assert loops.n_loops == 4 and all(len(loops.loop(i)) == 4 for i in range(4))
    e, f = (2, 3), (7, 10)
    times, signs = np.empty(3), np.empty(3, np.int64)
    p0 = mesh.node_pos.copy()  # (writable, as the loop's: the kernels' compile is shared)
    found = []
    for g, (a, b) in enumerate(mesh.elem_nodes[:7]):
        for h, (c, d) in enumerate(mesh.elem_nodes[7:]):
            k = loop_crossings(p0[a], pos1[a], p0[b], pos1[b], p0[c], pos1[c], p0[d],
                               pos1[d], times, signs)
            found += [((a, b), (c, d), int(signs[r])) for r in range(k)]
    assert len(found) == 1 and found[0][:2] == (e, f)
    s = found[0][2]
    lk0 = {(i, j): v for i, j, v in linked_pairs(p0, loops).links}
    lk1 = {(i, j): v for i, j, v in linked_pairs(pos1, loops).links}
    w1 = [i for i in range(4) if loops.loop(i).max() < 6]
    w2 = [i for i in range(4) if loops.loop(i).min() >= 6]
    changes = []
    for P in w1:
        for Q in w2:
            key = (min(P, Q), max(P, Q))
            want = s * along(loops.loop(P), *e) * along(loops.loop(Q), *f)
            assert lk1.get(key, 0) - lk0.get(key, 0) == want
            changes.append(want)
    assert sorted(changes) == [-1, -1, 1, 1]


def test_cells_of_the_flat_webs():
    """Every cell once, counter-clockwise in the flat web, each interior element run once
    each way; the cut-out's rim is one more loop."""
    for name, side, t, k, n_cells, size in (("quadquad", 20.0, 2.5, 1, 64 - 4 + 1, 4),
                                            ("quadquad", 20.0, 2.5, 2, 64 - 4 + 1, 8),
                                            ("tritri", 10.0, 1.0, 1, 100, 3),
                                            ("tritri", 10.0, 1.0, 3, 100, 9)):
        mesh = flat_web(name, side, t, k, 0.0, 2.5 if name == "quadquad" else 0.0)
        loops = cell_loops(mesh)
        assert loops.n_loops == n_cells
        sizes = np.diff(loops.ptr)
        assert np.sum(sizes == size) >= n_cells - 1
        xy = mesh.node_ref[:, :2]
        runs = {}
        for i in range(loops.n_loops):
            v = loops.loop(i)
            p, q = xy[v], xy[np.roll(v, -1)]
            assert np.sum(p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]) > 0
            for a, b in zip(v.tolist(), np.roll(v, -1).tolist()):
                assert (a, b) not in runs
                runs[(a, b)] = i
        for a, b in mesh.elem_nodes.tolist():
            assert ((a, b) in runs) or ((b, a) in runs)
        boundary = [e for e in mesh.elem_nodes.tolist()
                    if ((e[0], e[1]) in runs) != ((e[1], e[0]) in runs)]
        assert len(boundary) == len(mesh.elem_sets["boundary"])
    hexes = cell_loops(flat_web("quadhex", 20.0, 1.0, 1, 0.0, 0.0))
    assert np.median(np.diff(hexes.ptr)) == 6


def test_a_flat_web_links_nothing_nor_does_it_ruffled_or_rolled_up():
    """Flat: no box overlaps another (z = 0 separates them all). Ruffled by up to a fifth
    of the mesh width (no element crossing another on the way, fe/contact/crossing.py) and
    turned: nothing linked. Rolled up like a carpet (a spiral of 1.68 turns, layers 1 m
    apart, an embedding like the flat web): many boxes overlap, nothing is linked."""
    mesh = flat_web("quadquad", 30.0, 2.5, 1, 0.0, 5.0)
    loops = cell_loops(mesh)
    res = linked_pairs(mesh.node_pos, loops)
    assert res.links.shape == (0, 3) and res.candidates == 0 and res.worst == 0.0
    rng = np.random.default_rng(3)
    # (writable copies, as the loop's arrays: the crossing kernels' compile is shared)
    ref, elems = mesh.node_ref.copy(), mesh.elem_nodes.copy()
    ruffled = ref + rng.uniform(-0.5, 0.5, size=ref.shape)
    mid = ref[elems].mean(axis=1)
    e, f = np.nonzero(np.triu(np.linalg.norm(mid[:, None] - mid[None], axis=-1) < 4.0, 1))
    pairs = np.column_stack([e, f])[~(elems[e, :, None] == elems[f, None, :]).any((1, 2))]
    out = [np.empty(8), np.empty(8, np.int64), np.empty(8, np.int64), np.empty(8, np.int64)]
    assert step_crossings(pairs, elems, ref, ruffled, *out) == 0
    res = linked_pairs(ruffled @ rot([1, 2, 3], 0.7).T, loops)
    assert res.links.shape == (0, 3) and len(res.suspect) == 0 and res.worst < 1e-12
    # the roll: arc length s = r0 phi + g phi^2 / (4 pi) along x, radius r0 + g phi / 2 pi
    r0, g = 2.0, 1.0
    s = ref[:, 0] - ref[:, 0].min()
    phi = (-r0 + np.sqrt(r0 ** 2 + g * s / np.pi)) / (g / (2 * np.pi))
    r = r0 + g * phi / (2 * np.pi)
    rolled = np.column_stack([r * np.cos(phi), ref[:, 1], r * np.sin(phi)])
    assert phi.max() > 3 * np.pi  # 1.68 turns
    res = linked_pairs(rolled, loops)
    assert res.links.shape == (0, 3) and len(res.suspect) == 0 and res.worst < 1e-9
    assert res.candidates > 40


def test_linked_pairs_of_a_chain_of_rings():
    """Three rings, each through the next: (0, 1) and (1, 2) linked, (0, 2) not; a fourth
    ring far away. Orientation decides the signs."""
    r0 = ring(12, [0, 0, 0], [1, 0, 0], [0, 1, 0])
    r1 = ring(12, [1, 0, 0], [1, 0, 0], [0, 0, 1])
    r2 = ring(12, [2, 0, 0], [1, 0, 0], [0, 1, 0])
    r3 = ring(12, [20, 0, 0], [1, 0, 0], [0, 1, 0])
    pos = np.vstack([r0, r1, r2, r3])
    loops = loops_from([np.arange(12) + 12 * i for i in range(4)])
    res = linked_pairs(pos, loops)
    assert res.candidates == 2  # r0 and r2 have disjoint boxes
    want = [[0, 1, round(linking_number(r0, r1))], [1, 2, round(linking_number(r1, r2))]]
    assert res.links.tolist() == want and abs(want[0][2]) == 1 == abs(want[1][2])
    assert res.worst < 1e-12 and len(res.suspect) == 0


def test_box_pairs_lists_what_a_brute_force_box_test_lists():
    """Random small loops (some sharing nodes, some flat, one large): the broad phase
    lists exactly the node-disjoint pairs whose boxes overlap."""
    rng = np.random.default_rng(21)
    pos = rng.uniform(0, 20, size=(400, 3))
    pos[:40, 2] = 5.0  # flat loops among them
    cycles = [rng.choice(40, size=4, replace=False) for _ in range(10)]
    for _ in range(150):
        c = rng.integers(0, 400)
        near = np.argsort(np.linalg.norm(pos - pos[c], axis=1))[:rng.integers(3, 7)]
        cycles.append(rng.permutation(near))
    cycles.append(rng.choice(400, size=30, replace=False))
    loops = loops_from(cycles)
    got = box_pairs(pos, loops)
    lo = np.array([pos[c].min(0) for c in cycles])
    hi = np.array([pos[c].max(0) for c in cycles])
    want = [[i, j] for i in range(len(cycles)) for j in range(i + 1, len(cycles))
            if np.all(lo[i] < hi[j]) and np.all(lo[j] < hi[i])
            and not set(cycles[i].tolist()) & set(cycles[j].tolist())]
    assert len(want) > 100 and got.tolist() == want
