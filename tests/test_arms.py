"""Arm measures (L, phi, omega_tip) against geometry built by hand."""

import math

import numpy as np
import pytest

from spinweb_fe.case.scene import build_mesh
from meshgen.tethers import tethers
from spinweb_fe import case as case_mod
from spinweb_fe.record.arms import ArmTracker, arm_probes, deployed_length

R0, H, M = 6.3, 50.0, 50


def measure(mesh, pos, vel=None, hub_angle=0.0):
    tr = ArmTracker(mesh, R0)
    p = pos[tr.probes][None]
    v = np.zeros_like(p) if vel is None else vel[tr.probes][None]
    L, phi, w = tr.update(p, v, np.array([hub_angle]))
    return L[0], phi[0], w[0]


def test_deployed_lengths():
    assert np.allclose(deployed_length(tethers(4, H, M, R0, 10.0, "coiled")), H)
    case = case_mod.load("cases/paper_free_web.toml")
    assert np.allclose(deployed_length(build_mesh(case)), 50 * math.sqrt(2) - R0)


@pytest.mark.parametrize("wrap,sign", [("trailing", -1), ("leading", 1)])
def test_fully_coiled_tethers(wrap, sign):
    mesh = tethers(4, H, M, R0, 10.0, "coiled", wrap)
    L, phi, _ = measure(mesh, mesh.node_pos)
    assert np.allclose(L, 0.0, atol=1e-9)
    assert np.allclose(phi, sign * (math.pi / 2 + H / R0))


def test_straight_tether_swung_by_an_angle_and_tip_rate():
    """A straight tether from its root at angle beta from the radial: L = H, phi = beta; a
    rigid rotation at omega gives omega_tip = omega."""
    mesh = tethers(1, H, M, R0, 10.0, "straight")
    beta = 0.4
    s = np.arange(M + 1) * H / M
    pos = np.zeros((M + 1, 3))
    pos[:, 0] = R0 + s * math.cos(beta)
    pos[:, 1] = s * math.sin(beta)
    w = 3.0
    vel = np.column_stack([-w * pos[:, 1], w * pos[:, 0], np.zeros(M + 1)])
    L, phi, wt = measure(mesh, pos, vel)
    assert L[0] == pytest.approx(H) and phi[0] == pytest.approx(beta) and wt[0] == pytest.approx(w)


def test_partly_wound_tether_leaves_the_rim_tangentially():
    """Wound over alpha (trailing), straight tangent for the rest: L = H - r0 alpha,
    phi = -(pi/2 + alpha), to the discretisation of the spine (one element)."""
    mesh = tethers(1, H, M, R0, 10.0, "straight")
    alpha = 3.0
    s = np.arange(M + 1) * H / M
    pos = np.zeros((M + 1, 3))
    wound = s <= R0 * alpha
    pos[wound, 0] = R0 * np.cos(-s[wound] / R0)
    pos[wound, 1] = R0 * np.sin(-s[wound] / R0)
    d = np.array([R0 * math.cos(-alpha), R0 * math.sin(-alpha)])
    t = np.array([math.sin(-alpha), -math.cos(-alpha)])  # clockwise tangent at the departure
    pos[~wound, :2] = d + np.outer(s[~wound] - R0 * alpha, t)
    L, phi, _ = measure(mesh, pos)
    assert L[0] == pytest.approx(H - R0 * alpha, rel=1e-9)
    assert phi[0] == pytest.approx(-(math.pi / 2 + alpha), abs=1e-5)


def test_free_arm_angle_is_continuous_past_pi():
    """An arm swinging round behind its root keeps counting (no jump at +-pi)."""
    mesh = tethers(1, H, M, R0, 10.0, "straight")
    tr = ArmTracker(mesh, R0)
    angles = np.linspace(2.8, 3.6, 9)
    rows = []
    for b in angles:  # only the tip matters while nothing touches the hub: put every probe there
        tip = np.array([R0 + H * math.cos(b), H * math.sin(b), 0.0])
        rows.append(np.tile(tip, (len(tr.probes), 1)))
    p = np.array(rows)
    _, phi, _ = tr.update(p, np.zeros_like(p), np.zeros(len(angles)))
    assert np.allclose(phi[:, 0], angles)


@pytest.mark.parametrize("case", ["paper_free_web.toml", "tri_ramp_web.toml"])
def test_web_spine_lies_on_the_outline(case):
    """A web's spine probes are outline nodes (the arm's taut edges), one level per outline
    arm coordinate from the coil root to the tip, no gap wider than an element: in the
    triangular mesh the interior levels, slack concertina points, are left out."""
    from pathlib import Path

    from meshgen.fold import half_axes

    mesh = build_mesh(case_mod.load(Path(__file__).resolve().parents[1] / "cases" / case))
    probes, s_arm, s_lev, s_coord = arm_probes(mesh)
    spine = probes[mesh.n_arms:]
    gauge = np.max(mesh.node_ref[:, :2] @ half_axes(mesh.arm_root_angle).T, axis=1)
    assert np.allclose(gauge[spine], gauge.max(), rtol=1e-9)
    for k in range(mesh.n_arms):
        lev = np.unique(s_coord[s_arm == k])
        assert 0.0 <= lev[0] <= mesh.elem_rest_len.max() + 1e-9   # first level past the root
        assert lev[-1] == pytest.approx(mesh.arm_length - mesh.arm_root_coord, rel=1e-9)
        assert np.max(np.diff(lev)) <= mesh.elem_rest_len.max() + 1e-9
