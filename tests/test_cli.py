"""Command line: exit codes and messages (docs/interface.md), plot pixels, failures keep results."""

import subprocess
import sys
from pathlib import Path

import h5py
import pytest

from spinweb_fe.fe import model as model_mod
from spinweb_fe.cli import main

CASES = Path(__file__).parent.parent / "cases"
FAST = ["--set", "time.end=0.01", "--set", "output.frame_dt=0", "--no-progress"]


def test_check_prints_resolved_case(capsys):
    assert main(["check", str(CASES / "demo.toml")]) == 0
    out = capsys.readouterr().out
    assert "cfl = 0.2" in out and "inertia = 100.0" in out and 'law = "torque_feedback"' in out


@pytest.mark.parametrize("args,needle", [
    (["run", "nope.toml"], "nope.toml: no such file"),
    (["run", str(CASES / "demo.toml"), "--set", "time.ned=1"], "time.ned: unknown key (did you mean 'end'?)"),
    (["run", str(CASES / "demo.toml"), "--set", "control.law=magic"], "control.law: unknown value 'magic'"),
    (["run", str(CASES / "demo.toml"), "--set", "hub.radius=-1"], "hub.radius: must be > 0"),
    (["run", str(CASES / "demo.toml"), "--set", "web.mesh_width=0.7"], "web.mesh_width"),
    (["frobnicate"], "invalid choice"),
])
def test_bad_input_exits_2_with_one_line(args, needle, capsys, tmp_path):
    rc = main(args + ["-o", str(tmp_path / "o")] if args[0] == "run" else args)
    err = capsys.readouterr().err
    assert rc == 2
    assert needle in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not (tmp_path / "o" / "results.h5").exists()


def test_bad_input_in_a_subprocess_has_no_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[web]\nside = 'wide'\n[time]\nend = 1.0\n")
    p = subprocess.run([sys.executable, "-m", "spinweb_fe", "run", str(bad), "-o", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert p.stderr.strip() == f"spinweb: error: {bad}: web.side: expected a number, got str 'wide'"


def test_instability_exits_1_and_keeps_results(tmp_path, monkeypatch, capsys):
    """A step three times the critical one must be caught (non-finite or runaway energy): exit 1
    with the time and the cause; results.h5 stays readable with the rows written so far."""
    real = model_mod.choose_dt
    monkeypatch.setattr("spinweb_fe.case.scene.choose_dt",
                        lambda m, cfl, cap=None, hist=None: real(m, 1.0, None, None) * 3.0)
    out = tmp_path / "o"
    rc = main(["run", str(CASES / "paper_free_arms.toml"), "-o", str(out), "--set", "time.end=0.5",
               "--set", "output.frame_dt=0.01", "--no-progress"])
    err = capsys.readouterr().err
    assert rc == 1
    assert "stopped at t = " in err and ("non-finite" in err or "energy balance" in err)
    with h5py.File(out / "results.h5", "r") as h5:
        assert h5.attrs["status"].startswith("failed")
        assert h5["history/time"].shape[0] >= 1
    assert (out / "web.pvd").exists()


def test_plot_writes_a_real_picture(tmp_path):
    out = tmp_path / "r"
    assert main(["run", str(CASES / "paper_free_arms.toml"), "-o", str(out)] + FAST) == 0
    png = tmp_path / "p.png"
    assert main(["plot", str(out / "results.h5"), str(out / "results.h5"), "-o", str(png)]) == 0
    import matplotlib.image as mpimg

    img = mpimg.imread(png)
    assert img.shape[0] > 300 and img.shape[1] > 300
    gray = img[..., :3].mean(axis=2)
    assert gray.std() > 0.05  # axes, curves and labels, not a blank page
    assert (gray < 0.5).mean() > 0.005


def test_python_m_entry_point():
    from importlib.metadata import version

    from spinweb_fe import __version__

    p = subprocess.run([sys.executable, "-m", "spinweb_fe", "--version"], capture_output=True, text=True)
    assert p.returncode == 0 and p.stdout.strip() == f"spinweb {__version__}"
    assert __version__ == version("spinweb")  # the installed metadata says the same
