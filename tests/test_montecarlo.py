"""Monte-Carlo sweeps (sweep/draws.py): distributions drawn member by member, reproducibly;
the pass rate and its Wilson interval; the worst member run again alone; bad input."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from spinweb_fe.cli import main
from spinweb_fe.errors import InputError
from spinweb_fe.sweep import cluster, draws
from spinweb_fe.sweep import run as sw

ROOT = Path(__file__).resolve().parents[1]
TETHERS = ROOT / "cases" / "paper_free_arms.toml"
MC = ROOT / "cases" / "sweeps" / "montecarlo_feedback_web.toml"

# small feedback-law tethers (test_verdict's scene) with the feedback gain drawn around the
# least that deploys them: some members pass, some re-coil
SMALL = f"""
title = "small tethers, feedback gain drawn"
base = "{TETHERS}"
mode = "analytic"
members = {{members}}
seed = 7
[set]
tethers.length = 5.0
tethers.elements = 10
hub.radius = 1.0
time.end = 1.0
output.frame_dt = 0.0
control.law = "torque_feedback"
control.omega0 = 25.132741228718345
[random]
"control.M0" = {{{{dist = "uniform", low = 0.0, high = 2e4}}}}
"tip_mass.mass" = {{{{dist = "normal", mean = 10.0, std = 0.5, low = 9.0}}}}
"""


def sweep_file(tmp_path, members=12, name="mc.toml"):
    path = tmp_path / name
    path.write_text(SMALL.format(members=members))
    return path


def test_each_member_draws_its_own_values_whatever_the_count(tmp_path):
    few = sw.load_sweep(sweep_file(tmp_path, 4, "few.toml"))
    many = sw.load_sweep(sweep_file(tmp_path, 40, "many.toml"))
    assert [r.values for r in few.runs] == [r.values for r in many.runs[:4]]
    assert len({r.values["control.M0"] for r in many.runs}) == 40
    assert all(r.values["tip_mass.mass"] >= 9.0 for r in many.runs)  # the clip
    one = sw.load_sweep(sweep_file(tmp_path, 40, "many.toml"), only=[many.runs[17].name])
    assert [(r.name, r.values) for r in one.runs] == [(many.runs[17].name, many.runs[17].values)]
    assert sw.load_sweep(sweep_file(tmp_path, 40, "many.toml"), only=["17"]).runs == one.runs


def test_the_draws_follow_their_distributions():
    """4000 draws: means within 4 standard errors, the uniform inside its bounds and
    spread over them, every choice drawn with its share within 4 standard errors."""
    spec = {"random": {"a": {"dist": "normal", "mean": 3.0, "std": 2.0},
                       "b": {"dist": "uniform", "low": -1.0, "high": 5.0},
                       "c": {"dist": "choice", "values": [0, 1, 2, 3]}}, "members": 4000}
    n, seed, ds = draws.parse("x.toml", spec)
    vals = [draws.member_values(ds, seed, m) for m in range(n)]
    a = np.array([v["a"] for v in vals])
    b = np.array([v["b"] for v in vals])
    c = np.array([v["c"] for v in vals])
    assert abs(a.mean() - 3.0) < 4 * 2.0 / math.sqrt(n)
    assert a.std() == pytest.approx(2.0, rel=4 / math.sqrt(2 * n))
    assert b.min() >= -1.0 and b.max() <= 5.0
    assert abs(b.mean() - 2.0) < 4 * (6 / math.sqrt(12)) / math.sqrt(n)
    share = np.bincount(c, minlength=4) / n
    assert np.all(np.abs(share - 0.25) < 4 * math.sqrt(0.25 * 0.75 / n))


@pytest.mark.parametrize("passes, n, low, high", [
    (0, 10, 0.0, 0.2775), (10, 10, 0.7225, 1.0), (5, 10, 0.2366, 0.7634)])
def test_wilson_interval_against_its_tabulated_values(passes, n, low, high):
    lo, hi = draws.wilson(passes, n)
    assert lo == pytest.approx(low, abs=1e-4) and hi == pytest.approx(high, abs=1e-4)


@pytest.mark.parametrize("passes, n", [(30, 32), (1, 32), (17, 40)])
def test_wilson_bounds_are_the_roots_of_the_score_test(passes, n):
    """The rates p at which the score statistic (p_hat - p)^2 n / (p (1 - p)) equals
    z^2 (z = 1.96 for 95 %), found by root bracketing: a second method."""
    from scipy.optimize import brentq

    z, p_hat = 1.959963984540054, passes / n

    def score(p):
        return (p_hat - p) ** 2 * n - z * z * p * (1 - p)
    lo, hi = draws.wilson(passes, n)
    assert lo == pytest.approx(brentq(score, 1e-12, p_hat), abs=1e-10)
    assert hi == pytest.approx(brentq(score, p_hat, 1 - 1e-12), abs=1e-10)


@pytest.mark.parametrize("random, words", [
    ('"tip_mass.mass" = {dist = "gamma", shape = 2.0}', "unknown distribution 'gamma'"),
    ('"tip_mass.mass" = {dist = "normal", mean = 10.0, std = -1.0}', "std: must be >= 0"),
    ('"tip_mass.mass" = {dist = "normal", mean = 10.0}', "normal needs mean, std"),
    ('"tip_mass.mass" = {dist = "uniform", low = 2.0, high = 1.0}', "must be below high"),
    ('"tip_mass.mass" = {dist = "uniform", low = 0.0, hi = 1.0}', "not a parameter"),
    ('"perturbation.arm" = {dist = "choice", values = []}', "non-empty list"),
    ('"tip_mass.mass" = 3.0', "distribution table"),
    ('"tip_mass.mass" = {dist = "normal", mean = -10.0, std = 0.1}', "tip_mass.mass"),
    ('"control.omega0" = {dist = "uniform", low = 20.0, high = 30.0}', "one place"),
])
def test_bad_random_tables_exit_2_with_one_line(tmp_path, capsys, random, words):
    text = SMALL.format(members=4).split("[random]")[0] + "[random]\n" + random + "\n"
    if "one place" not in words:
        text = text.replace('control.law = "torque_feedback"\ncontrol.omega0 = '
                            '25.132741228718345\n', "")
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["sweep", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "out").exists()


def test_random_needs_members_and_members_needs_random(tmp_path):
    with pytest.raises(InputError, match="members"):
        draws.parse("x.toml", {"random": {"a": {"dist": "uniform", "low": 0, "high": 1}}})
    with pytest.raises(InputError, match="random"):
        draws.parse("x.toml", {"members": 3})
    with pytest.raises(InputError, match="members"):
        draws.parse("x.toml", {"members": 0, "random": {"a": {"dist": "choice",
                                                              "values": [1]}}})


def test_monte_carlo_sweep_reports_the_pass_rate_and_reruns_the_worst(tmp_path, capsys,
                                                                     monkeypatch):
    """12 members of the analytical model, in this process (a batch too small for a
    cluster's start: none starts): the printed pass rate is the members' own verdicts, the
    interval Wilson's, and the worst member named runs alone with the same draws and the
    same result."""
    def refuse(*_):
        raise AssertionError("a cluster was started")
    monkeypatch.setattr(cluster, "_start", refuse)
    path = sweep_file(tmp_path, 12)
    out = tmp_path / "out"
    assert main(["sweep", str(path), "-o", str(out), "--workers", "1", "--no-progress"]) == 0
    printed = capsys.readouterr().out
    with open(out / "summary.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    passed = [float(r["passed"]) for r in rows]
    k = int(sum(passed))
    assert 0 < k < 12, "the drawn gain should deploy some members and not others"
    lo, hi = draws.wilson(k, 12)
    assert f"verdicts: {k} of 12 Monte-Carlo members pass" in printed
    assert f"{100 * lo:.1f} .. {100 * hi:.1f} %" in printed
    for r in rows:  # a member fails exactly when its verdict names a failed criterion
        assert (float(r["passed"]) == 1.0) == (r["failed"] == "")
        with h5py.File(out / r["run_dir"] / "analytic.h5") as h5:
            assert h5.attrs["verdict"] == ("pass" if float(r["passed"]) else "fail")
    # the gain decides: every passing member has a larger M0 than every re-coiling one
    m0 = np.array([float(r["control.M0"]) for r in rows])
    ok = np.array(passed) == 1.0
    assert m0[ok].min() > m0[~ok].max()
    worst = max(rows, key=lambda r: float(r["severity"]))
    assert f"worst: {worst['name']}" in printed
    with h5py.File(out / "summary.h5") as h5:
        assert h5.attrs["passes"] == k and h5.attrs["members"] == 12
        assert h5.attrs["worst_run"] == worst["name"]
        rerun = h5.attrs["worst_rerun"]
    assert rerun.endswith(f"--only {worst['name']}")
    again = tmp_path / "again"
    assert main(["sweep", str(path), "--only", worst["name"], "-o", str(again),
                 "--workers", "1", "--no-progress"]) == 0
    with open(again / "summary.csv", newline="") as fh:
        (alone,) = list(csv.DictReader(fh))
    for key in ("control.M0", "tip_mass.mass", "severity", "failed", "deploy_time_s"):
        assert alone[key] == worst[key]


def test_the_shipped_monte_carlo_sweep_validates(capsys):
    assert main(["sweep", str(MC), "--dry-run"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("64 fe runs") and len(lines) == 65
    assert main(["sweep", str(MC), "--only", "nope", "--dry-run"]) == 2
