"""Star fold and coil of the QuadQuad web (docs/mesh.md): invariants, geometry, Eq. 7."""

import math

import numpy as np
import pytest

from meshgen.build import build_mesh
from meshgen.checks import check_mesh, eq7_error
from meshgen.flat import area_from_areal_density, default_cutout, flat_quadquad
from meshgen.fold import assign_arms, coil, fold_web, star_fold
from meshgen.mesh import lumped_mass
from spinweb_fe.case import loads
from spinweb_fe.errors import InputError

RHO_A, RHO, R0 = 1.267e-2, 1540.0, 6.3
PSI = math.pi / 4 + np.arange(4) * math.pi / 2


def _web(t=2.5, k=1, side=100.0, r0=R0, corner=10.0):
    c = default_cutout(side, t, r0)
    return flat_quadquad(side, t, k, corner, c), c


@pytest.fixture(scope="module", params=[(2.5, 1), (2.5, 2), (5.0, 3), (1.0, 1)],
                ids=lambda p: f"t{p[0]}-k{p[1]}")
def stages(request):
    t, k = request.param
    flat, c = _web(t, k)
    arms = assign_arms(flat, R0)
    star = star_fold(arms)
    return dict(flat=flat, c=c, t=t, k=k, arms=arms, star=star,
                trailing=coil(star, "trailing"), leading=coil(star, "leading"))


@pytest.mark.parametrize("stage", ["arms", "star", "trailing", "leading"])
def test_invariants_every_stage(stages, stage):
    m = stages[stage]
    assert check_mesh(m) == []               # no stretched element, nobody inside the hub
    assert np.max(m.elem_length() / m.elem_rest_len) <= 1 + 1e-9
    r = np.hypot(m.node_pos[:, 0], m.node_pos[:, 1])
    assert r.min() >= R0 * (1 - 1e-9)
    flat = stages["flat"]                    # rest lengths and topology from the flat web
    assert np.array_equal(m.elem_rest_len, flat.elem_rest_len)
    assert np.array_equal(m.elem_nodes, flat.elem_nodes)
    assert np.array_equal(m.node_ref, flat.node_pos)
    assert np.array_equal(m.node_point_mass, flat.node_point_mass)
    assert np.all(m.node_pos[:, 2] == 0.0)


def test_arm_metadata(stages):
    m, c = stages["trailing"], stages["c"]
    assert m.n_arms == 4 and np.allclose(m.arm_root_angle, PSI)
    assert (m.arm_length, m.arm_root_coord, m.hub_radius, m.wrap) == (50.0, c, R0, 1)
    assert stages["leading"].wrap == -1 and stages["arms"].wrap == 0
    cross = m.node_sets["cross"]
    assert np.all(m.node_arm[cross] == -1) and np.all(np.isnan(m.node_arm_coord[cross]))
    arm = m.node_arm >= 0
    assert np.all(m.node_arm_coord[arm] >= 0) and np.all(m.node_arm_coord[arm] <= 50.0)
    tips = m.node_sets["tips"]
    assert np.array_equal(m.node_arm[tips], np.arange(4))
    assert np.allclose(m.node_arm_coord[tips], 50.0)


def test_tied_nodes(stages):
    c = stages["c"]
    for name in ("arms", "star", "trailing", "leading"):
        m = stages[name]
        tied = m.node_sets["hub_tied"]
        beta = np.arange(4) * math.pi / 2
        assert np.allclose(m.node_ref[tied, :2], c * np.column_stack([np.cos(beta), np.sin(beta)]),
                           atol=1e-12)
        # at t = 0 the hub frame is the global frame: same position folded and flat
        assert np.array_equal(m.node_pos[tied], m.node_ref[tied])
        assert np.all(np.hypot(*m.node_pos[tied, :2].T) >= R0)


def test_cross_halves_gathered_at_ties(stages):
    m = stages["trailing"]
    ref, pos = m.node_ref, m.node_pos
    for j, node in enumerate(m.node_sets["hub_tied"]):
        beta = j * math.pi / 2
        on_half = np.flatnonzero(
            (np.abs(ref[:, 0] * math.sin(beta) - ref[:, 1] * math.cos(beta)) < 1e-9)
            & (ref[:, 0] * math.cos(beta) + ref[:, 1] * math.sin(beta) > 0))
        assert np.allclose(pos[on_half], pos[node], atol=1e-12)
    assert len(m.node_sets["cross"]) == 4 * (round((50 - stages["c"]) / stages["t"]) * stages["k"] + 1)


def test_equal_arm_coordinate_coincides_beyond_root(stages):
    """Every node with the same (arm, l >= c) sits at one point: the concertina."""
    m, c = stages["trailing"], stages["c"]
    key_l = np.round(np.nan_to_num(m.node_arm_coord, nan=-1.0) / stages["t"] * stages["k"])
    for k in range(4):
        sel = (m.node_arm == k) & (m.node_arm_coord >= c)
        for lval in np.unique(key_l[sel])[:: max(1, len(np.unique(key_l[sel])) // 7)]:
            pts = m.node_pos[sel & (key_l == lval)]
            assert np.ptp(pts, axis=0).max() < 1e-9


def test_coil_geometry(stages):
    c = stages["c"]
    for name, w in (("trailing", 1), ("leading", -1)):
        m = stages[name]
        sel = (m.node_arm >= 0) & (m.node_arm_coord >= c)
        ang = m.arm_root_angle[m.node_arm[sel]] - w * (m.node_arm_coord[sel] - c) / R0
        assert np.allclose(m.node_pos[sel, :2], R0 * np.column_stack([np.cos(ang), np.sin(ang)]),
                           atol=1e-12)
        tips = m.node_pos[m.node_sets["tips"]]
        tip_ang = np.arctan2(tips[:, 1], tips[:, 0])
        d = (tip_ang - (PSI - w * (50.0 - c) / R0) + math.pi) % (2 * math.pi) - math.pi
        assert np.allclose(d, 0, atol=1e-12)


def test_star_arms_straight_and_radial(stages):
    m, c = stages["star"], stages["c"]
    sel = (m.node_arm >= 0) & (m.node_arm_coord >= c)
    k = m.node_arm[sel]
    r = R0 + m.node_arm_coord[sel] - c
    assert np.allclose(m.node_pos[sel, :2],
                       r[:, None] * np.column_stack([np.cos(PSI[k]), np.sin(PSI[k])]), atol=1e-12)
    root = m.node_sets["root_region"]            # legs: between the rim and the tie radius
    rr = np.hypot(*m.node_pos[root, :2].T)
    assert np.all((rr >= R0 * (1 - 1e-12)) & (rr <= c * (1 + 1e-12)))


def test_flat_pattern_keeps_positions():
    flat, c = _web(2.5, 2)
    m = fold_web(flat, R0, "flat")
    assert np.array_equal(m.node_pos, m.node_ref)
    assert m.wrap == 0 and len(m.node_sets["hub_tied"]) == 4 and check_mesh(m) == []


def test_web_mass_and_total_mass():
    m, c = _web(2.5, 1)
    m = fold_web(m, R0, "star", "trailing")
    mu = RHO * area_from_areal_density("quadquad", RHO_A, 2.5, RHO)
    nm = lumped_mass(m, mu)
    assert math.isclose(nm.sum(), mu * m.elem_rest_len.sum() + 40.0, rel_tol=1e-12)
    cable = nm - m.node_point_mass
    # documented cut-out: rho_A (S^2 - (2c)^2), plus the half strips of the edge lines
    assert math.isclose(cable.sum(), RHO_A * (100 ** 2 - (2 * c) ** 2) * (1 + 2.5 / (100 - 2 * c)),
                        rel_tol=1e-12)
    per_arm = [cable[m.node_arm == k].sum() for k in range(4)]
    assert np.allclose(per_arm, per_arm[0], rtol=1e-12)     # 4-fold symmetry


@pytest.mark.parametrize("k", [1, 2])
def test_eq7_convergence(k):
    """The arms' mass per unit arm coordinate approaches rho_L = 2 rho_A (a - l) (Eq. 7,
    l >= c; constant 2 rho_A (a - c) in the gathered root region) at first order in t."""
    ts = (5.0, 2.5, 1.25, 0.625)
    errs = []
    for t in ts:
        flat, c = _web(t, k, corner=0.0)
        m = fold_web(flat, R0, "star", "trailing")
        mu = RHO * area_from_areal_density("quadquad", RHO_A, t, RHO)
        nm = lumped_mass(m, mu)
        errs.append((eq7_error(m, nm, RHO_A, c), eq7_error(m, nm, RHO_A, c, beyond_root=True)))
    errs = np.array(errs)   # columns: vs the exact density, vs Eq. 7 on l >= c
    print(f"\nEq. 7 error, k = {k}: " + ", ".join(
        f"t={t}: {e[0]:.3e} / {e[1]:.3e}" for t, e in zip(ts, errs)))
    assert np.all(np.diff(errs, axis=0) < 0)                 # decreases as t shrinks
    slope = np.polyfit(np.log(ts), np.log(errs[:, 1]), 1)[0]
    assert 0.9 < slope < 1.2                                  # first order
    assert errs[-1, 1] < 0.01                                 # < 1 % at t = 0.625 m


def test_mass_fractions_paper_web():
    """Mass in the gathered root region (0 < l < c), on the line l = c and on the cross.

    Continuum: the region 0 <= l <= c holds 8 (a - c) c / (S^2 - 4 c^2) = 0.2609 of the web;
    the cross (measure zero) holds O(t)."""
    flat, c = _web(2.5, 1, corner=0.0)
    m = fold_web(flat, R0, "star", "trailing")
    nm = lumped_mass(m, RHO * area_from_areal_density("quadquad", RHO_A, 2.5, RHO))
    tot = nm.sum()
    cross = nm[m.node_sets["cross"]].sum() / tot
    root = nm[m.node_sets["root_region"]].sum() / tot
    on_c = nm[(m.node_arm >= 0) & (np.abs(m.node_arm_coord - c) < 1e-9)].sum() / tot
    print(f"\npaper web: cross {cross:.4f}, 0<l<c {root:.4f}, l=c {on_c:.4f}")
    assert math.isclose(cross, 0.0435, abs_tol=5e-4)
    assert math.isclose(root, 0.1739, abs_tol=5e-4)
    assert math.isclose(root + on_c, 8 * (50 - c) * c / (100 ** 2 - 4 * c * c), abs_tol=0.005)


def test_star_fold_rejects_bad_webs():
    odd = flat_quadquad(21.0, 1.0, 1, 0.0, 1.5)
    with pytest.raises(ValueError, match="even"):
        assign_arms(odd, 1.0)
    flat = flat_quadquad(20.0, 1.0, 1, 0.0, 1.0)
    with pytest.raises(ValueError, match="smaller than the hub radius"):
        assign_arms(flat, 2.0)
    with pytest.raises(ValueError, match="quadquad only"):
        star_fold(flat)


def test_build_mesh_maps_errors_to_case_keys():
    base = "[web]\nside = 20.0\nmesh_width = 1.0\n[hub]\nradius = 1.0\n[time]\nend = 1.0\n"
    m = build_mesh(loads(base))
    assert m.n_arms == 4 and m.wrap == 1
    with pytest.raises(InputError) as e:
        build_mesh(loads(base, ["web.side=21.0"]))
    assert e.value.key == "web.mesh_width"
    with pytest.raises(InputError) as e:
        build_mesh(loads(base, ["web.hub_cutout=0.5", "web.mesh_width=0.5"]))
    assert e.value.key == "web.hub_cutout"
    with pytest.raises(InputError) as e:
        build_mesh(loads(base, ["web.topology=tritri"]))
    assert e.value.key == "fold.pattern" and "quadquad only" in e.value.reason


def test_root_legs_two_points_per_coordinate(stages):
    """In 0 < l < c each arm coordinate holds exactly two points: one per leg."""
    m, c = stages["trailing"], stages["c"]
    root = m.node_sets["root_region"]
    key = np.round(m.node_arm_coord[root] / stages["t"] * stages["k"])
    for k in range(4):
        for lval in np.unique(key[m.node_arm[root] == k]):
            sel = root[(m.node_arm[root] == k) & (key == lval)]
            assert len(np.unique(np.round(m.node_pos[sel], 9), axis=0)) == (2 if lval else 1)


@pytest.mark.parametrize("topology", ["tritri", "trihex", "quadtri", "quadhex"])
def test_build_other_topologies_flat(topology):
    pytest.importorskip("meshgen.topologies")
    case = loads(f"[web]\ntopology = '{topology}'\nside = 20.0\nmesh_width = 1.0\n"
                 "[hub]\nradius = 1.0\n[fold]\npattern = 'flat'\n[time]\nend = 1.0\n")
    m = build_mesh(case)
    assert len(m.node_sets["hub_tied"]) > 0 and m.hub_radius == 1.0
    assert np.array_equal(m.node_pos, m.node_ref) and check_mesh(m) == []
