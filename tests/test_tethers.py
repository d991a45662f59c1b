"""Tether scenes: counts, roots on the rim, coiling without stretch."""

import math
from pathlib import Path

import numpy as np
import pytest

from meshgen.checks import check_mesh
from meshgen.tethers import tethers

H, R0 = 50.0, 6.3


@pytest.mark.parametrize("n, m", [(4, 50), (3, 7), (1, 1)])
def test_counts_and_roots(n, m):
    t = tethers(n, H, m, R0, 10.0, "straight")
    assert (t.n_nodes, t.n_elems, t.n_arms) == (n * (m + 1), n * m, n)
    roots, tips = t.node_sets["hub_tied"], t.node_sets["tips"]
    theta = 2 * math.pi * np.arange(n) / n
    assert np.allclose(t.node_pos[roots, :2], R0 * np.column_stack([np.cos(theta), np.sin(theta)]))
    assert np.allclose(np.hypot(*t.node_pos[tips, :2].T), R0 + H)
    assert np.allclose(t.elem_rest_len, H / m) and np.allclose(t.elem_length(), H / m)
    assert t.node_point_mass.sum() == 10.0 * n and np.all(t.node_point_mass[tips] == 10.0)
    assert np.array_equal(t.node_arm_coord[tips], np.full(n, H))
    assert (t.arm_length, t.arm_root_coord, t.hub_radius, t.wrap) == (H, 0.0, R0, 0)
    assert check_mesh(t) == []


@pytest.mark.parametrize("wrap, w", [("trailing", 1), ("leading", -1)])
def test_coiled(wrap, w):
    n, m = 4, 50
    t = tethers(n, H, m, R0, 10.0, "coiled", wrap)
    straight = tethers(n, H, m, R0, 10.0, "straight")
    assert check_mesh(t) == [] and t.wrap == w
    assert np.all(t.elem_length() <= t.elem_rest_len * (1 + 1e-12))   # slack, not stretched
    assert np.allclose(np.hypot(*t.node_pos[:, :2].T), R0)           # on the rim
    assert np.array_equal(t.node_ref, straight.node_pos)
    roots, tips = t.node_sets["hub_tied"], t.node_sets["tips"]
    assert np.array_equal(t.node_pos[roots], t.node_ref[roots])      # ties keep their place
    theta = 2 * math.pi * np.arange(n) / n
    tip_ang = np.arctan2(t.node_pos[tips, 1], t.node_pos[tips, 0])
    d = (tip_ang - (theta - w * H / R0) + math.pi) % (2 * math.pi) - math.pi
    assert np.allclose(d, 0, atol=1e-12)                              # -H/r0 when trailing


def test_invalid_arguments():
    with pytest.raises(ValueError, match="hub_radius"):
        tethers(4, H, 10, 0.0, 1.0)
    with pytest.raises(ValueError, match="pattern"):
        tethers(4, H, 10, R0, 1.0, "star")
    with pytest.raises(ValueError, match="wrap"):
        tethers(4, H, 10, R0, 1.0, "coiled", "sideways")


def test_eq7_tethers_carry_the_profiles_exact_masses():
    """tethers.arm_mass (the paper's Eq. 7 line density rho(s) = 2 m (H - s) / H^2): every
    element holds the exact integral of the profile over its length and each tether's cable
    sums to arm_mass (to round-off, 1e-12 relative; evaluating the density at an element's
    end instead of its middle is 2 % off in the sum and m L^2 / H^2 per element)."""
    from spinweb_fe import case as case_mod
    from spinweb_fe.case.scene import prepare

    case = case_mod.load(Path(__file__).parent.parent / "cases" / "paper_free_arms_eq7.toml",
                         ["tethers.elements=20"])
    mesh, model = prepare(case)[:2]
    m, H = case.tethers.arm_mass, mesh.arm_length
    s = mesh.node_arm_coord[mesh.elem_nodes]
    sa, sb = s.min(axis=1), s.max(axis=1)
    exact = 2.0 * m / H ** 2 * ((H * sb - 0.5 * sb ** 2) - (H * sa - 0.5 * sa ** 2))
    lumped = np.zeros(mesh.n_nodes)
    np.add.at(lumped, mesh.elem_nodes[:, 0], 0.5 * exact)
    np.add.at(lumped, mesh.elem_nodes[:, 1], 0.5 * exact)
    cable = model.nodes.mass - mesh.node_point_mass  # the point (tip) masses out
    assert np.allclose(cable, lumped, rtol=1e-12, atol=1e-12 * m)
    for arm in range(case.tethers.count):
        on_arm = mesh.node_arm == arm
        assert abs(cable[on_arm].sum() - m) < 1e-12 * m
