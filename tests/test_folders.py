"""A result folder is changed only by its own run (issue #15, items 1, 3, 6, 7): one run per
folder (a second one exits 1 naming the first and changes nothing), an earlier result is
replaced only after the new run's first flush, environment and folder are checked before
anything is touched, live / killed / empty result files can be read, and frames get the
umask's permissions."""

import hashlib
import json
import os
import re
import signal
import stat
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import h5py
import numpy as np
import pytest

from spinweb_fe.cli import main
from spinweb_fe.cli.info import summary
from spinweb_fe.errors import RunError
from spinweb_fe.io.h5 import read_history

CASES = Path(__file__).parent.parent / "cases"
LOCK_NAME, ASIDE_NAME = "run.lock", ".previous"  # spinweb_fe.io.folder
FAST = [str(CASES / "paper_free_arms.toml"), "--no-progress", "--set", "time.end=0.004",
        "--set", "output.frame_dt=0.002"]
# about 18 s of wall time per simulated second, frames every 0.01 s (as tests/test_signals.py)
LONG = [str(CASES / "paper_free_web_stiff.toml"), "--set", "output.frame_dt=0.01",
        "--no-progress"]


def digest(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def pvd_entries(path: Path):
    if not path.exists():
        return []
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError:  # read while a frame's entry was being written in: poll again
        return []
    return [(float(d.get("timestep")), d.get("file")) for d in root.iter("DataSet")]


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def start(out: Path, *extra, t_end="5"):
    """A real run in its own process; returns once it has written two frames."""
    proc = subprocess.Popen([sys.executable, "-m", "spinweb_fe", "run", *LONG, "--set",
                             f"time.end={t_end}", "-o", str(out), *extra],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 90  # a cold numba cache compiles first
    while len(pvd_entries(out / "web.pvd")) < 2:
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"the run did not write frames: {proc.communicate()}")
        time.sleep(0.05)
    return proc


@pytest.fixture
def good_run(tmp_path):
    out = tmp_path / "good"
    assert main(["run", *FAST, "-o", str(out)]) == 0
    return out, digest(out)


def test_a_second_run_into_a_live_folder_exits_1_and_changes_nothing(tmp_path, capsys):
    """Item 1 (and item 6, live files): the second run used to delete the first's checkpoint
    and truncate its results.h5. Now it exits 1 with one line naming the first run; while
    the first runs, info and plot read its file; the first's file stays whole."""
    out = tmp_path / "shared"
    proc = start(out, "--checkpoint-dt", "0.005")
    try:
        while not (out / "checkpoint.h5").exists():
            time.sleep(0.05)
        before = os.stat(out / "results.h5").st_ino
        assert main(["run", str(CASES / "demo.toml"), "-o", str(out), "--set", "time.end=0.5",
                     "--no-progress"]) == 1
        line = one_line(capsys.readouterr().err)
        assert re.fullmatch(rf"spinweb: run failed: {re.escape(str(out))} is in use by another "
                            rf"run \(pid {proc.pid} on .+: spinweb run .+\); nothing was "
                            r"changed", line), line
        assert os.stat(out / "results.h5").st_ino == before  # not recreated, not deleted
        assert (out / "checkpoint.h5").exists()  # used to be deleted by the second run
        for _ in range(5):  # a file that a run is writing: read, and the run named
            text = summary(out / "results.h5")
            assert "status: running" in text and f"live: a run is writing this file (pid " \
                f"{proc.pid}" in text
            time.sleep(0.1)
        assert main(["plot", str(out / "results.h5"), "-o", str(tmp_path / "live.png")]) == 0
        assert proc.poll() is None  # all of this while the first run went on
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 1 and "interrupted by SIGTERM" in err
    with h5py.File(out / "results.h5", "r") as h5:
        assert h5.attrs["status"].startswith("interrupted by SIGTERM")
        n_frames, steps, dt = h5["frames/time"].shape[0], h5.attrs["steps"], h5.attrs["dt"]
    h = read_history(out / "results.h5")
    assert len(h["time"]) == -(-steps // round(1e-3 / dt)) and np.all(np.diff(h["time"]) > 0)
    assert len(pvd_entries(out / "web.pvd")) == n_frames >= 2
    assert not (out / LOCK_NAME).exists() and not (out / ASIDE_NAME).exists()


def test_the_lock_names_its_run_and_is_gone_after_it(tmp_path):
    from spinweb_fe.io.folder import LOCK_NAME, FolderLock, holder

    folder = tmp_path / "f"
    with FolderLock(folder):
        info = holder(folder)
        assert info["pid"] == os.getpid() and info["host"] and info["started"]
        with pytest.raises(RunError, match=rf"in use by another run \(pid {os.getpid()}"):
            FolderLock(folder).acquire()
    assert holder(folder) is None and not folder.exists()  # a bare claim leaves no folder
    folder.mkdir()
    (folder / LOCK_NAME).write_text(json.dumps({"pid": 1}))  # left by a killed run
    assert (folder / LOCK_NAME).exists() and holder(folder) is None  # a stale lock
    with FolderLock(folder):  # a stale lock file does not stop the next run
        assert holder(folder)["pid"] == os.getpid()


def test_the_folder_is_claimed_before_the_set_up(tmp_path, good_run, monkeypatch, capsys):
    """Issue #27, item 4: a second run into a folder whose run is still in its set-up (the
    mesh, numba's compile) is refused at once with one line, and the first run goes on; an
    earlier result stays untouched until the first run's own rows replace it. The second
    run is started from inside the first one's set-up (a warm cache: the compile is the
    set-up's longest part; the cold-cache case is the next test)."""
    import spinweb_fe.run.driver as driver
    from spinweb_fe.io.folder import holder

    out, before = good_run
    real, seen = driver.prepare, {}

    def prepare_and_try_a_second_run(case):
        seen["holder"] = holder(out)
        seen["digest"] = digest(out)
        seen["rc"] = main(["run", *FAST, "-o", str(out)])
        seen["err"] = capsys.readouterr().err
        return real(case)

    monkeypatch.setattr(driver, "prepare", prepare_and_try_a_second_run)
    assert main(["run", *FAST, "-o", str(out)]) == 0
    assert seen["holder"]["pid"] == os.getpid() and seen["rc"] == 1
    assert re.fullmatch(rf"spinweb: run failed: {re.escape(str(out))} is in use by another "
                        r"run \(pid \d+ on .+\); nothing was changed", one_line(seen["err"]))
    assert {k: v for k, v in seen["digest"].items() if k != LOCK_NAME} == before
    assert not (out / LOCK_NAME).exists()


def test_an_earlier_result_is_replaced_only_after_the_first_flush(tmp_path, good_run,
                                                                   monkeypatch, capsys):
    """Item 1: the earlier result is kept aside in DIR/.previous until the new run's first
    rows are on disk; a run that fails before that puts it back untouched."""
    from spinweb_fe.io import results

    out, before = good_run
    real = results.ResultWriter.rows
    seen = []

    def failing(self, rows):
        seen.append((out / ASIDE_NAME / "results.h5").exists())
        raise RunError("simulated failure before the first flush", time=0.0)

    monkeypatch.setattr(results.ResultWriter, "rows", failing)
    assert main(["run", *FAST, "-o", str(out)]) == 1
    assert "simulated failure" in capsys.readouterr().err
    assert seen == [True] and digest(out) == before  # the earlier result, back as it was
    # a run killed before its first flush left .previous (with the manifest it writes
    # before moving anything) and its own partial files
    (out / ASIDE_NAME).mkdir()
    (out / ASIDE_NAME / "MANIFEST").write_text(json.dumps(["results.h5", "web.pvd", "frames"]))
    for name in ("results.h5", "web.pvd", "frames"):
        os.replace(out / name, out / ASIDE_NAME / name)
    (out / "results.h5").write_bytes(b"partial")
    assert main(["run", *FAST, "-o", str(out)]) == 1
    assert digest(out) == before
    # a run that gets past its first flush replaces the earlier result
    def watching(self, rows):
        seen.append((out / ASIDE_NAME).exists())
        return real(self, rows)

    monkeypatch.setattr(results.ResultWriter, "rows", watching)
    assert main(["run", *FAST, "-o", str(out)]) == 0
    capsys.readouterr()
    assert seen[1:3] == [True, True] and seen[-1] is False and not (out / ASIDE_NAME).exists()
    assert digest(out) != before


@pytest.mark.parametrize("value", ["abc", "0", "-2", "1.5"])
def test_a_bad_thread_count_leaves_the_earlier_result_intact(value, good_run, monkeypatch,
                                                             capsys):
    """Item 3: SPINWEB_THREADS=abc gave a ValueError traceback after the folder was reset."""
    out, before = good_run
    monkeypatch.setenv("SPINWEB_THREADS", value)
    assert main(["run", *FAST, "-o", str(out)]) == 2
    line = one_line(capsys.readouterr().err)
    assert line == f"spinweb: error: SPINWEB_THREADS: must be an integer >= 1, got '{value}'"
    assert digest(out) == before


def test_folder_problems_are_found_before_anything_is_written(tmp_path, good_run,
                                                              monkeypatch, capsys):
    out, before = good_run
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    assert main(["run", *FAST, "-o", str(blocker / "sub")]) == 2
    assert "a_file is not a folder" in one_line(capsys.readouterr().err)
    assert main(["run", *FAST, "-o", str(blocker)]) == 2
    assert "exists and is not a folder" in one_line(capsys.readouterr().err)
    # more output than the free disk space: refused before the folder is touched
    monkeypatch.setattr("spinweb_fe.run.estimate.free_bytes", lambda folder: 1000)
    assert main(["run", *FAST, "-o", str(out)]) == 2
    line = one_line(capsys.readouterr().err)
    assert f"spinweb: error: {out}: the run writes about" in line and "more than the 1000 B " \
        "free there" in line and "--force" in line
    assert digest(out) == before


def test_killed_runs_and_empty_histories_are_told(tmp_path, capsys):
    """Item 6: after SIGKILL status stays 'running' and nothing said so; a run killed before
    its first flush left an empty /history on which info and plot crashed (KeyError)."""
    out = tmp_path / "killed"
    assert main(["run", *FAST, "-o", str(out), "--checkpoint-dt", "0.002"]) == 0
    with h5py.File(out / "results.h5", "r+") as h5:  # what SIGKILL leaves: no final status,
        h5.attrs["status"] = "running"               # and a lock file that nobody holds
    (out / LOCK_NAME).write_text(json.dumps({"pid": 99999999}))
    capsys.readouterr()
    text = summary(out / "results.h5")
    assert "status: running" in text
    assert re.search(r"interrupted: no process is running it any more \(killed after t = "
                     r"0.004 s\?\); continue it with `spinweb run --restart ", text), text
    assert main(["run", "--restart", str(out), "--set", "time.end=0.006", "--no-progress"]) == 0
    capsys.readouterr()
    with h5py.File(out / "results.h5", "r") as h5:
        assert h5.attrs["status"] == "completed"
    assert not (out / LOCK_NAME).exists()
    # a file whose run stopped before its first rows: an empty /history
    empty = tmp_path / "empty"
    empty.mkdir()
    with h5py.File(empty / "results.h5", "w") as h5:
        h5.attrs["status"] = "running"
        h5.create_group("history")
    (empty / LOCK_NAME).write_text("{}")
    assert main(["info", str(empty / "results.h5")]) == 0
    text = capsys.readouterr().out
    assert "history: 0 rows (the run stopped before its first rows were written)" in text
    assert "killed before its first rows?); run the case again (no checkpoint)" in text
    assert main(["plot", str(empty / "results.h5"), "-o", str(tmp_path / "e.png")]) == 2
    assert "history: no rows yet" in one_line(capsys.readouterr().err)


@pytest.mark.parametrize("umask,mode", [(0o022, 0o644), (0o027, 0o640), (0o002, 0o664)])
def test_frames_get_the_permissions_of_the_umask(umask, mode, tmp_path, capsys):
    """Item 7: frames/*.vtu and mesh_*.vtu were 0600 whatever the umask."""
    old = os.umask(umask)
    try:
        assert main(["run", *FAST, "-o", str(tmp_path / "r")]) == 0
        assert main(["mesh", str(CASES / "paper_free_arms.toml"), "-o", str(tmp_path / "m")]) == 0
    finally:
        os.umask(old)
    capsys.readouterr()
    files = [*(tmp_path / "r" / "frames").glob("*.vtu"), *(tmp_path / "m").glob("*.vtu"),
             tmp_path / "r" / "web.pvd", tmp_path / "r" / "results.h5"]
    assert len(files) >= 6
    for f in files:
        assert stat.S_IMODE(f.stat().st_mode) == mode, f


def test_a_run_killed_while_moving_the_earlier_result_is_undone(tmp_path):
    """Whatever moment a run is killed at while it keeps the earlier result aside, puts it
    back or drops it, the next run finds a whole result: the earlier one (before the new
    run's first flush) or the new one (after it)."""
    from spinweb_fe.io.folder import Aside

    def earlier(folder):
        folder.mkdir()
        (folder / "results.h5").write_text("A results")
        (folder / "web.pvd").write_text("A pvd")
        (folder / "frames").mkdir()
        (folder / "frames" / "web_000000.vtu").write_text("A frame")
        return digest(folder)

    # killed halfway through the move: the manifest names three, one was moved
    a = tmp_path / "move"
    before = earlier(a)
    (a / ASIDE_NAME).mkdir()
    (a / ASIDE_NAME / "MANIFEST").write_text(json.dumps(["results.h5", "web.pvd", "frames"]))
    os.replace(a / "results.h5", a / ASIDE_NAME / "results.h5")
    assert Aside.recover(a) and digest(a) == before and not (a / ASIDE_NAME).exists()
    # killed halfway through a restore: one item back, the new run's web.pvd still there
    b = tmp_path / "restore"
    before = earlier(b)
    aside = Aside(b).move()
    (b / "results.h5").write_text("B partial")
    (b / "web.pvd").write_text("B partial")
    os.replace(b / ASIDE_NAME / "results.h5", b / "results.h5.back")
    (b / "results.h5").unlink()
    os.replace(b / "results.h5.back", b / "results.h5")
    assert Aside.recover(b) and digest(b) == before and aside.moved
    # killed while dropping it: the new result stays
    c = tmp_path / "drop"
    earlier(c)
    Aside(c).move()
    (c / "results.h5").write_text("B flushed")
    os.replace(c / ASIDE_NAME, c / f"{ASIDE_NAME}-dropped")
    assert not Aside.recover(c) and (c / "results.h5").read_text() == "B flushed"
    assert sorted(p.name for p in c.iterdir()) == ["results.h5"]
