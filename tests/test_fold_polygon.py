"""Star fold of the triangular webs (3 arms) and of the square web with triangular and
hexagonal meshes (4 arms). The hub frame is a hole shaped like the web outline, clipped
into the mesh (docs/mesh.md); the fold is the nearest-point projection onto it plus a
radial run-out from its corners."""

import math

import numpy as np
import pytest

from spinweb_fe.case.scene import build_mesh
from meshgen.checks import check_mesh, eq7_error, eq7_reference
from meshgen.fold import assign_arms, coil, corner_coord, frame_lead_in, star_fold, tie_mode
from meshgen.mesh import lumped_mass
from meshgen.registry import cable_length_per_area
from meshgen.clip import _nearest_on_outline
from meshgen.topologies import flat_other, outline_cutout, outline_hole
from spinweb_fe.case import loads
from spinweb_fe.errors import InputError

RHO_A, RHO, R0, S = 1.267e-2, 1540.0, 6.3, 100.0
TOPOLOGIES = ["tritri", "trihex", "triquad", "quadtri", "quadhex"]


def _n_arms(topology):
    return 3 if topology.startswith("tri") else 4


def _assert_symmetric(topology, per_arm, rtol):
    """Arms related by a symmetry of web and lattice carry the same: all of them (C3 for
    the triangular and hexagonal lattices in the triangle, both mirrors for the square
    web); for triquad (a square lattice in a triangle: one mirror) arms 1 and 2."""
    if topology == "triquad":
        assert per_arm[1] == pytest.approx(per_arm[2], rel=rtol, abs=0)
    else:
        assert np.allclose(per_arm, per_arm[0], rtol=rtol, atol=0)


@pytest.fixture(scope="module", params=[(top, t, k) for top in TOPOLOGIES
                                        for t, k in ((5.0, 2), (2.5, 1))],
                ids=lambda p: f"{p[0]}-t{p[1]}-k{p[2]}")
def web(request):
    top, t, k = request.param
    c = outline_cutout(top, S, t, R0)
    flat = flat_other(top, S, t, k, 10.0, c, hole="outline")
    arms = assign_arms(flat, R0)
    star = star_fold(arms)
    return dict(top=top, t=t, k=k, c=c, n=_n_arms(top), flat=flat, arms=arms, star=star,
                trailing=coil(star, "trailing"), leading=coil(star, "leading"),
                hole=outline_hole(top, S, c))


@pytest.mark.parametrize("stage", ["arms", "star", "trailing", "leading"])
def test_invariants_every_stage(web, stage):
    m, flat = web[stage], web["flat"]
    assert check_mesh(m) == []
    assert np.max(m.elem_length() / m.elem_rest_len) <= 1 + 1e-9     # nothing stretched
    r = np.hypot(m.node_pos[:, 0], m.node_pos[:, 1])
    assert r.min() >= R0 * (1 - 1e-9)                                 # nobody in the hub
    assert np.array_equal(m.elem_rest_len, flat.elem_rest_len)        # rest from the flat web
    assert np.array_equal(m.elem_nodes, flat.elem_nodes)
    assert np.array_equal(m.node_ref, flat.node_pos)
    assert np.array_equal(m.node_point_mass, flat.node_point_mass)
    assert np.all(m.node_pos[:, 2] == 0.0) and tie_mode(m) == "frame"


def test_arm_metadata(web):
    m, n, c = web["trailing"], web["n"], web["c"]
    assert m.n_arms == n and m.wrap == 1 and web["leading"].wrap == -1
    psi0 = math.pi / 2 if n == 3 else math.pi / 4
    assert np.allclose(m.arm_root_angle, psi0 + 2 * math.pi * np.arange(n) / n, atol=1e-12)
    # the half sides from the side midpoints to a corner become the arm: H = S/2
    assert m.arm_length == pytest.approx(S / 2, rel=1e-12)
    tips = m.node_sets["tips"]
    assert np.array_equal(m.node_arm[tips], np.arange(n))
    assert np.allclose(m.node_arm_coord[tips], S / 2, rtol=1e-12)
    l_c = c * (math.sqrt(3.0) if n == 3 else 1.0)
    assert corner_coord(c, n) == pytest.approx(l_c, rel=1e-15)
    d0 = c / math.cos(math.pi / n) - R0
    assert frame_lead_in(c, R0, n) == pytest.approx(d0, rel=1e-14)
    assert m.arm_root_coord == pytest.approx(l_c + d0, rel=1e-14)
    # every node of the web outside the hole belongs to one arm or to a half-axis
    on_axis = m.node_sets["cross"]
    assert np.all(m.node_arm[on_axis] == -1) and np.all(np.isnan(m.node_arm_coord[on_axis]))
    assert np.count_nonzero(m.node_arm < 0) == len(on_axis)
    counts = np.bincount(m.node_arm[m.node_arm >= 0], minlength=n)
    _assert_symmetric(web["top"], counts, 0)


def test_tied_nodes_are_the_frame(web):
    """The tied set is the whole hole outline (on the polygon, by an independent distance
    computation); tied nodes keep their flat, hub-frame position through every stage."""
    flat, hole = web["flat"], web["hole"]
    tied = flat.node_sets["hub_tied"]
    assert np.array_equal(tied, flat.node_sets["hole_boundary"]) and len(tied) > web["n"]
    _, dist, _, _ = _nearest_on_outline(flat.node_ref[tied, :2], hole, 0.0)
    assert dist.max() < 1e-9
    _, dist_all, _, _ = _nearest_on_outline(flat.node_ref[:, :2], hole, 0.0)
    assert np.count_nonzero(dist_all < 1e-9) == len(tied)           # nobody else on it
    assert set(flat.node_sets["hole_corners"]) <= set(tied)
    for stage in ("arms", "star", "trailing", "leading"):
        m = web[stage]
        assert np.array_equal(m.node_sets["hub_tied"], tied)
        assert np.array_equal(m.node_pos[tied], m.node_ref[tied])
    # the frame's cables join tied nodes only: a rigid polygon
    frame = flat.elem_nodes[flat.elem_sets["hole_boundary"]]
    assert np.isin(frame, tied).all() and len(frame) == len(tied)


def test_star_is_projection_onto_frame(web):
    """Root region (l < l_c): the nearest point of the frame polygon, found independently;
    beyond: straight and radial from the frame corner, radius c / cos(pi/n) + l - l_c."""
    m, hole, n, c = web["star"], web["hole"], web["n"], web["c"]
    free = np.setdiff1d(np.arange(m.n_nodes), m.node_sets["hub_tied"])
    l = np.nan_to_num(m.node_arm_coord, nan=0.0)
    l_c = corner_coord(c, n)
    root = free[l[free] < l_c - 1e-9]
    near, _, inside, _ = _nearest_on_outline(m.node_ref[root, :2], hole, 0.0)
    assert not inside.any()
    assert np.abs(m.node_pos[root, :2] - near).max() < 1e-9
    out = free[l[free] >= l_c - 1e-9]
    psi = m.arm_root_angle[m.node_arm[out]]
    radius = c / math.cos(math.pi / n) + l[out] - l_c
    expect = radius[:, None] * np.column_stack([np.cos(psi), np.sin(psi)])
    assert np.abs(m.node_pos[out, :2] - expect).max() < 1e-9
    assert np.all(m.node_arm[out] >= 0)


def test_half_axes_collapse_onto_their_frame_points(web):
    m, n, c = web["star"], web["n"], web["c"]
    beta = m.arm_root_angle - math.pi / n
    for j, b in enumerate(beta):
        sel = m.node_sets["cross"]
        u = np.array([math.cos(b), math.sin(b)])
        mine = sel[m.node_ref[sel, :2] @ u > 0]
        mine = mine[np.abs(m.node_ref[mine, 0] * u[1] - m.node_ref[mine, 1] * u[0]) < 1e-6]
        assert np.allclose(m.node_pos[mine, :2], c * u, atol=1e-9)


def test_coil_geometry(web):
    for stage, w in (("trailing", 1), ("leading", -1)):
        m = web[stage]
        l0 = m.arm_root_coord
        sel = (m.node_arm >= 0) & (np.nan_to_num(m.node_arm_coord) >= l0)
        ang = m.arm_root_angle[m.node_arm[sel]] - w * (m.node_arm_coord[sel] - l0) / R0
        assert np.allclose(m.node_pos[sel, :2], R0 * np.column_stack([np.cos(ang), np.sin(ang)]),
                           atol=1e-9)
        # the spoke from the frame corner in to the rim, radial
        spoke = ((m.node_arm >= 0) & (np.nan_to_num(m.node_arm_coord) < l0)
                 & (np.nan_to_num(m.node_arm_coord) >= corner_coord(web["c"], web["n"])))
        r = np.hypot(m.node_pos[spoke, 0], m.node_pos[spoke, 1])
        assert np.allclose(r, R0 + l0 - m.node_arm_coord[spoke], atol=1e-9)


def test_masses(web):
    m, n = web["trailing"], web["n"]
    mu = RHO * RHO_A / (RHO * cable_length_per_area(web["top"], web["t"]))
    nm = lumped_mass(m, mu)
    assert nm.sum() == pytest.approx(mu * m.elem_rest_len.sum() + 10.0 * n, rel=1e-12)
    assert np.all(m.node_point_mass[m.node_sets["tips"]] == 10.0)
    per_arm = np.bincount(m.node_arm[m.node_arm >= 0], weights=nm[m.node_arm >= 0])
    _assert_symmetric(web["top"], per_arm, 1e-9)


@pytest.mark.parametrize("topology", TOPOLOGIES)
def test_eq7_and_mass_converge_first_order(topology):
    """Each arm's mass per unit arm coordinate approaches the Eq. 7 density (H = S/2,
    m_w / n per arm), deposited on a fixed 5 m grid, at first order in t; so does the
    web's cable mass to rho_A (A_web - A_hole) (the outline and hole cables are the
    O(t) excess)."""
    ts = (5.0, 2.5, 1.25, 0.625)
    n = _n_arms(topology)
    area = math.sqrt(3) / 4 * S * S if n == 3 else S * S
    rows = []
    for t in ts:
        c = outline_cutout(topology, S, t, R0)
        m = coil(star_fold(assign_arms(flat_other(topology, S, t, 1, 0.0, c, hole="outline"),
                                       R0)))
        mu = RHO_A / cable_length_per_area(topology, t)
        nm = lumped_mass(m, mu)
        hole = (3 * math.sqrt(3) if n == 3 else 4.0) * c * c
        rows.append((nm.sum() / (RHO_A * (area - hole)) - 1,
                     eq7_error(m, nm, RHO_A, c, beyond_root=True, h=5.0)))
    rows = np.array(rows)
    print(f"\n{topology}: " + ", ".join(f"t={t}: mass {r[0]:+.4f}, Eq.7 {r[1]:.4f}"
                                       for t, r in zip(ts, rows)))
    assert np.all(rows[:, 0] > 0)
    slope = np.polyfit(np.log(ts), np.log(rows[:, 1]), 1)[0]
    assert 0.8 < slope < 1.3, slope
    assert np.all(np.diff(rows[:, 1]) < 0)
    assert rows[-1, 1] < {"tritri": 0.011, "quadtri": 0.011}.get(topology, 0.06)


def test_eq7_reference_is_exact():
    """The hat-weighted reference (Gauss-Legendre split at the kink) sums to the integral
    of the density: rho_A cot(pi/n) (H^2 - l_c^2) + 2 rho_A cot(pi/n) l_c (H - l_c)."""
    for n, l_c, h in ((3, 7.22 * math.sqrt(3), 5.0), (3, 11.57, 2.5), (4, 7.5, 2.5)):
        l = np.arange(int(round(50.0 / h)) + 1) * h
        cot = 1 / math.tan(math.pi / n)
        exact = RHO_A * cot * ((50 - l_c) ** 2 + 2 * l_c * (50 - l_c))
        assert eq7_reference(l, h, 50.0, l_c, RHO_A, n).sum() == pytest.approx(exact, rel=1e-13)


def test_tritri_hole_sides_are_mesh_lines():
    """tritri rounds the hole out to mesh lines: no cable is cut, and the hole removes
    exactly the lattice nodes strictly inside it (counted on the web without a hole)."""
    t = 2.5
    c = outline_cutout("tritri", S, t, R0)
    assert c >= R0 and c == pytest.approx(S / (2 * math.sqrt(3)) - 10 * t * math.sqrt(3) / 2)
    full = flat_other("tritri", S, t, 1)
    holed = flat_other("tritri", S, t, 1, 0.0, c, hole="outline")
    assert np.allclose(holed.elem_rest_len, t, rtol=1e-12)             # nothing cut
    hole = outline_hole("tritri", S, c)
    _, dist, inside, _ = _nearest_on_outline(full.node_ref[:, :2], hole, 0.0)
    strictly = inside & (dist > 1e-9)
    assert holed.n_nodes == full.n_nodes - strictly.sum()
    # side 2 sqrt(3) c = 25 m: 10 mesh widths per side, 30 frame nodes
    assert len(holed.node_sets["hub_tied"]) == 30


@pytest.mark.parametrize("topology", TOPOLOGIES)
def test_build_mesh_star_from_a_case(topology):
    case = loads(f"[web]\ntopology = '{topology}'\nside = 20.0\nmesh_width = 1.0\n"
                 "[hub]\nradius = 1.0\n[time]\nend = 1.0\n")
    m = build_mesh(case)
    assert m.n_arms == _n_arms(topology) and m.wrap == 1 and tie_mode(m) == "frame"
    assert check_mesh(m) == []
    with pytest.raises(InputError) as e:
        build_mesh(loads(f"[web]\ntopology = '{topology}'\nside = 20.0\nmesh_width = 1.0\n"
                         "hub_cutout = 0.5\n[hub]\nradius = 1.0\n[time]\nend = 1.0\n"))
    assert e.value.key == "web.hub_cutout"
