"""Tether scenes: counts, roots on the rim, coiling without stretch."""

import math

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
