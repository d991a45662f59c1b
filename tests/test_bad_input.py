"""Bad input matrix: every file in tests/bad_cases/ must make ``spinweb run FILE -o DIR`` exit
with code 2 and one stderr line naming the file, the key and the reason, write nothing, and
leave the results of an earlier good run in DIR untouched.

Each bad file states what it expects on its first line: ``# expect: KEY | REASON`` (KEY ``-``
when the whole file is at fault). Files that cannot carry a comment are listed in NO_COMMENT.
"""

import hashlib
import subprocess
import sys
from pathlib import Path

import pytest

from spinweb_fe.cli import main

HERE = Path(__file__).parent
BAD = sorted((HERE / "bad_cases").glob("*.toml"))
CASES = HERE.parent / "cases"
NO_COMMENT = {"empty.toml": ("-", "the file is empty")}
MISSING = HERE / "bad_cases" / "does_not_exist.toml"
#: a few run in a real process too (file-level, schema, cross-key and mesh errors)
IN_SUBPROCESS = ("not_utf8", "syntax_error", "nan_youngs_modulus", "hub_larger_than_web",
                 "mesh_width_not_dividing", "spin_ramp_nonzero_omega")


def expectation(path: Path):
    """(key, reason fragment) a bad case file announces on its first line."""
    if path.name in NO_COMMENT:
        return NO_COMMENT[path.name]
    if path == MISSING:
        return "-", "no such file"
    first = path.read_bytes().split(b"\n", 1)[0].decode("ascii")
    assert first.startswith("# expect: "), f"{path.name}: first line: '# expect: KEY | REASON'"
    key, reason = first[len("# expect: "):].split(" | ", 1)
    return key.strip(), reason.strip()


def check_message(err: str, path: Path):
    """One line: 'spinweb: error: FILE: KEY: REASON' (FILE: REASON for file-level errors)."""
    key, reason = expectation(path)
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    line = lines[0]
    where = f"{path}: " if key == "-" else f"{path}: {key}: "
    assert line.startswith("spinweb: error: " + where), line
    assert reason in line[len("spinweb: error: " + where):], (reason, line)


def digest(folder: Path) -> dict:
    """sha256 of every file under folder (results.h5, web.pvd, frames)."""
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def good_run(tmp_path_factory):
    """A folder holding the results of an earlier, successful run."""
    out = tmp_path_factory.mktemp("good")
    assert main(["run", str(CASES / "paper_free_arms.toml"), "-o", str(out), "--no-progress",
                 "--set", "time.end=0.004", "--set", "output.frame_dt=0.002"]) == 0
    return out, digest(out)


def test_the_matrix_is_large_enough():
    assert len(BAD) >= 30
    keys = {expectation(p)[0] for p in BAD}
    assert len(keys) >= 20  # many different keys, not one key thirty times


def exit_code(args):
    """main's exit code, or the exception a bad input let through (a traceback instead of
    one line: the assertion on the code then says which)."""
    try:
        return main(args)
    except Exception as exc:  # noqa: BLE001 - any escape is the failure under test
        return f"{type(exc).__name__}: {exc}"


@pytest.mark.parametrize("path", BAD + [MISSING], ids=lambda p: p.stem)
def test_bad_case_exits_2_and_writes_nothing(path, tmp_path, capsys, good_run):
    fresh = tmp_path / "fresh"
    assert exit_code(["run", str(path), "-o", str(fresh), "--no-progress"]) == 2
    check_message(capsys.readouterr().err, path)
    assert not fresh.exists()
    # a folder with results of an earlier good run: never damaged
    out, before = good_run
    assert exit_code(["run", str(path), "-o", str(out), "--no-progress"]) == 2
    check_message(capsys.readouterr().err, path)
    assert digest(out) == before


@pytest.mark.parametrize("stem", IN_SUBPROCESS)
def test_bad_case_in_a_real_process(stem, tmp_path):
    path = HERE / "bad_cases" / f"{stem}.toml"
    p = subprocess.run([sys.executable, "-m", "spinweb_fe", "run", str(path),
                        "-o", str(tmp_path / "o")], capture_output=True, text=True, timeout=60)
    assert p.returncode == 2
    assert p.stdout == ""
    check_message(p.stderr, path)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("args,key,reason", [
    (["--checkpoint-dt", "0"], "--checkpoint-dt", "must be a finite time > 0 s"),
    (["--checkpoint-dt", "nan"], "--checkpoint-dt", "must be a finite time > 0 s"),
    (["--threads", "0"], "--threads", "must be >= 1"),
    (["--set", "hub.radius.x=1"], "--set", "'radius' is not a table"),
])
def test_bad_arguments_exit_2(args, key, reason, tmp_path, capsys):
    rc = main(["run", str(CASES / "paper_free_arms.toml"), "-o", str(tmp_path / "o")] + args)
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1
    assert err.startswith(f"spinweb: error: {key}") and reason in err
    assert not (tmp_path / "o").exists()


def test_restart_without_checkpoint_exits_2(tmp_path, capsys):
    assert main(["run", "--restart", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "checkpoint.h5: no checkpoint here" in err


def test_the_matrix_is_documented():
    """docs/robustness.md lists every bad case file with its key."""
    doc = (HERE.parent / "docs" / "robustness.md").read_text()
    for path in BAD:
        key = expectation(path)[0].replace("|", "\\|")  # a pipe in a table cell is escaped
        assert f"| `{path.name}` | `{key}` |" in doc, (path.name, key)
