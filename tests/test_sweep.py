"""``spinweb sweep``: runs on a real Dask LocalCluster, summary rows, failures, bad input."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import h5py
import numpy as np
import pytest
from PIL import Image

from spinweb_fe.sweep import run as sw
from spinweb_fe.cli import main
from spinweb_fe.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "cases" / "sweeps" / "smoke.toml"
FINITE = ("peak_hub_torque_Nm", "final_hub_omega_rad_s", "max_tension_N", "wall_time_s")

# spin_ramp prescribes omega(0) = 0 but the base case starts at 8 pi rad/s: the case is
# valid, the solver rejects it when the run starts (a failure at run time, not up front)
REJECTED = """
[[runs]]
name = "free"

[[runs]]
name = "rejected"
control.law = "spin_ramp"
control.omega_max = 10.0
control.ramp_time = 0.1
"""


def smoke_with_failure(tmp_path) -> Path:
    """smoke.toml (two hub radii) x [[runs]] (free, rejected): 4 runs, 2 of them fail."""
    text = SMOKE.read_text().replace('base = "../paper_free_arms.toml"',
                                     f'base = "{ROOT / "cases" / "paper_free_arms.toml"}"')
    path = tmp_path / "smoke_fail.toml"
    path.write_text(text + REJECTED)
    return path


def read_csv(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def deploy_time_by_hand(h5path):
    """The first row from which every tip stays at least 0.8 of its flat distance from the
    axis to the end (the hub on a fixed axis at the origin; inf: never)."""
    with h5py.File(h5path) as h5:
        tips = h5["mesh/node_sets/tips"][()]
        reach = np.hypot(*h5["mesh/reference_points"][()][tips, :2].T)
        t, p = h5["history/time"][()], h5["history/tip_position"][()]
    out = [all(np.hypot(p[k, :, 0], p[k, :, 1]) >= 0.8 * reach) for k in range(len(t))]
    for k in range(len(t)):
        if all(out[k:]):
            return t[k]
    return math.inf


@pytest.fixture(scope="module")
def warm_numba_cache(tmp_path_factory):
    """One tiny FE run in this process first, so that the workers load the compiled kernels
    from numba's cache instead of compiling them twice at once."""
    out = tmp_path_factory.mktemp("warm")
    assert main(["run", str(ROOT / "cases" / "paper_free_arms.toml"), "-o", str(out),
                 "--set", "time.end=0.002", "--set", "output.frame_dt=0", "--no-progress"]) == 0


def test_sweep_on_a_local_cluster(tmp_path, capsys, warm_numba_cache):
    out = tmp_path / "sweep"
    rc = main(["sweep", str(smoke_with_failure(tmp_path)), "-o", str(out), "--workers", "2",
               "--no-progress"])
    assert rc == 0
    printed = capsys.readouterr().out
    assert "2 of 4 runs ok, 2 failed" in printed
    rows = read_csv(out / "summary.csv")
    assert [r["name"] for r in rows] == ["000_free_radius=1", "001_free_radius=1.5",
                                         "002_rejected_radius=1", "003_rejected_radius=1.5"]
    assert list(rows[0])[2:4] == ["hub.radius", "control.law"]  # grid keys, then runs keys
    assert [float(r["hub.radius"]) for r in rows] == [1.0, 1.5, 1.0, 1.5]
    assert [r["control.law"] for r in rows] == ["free", "free", "spin_ramp", "spin_ramp"]
    ok, failed = rows[:2], rows[2:]
    for r in ok:
        assert r["status"] == "ok"
        assert all(math.isfinite(float(r[m])) for m in FINITE), r
        assert r["recoiled"] in ("0.0", "1.0")
        res = out / r["run_dir"] / "results.h5"
        assert res.is_file()
        assert float(r["deploy_time_s"]) == pytest.approx(deploy_time_by_hand(res))
        with h5py.File(res) as h5:
            assert float(r["max_tension_N"]) == pytest.approx(h5["history/max_tension"][()].max())
            assert float(r["final_hub_omega_rad_s"]) == pytest.approx(h5["history/hub_omega"][-1])
            assert h5["history/time"][-1] == pytest.approx(0.3)
    # a smaller hub has less inertia: the arms spin it down further
    assert float(ok[0]["final_hub_omega_rad_s"]) < float(ok[1]["final_hub_omega_rad_s"])
    for r in failed:
        assert r["status"] != "ok" and "initial.omega" in r["status"]
        assert math.isnan(float(r["deploy_time_s"]))  # the run failed: no metrics
        assert "Traceback" in (out / r["run_dir"] / "run.log").read_text()
    with h5py.File(out / "summary.h5") as h5:
        g = h5["runs"]
        assert list(g.attrs["columns"]) == list(rows[0].keys())
        assert h5.attrs["n_runs"] == 4 and h5.attrs["n_failed"] == 2
        assert g["deploy_time_s"].attrs["units"] == "s"
        assert g["hub.radius"].attrs["units"] == "m"
        np.testing.assert_allclose(g["max_tension_N"][:2], [float(r["max_tension_N"]) for r in ok])
        assert [s.decode() for s in g["status"][()]] == [r["status"] for r in rows]
    img = np.asarray(Image.open(out / "summary.png").convert("L"), dtype=float)
    assert img.std() > 10


@pytest.mark.parametrize("body, words", [
    ('base = "{base}"\nmodes = "fe"\n', "did you mean 'mode'"),
    ('mode = "fe"\n', "base"),
    ('base = "no_such_case.toml"\n', "no such base case"),
    ('base = "{base}"\nmode = "gpu"\n', "unknown mode"),
    ('base = "{base}"\n[grid]\nhub.radius = 2.0\n', "non-empty list"),
    ('base = "{base}"\n[grid]\nhub.radius = [1.0, -2.0]\n', "run 1: hub.radius"),
    ('base = "{base}"\n[[runs]]\nhub.radiuss = 2.0\n', "did you mean 'radius'"),
    ('base = "{base}"\n[grid]\nhub.radius = [1.0]\n[[runs]]\nhub.radius = 2.0\n', "one place"),
    ('base = "{base}"\n[set]\ntime.end = "long"\n', "expected a number"),
])
def test_invalid_sweep_exits_2_before_any_run(tmp_path, capsys, body, words):
    path = tmp_path / "bad.toml"
    path.write_text(body.format(base=ROOT / "cases" / "paper_free_arms.toml"))
    out = tmp_path / "out"
    assert main(["sweep", str(path), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_missing_sweep_file_and_bad_workers(tmp_path, capsys):
    assert main(["sweep", str(tmp_path / "none.toml")]) == 2
    assert main(["sweep", str(SMOKE), "--workers", "0"]) == 2
    assert "--workers" in capsys.readouterr().err


def test_grid_times_runs_and_dry_run(capsys):
    s = sw.load_sweep(ROOT / "cases" / "sweeps" / "fig8.toml")
    assert s.mode == "analytic" and s.keys == ("initial.omega", "control.omega0")
    w = [r.values["initial.omega"] for r in s.runs]
    np.testing.assert_allclose(w, [math.pi / 2, 2 * math.pi, 8 * math.pi])
    assert all(r.values["initial.omega"] == r.values["control.omega0"] for r in s.runs)
    s = sw.load_sweep(SMOKE, mode="analytic", sets=["time.end=0.2"])
    assert s.mode == "analytic" and [r.raw["time"]["end"] for r in s.runs] == [0.2, 0.2]
    assert main(["sweep", str(SMOKE), "--dry-run"]) == 0
    assert "000_radius=1: hub.radius = 1" in capsys.readouterr().out


def test_history_metrics():
    """Analytical rows (L and phi): arm 1 reaches 0.8 of its reach r0 + H = 21 m when
    r0 + 8 t = 16.8 m, at t = 1.975 s (arm 0 at 10 m/s is out before), and stays; an arm
    that falls back afterwards has no deployment time (the verdict's: out for good)."""
    t = np.linspace(0.0, 4.0, 401)
    L = np.clip(t[:, None] * [10.0, 8.0], 0.0, 20.0)
    h = {"time": t, "arm_length": L, "arm_angle": np.zeros_like(L),
         "hub_torque": -3.0 * np.sin(t), "hub_omega": 5.0 - t, "max_tension": t ** 2}
    m = sw.history_metrics(h, [], 21.0, 1.0)
    assert m["deploy_time_s"] == pytest.approx(1.98)  # the first row at or after 1.975 s
    assert m["final_hub_omega_rad_s"] == pytest.approx(1.0)
    assert m["peak_hub_torque_Nm"] == pytest.approx(3.0, rel=1e-4)
    assert m["max_tension_N"] == pytest.approx(16.0)
    assert sw.history_metrics(h, [], 21.0, 1.0, 0.95)["deploy_time_s"] == pytest.approx(2.37)
    back = L.copy()
    back[350:, 1] = 5.0  # arm 1 falls back at 3.5 s
    h["arm_length"] = back
    assert math.isinf(sw.history_metrics(h, [], 21.0, 1.0)["deploy_time_s"])
    h["arm_length"] = L * 0.5  # never deployed
    assert math.isinf(sw.history_metrics(h, [], 21.0, 1.0)["deploy_time_s"])


def test_analytic_run_one_fig8_recoils(tmp_path):
    """The 8 pi run of Fig. 8 (run in-process): out in about 2 s, then re-coils (so it has
    no deployment time: the verdict's, out for good)."""
    s = sw.load_sweep(ROOT / "cases" / "sweeps" / "fig8.toml", sets=["time.end=20.0"])
    run = s.runs[2]
    row = sw.run_one({"raw": run.raw, "source": str(s.base), "mode": "analytic",
                      "model": s.model, "out_dir": str(tmp_path / run.name)})
    assert row["status"] == "ok"
    assert math.isinf(row["deploy_time_s"]) and row["recoiled"] == 1.0
    assert (tmp_path / run.name / "analytic.h5").is_file()


def test_apply_rejects_a_scalar_as_table():
    with pytest.raises(InputError, match="not a table"):
        sw.apply({"title": "x"}, {"title.sub": 1}, "s.toml", "run 0")
