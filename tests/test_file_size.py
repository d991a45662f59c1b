"""A file-size limit (``ulimit -f``) is the full disk by another road (issue #46, item 4):
refused before the run when results.h5 would outgrow it, and with --force stopped before
the write that would cross it: one line, exit 1, a readable results.h5 with every row and
frame flushed before. On main the write failed inside HDF5 (EFBIG; Python ignores SIGXFSZ)
and left an unreadable file and a cryptic message."""

import resource
from pathlib import Path

import h5py
import pytest

from spinweb_fe.cli import main

CASES = Path(__file__).parent.parent / "cases"
GROWING = [str(CASES / "paper_free_arms.toml"), "--no-progress", "--set", "time.end=0.6",
           "--set", "output.frame_dt=0.002", "--set", "output.history_dt=1e-4"]
LIMIT = 2560 * 1024  # [bytes] results.h5 of GROWING is about 4.5 MB


@pytest.fixture
def size_limit():
    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, hard))
    try:
        yield LIMIT
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))


def lines_of(err):
    return [x for x in err.strip().splitlines() if x]


def test_a_run_beyond_the_file_size_limit_is_refused(tmp_path, size_limit, capsys):
    out = tmp_path / "r"
    assert main(["run", *GROWING, "-o", str(out)]) == 2
    line = lines_of(capsys.readouterr().err)[-1]
    assert "file-size limit (ulimit -f)" in line and "--force" in line, line
    assert not out.exists()


def test_a_forced_run_stops_before_the_limit_with_a_readable_file(tmp_path, size_limit,
                                                                  capsys):
    out = tmp_path / "r"
    assert main(["run", *GROWING, "--force", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    last = lines_of(err)[-1]
    assert "Traceback" not in err
    assert last.startswith("spinweb: run failed: stopped at t = ") and \
        "file-size limit (ulimit -f)" in last, err
    path = out / "results.h5"
    assert path.stat().st_size < size_limit
    with h5py.File(path, "r") as h5:
        n_rows = h5["history/time"].shape[0]
        n_frames = h5["frames/time"].shape[0]
        assert "file-size limit" in h5.attrs["status"]
    assert n_rows > 100 and n_frames > 2
    assert not (out / ".reserve").exists() and not (out / "run.lock").exists()
