"""Result folders that cannot be turned against their owner (issue #46, items 1 and 2): links
planted under the names of the files a run writes are replaced, never followed; a lock that
is not a regular file is refused in one line (a FIFO without a hang); a ``.previous`` that
spinweb did not leave never costs a result, and one linked to another folder never touches
that folder."""

import hashlib
import json
import os
import signal
from pathlib import Path

import h5py
import pytest

from spinweb_fe.cli import main

CASES = Path(__file__).parent.parent / "cases"
FAST = [str(CASES / "paper_free_arms.toml"), "--no-progress", "--set", "time.end=0.004",
        "--set", "output.frame_dt=0.002"]


def digest(folder: Path) -> dict:
    """Every entry under ``folder`` (links by their target's name, not followed)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        key = p.relative_to(folder).as_posix()
        if p.is_symlink():
            out[key] = "-> " + os.readlink(p)
        elif p.is_file():
            out[key] = hashlib.sha256(p.read_bytes()).hexdigest()
        elif p.is_dir():
            out[key] = "folder"
    return out


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def rows(folder: Path) -> int:
    with h5py.File(folder / "results.h5", "r") as h5:
        return h5["history/time"].shape[0]


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished run with a checkpoint (its folder is copied by each test)."""
    out = tmp_path_factory.mktemp("links") / "done"
    assert main(["run", *FAST, "--checkpoint-dt", "0.002", "-o", str(out)]) == 0
    return out


def copy_of(src: Path, dst: Path) -> Path:
    import shutil

    shutil.copytree(src, dst, symlinks=True)
    return dst


def victims(tmp_path: Path) -> dict:
    """Files outside the folder that a planted link points to, and their contents."""
    outside = tmp_path / "outside"
    outside.mkdir()
    files = {}
    for name in ("reserve", "pvd_tmp", "ck_tmp", "lock", "pvd", "results"):
        p = outside / name
        p.write_text(f"not spinweb's: {name}\n")
        files[name] = p
    return files


def unchanged(files: dict) -> bool:
    return all(p.read_text() == f"not spinweb's: {name}\n" for name, p in files.items())


def test_planted_links_are_replaced_not_followed(finished, tmp_path, capsys):
    """.reserve, web.pvd.tmp and checkpoint.h5.tmp planted as links to files outside the
    folder: a restart and a fresh run write their own files, the targets keep their bytes
    (on main the reserve, the collection and the checkpoint were written through them)."""
    out = copy_of(finished, tmp_path / "run")
    files = victims(tmp_path)
    for name, target in ((".reserve", "reserve"), ("web.pvd.tmp", "pvd_tmp"),
                         ("checkpoint.h5.tmp", "ck_tmp")):
        (out / name).symlink_to(files[target])
    assert main(["run", "--restart", str(out), "--set", "time.end=0.008",
                 "--no-progress"]) == 0
    assert unchanged(files) and rows(out) > rows(finished)
    for name in (".reserve", "web.pvd.tmp", "checkpoint.h5.tmp"):  # a fresh run too
        (out / name).unlink(missing_ok=True)
        (out / name).symlink_to(files["reserve" if name == ".reserve" else
                                      "pvd_tmp" if name == "web.pvd.tmp" else "ck_tmp"])
    (out / "web.pvd").unlink()
    (out / "web.pvd").symlink_to(files["pvd"])  # moved aside and dropped: the link only
    assert main(["run", *FAST, "--checkpoint-dt", "0.002", "-o", str(out)]) == 0
    capsys.readouterr()
    assert unchanged(files)
    assert not any(p.is_symlink() for p in out.rglob("*"))


@pytest.mark.parametrize("what", ["link", "fifo", "folder"])
def test_a_lock_that_is_not_a_file_is_refused_at_once(finished, tmp_path, capsys, what):
    """run.lock as a link (to a file outside), a FIFO (on main: `run` and `--restart` hung
    opening it) or a folder: one line, exit 2, the folder and the target unchanged."""
    out = copy_of(finished, tmp_path / "run")
    files = victims(tmp_path)
    lock = out / "run.lock"
    if what == "link":
        lock.symlink_to(files["lock"])
    elif what == "fifo":
        os.mkfifo(lock)
    else:
        lock.mkdir()
    before = digest(out)

    def hung(signum, frame):
        raise TimeoutError("the run hung on run.lock")

    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(30)
    try:
        for argv in (["run", *FAST, "-o", str(out)],
                     ["run", "--restart", str(out), "--set", "time.end=0.008"]):
            assert main(argv) == 2
            line = one_line(capsys.readouterr().err)
            assert "run.lock" in line and "remove it" in line, line
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    assert digest(out) == before and unchanged(files)


@pytest.mark.parametrize("manifest", [None, "{not json", json.dumps(["../../etc"])])
def test_an_empty_previous_never_costs_the_result(finished, tmp_path, capsys, manifest):
    """`mkdir DIR/.previous; spinweb run --restart DIR` (and a .previous with only a damaged
    manifest) deleted results.h5, web.pvd, frames/ and checkpoint.h5 on main; now the
    restart continues the result and .previous is gone."""
    out = copy_of(finished, tmp_path / "run")
    (out / ".previous").mkdir()
    if manifest is not None:
        (out / ".previous" / "MANIFEST").write_text(manifest)
    assert main(["run", "--restart", str(out), "--set", "time.end=0.008",
                 "--no-progress"]) == 0
    capsys.readouterr()
    assert rows(out) > rows(finished)
    assert {"results.h5", "web.pvd", "frames", "checkpoint.h5"} <= {p.name for p in out.iterdir()}
    assert not (out / ".previous").exists()


def test_a_foreign_previous_is_refused_and_kept(finished, tmp_path, capsys):
    """A .previous holding files that no valid manifest names (a damaged one): both a fresh
    run and a restart refuse in one line, exit 2, every file where it was."""
    out = copy_of(finished, tmp_path / "run")
    (out / ".previous").mkdir()
    (out / ".previous" / "MANIFEST").write_text("{damaged")
    (out / ".previous" / "results.h5").write_text("someone's file")
    before = digest(out)
    for argv in (["run", *FAST, "-o", str(out)],
                 ["run", "--restart", str(out), "--set", "time.end=0.008"]):
        assert main(argv) == 2
        assert ".previous" in one_line(capsys.readouterr().err)
    assert digest(out) == before


def test_a_previous_linked_to_another_run_never_touches_it(finished, tmp_path, capsys):
    """.previous as a link to another run's folder: on main a fresh run moved that run's
    results into this folder (and a restart deleted them); now both refuse in one line, and
    neither folder changes."""
    other = copy_of(finished, tmp_path / "other")
    out = copy_of(finished, tmp_path / "run")
    (out / ".previous").symlink_to(other)
    before, mine = digest(other), digest(out)
    for argv in (["run", *FAST, "-o", str(out)],
                 ["run", "--restart", str(out), "--set", "time.end=0.008"]):
        assert main(argv) == 2
        assert ".previous" in one_line(capsys.readouterr().err)
    assert digest(other) == before and digest(out) == mine


@pytest.mark.parametrize("name", ["results.h5", "frames", "web.pvd", "checkpoint.h5"])
def test_a_restart_does_not_write_through_a_linked_result(finished, tmp_path, capsys, name):
    """A restart changes results.h5, web.pvd and frames/ in place: one of them replaced by a
    link (to another run's copy) is refused in one line, the other run's files unchanged
    (on main the restart cut the other run's results.h5 and deleted its frames)."""
    other = copy_of(finished, tmp_path / "other")
    out = copy_of(finished, tmp_path / "run")
    target = other / name
    import shutil

    if (out / name).is_dir():
        shutil.rmtree(out / name)
    else:
        (out / name).unlink()
    (out / name).symlink_to(target)
    before = digest(other)
    assert main(["run", "--restart", str(out), "--set", "time.end=0.008"]) == 2
    assert name in one_line(capsys.readouterr().err)
    assert digest(other) == before


def test_a_killed_run_is_still_undone(finished, tmp_path):
    """The manifest still does its work: a run killed after moving the earlier result and
    writing its own results.h5 (no rows) is undone by the next run into the folder."""
    from spinweb_fe.io.folder import Aside

    out = copy_of(finished, tmp_path / "run")
    before = digest(out)
    aside = Aside(out).move()
    assert aside.moved == ["results.h5", "web.pvd", "frames", "checkpoint.h5"]
    (out / "results.h5").write_text("the killed run's")
    (out / "frames").mkdir()
    assert Aside.recover(out)
    assert digest(out) == before
