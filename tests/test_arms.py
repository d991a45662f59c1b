"""Arm measures (L, phi, omega_tip) against geometry built by hand (docs/results.md)."""

import math

import numpy as np
import pytest

from meshgen.tethers import tethers
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import build_mesh
from spinweb_fe.record.arms import ArmTracker, deployed_length

R0, H, M = 6.3, 50.0, 50


def tip_rows(points):
    """(T, 1, 3) tip positions of one arm from a list of (x, y)."""
    return np.array([[[x, y, 0.0]] for x, y in points])


def free_tracker():
    return ArmTracker(tethers(1, H, M, R0, 10.0, "straight"), R0)


def test_deployed_lengths():
    assert np.allclose(deployed_length(tethers(4, H, M, R0, 10.0, "coiled")), H)
    case = case_mod.load("cases/paper_free_web.toml")
    assert np.allclose(deployed_length(build_mesh(case)), 50 * math.sqrt(2) - R0)


def test_straight_tether_swung_by_an_angle_and_tip_rate():
    """A straight tether from its root at angle beta from the radial: L = H, phi = beta; a
    rigid rotation at omega gives omega_tip = omega."""
    beta, w = 0.4, 3.0
    tip = np.array([R0 + H * math.cos(beta), H * math.sin(beta), 0.0])
    vel = np.array([-w * tip[1], w * tip[0], 0.0])
    L, phi, wt, _ = free_tracker().update(tip[None, None], vel[None, None], np.zeros(1))
    assert L[0, 0] == pytest.approx(H, rel=1e-12) and phi[0, 0] == pytest.approx(beta)
    assert wt[0, 0] == pytest.approx(w)


@pytest.mark.parametrize("c", [1.0, -1.0])
def test_wrapped_arm_leaves_the_rim_tangentially(c):
    """An arm wound over alpha (c = +1 clockwise) whose straight free part of length l leaves
    the rim tangentially: the tracker, following the arm as it winds on (a continuous swing
    from pivoting past the tangent at R), gives L = l and phi = -c (pi/2 + alpha)."""
    tr = free_tracker()
    l = 30.0
    rows = []
    for alpha in np.linspace(0.0, 4.0, 401):  # wound on from R, several rad
        th_d = -c * alpha
        d = R0 * np.array([math.cos(th_d), math.sin(th_d)])
        t = c * np.array([math.sin(th_d), -math.cos(th_d)])  # the coil's forward tangent
        rows.append(d + l * t)
    L, phi, _, _ = tr.update(tip_rows(rows), np.zeros((401, 1, 3)), np.zeros(401))
    alphas = np.linspace(0.0, 4.0, 401)
    np.testing.assert_allclose(L[:, 0], l, rtol=1e-9)
    np.testing.assert_allclose(phi[:, 0], -c * (math.pi / 2 + alphas), atol=1e-9)


def test_free_arm_angle_is_continuous_past_pi_when_the_root_is_off_the_hub():
    """Without a hub (r0 = 0: nothing to wind on) an arm swinging round keeps counting: no
    jump at +-pi."""
    tr = ArmTracker(tethers(1, H, M, R0, 10.0, "straight"), 0.0)
    angles = np.linspace(2.8, 3.6, 9)
    rows = [(H * math.cos(b), H * math.sin(b)) for b in angles]
    _, phi, _, _ = tr.update(tip_rows(rows), np.zeros((9, 1, 3)), np.zeros(9))
    assert np.allclose(phi[:, 0], angles)


def test_rewinding_the_other_way_is_continuous_and_unwinds_back():
    """A pivoting arm swung past +pi/2 winds on counter-clockwise (phi = +(pi/2 + alpha));
    swung back, it unwinds and pivots again: phi is continuous and returns to its values."""
    tr = free_tracker()
    l = 40.0
    path = []
    betas = np.linspace(0.0, math.pi / 2, 50)          # pivot from radial to the tangent
    path += [(R0 + l * math.cos(b), l * math.sin(b)) for b in betas]
    alphas = np.linspace(0.0, 1.0, 50)[1:]              # then wind on counter-clockwise
    for a in alphas:
        d = R0 * np.array([math.cos(a), math.sin(a)])
        t = np.array([-math.sin(a), math.cos(a)])
        path.append(tuple(d + (l - R0 * a) * t))
    path += path[::-1]                                  # and all the way back
    _, phi, _, _ = tr.update(tip_rows(path), np.zeros((len(path), 1, 3)), np.zeros(len(path)))
    phi = phi[:, 0]
    expect = np.concatenate([betas, math.pi / 2 + alphas])
    np.testing.assert_allclose(phi[:len(expect)], expect, atol=1e-9)
    np.testing.assert_allclose(phi[len(expect):], expect[::-1], atol=1e-9)


def test_coiled_start_is_fully_wound_and_memory_restores():
    """A coiled mesh starts wound over its whole coil; the memory carries every branch so a
    restarted tracker continues the same values."""
    mesh = tethers(4, H, M, R0, 10.0, "coiled", "trailing")
    tr = ArmTracker(mesh, R0)
    assert np.all(tr.prev_ad == pytest.approx(H / R0))
    path = []
    for a in np.linspace(H / R0, H / R0 - 0.5, 20):   # a little unwound, arm 0 only matters
        th = -a
        d = R0 * np.array([math.cos(th), math.sin(th)])
        t = np.array([math.sin(th), -math.cos(th)])
        path.append(d + (H - R0 * a) * t)
    p = np.repeat(tip_rows(path), 4, axis=1)
    v = np.zeros_like(p)
    L1, phi1, _, _ = tr.update(p[:10], v[:10], np.zeros(10))
    memory = tr.memory()
    L2, phi2, _, _ = tr.update(p[10:], v[10:], np.zeros(10))
    other = ArmTracker(mesh, R0)
    other.restore(memory)
    L3, phi3, _, _ = other.update(p[10:], v[10:], np.zeros(10))
    assert np.array_equal(phi2, phi3) and np.array_equal(L2, L3)
    assert phi1[0, 0] == pytest.approx(-(math.pi / 2 + H / R0), abs=1e-9)


@pytest.mark.parametrize("bound", [0.0, 1.0])
def test_held_coil_leaves_tangentially_or_pivots_about_a_front_held_back(bound):
    """A held coil departing tangentially at s_D = 20 m, beyond its front at 19 m (the
    released material still lies on the rim): alpha = s_D / r0, phi = -(pi/2 + alpha),
    L = H - s_D, whether or not a rate payout holds the front back. With
    the front at 18 m held back, the arm pivots about the front: an arm straight from F at
    beta = -1.2 rad from F's radial gives phi = -alpha_F + beta, L = its length."""
    mesh = tethers(1, H, M, R0, 10.0, "coiled", "trailing")
    tr = ArmTracker(mesh, R0)
    tr.prev_ad[:] = 20.0 / R0
    s_d = 20.0
    th = -s_d / R0
    d = R0 * np.array([math.cos(th), math.sin(th)])
    t = np.array([math.sin(th), -math.cos(th)])
    tip = d + (H - s_d) * t
    row = np.array([[[19.0, 20.0, 1.0, bound, np.nan]]])
    L, phi, _, sd = tr.update(tip_rows([tip]), np.zeros((1, 1, 3)), np.zeros(1), row)
    assert sd[0, 0] == pytest.approx(s_d, rel=1e-12)
    assert phi[0, 0] == pytest.approx(-(math.pi / 2 + s_d / R0), abs=1e-12)
    assert L[0, 0] == pytest.approx(H - s_d, rel=1e-12)
    s_f, beta, l = 18.0, -1.2, 25.0
    th_f = -s_f / R0
    radial = np.array([math.cos(th_f), math.sin(th_f)])
    ccw = np.array([-math.sin(th_f), math.cos(th_f)])
    tip2 = R0 * radial + l * (math.cos(beta) * radial + math.sin(beta) * ccw)
    row2 = np.array([[[s_f, 19.0, 1.0, bound, np.nan]]])
    L, phi, _, sd = tr.update(tip_rows([tip2]), np.zeros((1, 1, 3)), np.zeros(1), row2)
    if bound:
        assert sd[0, 0] == s_f and L[0, 0] == pytest.approx(l, rel=1e-12)
        assert phi[0, 0] == pytest.approx(-s_f / R0 + beta, abs=1e-12)
    else:  # free payout: the tangent from R, even behind the front
        assert sd[0, 0] < s_f and phi[0, 0] == pytest.approx(
            -(math.pi / 2 + (sd[0, 0] - 0.0) / R0), abs=1e-9)
