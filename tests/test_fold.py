"""Star fold and coil of the QuadQuad web (docs/mesh.md): invariants, geometry, Eq. 7,
for both hub attachments (``ties = 'axes'``: 4 tied nodes; ``'frame'``: the whole hole
boundary, the default)."""

import math

import numpy as np
import pytest

from spinweb_fe.case.scene import build_mesh
from meshgen.checks import check_mesh, eq7_error
from meshgen.flat import default_cutout, flat_quadquad
from meshgen.fold import assign_arms, coil, fold_web, frame_lead_in, star_fold, tie_mode
from meshgen.mesh import lumped_mass
from meshgen.registry import area_from_areal_density
from spinweb_fe.case import loads
from spinweb_fe.errors import InputError
from closed_forms import quadquad_line_tensions

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
    arms = assign_arms(flat, R0, "axes")
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


@pytest.mark.parametrize("ties, n_tied", [("axes", 4), ("frame", 8 * 7.5 * 2 / 2.5)])
def test_flat_pattern_keeps_positions(ties, n_tied):
    flat, c = _web(2.5, 2)
    m = fold_web(flat, R0, "flat", ties=ties)
    assert np.array_equal(m.node_pos, m.node_ref)
    assert m.wrap == 0 and len(m.node_sets["hub_tied"]) == n_tied and check_mesh(m) == []
    assert tie_mode(m) == ties


@pytest.mark.parametrize("ties", ["frame", "axes"])
def test_web_mass_and_total_mass(ties):
    m, c = _web(2.5, 1)
    m = fold_web(m, R0, "star", "trailing", ties)
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
    m = fold_web(flat, R0, "star", "trailing", "axes")
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
        assign_arms(odd, 1.0, "axes")
    # the frame needs no mesh line on the half-axes: an odd grid folds too
    folded = coil(star_fold(assign_arms(odd, 1.0)))
    assert tie_mode(folded) == "frame" and check_mesh(folded) == []
    flat = flat_quadquad(20.0, 1.0, 1, 0.0, 1.0)
    with pytest.raises(ValueError, match="smaller than the hub radius"):
        assign_arms(flat, 2.0)
    with pytest.raises(ValueError, match="assign_arms"):
        star_fold(flat)


def test_build_mesh_maps_errors_to_case_keys():
    base = "[web]\nside = 20.0\nmesh_width = 1.0\n[hub]\nradius = 1.0\n[time]\nend = 1.0\n"
    m = build_mesh(loads(base))
    assert m.n_arms == 4 and m.wrap == 1
    assert tie_mode(m) == "frame" and len(m.node_sets["hub_tied"]) == 8   # the default
    assert tie_mode(build_mesh(loads(base, ["fold.ties='axes'"]))) == "axes"
    with pytest.raises(InputError) as e:
        loads(base, ["fold.ties='rim'"])
    assert e.value.key == "fold.ties"
    with pytest.raises(InputError) as e:
        build_mesh(loads(base, ["web.side=21.0", "fold.ties='axes'"]))
    assert e.value.key == "web.mesh_width"
    with pytest.raises(InputError) as e:
        build_mesh(loads(base, ["web.hub_cutout=0.5", "web.mesh_width=0.5"]))
    assert e.value.key == "web.hub_cutout"
    with pytest.raises(InputError) as e:
        build_mesh(loads(base, ["web.topology=tritri", "fold.ties='axes'"]))
    assert e.value.key == "fold.ties" and "square web" in e.value.reason


def test_root_legs_two_points_per_coordinate(stages):
    """In 0 < l < c each arm coordinate holds exactly two points: one per leg."""
    m = stages["trailing"]
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


# ---------------------------------------------------------------- ties = "frame" (default)
# (side, mesh width, elements per segment, hub radius): the paper web, a 20 m web (the
# demo's side at a finer mesh; cases/demo.toml has t = 2 m) and the Fig. 8 web (cases/analytic_fig8_*.toml, c = 5 m > r0 = 1 m)
FRAME_WEBS = [(100.0, 2.5, 1, R0), (100.0, 2.5, 2, R0), (20.0, 1.0, 1, 1.0),
              (20.0, 1.0, 2, 1.0), (100.0, 5.0, 1, 1.0), (100.0, 5.0, 3, R0)]


@pytest.fixture(scope="module", params=FRAME_WEBS,
                ids=lambda p: f"S{p[0]:g}-t{p[1]:g}-k{p[2]}-r{p[3]:g}")
def frame(request):
    side, t, k, r0 = request.param
    c = default_cutout(side, t, r0)
    flat = flat_quadquad(side, t, k, 10.0, c)
    arms = assign_arms(flat, r0)                      # default: frame
    star = star_fold(arms)
    return dict(flat=flat, c=c, t=t, k=k, r0=r0, a=side / 2, arms=arms, star=star,
                trailing=coil(star, "trailing"), leading=coil(star, "leading"),
                d0=frame_lead_in(c, r0))


def _local(xy, k):
    """Quadrant-k local coordinates (x', y') = R(-k pi/2) (x, y) of (p, 2) points."""
    ang = -k * math.pi / 2
    ca, sa = np.cos(ang), np.sin(ang)
    return np.column_stack([ca * xy[:, 0] - sa * xy[:, 1], sa * xy[:, 0] + ca * xy[:, 1]])


@pytest.mark.parametrize("stage", ["arms", "star", "trailing", "leading"])
def test_frame_invariants_every_stage(frame, stage):
    m, r0 = frame[stage], frame["r0"]
    assert tie_mode(m) == "frame"
    assert check_mesh(m) == []               # no stretched element, nobody inside the hub
    assert np.max(m.elem_length() / m.elem_rest_len) <= 1 + 1e-9
    tied = np.zeros(m.n_nodes, bool)
    tied[m.node_sets["hub_tied"]] = True
    r = np.hypot(m.node_pos[:, 0], m.node_pos[:, 1])
    assert r[~tied].min() >= r0 * (1 - 1e-9) and r[tied].min() >= frame["c"] * (1 - 1e-12)
    flat = frame["flat"]
    assert np.array_equal(m.elem_rest_len, flat.elem_rest_len)
    assert np.array_equal(m.elem_nodes, flat.elem_nodes)
    assert np.array_equal(m.node_ref, flat.node_pos)
    assert np.array_equal(m.node_point_mass, flat.node_point_mass)
    assert np.all(m.node_pos[:, 2] == 0.0)


def test_frame_tied_nodes(frame):
    """The whole square loop max(|x|, |y|) = c (subdivision nodes included, 8 c k / t
    nodes) is tied and keeps its flat position in every state."""
    c, t, k = frame["c"], frame["t"], frame["k"]
    tied = frame["arms"].node_sets["hub_tied"]
    loop = np.flatnonzero(np.abs(np.max(np.abs(frame["flat"].node_ref[:, :2]), axis=1) - c)
                          < 1e-9)
    assert np.array_equal(np.sort(tied), loop)
    assert np.array_equal(np.sort(tied), np.sort(frame["flat"].node_sets["hole_boundary"]))
    assert len(tied) == round(8 * c * k / t)
    for name in ("arms", "star", "trailing", "leading"):
        m = frame[name]
        assert np.array_equal(m.node_sets["hub_tied"], tied)
        assert np.array_equal(m.node_pos[tied], m.node_ref[tied])


def test_frame_metadata(frame):
    c, d0, r0, a = frame["c"], frame["d0"], frame["r0"], frame["a"]
    assert d0 == pytest.approx(c * math.sqrt(2) - r0, rel=1e-15) and d0 > 0
    m = frame["trailing"]
    assert np.allclose(m.arm_root_angle, PSI)
    assert (m.arm_length, m.hub_radius, m.wrap) == (a, r0, 1)
    assert m.arm_root_coord == pytest.approx(c + d0, rel=1e-15)
    assert frame["leading"].wrap == -1 and frame["arms"].wrap == 0
    # the fold map's arm coordinate is the flat one
    assert np.array_equal(m.node_arm_coord, frame["arms"].node_arm_coord, equal_nan=True)


def test_frame_strips_gathered_on_frame(frame):
    """Leg nodes with l < c: local (x', l) with x' > l at the frame node (c, l), (l, y')
    with y' > l at (l, c); cross halves at their T_j; each sits on a tied frame node."""
    c = frame["c"]
    for name in ("star", "trailing", "leading"):
        m = frame[name]
        ref, pos = m.node_ref[:, :2], m.node_pos[:, :2]
        tied_pts = pos[m.node_sets["hub_tied"]]
        for k in range(4):
            sel = np.flatnonzero((m.node_arm == k) & (m.node_arm_coord < c - 1e-9))
            loc = _local(ref[sel], k)
            want = np.where((loc[:, 0] > loc[:, 1])[:, None],
                            np.column_stack([np.full(len(sel), c), loc[:, 1]]),
                            np.column_stack([loc[:, 0], np.full(len(sel), c)]))
            assert np.allclose(_local(pos[sel], k), want, atol=1e-12)
        gathered = np.concatenate([m.node_sets["root_region"], m.node_sets["cross"]])
        dist = np.abs(pos[gathered][:, None, :] - tied_pts[None]).max(axis=2).min(axis=1)
        assert dist.max() < 1e-12
        for j, beta in enumerate(np.arange(4) * math.pi / 2):
            on = np.flatnonzero((np.abs(ref[:, 0] * math.sin(beta) - ref[:, 1] * math.cos(beta))
                                 < 1e-9) & (ref[:, 0] * math.cos(beta) + ref[:, 1] * math.sin(beta) > 0))
            assert np.allclose(pos[on], c * np.array([math.cos(beta), math.sin(beta)]), atol=1e-12)


def test_frame_arm_map(frame):
    """l >= c: star -- radial from the frame corner, r = c sqrt2 + (l - c); coil -- radially
    in to the rim (r = c sqrt2 - (l - c)) for l < c + d0, then on the rim at
    psi_k - w (l - c - d0) / r0."""
    c, d0, r0, a = frame["c"], frame["d0"], frame["r0"], frame["a"]
    sq = c * math.sqrt(2)
    m = frame["star"]
    sel = (m.node_arm >= 0) & (m.node_arm_coord >= c)
    k, l = m.node_arm[sel], m.node_arm_coord[sel]
    u = np.column_stack([np.cos(PSI[k]), np.sin(PSI[k])])
    assert np.allclose(m.node_pos[sel, :2], (sq + l - c)[:, None] * u, atol=1e-12)
    for name, w in (("trailing", 1), ("leading", -1)):
        m = frame[name]
        spoke = l < c + d0
        assert np.allclose(m.node_pos[sel][spoke, :2], (sq - (l - c))[spoke, None] * u[spoke],
                           atol=1e-12)
        ang = PSI[k] - w * (l - c - d0) / r0
        rim = r0 * np.column_stack([np.cos(ang), np.sin(ang)])
        assert np.allclose(m.node_pos[sel][~spoke, :2], rim[~spoke], atol=1e-12)
        tips = m.node_pos[m.node_sets["tips"]]
        d = (np.arctan2(tips[:, 1], tips[:, 0]) - (PSI - w * (a - c - d0) / r0) + math.pi) \
            % (2 * math.pi) - math.pi
        assert np.allclose(d, 0, atol=1e-12)


def test_frame_mass_unchanged(frame):
    """The fold moves nodes only: the lumped masses (cable + corners) are those of the
    flat web, independent of the ties, and the 4 arms weigh the same."""
    mu = RHO * area_from_areal_density("quadquad", RHO_A, frame["t"], RHO)
    flat = lumped_mass(frame["flat"], mu)
    for name in ("arms", "star", "trailing", "leading"):
        assert np.array_equal(lumped_mass(frame[name], mu), flat)
    m = frame["trailing"]
    c, side, t = frame["c"], 2 * frame["a"], frame["t"]
    cable = flat.sum() - 40.0
    assert math.isclose(cable, RHO_A * (side ** 2 + side * t - 4 * c * c + 2 * c * t),
                        rel_tol=1e-12)
    per_arm = [flat[m.node_arm == k].sum() for k in range(4)]
    assert np.allclose(per_arm, per_arm[0], rtol=1e-12)


def test_frame_build_cases():
    """The shipped web cases build with the frame ties and pass check_mesh."""
    from pathlib import Path

    from spinweb_fe.case import load
    cases = Path(__file__).parent.parent / "cases"
    for name, c in (("demo.toml", 2.0), ("analytic_fig8_2pi.toml", 5.0),
                    ("paper_free_web.toml", 7.5)):
        m = build_mesh(load(cases / name))
        assert tie_mode(m) == "frame" and check_mesh(m) == []
        assert m.arm_root_coord == pytest.approx(c + frame_lead_in(c, m.hub_radius))


def test_frame_mass_fractions_paper_web():
    """Where the paper web's mass starts (docs/mesh.md section 2.5, frame ties)."""
    flat, c = _web(2.5, 1, corner=0.0)
    m = fold_web(flat, R0, "star", "trailing")
    nm = lumped_mass(m, RHO * area_from_areal_density("quadquad", RHO_A, 2.5, RHO))
    tot = nm.sum()
    arm, l = m.node_arm, m.node_arm_coord
    l0 = m.arm_root_coord
    parts = dict(tied=nm[m.node_sets["hub_tied"]].sum(),
                 cross=nm[m.node_sets["cross"]].sum(),
                 strips=nm[m.node_sets["root_region"]].sum(),
                 corner=nm[(arm >= 0) & (np.abs(l - c) < 1e-9)].sum(),
                 spoke=nm[(arm >= 0) & (l > c + 1e-9) & (l < l0)].sum(),
                 coil=nm[(arm >= 0) & (l >= l0)].sum())
    print("\npaper web, frame: " + ", ".join(f"{k} {v:.3f} kg ({v / tot:.4f})"
                                             for k, v in parts.items()))
    assert math.isclose(sum(v for k, v in parts.items() if k != "tied"), tot, rel_tol=1e-12)
    assert math.isclose(parts["cross"] / tot, 0.0435, abs_tol=5e-4)
    assert math.isclose(parts["strips"] / tot, 0.1739, abs_tol=5e-4)


@pytest.mark.parametrize("ties, ok", [("frame", True), ("axes", False)])
def test_prestress_paper_web_ties(ties, ok):
    """Force method on the flat paper web (t = 5 m, c = 10 m, the lines x, y = +-5 m end
    on the hole boundary): with the frame tied the spin load is carried in tension
    (prestressable); with the 4 axis nodes tied the rim must bow in (distorts)."""
    from spinweb_fe.linear.prestress import analyse

    flat, _ = _web(5.0, 1)
    m = fold_web(flat, R0, "flat", ties=ties)
    rep = analyse(m, 8 * math.pi, RHO * 1.025e-5, stability=False)
    assert rep.prestressable == ok and rep.load_compatible == ok
    if ok:
        assert rep.load_residual < 1e-12 and rep.min_force > 0
        # statically determinate: each mesh line carries the centrifugal pull of its own
        # nodes beyond the bar (tests/closed_forms.py), so min_force (3739 N, docs/mesh.md
        # 2.7: 3.74 kN) is the closed form's smallest bar force
        ref = quadquad_line_tensions(m, 8 * math.pi, RHO * 1.025e-5)[rep.bars]
        np.testing.assert_allclose(rep.tension, ref, rtol=1e-12)
        assert rep.min_force == pytest.approx(ref.min(), rel=1e-12)
        assert rep.min_force == pytest.approx(3739.0, rel=1e-3)
    else:
        assert rep.load_residual > 1e-2 and rep.node_residual_max > 1.0
