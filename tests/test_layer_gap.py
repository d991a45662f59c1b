"""fold.layer_gap (issue 26, item 1; docs/mesh.md 2.9): the star fold's layers stacked in
columns along the hub axis and the coil rising pass over pass, so that no two elements
that share no node start closer than the gap g. Measured by an exact segment-segment
distance over every pair of elements (brute force). Gap 0 is today's geometry."""

import math

import numpy as np
import pytest

from meshgen.build import web_mesh
from meshgen.checks import MeshValueError, check_mesh
from meshgen.flat import flat_quadquad
from meshgen.fold import assign_arms, coil, fold_web, star_fold
from meshgen.layers import layer_plan
from meshgen.mesh import lumped_mass
from meshgen.tethers import tethers
from spinweb_fe.case import loads
from spinweb_fe.case.scene import build_mesh
from spinweb_fe.errors import InputError
from spinweb_fe.fe.coil.build import build_coil

MU = 0.0158  # kg/m, any line density: masses come from rest lengths only


def segment_distance(p1, q1, p2, q2):
    """(k,) exact distances between the segments [p1, q1] and [p2, q2], each (k, 3): the
    closest points of the two lines, clamped to the segments (Ericson, Real-Time Collision
    Detection, 5.1.9), for parallel and zero-length segments too."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = np.einsum("ij,ij->i", d1, d1), np.einsum("ij,ij->i", d2, d2)
    b, c, f = (np.einsum("ij,ij->i", d1, d2), np.einsum("ij,ij->i", d1, r),
               np.einsum("ij,ij->i", d2, r))
    pa, pe = a > 0.0, e > 0.0
    sa, se = np.where(pa, a, 1.0), np.where(pe, e, 1.0)
    denom = a * e - b * b
    general = denom > 1e-14 * a * e                       # not parallel
    s = np.where(general, np.clip((b * f - c * e) / np.where(general, denom, 1.0), 0, 1), 0.0)
    t = (b * s + f) / se
    low, high = t < 0.0, t > 1.0
    s = np.where(low, np.clip(-c / sa, 0, 1), np.where(high, np.clip((b - c) / sa, 0, 1), s))
    t = np.clip(t, 0.0, 1.0)
    # a point on either side: the other segment's nearest point to it
    s = np.where(pe, s, np.clip(-c / sa, 0, 1))
    t = np.where(pe, t, 0.0)
    t = np.where(pa, t, np.clip(f / se, 0, 1))
    s = np.where(pa, s, 0.0)
    gap = (p1 + s[:, None] * d1) - (p2 + t[:, None] * d2)
    return np.sqrt(np.einsum("ij,ij->i", gap, gap))


def min_separation(mesh, chunk=192):
    """Smallest distance between two elements that share no node: (distance, i, j)."""
    en, pos = mesh.elem_nodes, mesh.node_pos
    p, q = pos[en[:, 0]], pos[en[:, 1]]
    best = (math.inf, -1, -1)
    for i0 in range(0, len(en), chunk):
        ii, jj = np.meshgrid(np.arange(i0, min(i0 + chunk, len(en))), np.arange(len(en)),
                             indexing="ij")
        keep = jj > ii
        ii, jj = ii[keep], jj[keep]
        a, b = en[ii], en[jj]
        joined = (a[:, :1] == b).any(axis=1) | (a[:, 1:] == b).any(axis=1)
        ii, jj = ii[~joined], jj[~joined]
        d = segment_distance(p[ii], q[ii], p[jj], q[jj])
        k = int(np.argmin(d))
        if d[k] < best[0]:
            best = (float(d[k]), int(ii[k]), int(jj[k]))
    return best


def test_segment_distance_against_closed_forms_and_sampling():
    P = lambda *v: np.array([v], float)  # noqa: E731
    cases = [  # (p1, q1, p2, q2, distance)
        (P(0, 0, 0), P(1, 0, 0), P(0, 1, 2), P(1, 1, 2), math.sqrt(5)),        # parallel
        (P(0, 0, 0), P(2, 0, 0), P(1, -1, 0.5), P(1, 1, 0.5), 0.5),             # skew, crossing
        (P(0, 0, 0), P(1, 0, 0), P(3, 0, 0), P(5, 0, 0), 2.0),                  # collinear apart
        (P(0, 0, 0), P(1, 0, 0), P(0.5, 0.3, 0), P(0.5, 0.3, 0), 0.3),          # a point
        (P(0, 0, 0), P(0, 0, 0), P(0, 0, 1), P(0, 0, 1), 1.0),                  # two points
        (P(0, 0, 0), P(1, 0, 0), P(2, 1, 0), P(2, 3, 0), math.sqrt(2)),         # end to end
    ]
    for p1, q1, p2, q2, d in cases:
        assert segment_distance(p1, q1, p2, q2)[0] == pytest.approx(d, rel=1e-14, abs=1e-15)
        assert segment_distance(p2, q2, p1, q1)[0] == pytest.approx(d, rel=1e-14, abs=1e-15)
    rng = np.random.default_rng(1)
    x = rng.normal(size=(300, 4, 3))
    x[::3, 3] = x[::3, 2] + 0.7 * (x[::3, 1] - x[::3, 0])                   # parallel pairs
    d = segment_distance(x[:, 0], x[:, 1], x[:, 2], x[:, 3])
    s = np.linspace(0.0, 1.0, 301)[:, None]
    for k in range(len(x)):
        a = x[k, 0] + s * (x[k, 1] - x[k, 0])
        b = x[k, 2] + s * (x[k, 3] - x[k, 2])
        sampled = np.sqrt(((a[:, None] - b[None]) ** 2).sum(axis=2)).min()
        assert d[k] <= sampled + 1e-12 and d[k] >= sampled - 2e-3


def _paper_star(gap):
    return star_fold(assign_arms(flat_quadquad(100.0, 2.5, 1, 10.0, 7.5), 6.3), gap)


#: name -> (mesh builder of a gap g, g): the paper web (S = 100 m, t = 2.5 m, r0 = 6.3 m)
#: star-folded and coiled, a small web with 2 elements per segment coiled leading over
#: 5 passes, one whose elements are as long as the hub radius (the longest allowed) at
#: 3 cm, and tethers (4 on the paper hub; 2 that wind 8 turns on a 1 m hub)
MESHES = {
    "paper_star_5mm": (_paper_star, 0.005),
    "paper_coiled_5mm": (lambda g: web_mesh("quadquad", 100.0, 2.5, 1, 10.0, 6.3, None,
                                            "star", "trailing", "frame", g), 0.005),
    "small_k2_leading_1cm": (lambda g: web_mesh("quadquad", 20.0, 1.0, 2, 1.0, 1.9, 2.0,
                                                "star", "leading", "frame", g), 0.01),
    "small_e_eq_r0_3cm": (lambda g: web_mesh("quadquad", 20.0, 1.0, 1, 1.0, 1.0, 2.0,
                                             "star", "trailing", "frame", g), 0.03),
    "tethers_paper_5mm": (lambda g: tethers(4, 50.0, 50, 6.3, 10.0, "coiled", "trailing", g),
                          0.005),
    "tethers_8_turns_2cm": (lambda g: tethers(2, 50.0, 100, 1.0, 1.0, "coiled", "leading", g),
                            0.02),
}


@pytest.fixture(scope="module", params=list(MESHES))
def stacked(request):
    make, gap = MESHES[request.param]
    return request.param, make(gap), make(0.0), gap


def test_no_two_unjoined_elements_start_closer_than_the_gap(stacked):
    """Measured (docs/mesh.md 2.9): paper web star-folded 1.00038 g, coiled 1.00021 g; the
    small web 1.0089 g, e = r0 1.059 g; tethers 1.100 g and 1.099 g (the margins: h > g
    for the tilt of the cables, KAPPA = 1.1 between passes)."""
    name, mesh, flat0, gap = stacked
    d, i, j = min_separation(mesh)
    assert d >= gap * (1.0 - 1e-12), (name, d / gap, i, j)
    if mesh.n_elems < 2000:           # without the gap, layers and turns coincide
        assert min_separation(flat0)[0] < 1e-12


def test_the_invariants_hold_as_without_a_gap(stacked):
    """No element starts stretched, rest lengths and topology from the flat web, the same
    lumped masses, nobody inside the hub, tied nodes where they were (in the hub plane)."""
    name, mesh, flat0, gap = stacked
    assert check_mesh(mesh) == []
    assert np.max(mesh.elem_length() / mesh.elem_rest_len) <= 1.0 + 1e-12
    for f in ("elem_rest_len", "elem_nodes", "node_ref", "node_point_mass", "node_arm",
              "node_arm_coord", "arm_root_angle"):
        assert np.array_equal(getattr(mesh, f), getattr(flat0, f), equal_nan=True), f
    assert np.allclose(mesh.elem_rest_len, mesh.elem_length(mesh.node_ref), rtol=1e-12, atol=0)
    m, m0 = lumped_mass(mesh, MU), lumped_mass(flat0, MU)
    assert np.array_equal(m, m0)
    assert m.sum() == pytest.approx(MU * mesh.elem_rest_len.sum() + mesh.node_point_mass.sum(),
                                    rel=1e-13)
    tied = mesh.node_sets["hub_tied"]
    assert np.array_equal(mesh.node_pos[tied], flat0.node_pos[tied])
    assert np.all(mesh.node_pos[tied, 2] == 0.0)
    assert np.all(flat0.node_pos[:, 2] == 0.0) and np.any(mesh.node_pos[:, 2] != 0.0)


def test_gap_zero_is_todays_geometry():
    """layer_gap = 0 takes today's code path: the same arrays, bit for bit, as a call
    without the argument (tests/test_fold.py and the shipped cases hold those)."""
    flat = flat_quadquad(40.0, 2.5, 2, 3.0, 5.0)
    for ties in ("frame", "axes"):
        for wrap in ("trailing", "leading"):
            a = fold_web(flat, 3.0, "star", wrap, ties)
            b = fold_web(flat, 3.0, "star", wrap, ties, layer_gap=0.0)
            assert np.array_equal(a.node_pos, b.node_pos)
    arms = assign_arms(flat, 3.0)
    assert np.array_equal(star_fold(arms).node_pos, star_fold(arms, 0.0).node_pos)
    assert np.array_equal(coil(star_fold(arms)).node_pos,
                          coil(star_fold(arms), layer_gap=0.0).node_pos)
    assert np.array_equal(tethers(3, 20.0, 17, 1.3, 2.0).node_pos,
                          tethers(3, 20.0, 17, 1.3, 2.0, layer_gap=0.0).node_pos)


def test_columns_of_the_paper_web():
    """Each arm level is a column along z at one in-plane point, its layers h apart and
    centred on the hub plane beyond the frame corner (one-sided on the frame edges); the
    radial run is shorter by the factor s; the frame corner holds 35 layers, 17 h above
    and below the plane (docs/mesh.md 2.9)."""
    g = 0.005
    star, star0 = _paper_star(g), _paper_star(0.0)
    plan = layer_plan(star, g, 7.5, columns=True)
    h = plan.spacing
    assert g < h < 1.001 * g and 0.9998 < plan.shrink < 1.0
    for k in range(4):
        for lev in np.unique(star.node_arm_coord[star.node_arm == k]):
            at = np.flatnonzero((star.node_arm == k) & (star.node_arm_coord == lev))
            xy = star.node_pos[at, :2]
            if lev >= 7.5 and len(at) > 1:    # one point per level (the strips lie along
                                              # the frame edges, the tip is one node)
                assert np.ptp(xy, axis=0).max() < 1e-12
                z = np.sort(star.node_pos[at, 2])
                assert z[0] == pytest.approx(-z[-1], abs=1e-15)
                assert np.min(np.diff(z)) == pytest.approx(h, rel=1e-12)
                r = np.hypot(*xy[0])
                assert r == pytest.approx(7.5 * math.sqrt(2) + plan.shrink * (lev - 7.5),
                                          rel=1e-14)
    corner = np.flatnonzero((star.node_arm == 0) & (star.node_arm_coord == 7.5))
    z = np.unique(np.round(star.node_pos[corner, 2] / h, 9))
    assert len(z) == 35 and z.min() == -17 and z.max() == 17
    assert np.ptp(star.node_pos[:, 2]) == pytest.approx(34 * h, rel=1e-12)     # 0.170 m
    shift = np.hypot(*(star.node_pos[:, :2] - star0.node_pos[:, :2]).T)
    assert shift.max() <= (1 - plan.shrink) * (50.0 - 7.5) * (1 + 1e-9)


@pytest.mark.parametrize("gap, top", [(0.005, 0.3478), (0.01, 0.6959)])
def test_the_paper_coil_rises_pass_over_pass(gap, top):
    """The coil stays on the rim and rises along the hub axis, monotonically along each arm,
    to 0.35 m (5 mm) and 0.70 m (1 cm) at the tips (3.86 passes); the arms' rim positions
    move by at most 8.1 mm (5 mm) and 33 mm (1 cm) of arc against the gap-free coil."""
    mesh = web_mesh("quadquad", 100.0, 2.5, 1, 10.0, 6.3, None, "star", "trailing", "frame",
                    gap)
    mesh0 = web_mesh("quadquad", 100.0, 2.5, 1, 10.0, 6.3)
    assert mesh.node_pos[:, 2].max() == pytest.approx(top, abs=1e-4)
    plan = layer_plan(mesh, gap, 7.5, columns=True)
    coiled = mesh.node_sets["coil"]
    lev = mesh.node_arm_coord[coiled]
    on_rim = lev >= plan.rim
    r = np.hypot(mesh.node_pos[coiled, 0], mesh.node_pos[coiled, 1])
    assert np.allclose(r[on_rim], 6.3, rtol=1e-14, atol=0)
    assert np.all(r[~on_rim] > 6.3)
    for k in range(4):
        mine = coiled[(mesh.node_arm[coiled] == k) & on_rim]
        rise = plan.lift(np.unique(mesh.node_arm_coord[mine]))
        assert rise[0] >= 0 and np.all(np.diff(rise) > 0)
        for l in np.unique(mesh.node_arm_coord[mine]):   # each level: its column, lifted
            at = mine[mesh.node_arm_coord[mine] == l]
            z = mesh.node_pos[at, 2] - plan.lift(np.array([l]))[0]
            assert z.min() == pytest.approx(-z.max(), abs=1e-12)
    shift = np.hypot(*(mesh.node_pos[:, :2] - mesh0.node_pos[:, :2]).T).max()
    assert shift == pytest.approx({0.005: 0.00812, 0.01: 0.0325}[gap], abs=1e-4)


@pytest.mark.parametrize("gap", [0.005, 0.01])
def test_the_held_coil_keeps_its_levels_on_the_rim(gap):
    """The FE held coil (fe.coil.build) reads the stacked mesh as the gap-free one: the same
    levels, free elements, rim flags and bases (every level on the rim stays at r0, so the
    release test, the departure point and the arm measure see the same coil); only the
    hub-frame places of the held nodes (level_ref) carry the stack. No free element of a
    held level starts taut: nothing is released at the start that was not before."""
    for make in (lambda g: web_mesh("quadquad", 100.0, 2.5, 1, 10.0, 6.3, None, "star",
                                    "trailing", "frame", g),
                 lambda g: tethers(4, 50.0, 50, 6.3, 10.0, "coiled", "trailing", g)):
        mesh, mesh0 = make(gap), make(0.0)
        c, c0 = (build_coil(m, m.elem_nodes, lumped_mass(m, MU)) for m in (mesh, mesh0))
        for f in c._fields:
            a, b = getattr(c, f), getattr(c0, f)
            if f == "level_ref":
                assert np.array_equal(a, mesh.node_pos[c.level_nodes])
            elif isinstance(a, np.ndarray):
                assert np.array_equal(a, b), f
            else:
                assert a == b, f
        assert c.level_rim.sum() > 0
        held = np.arange(c.arm_ptr[0] + 1, c.arm_ptr[1])       # arm 0 behind its tip level
        e = c.test_elem[c.test_ptr[held[0]]:c.test_ptr[held[-1] + 1]]
        assert np.all(mesh.elem_length()[e] <= mesh.elem_rest_len[e])


BASE = """
[web]
side = 20.0
mesh_width = 1.0
hub_cutout = 2.0
[hub]
radius = 1.0
mass = 10.0
[time]
end = 0.01
"""
TETHERS = """
[tethers]
count = 4
[time]
end = 0.01
"""


@pytest.mark.parametrize("text, sets, reason", [
    (BASE, ["fold.layer_gap=-0.001"], "must be >= 0"),
    (BASE, ["fold.layer_gap=0.01", "fold.pattern='flat'"], "only a folded scene has layers"),
    (TETHERS, ["fold.layer_gap=0.01", "fold.pattern='straight'"],
     "only a folded scene has layers"),
    (BASE, ["fold.layer_gap=0.01", "stowage.bundle='until_time'", "stowage.bundle_release=0.1"],
     "a bundle (stowage.bundle) moves each level as one point"),
    (BASE, ["fold.layer_gap=0.01", "stowage.payout='rate'", "stowage.payout_rate=1.0"],
     "a rate device lets each level out at one point"),
])
def test_the_loader_refuses(text, sets, reason):
    with pytest.raises(InputError) as exc:
        loads(text, sets)
    assert exc.value.key == "fold.layer_gap" and reason in exc.value.reason


@pytest.mark.parametrize("sets, reason", [
    (["fold.ties='axes'"], "need fold.ties = 'frame'"),
    (["web.topology='tritri'"], "need the square web with a square mesh"),
    (["web.hub_cutout=1.0"], "needs the hub frame at least r0 + 0.0"),        # c = r0
    (["hub.radius=0.9", "web.hub_cutout=1.0"], "needs elements no longer than the hub"),
    (["fold.layer_gap=0.2"], "is too large for elements of 1 m"),
])
def test_the_mesh_generator_refuses(sets, reason):
    """Geometry the stacking does not cover: one line naming fold.layer_gap (exit 2)."""
    case = loads(BASE, ["fold.layer_gap=0.01"] + sets)
    with pytest.raises(InputError) as exc:
        build_mesh(case)
    assert exc.value.key == "fold.layer_gap" and reason in exc.value.reason
    with pytest.raises(MeshValueError):
        fold_web(flat_quadquad(20.0, 1.0, 1, 1.0, 2.0), 1.0, "flat", layer_gap=0.01)
