"""Robust designs (issue #43): Monte-Carlo members of the FE-verified points, the choice by
the low end of the pass rate's interval, the design file written carrying what it was
verified for, why no design exists, table entries searched by index."""

from __future__ import annotations

import json
import math
from pathlib import Path

import h5py
import pytest

from spinweb_fe.case.load import load as load_case
from spinweb_fe.cli import main
from spinweb_fe.errors import InputError
from spinweb_fe.sweep import design as ds
from spinweb_fe.sweep import verify as vf
from spinweb_fe.sweep.design import Point
from spinweb_fe.sweep.run import load_sweep

ROOT = Path(__file__).resolve().parents[1]
BASE = ROOT / "cases" / "paper_free_arms.toml"
ROBUST = f"""
title = "small tethers, robust"
base = "{BASE}"
law = "torque_feedback"
minimise = "peak_torque"
require = ["completed", "deployed", "recoil"]
members = 3
seed = 7
pass_rate = 0.2
candidates = 1
[search]
"control.M0" = [1e3, 1e7]
[set]
"tethers.length" = 5.0
"tethers.elements" = 10
"time.end" = 0.3
[tie]
"control.omega0" = "initial.omega"
[bounds]
peak_torque = 2e6
[random]
"perturbation.arm" = {{dist = "choice", values = [0, 1, 2, 3]}}
"perturbation.tip_mass_scale" = {{dist = "uniform", low = 0.97, high = 1.03}}
[fe]
"output.frame_dt" = 0.0
"""


def write(tmp_path, text, name="d.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_robust_design_end_to_end(tmp_path, capsys):
    """The members run in FE, their pass rate and interval are recorded and decide; the
    design.toml written requires what the design required and passes when run again; the
    design_check.toml is the members' sweep."""
    out = tmp_path / "out"
    assert main(["design", str(write(tmp_path, ROBUST)), "-o", str(out), "--workers", "1",
                 "--no-progress"]) == 0
    printed = capsys.readouterr().out
    assert "FE Monte-Carlo " in printed and "Monte-Carlo members pass" in printed
    doc = json.loads((out / "design.json").read_text())
    recs = [r for _, f, r in doc["verified"] if f["feasible"]]
    assert recs and all(r["members"] == 3 for r in recs)
    assert doc["chosen_robust"]["low"] >= 0.2 and doc["rate_met"] is True
    members = sorted((out / "members" / "fe").iterdir())
    assert len(members) == 3 * len(recs)
    case = load_case(out / "design.toml")
    assert case.verdict.require == ("completed", "deployed", "recoil")
    run_dir = tmp_path / "again"
    assert main(["run", str(out / "design.toml"), "-o", str(run_dir), "--no-progress"]) == 0
    with h5py.File(run_dir / "results.h5") as h5:
        assert h5.attrs["verdict"] == "pass"
    sweep = load_sweep(out / "design_check.toml")
    assert sweep.members == 3 and sweep.seed == 7
    assert {d.key for d in sweep.draws} == {"perturbation.arm", "perturbation.tip_mass_scale"}


def _pt(value, feasible, objective, margin=0.1, failed=()):
    return Point({"x": value}, "fe", feasible, margin, objective, {}, tuple(failed))


def test_the_choice_by_the_low_end_of_the_interval():
    pairs = [(_pt(1.0, True, 1.0), _pt(1.0, True, 1.0)),
             (_pt(2.0, True, 2.0), _pt(2.0, True, 2.0)),
             (_pt(3.0, True, 3.0), _pt(3.0, False, 3.0))]
    robust = {0: {"low": 0.3}, 1: {"low": 0.7}}
    (a, f), rec, met = vf.choose(pairs, robust, 0.6)
    assert a.values["x"] == 2.0 and met and rec["low"] == 0.7  # the best that is robust
    (a, f), rec, met = vf.choose(pairs, robust, 0.8)
    assert a.values["x"] == 2.0 and not met  # none robust enough: the most robust
    (a, f), rec, met = vf.choose(pairs)
    assert a.values["x"] == 1.0 and rec is None  # no members: the best objective
    assert vf.choose([(_pt(1, True, 1), _pt(1, False, 1))]) == (None, None, False)


def test_why_no_design_exists_in_physical_terms(tmp_path):
    d = ds.load_design(write(tmp_path, ROBUST))
    pts = [_pt(v, False, math.nan, -0.5, f) for v, f in
           ((1e3, ("recoil",)), (1e4, ("recoil",)), (1e5, ("deployed",)), (1e6, ("deployed",)))]
    for p in pts:
        p.values = {"control.M0": p.values["x"]}
        p.status = "ok"
    why, evidence = ds.diagnose(d, pts)
    assert why == ("control.M0 up to 1e+04: a tip falls back toward the hub (re-coil); "
                   "from 1e+05: the arms are not out for good")
    assert [(e["from"], e["to"], e["failed"]) for e in evidence] == [
        (1e3, 1e4, ["recoil"]), (1e5, 1e6, ["deployed"])]


def test_robust_file_errors(tmp_path):
    with pytest.raises(InputError, match="pass_rate"):
        ds.load_design(write(tmp_path, ROBUST.replace("members = 3\n", "").replace(
            "[random]\n", "[x]\n")))
    bad = ROBUST.replace('"control.M0" = [1e3, 1e7]', '"control.M0" = [1e3, 1e7]\n'
                         '"perturbation.tip_mass_scale" = [0.9, 1.1]')
    with pytest.raises(InputError, match="random.perturbation.tip_mass_scale"):
        ds.load_design(write(tmp_path, bad, "b.toml"))


def test_a_table_entry_is_searched_by_its_index(tmp_path):
    text = f"""
base = "{BASE}"
minimise = "deploy_time"
[search]
"stowage.payout_length.1.0" = [1.0, 3.0]
[set]
"stowage.payout" = "rate"
"stowage.payout_length" = [[0.0, 0.0], [2.0, 10.0], [6.0, 50.0]]
[bounds]
strength = true
"""
    d = ds.load_design(write(tmp_path, text))
    case = ds.build_case(d, {"stowage.payout_length.1.0": 1.5})
    assert case.stowage.payout_length == ((0.0, 0.0), (1.5, 10.0), (6.0, 50.0))
    with pytest.raises(InputError, match="not an index"):
        ds.build_case(d, {"stowage.payout_length.7.0": 1.5})
