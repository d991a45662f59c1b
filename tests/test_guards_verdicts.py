"""Guards of the verdicts (issue #47): which arm and which time a failed criterion reports,
the swing's time inside its window, the severity that ranks Monte-Carlo members, and the
momentum audit of a free hub whose axis tilts. Histories built row by row, so that each
expected arm, time and value is worked out by hand (the docstrings say how); no run."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from spinweb_fe.record import verdict
from spinweb_fe.record.verdict import Criterion
from spinweb_fe.sweep.report import pass_rate

R0, REACH = 1.0, 6.0  # hub radius, a tip's deployed distance [m]: arms of 5 m
T = np.linspace(0.0, 1.0, 1001)  # rows every 1 ms


def history(radius, phi=None):
    """Two arms, tips along +x and -x at ``radius`` (T, 2) [m]; a hub at 10 rad/s, no
    torque, K and the energy constant (the audits pass)."""
    pos = np.zeros((len(T), 2, 3))
    pos[:, 0, 0], pos[:, 1, 0] = radius[:, 0], -radius[:, 1]
    zero = np.zeros(len(T))
    return {"time": T, "tip_position": pos, "hub_omega": zero + 10.0, "hub_angle": 10.0 * T,
            "hub_torque": zero, "angular_momentum": zero + 100.0,
            "arm_angle": np.zeros((len(T), 2)) if phi is None else phi,
            "arm_length": radius - R0, "kinetic_energy": zero + 1e3,
            "strain_energy": zero, "torque_work": zero}


def deployed_radius():
    """Both tips from the rim out to their reach by 0.31 s, then staying there (0.8 of the
    reach, 4.8 m, from 0.2356 s: the row 0.236 s)."""
    return R0 + (REACH - R0) * np.minimum(T / 0.31, 1.0)[:, None] * np.ones(2)


def judge(h, **kw):
    return {c.name: c for c in verdict.judge(h, np.full(2, REACH), R0, **kw)}


def first_row_above(t_star):
    """The first row time strictly after t_star [s] (rows every 1 ms)."""
    return float(T[np.argmax(T > t_star + 1e-12)])


def test_recoil_reports_the_arm_and_time_of_the_first_failure_not_the_worst_arm():
    """Arm 0 falls back 3 m (0.6 of its 5 m) linearly over 0.4-0.5 s, arm 1 falls back
    4.5 m (0.9) over 0.6-0.7 s. The limit 0.5 is first passed by arm 0 at 0.4 + 0.1 x
    2.5 / 3 = 0.48333 s (first row 0.484 s); the value is the worst share, arm 1's 0.9;
    the detail names arm 1 as the one that fell back farthest. Exact to the row."""
    r = deployed_radius()
    r[:, 0] -= 3.0 * np.clip((T - 0.4) / 0.1, 0.0, 1.0)
    r[:, 1] -= 4.5 * np.clip((T - 0.6) / 0.1, 0.0, 1.0)
    c = judge(history(r))["recoil"]
    assert c.passed is False
    assert c.arm == 0
    assert c.time == first_row_above(0.4 + 0.1 * 2.5 / 3.0)
    assert c.value == pytest.approx(0.9, rel=1e-12)
    assert c.detail.startswith("arm 1's tip fell back 4.5 m")


def test_the_swing_reports_its_time_inside_the_window_and_the_arm_that_first_left():
    """Deployed from row 236 (0.236 s): the swing window starts at row 236 +
    (1001 - 236) // 2 = 618, t = 0.618 s. Arm 1 swings at 0.35 rad (10 Hz) from 0.7 s,
    arm 0 at 0.5 rad from 0.9 s (both centred on 0). Worst: arm 0's 0.5 rad; the first
    row beyond the 0.3 rad limit is arm 1's, after 0.7 + asin(0.3 / 0.35) / (20 pi) s, a
    time of the run (not of the window: 0.099 s would be the same row counted from 0.618)."""
    phi = np.zeros((len(T), 2))
    phi[:, 1] = np.where(T >= 0.7, 0.35 * np.sin(20 * np.pi * (T - 0.7)), 0.0)
    phi[:, 0] = np.where(T >= 0.9, 0.5 * np.sin(20 * np.pi * (T - 0.9)), 0.0)
    c = judge(history(deployed_radius(), phi=phi))["swing"]
    assert c.passed is False
    assert c.value == pytest.approx(0.5, rel=1e-12)
    assert c.arm == 1
    assert c.time == first_row_above(0.7 + math.asin(0.3 / 0.35) / (20 * np.pi))
    assert "over t = 0.618 .. 1 s" in c.detail


def test_overstrain_reports_the_arm_of_the_first_row_above_one():
    """Utilisation 0.5 + t: above 1 from the row after 0.5 s (0.501 s), where the most
    strained element is on arm 1; from 0.8 s on arm 0 holds the largest strain. The
    criterion reports arm 1 at 0.501 s, the value the largest utilisation 1.5."""
    h = history(deployed_radius())
    h["utilisation"] = 0.5 + T
    h["max_strain_arm"] = np.where(T < 0.8, 1, 0)
    c = judge(h, failure_strain=0.03)["overstrain"]
    assert c.passed is False and c.arm == 1
    assert c.time == first_row_above(0.5)
    assert c.value == pytest.approx(1.5, rel=1e-12)


def test_severity_is_each_criterion_against_its_limit():
    """The worst of value / limit (limit / value for the deployed share, time / deploy_by
    for a late deployment), leaving out what does not apply and what is not required;
    infinite for a run that did not complete. Hand-worked: a good deployment (share 0.95
    against 0.8) ranks 0.8 / 0.95, below the 0.9 of a recoil of 0.45 against 0.5."""
    good = [Criterion("completed", True, 1.0, 1.0),
            Criterion("deployed", True, 0.95, 0.8),
            Criterion("recoil", True, 0.2, 0.5),
            Criterion("swing", None),
            Criterion("energy", True, 0.001, 0.02),
            Criterion("momentum", False, 5.0, 0.01, required=False)]
    assert verdict.severity(good) == pytest.approx(0.8 / 0.95, rel=1e-15)
    recoiled = good[:2] + [Criterion("recoil", True, 0.45, 0.5)] + good[3:]
    assert verdict.severity(recoiled) == pytest.approx(0.9, rel=1e-15)
    late = [Criterion("completed", True, 1.0, 1.0),
            Criterion("deployed", False, 3.0, 2.0, "s")]
    assert verdict.severity(late) == pytest.approx(1.5, rel=1e-15)
    short = [Criterion("completed", True, 1.0, 1.0), Criterion("deployed", False, 0.4, 0.8)]
    assert verdict.severity(short) == pytest.approx(2.0, rel=1e-15)
    stopped = [Criterion("completed", False, 0.5, 1.0)] + good[1:]
    assert verdict.severity(stopped) == math.inf
    tangled = [Criterion("tangled", False, 3.0, 0.0)]
    assert verdict.severity(tangled) == math.inf


def test_the_sweep_names_the_member_of_largest_severity_as_the_worst():
    """Four members: severities 0.84 (deploys well), 1.5, 0.3 and one that failed to run
    (worst of all when present). The worst is the failed run, then the 1.5 one; the
    interval and counts are the rows'."""
    sweep = SimpleNamespace(runs=[SimpleNamespace(name=f"m{i}") for i in range(4)],
                            source="mc.toml")
    rows = [{"status": "ok", "severity": 0.8 / 0.95, "passed": 1.0, "failed": ""},
            {"status": "ok", "severity": 1.5, "passed": 0.0, "failed": "deployed"},
            {"status": "ok", "severity": 0.3, "passed": 1.0, "failed": ""},
            {"status": "error", "severity": math.nan, "passed": 0.0, "failed": ""}]
    pr = pass_rate(sweep, rows)
    assert pr["worst"] == "m3" and pr["worst_severity"] == math.inf
    pr = pass_rate(sweep, rows, [0, 1, 2])
    assert pr["worst"] == "m1" and pr["worst_severity"] == 1.5
    assert pr["passes"] == 2 and pr["failed_counts"] == {"deployed": 1}
    assert pass_rate(sweep, rows, [0, 2])["worst"] == "m0"


def test_a_free_hubs_torque_impulse_counts_along_its_tilting_axis():
    """A free hub's axis tilts with a_z = 0.9 - 0.2 t (its x and y parts from the rest of
    the unit vector); a constant torque M = 40 N m about the axis gives K_z = K0 + M
    (0.9 t - 0.1 t^2). The rows' z parts integrate that exactly (a_z linear in t, the
    impulse linear in t per row), so the audit is at round-off (1e-13; measured 4e-16); a
    drift of 0.02 K0 t shows as 2 / 134 (max K = 100 + 40 x 0.8 + 2)."""
    az = 0.9 - 0.2 * T
    ax = np.sqrt(1.0 - az * az)
    axis = np.column_stack([0.6 * ax, 0.8 * ax, az])
    zero = np.zeros(len(T))
    h = {"time": T, "hub_torque": zero + 40.0, "hub_omega": zero + 3.0,
         "hub_angle": 3.0 * T, "hub_axis": axis,
         "angular_momentum": 100.0 + 40.0 * (0.9 * T - 0.1 * T * T)}
    assert verdict.momentum_error(h) < 1e-13
    h["angular_momentum"] = h["angular_momentum"] + 2.0 * T
    assert verdict.momentum_error(h) == pytest.approx(2.0 / 134.0, rel=1e-12)
