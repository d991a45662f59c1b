"""Messages and arguments of the commands around a run (issue #15, items 5, 9, 10): info's
energy drift on the audit's scale, plot and sweep check their arguments and folders
first, help texts, the failing command named in I/O errors, keys named correctly."""

import argparse
import re
from pathlib import Path

import pytest

from spinweb_fe.cli import COMMANDS, build_parser, main
from spinweb_fe.io.h5 import read_history

CASES = Path(__file__).parent.parent / "cases"
DEMO = str(CASES / "demo.toml")
SMOKE = str(CASES / "sweeps" / "smoke.toml")


def one_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    assert main(["run", DEMO, "-o", str(out), "--set", "time.end=0.3",
                 "--set", "output.frame_dt=0.1", "--no-progress"]) == 0
    return out / "results.h5"


def test_info_measures_the_drift_as_the_audit_does(demo_run, capsys):
    """Item 5: a run from rest has an initial energy of about 0 J: info reported a drift of
    2.6e7 relative to it, while the audit (scaled by the torque work) found 1.7e-5."""
    from spinweb_fe.record.energy import EnergyAudit, balance_error

    capsys.readouterr()
    assert main(["info", str(demo_run)]) == 0
    m = re.search(r"energy balance drift: ([0-9.e+-]+) \(relative to the energy scale of the "
                  r"run's audit: max\(initial energy, torque work, round-off floor\)\)",
                  capsys.readouterr().out)
    h = read_history(demo_run)
    assert m and float(m.group(1)) == pytest.approx(balance_error(h), rel=1e-3)
    assert float(m.group(1)) < 0.01
    audit = EnergyAudit(limit=1.0)  # the audit over the whole history finds the same
    audit.rows(h)
    assert balance_error(h, audit.ref) == balance_error(h)


def test_plot_checks_its_arguments_first(demo_run, tmp_path, capsys):
    """Item 9: -o x.jpgx ended in a matplotlib traceback; --arm 9 of 4 arms drew arm 3."""
    for args, needle in [(["-o", str(tmp_path / "x.jpgx")], "-o: 'x.jpgx': unknown figure "
                           "type '.jpgx' (valid: "),
                         (["-o", str(tmp_path / "x.png"), "--arm", "9"],
                          f"--arm: arm 9 does not exist: {demo_run} has 4 arms (0 to 3)"),
                         (["-o", str(tmp_path / "x.png"), "--arm", "-1"], "arm -1 does not"),
                         (["-o", str(tmp_path / "file" / "x.png")],
                          "file: exists and is not a folder")]:
        (tmp_path / "file").write_text("")
        assert main(["plot", str(demo_run), *args]) == 2
        assert needle in one_line(capsys.readouterr().err)
    assert not list(tmp_path.glob("x.*"))


def test_sweep_checks_its_folder_and_its_set_keys_first(tmp_path, capsys):
    """Item 9: a sweep into an unwritable folder printed a Dask traceback per run; a --set
    of a key that the grid also sets was silently overridden."""
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["sweep", SMOKE, "-o", str(blocker / "sweep")]) == 2
    assert "file is not a folder" in one_line(capsys.readouterr().err)
    assert main(["sweep", SMOKE, "--set", "hub.radius=2.0", "--dry-run"]) == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith("spinweb: error: --set: hub.radius: is also set by the sweep's "
                           "[grid] (smoke.toml: grid.hub.radius)"), line
    assert main(["sweep", SMOKE, "--set", "time.end=0.1", "--dry-run"]) == 0  # [set]: fine


def test_help_texts(capsys):
    """Item 10: the top-level --help showed 'main(argv) -> int'; '(default: ...)' twice."""
    assert main(["--help"]) == 0
    assert "main(argv" not in capsys.readouterr().out
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name in COMMANDS:
        text = sub.choices[name].format_help()
        for opt in sub.choices[name]._actions:
            assert (opt.help or "").count("default") <= 1, (name, opt.dest)
        assert not re.search(r"\(default: [^)]*\)\s+\(default: ", text), name
        assert "(default: None)" not in text, name


@pytest.mark.parametrize("command", ["plot", "render", "mesh"])
def test_io_errors_name_the_command_that_failed(command, demo_run, tmp_path, capsys):
    """Item 10: I/O errors of plot, mesh and render were prefixed 'run failed'."""
    target = tmp_path / "taken.png"
    target.mkdir()  # a folder where the file should go: the write fails
    args = {"plot": ["plot", str(demo_run), "-o", str(target)],
            "render": ["render", str(demo_run), "-o", str(target), "--renderer", "matplotlib"],
            "mesh": ["mesh", str(CASES / "paper_free_arms.toml"), "-o", str(tmp_path / "m")]}
    if command == "mesh":
        (tmp_path / "m").mkdir()
        (tmp_path / "m" / "mesh.h5").mkdir()
    assert main(args[command]) == 1
    line = one_line(capsys.readouterr().err)
    assert line.startswith(f"spinweb: {command} failed: I/O error: "), line


def test_keys_at_fault_are_named(capsys):
    """Item 10: prestress --mesh-width 0.3 was reported as the case's web.mesh_width, and
    web.side = 1e9 was blamed on web.mesh_width."""
    assert main(["prestress", DEMO, "--mesh-width", "0.3"]) == 2
    assert one_line(capsys.readouterr().err).startswith("spinweb: error: --mesh-width: the "
                                                        "side 20 m must be an integer multiple")
    assert main(["run", DEMO, "--set", "web.side=1e9", "-o", "/nonexistent/x"]) == 2
    assert f"{DEMO}: web.side: gives about 5e+17 cable elements" in \
        one_line(capsys.readouterr().err)


def test_a_closed_pipe_is_not_an_error_message(tmp_path):
    """`spinweb sweep ... --dry-run | head -1` with more lines than a pipe holds (64 kB):
    the reader leaves after one line; the command stops quietly (no 'I/O error: Broken
    pipe', no traceback)."""
    import subprocess
    import sys as _sys
    from pathlib import Path as _Path

    root = _Path(__file__).resolve().parents[1]
    text = (root / "cases" / "sweeps" / "montecarlo_feedback_web.toml").read_text()
    big = tmp_path / "big.toml"
    big.write_text(text.replace("members = 32", "members = 600").replace(
        'base = "../paper_feedback_web.toml"', f'base = "{root / "cases" / "paper_feedback_web.toml"}"'))
    cmd = f"'{_sys.executable}' -m spinweb_fe sweep '{big}' --dry-run | head -1"
    proc = subprocess.run(["bash", "-c", cmd], capture_output=True, text=True, timeout=300,
                          cwd=tmp_path)
    assert proc.stdout.startswith("1200 fe runs")
    assert proc.stderr == ""
