"""Determinism: the same case gives bit-identical histories when run twice in one process and
in two separate processes, for every thread count the step loop supports
(:func:`thread_counts`); different thread counts give the same bits too
(tests/test_threads.py); docs/robustness.md says what holds."""

import subprocess
import sys
from pathlib import Path

import pytest

import numba

from spinweb_fe.cli import main
from spinweb_fe.io.h5 import read_history

CASES = Path(__file__).parent.parent / "cases"
# the star-folded web starts in rigid rotation on the slack/taut kink: the most sensitive scene
ARGS = [str(CASES / "paper_free_web.toml"), "--no-progress", "--set", "output.frame_dt=0"]
# serial: 0.1 s (1500 steps); threaded runs pay two parallel regions per step, which take
# milliseconds on a loaded 2-core machine, so they run 0.005 s (75 steps, 6 rows): a
# reduction order that varied would show from the first step on
END = {1: 0.1}


def thread_counts() -> tuple:
    """Representative thread counts of the step loop on this machine: 1, 2 and the size of
    numba's thread pool, as far as the pool allows."""
    pool = numba.config.NUMBA_NUM_THREADS
    return tuple(sorted({1, min(2, pool), pool}))


def assert_identical(a: dict, b: dict):
    assert a.keys() == b.keys()
    for key in a:
        assert a[key].dtype == b[key].dtype and a[key].shape == b[key].shape, key
        assert a[key].tobytes() == b[key].tobytes(), key


@pytest.mark.parametrize("threads", thread_counts())
def test_same_case_twice_in_one_process_and_in_two_processes(threads, tmp_path, capsys):
    end = END.get(threads, 0.005)
    args = ARGS + ["--set", f"time.end={end}", "--threads", str(threads)]
    runs = []
    for k in range(2):
        out = tmp_path / f"in_process_{k}"
        assert main(["run", *args, "-o", str(out)]) == 0
        runs.append(read_history(out / "results.h5"))
    capsys.readouterr()
    procs = [subprocess.Popen([sys.executable, "-m", "spinweb_fe", "run", *args, "-o",
                               str(tmp_path / f"process_{k}")],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for k in range(2)]
    for k, p in enumerate(procs):
        _, err = p.communicate(timeout=120)
        assert p.returncode == 0, err
        runs.append(read_history(tmp_path / f"process_{k}" / "results.h5"))
    for other in runs[1:]:
        assert_identical(runs[0], other)
    assert len(runs[0]["time"]) == round(end / 1e-3) + 1


def test_thread_counts_are_usable():
    counts = thread_counts()
    assert counts[0] == 1 and all(isinstance(n, int) and n >= 1 for n in counts)
