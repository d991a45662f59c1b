"""Arm measures (L, phi, omega_tip) against geometry built by hand (docs/results.md)."""

import math

import numpy as np
import pytest

from meshgen.tethers import tethers
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import build_mesh
from spinweb_fe.fe.layout import ARM, named
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


def _tangent_tip(s_d, free):
    """Tip of a straight arm leaving a trailing coil (on R0, from angle 0) tangentially at
    arm coordinate s_d, free length ``free``."""
    th = -s_d / R0
    d = R0 * np.array([math.cos(th), math.sin(th)])
    return d + free * np.array([math.sin(th), -math.cos(th)])


def _pivot_tip(s_f, beta, length):
    """Tip of a straight arm from the rim point at arm coordinate s_f, at beta from the
    outward radial there (counter-clockwise positive)."""
    th = -s_f / R0
    radial = np.array([math.cos(th), math.sin(th)])
    ccw = np.array([-math.sin(th), math.cos(th)])
    return R0 * radial + length * (math.cos(beta) * radial + math.sin(beta) * ccw)


def test_held_coil_leaves_tangentially_within_one_level_of_its_front():
    """A held coil under a free payout departing tangentially at s_D = 20 m: alpha =
    s_D / r0, phi = -(pi/2 + alpha), L = H - s_D, whether the front is behind the departure
    point (19 m: released material still on the rim) or beyond it (21.5 m: the kink of the
    discrete chain at the front)."""
    mesh = tethers(1, H, M, R0, 10.0, "coiled", "trailing")
    for front in (19.0, 21.5):
        tr = ArmTracker(mesh, R0)
        tr.prev_ad[:] = 20.0 / R0
        row = np.array([[[front, front + 1.0, 1.0, 0.0, np.nan, 0.0, 0.0]]])
        L, phi, _, sd = tr.update(tip_rows([_tangent_tip(20.0, H - 20.0)]),
                                  np.zeros((1, 1, 3)), np.zeros(1), named(row, ARM))
        assert sd[0, 0] == pytest.approx(20.0, rel=1e-12)
        assert phi[0, 0] == pytest.approx(-(math.pi / 2 + 20.0 / R0), abs=1e-12)
        assert L[0, 0] == pytest.approx(H - 20.0, rel=1e-12)


def test_an_arm_hanging_from_its_front_pivots_about_it_and_wraps_over_its_coil():
    """An arm straight from a front F (s_F = 18 m) that a rate payout holds back, at
    beta = -1.2 rad from F's radial, pivots about F: phi = -alpha_F + beta, L its length;
    swung round to the other side (beta past +pi/2) it wraps over the held coil,
    counter-clockwise, continuously (the law no longer binding: the arm hangs on the
    leading side)."""
    mesh = tethers(1, H, M, R0, 10.0, "coiled", "trailing")
    tr = ArmTracker(mesh, R0)
    tr.prev_ad[:] = 18.0 / R0
    s_f, l = 18.0, 25.0
    row = np.array([[[s_f, 19.0, 1.0, 1.0, np.nan, 0.0, 0.0]]])
    L, phi, _, sd = tr.update(tip_rows([_pivot_tip(s_f, -1.2, l)]), np.zeros((1, 1, 3)),
                              np.zeros(1), named(row, ARM))
    assert sd[0, 0] == s_f and L[0, 0] == pytest.approx(l, rel=1e-12)
    assert phi[0, 0] == pytest.approx(-s_f / R0 - 1.2, abs=1e-12)
    betas = np.linspace(-1.2, 1.5, 28)  # swing to the other side ...
    rows = [_pivot_tip(s_f, b, l) for b in betas]
    th_f = -s_f / R0
    for a in np.linspace(0.0, 0.6, 13)[1:]:  # ... and wind on over the coil
        d = R0 * np.array([math.cos(th_f + a), math.sin(th_f + a)])
        rows.append(d + (l - R0 * a) * np.array([-math.sin(th_f + a), math.cos(th_f + a)]))
    T = len(rows)
    rows_t = np.repeat(row, T, axis=0)
    rows_t[betas.size:, 0, 3] = 0.0  # wound over the coil: the law does not bind there
    L, phi, _, _ = tr.update(tip_rows(rows), np.zeros((T, 1, 3)), np.zeros(T),
                             named(rows_t, ARM))
    np.testing.assert_allclose(phi[:28, 0], -s_f / R0 + betas, atol=1e-12)
    wound = np.linspace(0.0, 0.6, 13)[1:]
    np.testing.assert_allclose(phi[28:, 0], -s_f / R0 + math.pi / 2 + wound, atol=1e-9)
    np.testing.assert_allclose(L[28:, 0], l - R0 * wound, rtol=1e-9)


def test_payout_speed_is_not_a_difference_across_a_release(tmp_path):
    """The demo web's last two levels (2 m each) are released at once, 0.86-1.0 s: the
    difference of the paid-out length across them read 2 000-2 143 m/s. Now those rows are
    NaN (a jump, no speed; the earlier releases, measured by the arm's tangent point on
    the rim, stay continuous) and every other row is a speed the arm can have: below its
    tips' largest speed about the hub axis plus the rim's (about 13 m/s here; the largest
    payout speed 12.6 m/s)."""
    import h5py

    from spinweb_fe.cli import main

    out = tmp_path / "demo"
    assert main(["run", "cases/demo.toml", "-o", str(out), "--set", "time.end=1.1", "--set",
                 "output.frame_dt=0", "--no-progress"]) == 0
    with h5py.File(out / "results.h5") as h5:
        h = {k: h5["history"][k][()] for k in ("payout_speed", "payout_front", "tip_position",
                                                 "tip_omega", "hub_omega")}
    v, front = h["payout_speed"], h["payout_front"]
    jumped = np.abs(np.diff(front, axis=0)) >= 1.0  # a 2 m level in one row
    # the last releases of every arm (measured from the front, no longer from the
    # tangent point on the rim, which the earlier ones keep continuous)
    assert (np.isnan(v[1:]) & jumped).any(axis=0).all()
    r = np.hypot(h["tip_position"][..., 0], h["tip_position"][..., 1])
    bound = np.max(np.abs(h["tip_omega"]) * r) + 1.0 * np.max(np.abs(h["hub_omega"]))
    assert np.nanmax(np.abs(v)) < bound
    assert np.isnan(v).sum() <= 4 * v.shape[1]  # NaN only at the jumps
