"""Flat QuadQuad web: counts against closed forms, cut-out, masses and the area rule."""

import math

import numpy as np
import pytest

from meshgen.checks import check_mesh
from meshgen.build import flat_web
from meshgen.flat import default_cutout, effective_cutout, flat_quadquad
from meshgen.mesh import lumped_mass
from meshgen.registry import area_from_areal_density

RHO_A, RHO = 1.267e-2, 1540.0


def test_paper_grid_counts():
    m = flat_quadquad(100.0, 2.5)
    assert (m.n_nodes, m.n_elems) == (41 * 41, 3280)
    assert check_mesh(m) == []
    assert np.array_equal(m.node_pos, m.node_ref)
    assert np.allclose(m.elem_length(), 2.5, rtol=1e-12)


def _closed_form(side, t, k, c):
    n = round(side / t)
    q = 0 if c == 0 else int(round(2 * c / t)) - 1   # grid lines strictly inside the cut-out
    n_seg = 2 * n * (n + 1) - 2 * q * (q + 1)
    return (n + 1) ** 2 - q ** 2 + (k - 1) * n_seg, k * n_seg


@pytest.mark.parametrize("side, t, k, cut", [
    (100.0, 2.5, 1, 0.0), (100.0, 2.5, 1, 6.3), (100.0, 2.5, 3, 6.3), (20.0, 1.0, 2, 1.0),
    (20.0, 1.0, 1, 2.5), (21.0, 1.0, 2, 0.0), (21.0, 1.0, 2, 1.2), (12.0, 4.0, 4, 0.0)])
def test_counts_closed_form(side, t, k, cut):
    c = effective_cutout(side, t, cut)
    m = flat_quadquad(side, t, k, 0.0, cut)
    assert (m.n_nodes, m.n_elems) == _closed_form(side, t, k, c)
    assert check_mesh(m) == []
    # the hole boundary (tied to the hub by fold.ties = 'frame'): a loop of 8 c k / t nodes
    hole = m.node_sets["hole_boundary"]
    assert len(hole) == (round(8 * c * k / t) if c > 0 else 0)
    if c > 0:
        assert np.allclose(np.max(np.abs(m.node_ref[hole, :2]), axis=1), c, rtol=1e-12)
    assert np.allclose(m.elem_rest_len, t / k, rtol=1e-12)
    xy = m.node_ref[:, :2]
    assert np.all(np.max(np.abs(xy), axis=1) >= c - 1e-9)   # nothing inside the cut-out


def test_cutout_rounding():
    assert default_cutout(100.0, 2.5, 6.3) == 7.5             # t * ceil(r0 / t)
    assert effective_cutout(100.0, 2.5, 7.5) == 7.5
    assert effective_cutout(20.0, 1.0, 1.0) == 1.0
    assert effective_cutout(21.0, 1.0, 1.2) == 1.5            # odd N: lines at half-integers
    assert effective_cutout(100.0, 2.5, 0.0) == 0.0
    with pytest.raises(ValueError, match="leaves no web"):
        effective_cutout(20.0, 1.0, 10.0)


@pytest.mark.parametrize("side, t", [(100.0, 3.0), (10.0, 10.0), (100.0, 2.4)])
def test_non_integer_ratio_rejected(side, t):
    with pytest.raises(ValueError, match="integer multiple"):
        flat_quadquad(side, t)


def test_corners_in_arm_order_and_point_mass():
    m = flat_quadquad(20.0, 2.0, 2, corner_mass=3.0, hub_cutout=2.0)
    tips = m.node_sets["tips"]
    assert np.array_equal(tips, m.node_sets["corners"])
    ang = np.arctan2(m.node_ref[tips, 1], m.node_ref[tips, 0]) % (2 * math.pi)
    assert np.allclose(ang, math.pi / 4 + np.arange(4) * math.pi / 2)
    assert m.node_point_mass.sum() == 12.0 and np.all(m.node_point_mass[tips] == 3.0)
    assert len(m.node_sets["boundary"]) == 4 * 10 * 2   # 4 N k nodes on the outer edge
    assert len(m.node_sets["hole_boundary"]) == 4 * 2 * 2
    assert len(m.elem_sets["boundary"]) == 4 * 10 * 2


@pytest.mark.parametrize("topology, factor", [
    ("quadquad", 2.0), ("quadtri", 2 * math.sqrt(3)), ("tritri", 2 * math.sqrt(3)),
    ("quadhex", 2 / math.sqrt(3)), ("trihex", 2 / math.sqrt(3))])
def test_area_rule(topology, factor):
    t = 2.5
    a = area_from_areal_density(topology, RHO_A, t, RHO)
    assert math.isclose(RHO * a * factor / t, RHO_A, rel_tol=1e-14)


def test_area_rule_paper_value():
    # rho_A t / (2 rho): close to the paper's 2.5/0.030 * 1.23e-7 = 1.025e-5 m^2
    a = area_from_areal_density("quadquad", RHO_A, 2.5, RHO)
    assert math.isclose(a, 1.0284090909e-5, rel_tol=1e-9)
    with pytest.raises(ValueError):
        area_from_areal_density("hexhex", RHO_A, 2.5, RHO)


@pytest.mark.parametrize("side, t, k, cut", [(100.0, 2.5, 1, 6.3), (100.0, 2.5, 2, 0.0),
                                             (20.0, 1.0, 3, 1.0), (40.0, 0.5, 1, 5.0)])
def test_web_mass_closed_form(side, t, k, cut):
    """Cable mass = rho_A (S^2 + S t - 4 c^2 + 2 c t) exactly: the outer edge lines and
    the cut-out's edge lines carry only half a strip of web, so the discrete web is
    heavier than rho_A (S^2 - 4 c^2) by the relative amount t / (S - 2 c)."""
    c = effective_cutout(side, t, cut)
    m = flat_quadquad(side, t, k, corner_mass=5.0, hub_cutout=cut)
    mu = RHO * area_from_areal_density("quadquad", RHO_A, t, RHO)
    nm = lumped_mass(m, mu)
    cable = nm.sum() - 20.0
    assert math.isclose(nm.sum(), mu * m.elem_rest_len.sum() + 20.0, rel_tol=1e-12)
    assert math.isclose(cable, RHO_A * (side ** 2 + side * t - 4 * c * c + 2 * c * t),
                        rel_tol=1e-12)
    ideal = RHO_A * (side ** 2 - 4 * c * c)
    assert math.isclose(cable / ideal - 1, t / (side - 2 * c), rel_tol=1e-9)


def test_flat_web_dispatch():
    m = flat_web("quadquad", 20.0, 1.0, 2, 1.0, 1.0)
    assert (m.n_nodes, m.n_elems) == _closed_form(20.0, 1.0, 2, 1.0)
