"""SIGTERM / SIGINT stop a run cleanly at the next event boundary: exit code 1, one line
'interrupted by SIG... at t = ... s', a readable results.h5 (status 'interrupted ...',
histories up to the stop), a valid web.pvd, and the previous signal handlers restored."""

import os
import re
import signal
import subprocess
import sys
import threading
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest

from spinweb_fe.cli import main
from spinweb_fe.io.h5 import read_history

CASES = Path(__file__).parent.parent / "cases"
# about 90 s of run time: a signal always arrives mid-run; frames every 0.01 s of simulated
# time and the wall-time cap of a chunk (run.loop.WALL_CHUNK_S) bring events often
LONG = [str(CASES / "paper_free_web_stiff.toml"), "--set", "time.end=5",
        "--set", "output.frame_dt=0.01", "--no-progress"]
MESSAGE = re.compile(r"spinweb: interrupted by (SIG\w+) at t = ([0-9.e+-]+) s")


def pvd_entries(path: Path):
    """(time, file) of a web.pvd, [] while it does not exist yet."""
    if not path.exists():
        return []
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError:  # read while a frame's entry was being written in: poll again
        return []
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def start_and_signal(out: Path, signum, extra=()):
    """Start a real run, wait for its third frame (t = 0.02 s), send ``signum``."""
    proc = subprocess.Popen([sys.executable, "-m", "spinweb_fe", "run", *LONG, "-o", str(out),
                             *extra], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 90  # a cold numba cache compiles first
        while len(pvd_entries(out / "web.pvd")) < 3:
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the run did not write frames"
            time.sleep(0.05)
        sent = time.monotonic()
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=30)
        return proc.returncode, err, time.monotonic() - sent
    finally:
        if proc.poll() is None:  # a failed check: do not leave a 90 s run behind
            proc.kill()
            proc.communicate()


def check_stopped_run(out: Path, rc, err, name):
    """Exit 1, the one-line message, and readable results up to the stop."""
    assert rc == 1, err
    assert "Traceback" not in err
    m = MESSAGE.fullmatch(err.strip().splitlines()[-1])
    assert m and m.group(1) == name, err
    t_stop = float(m.group(2))
    with h5py.File(out / "results.h5", "r") as h5:
        assert h5.attrs["status"] == f"interrupted by {name} at t = {t_stop:.6g} s"
        dt, steps = h5.attrs["dt"], int(h5.attrs["steps"])
        assert steps * dt == pytest.approx(t_stop, rel=1e-5)  # the message has 6 digits
        n_frames = h5["frames/time"].shape[0]
    h = read_history(out / "results.h5")
    # the rows of the steps before the stop (one every history_dt), all finite
    rec_every = round(1e-3 / dt)
    assert len(h["time"]) == -(-steps // rec_every)
    np.testing.assert_allclose(h["time"], np.arange(len(h["time"])) * 1e-3, atol=1e-12)
    for name_, arr in h.items():
        assert np.all(np.isfinite(arr)), name_
    entries = pvd_entries(out / "web.pvd")
    assert len(entries) == n_frames >= 3
    assert meshio.read(out / entries[-1][1]).points.shape[1] == 3
    return t_stop


def test_sigterm_stops_cleanly_and_the_run_restarts_bit_identically(tmp_path, capsys):
    out = tmp_path / "stopped"
    rc, err, latency = start_and_signal(out, signal.SIGTERM, ["--checkpoint-dt", "1"])
    t_stop = check_stopped_run(out, rc, err, "SIGTERM")
    assert latency < 10  # stops at the next event boundary, not at the end (about 90 s)
    # the stop wrote a checkpoint; continue a little and compare with an uninterrupted run
    with h5py.File(out / "checkpoint.h5", "r") as ck:
        assert ck.attrs["time"] == pytest.approx(t_stop, rel=1e-5)
    t_end = f"time.end={round(t_stop + 0.004, 3)}"
    assert main(["run", "--restart", str(out), "--set", t_end, "--no-progress"]) == 0
    ref = tmp_path / "ref"
    assert main(["run", *LONG, "-o", str(ref), "--set", t_end]) == 0
    capsys.readouterr()
    a, b = read_history(ref / "results.h5"), read_history(out / "results.h5")
    assert a.keys() == b.keys()
    for key in a:
        assert np.array_equal(a[key], b[key]), key


def test_sigint_stops_cleanly_without_checkpoint(tmp_path):
    out = tmp_path / "stopped"
    rc, err, latency = start_and_signal(out, signal.SIGINT)
    check_stopped_run(out, rc, err, "SIGINT")
    assert latency < 10
    assert not (out / "checkpoint.h5").exists()


def test_in_process_handlers_are_restored(tmp_path, capsys):
    """A signal to this process mid-run stops main() with exit 1; afterwards the handlers
    installed before the run are back in place."""
    seen = []

    def mine(signum, frame):
        seen.append(signum)

    done = threading.Event()

    def kill_when_running():  # once the run has written frames, its handlers are in place
        deadline = time.monotonic() + 60
        while len(pvd_entries(tmp_path / "o" / "web.pvd")) < 2 and time.monotonic() < deadline:
            if done.wait(0.05):
                return
        os.kill(os.getpid(), signal.SIGTERM)

    previous = signal.signal(signal.SIGTERM, mine)
    killer = threading.Thread(target=kill_when_running)
    try:
        killer.start()
        rc = main(["run", *LONG, "-o", str(tmp_path / "o")])
        killer.join()
        assert rc == 1
        assert MESSAGE.fullmatch(capsys.readouterr().err.strip().splitlines()[-1])
        assert signal.getsignal(signal.SIGTERM) is mine
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        assert seen == []  # the run's handler took it, not ours
    finally:
        done.set()
        killer.join()
        signal.signal(signal.SIGTERM, previous)


def test_instability_keeps_readable_results_and_says_why(tmp_path, monkeypatch, capsys):
    """A step three times the critical one blows up: exit 1 with time and cause, results.h5
    and web.pvd readable, ``status`` names the failure, no checkpoint after it."""
    from spinweb_fe.fe import model as model_mod

    real = model_mod.choose_dt
    monkeypatch.setattr("spinweb_fe.case.scene.choose_dt",
                        lambda m, cfl, cap=None, hist=None: real(m, 1.0, None, None) * 3.0)
    out = tmp_path / "o"
    rc = main(["run", str(CASES / "paper_free_arms.toml"), "-o", str(out), "--no-progress",
               "--set", "time.end=0.5", "--set", "output.frame_dt=0.005",
               "--checkpoint-dt", "0.005"])
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert rc == 1
    m = re.fullmatch(r"spinweb: run failed: stopped at t = ([0-9.e+-]+) s: (.+)", last)
    assert m and ("non-finite" in m.group(2) or "energy balance" in m.group(2)), last
    t_fail = float(m.group(1))
    with h5py.File(out / "results.h5", "r") as h5:
        assert h5.attrs["status"] == f"failed: stopped at t = {m.group(1)} s: {m.group(2)}"
        n_frames = h5["frames/time"].shape[0]
        assert h5["history/time"].shape[0] >= 1
    entries = pvd_entries(out / "web.pvd")
    assert len(entries) == n_frames >= 1
    meshio.read(out / entries[-1][1])
    if (out / "checkpoint.h5").exists():
        with h5py.File(out / "checkpoint.h5", "r") as ck:
            assert ck.attrs["time"] < t_fail
            values = []
            ck["state"].visititems(lambda name, obj: values.append(obj[()])
                                   if isinstance(obj, h5py.Dataset) else None)
            assert len(values) >= 10 and all(np.all(np.isfinite(v)) for v in values)


def test_second_sigint_aborts_at_once():
    """The first SIGINT only sets the flag; a second one raises KeyboardInterrupt."""
    from spinweb_fe.run.terminal import StopSignals

    before = signal.getsignal(signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        with StopSignals() as stop:
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)  # the handler runs at the next bytecode
            assert stop() == "SIGINT"
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)
    assert signal.getsignal(signal.SIGINT) is before
