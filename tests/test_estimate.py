"""Estimates before work (issue #15, item 4): a run prints its size and cost before it
starts and is refused (exit 2, one line, nothing written) beyond the budget unless forced;
set-up is linear in the mesh and stops at once on SIGINT / SIGTERM."""

import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

from spinweb_fe import case as case_mod
from spinweb_fe.cli import main
from spinweb_fe.errors import InputError

CASES = Path(__file__).parent.parent / "cases"
DEMO = str(CASES / "demo.toml")
ARMS = str(CASES / "paper_free_arms.toml")


def one_line(err):
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_a_run_of_days_is_refused_before_it_starts(tmp_path, capsys):
    """The issue's case: web.elements_per_segment = 1000 and time.dt = 2e-9 need about 1e15
    element-updates (on the demo web for 2 s, 2e14: days even at 1e9 element-updates/s); it
    started without a word."""
    out = tmp_path / "o"
    assert main(["run", DEMO, "-o", str(out), "--set", "web.elements_per_segment=1000",
                 "--set", "time.dt=2e-9", "--set", "time.end=2"]) == 2
    line = one_line(capsys.readouterr().err)
    m = re.fullmatch(r"spinweb: error: .*demo.toml: the run needs ([0-9.e+]+) element-updates "
                     r"\(1000000000 steps of 216000 elements\), about [0-9.e+]+ days at this "
                     r"machine's [0-9.e+]+ element-updates/s, more than the budget of 1 day "
                     r"\(.*--force runs it anyway\)", line)
    assert m and float(m.group(1)) == pytest.approx(2.16e14)
    assert not out.exists()


def test_the_size_is_printed_and_matches_the_run(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["run", DEMO, "-o", str(out), "--set", "time.end=0.1", "--no-progress"]) == 0
    err = capsys.readouterr().err
    size = re.search(r"size: 120 nodes, 216 elements, 2800 steps, 6.05e\+05 element-updates, "
                     r"about [0-9.e+-]+ (s|min) at ([0-9.e+]+) element-updates/s \(measured "
                     r"here, 1 thread\)", err)
    cost = re.search(r"estimate: memory about [0-9.]+ MB, output about ([0-9.]+) (KB|MB) "
                     r"\((\d+) history rows, (\d+) frames\)", err)
    assert size and cost, err
    with h5py.File(out / "results.h5", "r") as h5:
        rows, frames = h5["history/time"].shape[0], h5["frames/time"].shape[0]
    assert (int(cost.group(3)), int(cost.group(4))) == (rows, frames) == (101, 3)
    written = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
    estimated = float(cost.group(1)) * (1024 if cost.group(2) == "KB" else 1024 ** 2)
    assert written <= estimated <= 8 * written


def test_memory_beyond_the_budget_is_refused_before_the_mesh(tmp_path, monkeypatch, capsys):
    from spinweb_fe.run import estimate as est_mod

    monkeypatch.setattr(est_mod, "machine_memory", lambda: 100 * 2 ** 20)
    monkeypatch.setattr("spinweb_fe.run.driver.prepare",
                        lambda case: pytest.fail("the mesh was built"))
    assert main(["run", ARMS, "-o", str(tmp_path / "o")]) == 2
    line = one_line(capsys.readouterr().err)
    assert "the run needs about" in line and "of memory" in line and "more than 80 % of " \
        "this machine's 100 MB (--force runs it anyway)" in line
    assert not (tmp_path / "o").exists()


def test_force_lifts_the_budget():
    from spinweb_fe.run import estimate as est_mod

    case = case_mod.load(DEMO)
    e = est_mod.Estimate(10, 10, 10**12, 1e16, 1e6, 1e10, 1e15, 1e15, 10, 0)
    with pytest.raises(InputError, match="more than the budget of 1 day"):
        est_mod.check_budget(case, e, "/tmp")
    est_mod.check_budget(case, e, "/tmp", force=True)


def test_setup_is_linear_in_the_mesh():
    """arms.arm_probes grew with the square of the spine levels (4e5 elements: over 200 s);
    set-up CPU time of a tether scene at 5e4, 1e5 and 2e5 elements now grows linearly."""
    from spinweb_fe.case.scene import prepare

    cpu = {}
    for n in (50_000, 100_000, 200_000):
        case = case_mod.load(ARMS, [f"tethers.elements={n // 4}", "output.frame_dt=0"])
        t0 = time.process_time()
        prepare(case)
        cpu[n] = time.process_time() - t0
    assert cpu[200_000] < 8 * cpu[50_000] + 0.2, cpu  # quadratic: 16 times, linear: 4


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_setup_at_once(tmp_path, signum):
    """A 2.4e6-element tether hung in set-up for 12 minutes: SIGINT and SIGTERM only set a
    flag there. Now set-up stops at once, exit 1, nothing written."""
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "spinweb_fe", "run", ARMS, "-o", str(out),
                             "--set", "tethers.elements=300000", "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(2.5)  # imports done, the mesh being built (about 8 s of set-up)
    sent = time.monotonic()
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=60)
    name = signal.Signals(signum).name
    assert proc.returncode == 1, err
    assert time.monotonic() - sent < 5
    assert "Traceback" not in err
    assert re.fullmatch(rf"spinweb: interrupted by {name}( during set-up, before anything was "
                        r"written)?", err.strip().splitlines()[-1]), err
    assert not out.exists()


def test_sigterm_during_startup_exits_1_not_143(tmp_path):
    proc = subprocess.Popen([sys.executable, "-m", "spinweb_fe", "run", DEMO, "-o",
                             str(tmp_path / "o")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    time.sleep(0.4)  # importing numpy, numba, h5py
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 1, (proc.returncode, err)
    assert re.fullmatch(r"spinweb: interrupted by SIGTERM.*", err.strip().splitlines()[-1])
    assert not (tmp_path / "o").exists()


def test_progress_lines_when_stderr_is_no_terminal(monkeypatch, capsys):
    """Without a terminal the bar is off; a plain line every LINE_EVERY_S tells the run is
    alive (a long batch run said nothing for days)."""
    import numpy as np

    from spinweb_fe.run import terminal

    monkeypatch.setattr(terminal, "LINE_EVERY_S", 0.0)
    bar = terminal.Progress(2.0, enabled=True)
    bar.rows({"time": np.array([0.5])})
    assert re.fullmatch(r"t = 0.5 / 2 s \(25.0 %\), [0-9.]+ min so far, ETA [0-9.]+ min\n",
                        capsys.readouterr().err)
    quiet = terminal.Progress(2.0, enabled=False)  # --no-progress: nothing at all
    quiet.rows({"time": np.array([0.5])})
    assert capsys.readouterr().err == ""


def test_the_eta_is_the_loops(monkeypatch, capsys):
    """The ETA counts from the loop's start, not from set-up: 100 s of compile before it, then
    1 s of loop for 0.5 of 2 s, leaves 3 s (0.05 min), not 303 s."""
    import numpy as np

    from spinweb_fe.record.recorders import RunInfo
    from spinweb_fe.run import terminal

    clock = iter([0.0, 100.0, 101.0])
    monkeypatch.setattr(terminal.time, "perf_counter", lambda: next(clock))
    monkeypatch.setattr(terminal, "LINE_EVERY_S", 0.0)
    bar = terminal.Progress(2.0, enabled=True)
    bar.start(RunInfo(None, 1e-3, 2000, 0, 1))
    bar.rows({"time": np.array([0.5])})
    assert capsys.readouterr().err == "t = 0.5 / 2 s (25.0 %), 0.0 min so far, ETA 0.1 min\n"


def test_the_bar_starts_with_the_loop(monkeypatch):
    """On a terminal: nothing before the loop starts (the compile), then a tqdm bar of the
    steps with the simulated time, closed at the end."""
    import io

    import numpy as np

    from spinweb_fe.record.recorders import RunInfo
    from spinweb_fe.run import terminal

    class Tty(io.StringIO):
        def isatty(self):
            return True

    err = Tty()
    monkeypatch.setattr(terminal.sys, "stderr", err)
    monkeypatch.delenv("CI", raising=False)
    bar = terminal.Progress(2.0, enabled=True)
    assert err.getvalue() == "" and bar.bar is None
    bar.start(RunInfo(None, 1e-3, 2000, 500, 1))
    bar.rows({"time": np.array([1.0])})
    assert bar.bar.n == 1000 and bar.bar.total == 2000
    bar.end("completed")
    assert bar.bar is None
    text = err.getvalue()
    assert "run:" in text and "t = 1.0000 / 2 s" in text and "1.00k/2.00k" in text


def test_the_estimate_counts_the_contact(tmp_path, capsys):
    """The paper web with its layers 5 mm apart and the cable contact, its first 20 ms
    (before the layers meet): the estimate, measured on the run's own features, is within
    2x of the loop's time (the bare web's rate would put it 30-60x too low). Later the
    contact costs more per step as the layers meet and the list is rebuilt more often
    (docs/robustness.md): the progress bar's ETA follows the loop's rate."""
    out = tmp_path / "o"
    assert main(["run", str(CASES / "paper_feedback_web.toml"), "-o", str(out), "--set",
                 "fold.layer_gap=0.005", "--set", "contact.cables=true", "--set",
                 "time.end=0.02", "--set", "output.frame_dt=0", "--no-progress"]) == 0
    err = capsys.readouterr().err
    est = re.search(r"size: .* about ([0-9.]+) (s|min) at", err)
    loop = re.search(r"done: \d+ steps in ([0-9.]+) s loop", err)
    assert est and loop, err
    wall = float(est.group(1)) * (60.0 if est.group(2) == "min" else 1.0)
    assert 0.5 < wall / float(loop.group(1)) < 2.0, err


def test_the_measured_rate_runs_through_the_lists_rebuilds_and_leaves_the_run_alone():
    """The rate is timed on copies of the run's features, which serve the loop's stops (a
    stale candidate list rebuilt) as the run's would: the timed steps go past the first
    rebuild (before, they stopped there and timed only the cheap steps before it, 1.5x
    low over 20 ms of the layered web, 2.2x over 0.1 s), and the run's own features keep
    the list they had."""
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.run.features import features_of
    from spinweb_fe.run.loop import time_steps

    case = case_mod.load(CASES / "paper_feedback_web.toml",
                         ["fold.layer_gap=0.005", "time.end=0.02", "output.frame_dt=0",
                          "contact.cables=true"])
    sc = prepare(case)
    features = features_of(sc.model, sc.state, case)
    audit = {f.name: f for f in features}["crossings"]
    nsteps = 300
    _, _, ran = time_steps(sc.model, sc.control, sc.state, sc.dt, 1, 20, nsteps, features)
    assert ran == nsteps
    assert audit.rebuilds == 1 and audit.kernel_data.n_log[0] == 0
    assert int(sc.state.step[0]) == 0
