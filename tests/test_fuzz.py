"""The fuzz as a test (issue #46, item 6): hostile case, sweep and design files and result
folders (tests/fuzz.py, seeded), each through the command line in-process. The assertion
is the same for all: one line, the right exit code, nothing lost, no file outside the
folder touched, no hang. ``make test`` runs a few hundred variants (seed 0); ``make
validate`` (``-m slow``) thousands more (seeds 1 to 10). A failure names the kind, the seed
and the index: ``tests/fuzz.py`` rebuilds that variant."""

from __future__ import annotations

import hashlib
import os
import shutil
import signal
import stat
from contextlib import contextmanager
from pathlib import Path

import h5py
import pytest

import fuzz
from spinweb_fe.cli import main
from spinweb_fe.errors import InputError

FAST = [str(fuzz.CASES / "paper_free_arms.toml"), "--no-progress", "--set", "time.end=0.004",
        "--set", "output.frame_dt=0.002"]
#: variants per kind in make test (seed 0) and per seed in make validate
COUNTS = {"case": 240, "sweep": 80, "design": 40, "folder": 30}
SLOW_SEEDS = range(1, 11)
HANG_S = 300  # [s] a variant that takes longer has hung (a cold compile: a minute)
RUN_ELEMENTS = 2e4  # valid case mutants up to this size are also run (make validate)


@contextmanager
def no_hang(what):
    def hung(signum, frame):
        raise TimeoutError(f"{what} hung for {HANG_S} s")

    old = signal.signal(signal.SIGALRM, hung)
    signal.alarm(HANG_S)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def tree(folder: Path) -> dict:
    """Every entry under ``folder`` as lstat sees it (a link by its target, never followed)."""
    out = {}
    if not os.path.lexists(folder):
        return out
    for dirpath, dirnames, filenames in os.walk(folder):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            mode = os.lstat(p).st_mode
            key = p.relative_to(folder).as_posix()
            if stat.S_ISLNK(mode):
                out[key] = "-> " + os.readlink(p)
            elif stat.S_ISREG(mode):
                out[key] = hashlib.sha256(p.read_bytes()).hexdigest()
            else:
                out[key] = stat.S_IFMT(mode)
    return out


def judge(what, code, err, allowed=(0, 2)):
    """One line and the right code: exit 2 is exactly one 'spinweb: error:' line, exit 1
    ends in one 'spinweb: ... failed' or 'interrupted' line; never a traceback or an
    internal error."""
    assert code in allowed, f"{what}: exit {code}\n{err}"
    assert "Traceback" not in err and "internal error" not in err, f"{what}:\n{err}"
    lines = err.strip().splitlines()
    if code == 2:
        assert len(lines) == 1 and lines[0].startswith("spinweb: error: "), f"{what}:\n{err}"
    if code == 1:
        assert lines and lines[-1].startswith("spinweb: ") and (
            "failed" in lines[-1] or "interrupted" in lines[-1]), f"{what}:\n{err}"


def readable(path: Path) -> bool:
    try:
        with h5py.File(path, "r") as h5:
            return h5["history/time"].shape[0] > 0
    except (OSError, KeyError):
        return False


# -- case, sweep and design files --------------------------------------------------------

def run_case_variant(path, sets, what, tmp_path, capsys):
    """A valid mutant run for a few steps (small ones only): one line and the right code,
    nothing written when refused, a readable file when done."""
    from spinweb_fe import case as case_mod
    from spinweb_fe.run.estimate import case_elements

    tiny = ["--set", "output.history_dt=1e-4", "--set", "time.end=2e-4", "--set",
            "output.frame_dt=0", "--no-progress"]
    try:
        if case_elements(case_mod.load(path, [a for a in sets if a != "--set"])) > RUN_ELEMENTS:
            return
    except InputError:
        pass
    out = tmp_path / (path.stem + "_run")
    with no_hang(what):
        code = main(["run", str(path), *sets, *tiny, "-o", str(out)])
    judge(what + " (run)", code, capsys.readouterr().err, allowed=(0, 1, 2))
    if code == 2:
        assert not os.path.lexists(out), f"{what}: refused, but wrote {out}"
    if code == 0:
        assert readable(out / "results.h5"), what


def check_cases(seed, count, tmp_path, capsys, run=False):
    for i in range(count):
        data, sets = fuzz.case_variant(seed, i)
        path = tmp_path / f"case_{seed}_{i}.toml"
        path.write_bytes(data)
        what = f"case variant (seed {seed}, index {i})"
        with no_hang(what):
            code = main(["check", str(path), *sets])
        out, err = capsys.readouterr()
        judge(what, code, err)
        if code == 0:  # what check prints is a case again, resolved the same way
            again = tmp_path / f"resolved_{seed}_{i}.toml"
            again.write_text(out)
            assert main(["check", str(again)]) == 0, f"{what}: its resolved case\n{out}"
            assert capsys.readouterr().out == out, what
            if run:
                run_case_variant(path, sets, what, tmp_path, capsys)


def check_sweeps(seed, count, tmp_path, capsys):
    for i in range(count):
        data, args = fuzz.sweep_variant(seed, i)
        path = tmp_path / f"sweep_{seed}_{i}.toml"
        path.write_bytes(data)
        out = tmp_path / f"sweep_out_{seed}_{i}"
        what = f"sweep variant (seed {seed}, index {i})"
        with no_hang(what):
            code = main(["sweep", str(path), "--dry-run", "-o", str(out), *args])
        judge(what, code, capsys.readouterr().err)
        assert not os.path.lexists(out), f"{what}: a dry run wrote {out}"


def check_designs(seed, count, tmp_path, capsys):
    from spinweb_fe.sweep.design import load_design

    for i in range(count):
        path = tmp_path / f"design_{seed}_{i}.toml"
        path.write_bytes(fuzz.design_variant(seed, i))
        what = f"design variant (seed {seed}, index {i})"
        with no_hang(what):
            try:
                load_design(path)
            except InputError as exc:
                assert "\n" not in str(exc), what
            else:
                continue  # a valid design would search: the load is what is fuzzed
            out = tmp_path / f"design_out_{seed}_{i}"
            code = main(["design", str(path), "-o", str(out), "--no-fe"])
        judge(what, code, capsys.readouterr().err, allowed=(2,))
        assert not os.path.lexists(out), what


# -- result folders ----------------------------------------------------------------------

@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished run with a checkpoint, copied by each folder variant."""
    out = tmp_path_factory.mktemp("fuzz") / "done"
    assert main(["run", *FAST, "--checkpoint-dt", "0.002", "-o", str(out)]) == 0
    return out


def plant(folder: Path, outside: Path, name: str, kind: str):
    """Put an entry the tool did not make at ``folder/name``: a link to a file (or a run's
    folder) outside, a FIFO, a folder with a file, or garbage bytes."""
    path = folder / name
    path.parent.mkdir(parents=True, exist_ok=True)
    if os.path.lexists(path):
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
    if kind == "link":
        target = outside / ("run" if name in ("frames", ".previous", ".previous-dropped")
                            else "run/" + Path(name).name if name.endswith((".h5", ".pvd"))
                            else "victim.txt")
        path.symlink_to(target)
    elif kind == "fifo":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
        (path / "inside.txt").write_text("someone's")
    else:
        path.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(range(256)) * 4)


def check_folders(seed, count, tmp_path, capsys, finished):
    outside = tmp_path / "outside"
    shutil.copytree(finished, outside / "run")
    (outside / "victim.txt").write_text("not spinweb's\n")
    before_outside = tree(outside)
    for i in range(count):
        plants, command = fuzz.folder_variant(seed, i)
        folder = tmp_path / f"folder_{seed}_{i}"
        shutil.copytree(finished, folder, symlinks=True)
        for name, kind in plants:
            plant(folder, outside, name, kind)
        before = tree(folder)
        what = f"folder variant (seed {seed}, index {i}: {plants}, {command})"
        argv = {"run": ["run", *FAST, "-o", str(folder)],
                "restart": ["run", "--restart", str(folder), "--set", "time.end=0.008",
                            "--no-progress"],
                "info": ["info", str(folder / "results.h5")]}[command]
        with no_hang(what):
            code = main(argv)
        judge(what, code, capsys.readouterr().err, allowed=(0, 1, 2))
        assert tree(outside) == before_outside, f"{what}: changed a file outside the folder"
        if code == 2:
            assert tree(folder) == before, f"{what}: refused, but changed the folder"
        planted = {name.split("/")[0] for name, _ in plants}
        if code == 0 and command != "info" or "results.h5" not in planted:
            assert readable(folder / "results.h5"), f"{what}: lost the result"


# -- the tests ---------------------------------------------------------------------------

def test_fuzz_case_files(tmp_path, capsys):
    check_cases(0, COUNTS["case"], tmp_path, capsys)


def test_fuzz_sweep_files(tmp_path, capsys):
    check_sweeps(0, COUNTS["sweep"], tmp_path, capsys)


def test_fuzz_design_files(tmp_path, capsys):
    check_designs(0, COUNTS["design"], tmp_path, capsys)


def test_fuzz_result_folders(tmp_path, capsys, finished):
    check_folders(0, COUNTS["folder"], tmp_path, capsys, finished)


@pytest.mark.slow
@pytest.mark.parametrize("seed", SLOW_SEEDS)
def test_fuzz_thousands(seed, tmp_path, capsys, finished):
    check_cases(seed, COUNTS["case"], tmp_path, capsys, run=True)
    check_sweeps(seed, COUNTS["sweep"], tmp_path, capsys)
    check_designs(seed, COUNTS["design"], tmp_path, capsys)
    check_folders(seed, COUNTS["folder"], tmp_path, capsys, finished)
