"""Hostile environments and stops where they land (issue #46, item 6): environment variables
that break numba, OpenMP or matplotlib end in one line; a SIGINT / SIGTERM that lands inside
a C callback of numba's compiler (LLVM's object cache) stops quietly; any error the CLI does
not expect is one line, not a traceback."""

import ctypes
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from spinweb_fe.cli import main
from spinweb_fe.errors import InputError, RunInterrupted
from spinweb_fe.run.terminal import StopSignals

CASES = Path(__file__).parent.parent / "cases"
FAST = [str(CASES / "paper_free_arms.toml"), "--no-progress", "--set", "time.end=0.004"]


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("var,value,words", [
    ("NUMBA_NUM_THREADS", "0", "must be an integer >= 1"),
    ("NUMBA_NUM_THREADS", "-1", "must be an integer >= 1"),
    ("NUMBA_NUM_THREADS", "abc", "must be an integer >= 1"),
    ("OMP_NUM_THREADS", "abc", "must be an integer >= 1"),
    ("OMP_NUM_THREADS", "4,0", "must be an integer >= 1"),
    ("NUMBA_THREADING_LAYER", "foo", "unknown layer 'foo'"),
])
def test_variables_that_break_numba_are_refused(var, value, words, capsys, monkeypatch):
    """Each ended in a traceback (numba's import, its first parallel call) or in libgomp's
    own lines; now exit 2 with one line naming the variable."""
    monkeypatch.setenv(var, value)
    assert main(["check", FAST[0]]) == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith(f"spinweb: error: environment: {var}: ") and words in line, line


def test_good_values_pass_and_the_backend_is_agg(monkeypatch):
    from spinweb_fe.cli.environ import check_environment

    env = {"NUMBA_NUM_THREADS": "2", "OMP_NUM_THREADS": "4,2", "NUMBA_THREADING_LAYER":
           "workqueue", "MPLBACKEND": "TkAgg"}
    check_environment("plot", env)
    assert env["MPLBACKEND"] == "Agg"
    with pytest.raises(InputError):
        check_environment("run", {"NUMBA_THREADING_LAYER": "omq"})


def test_a_fresh_process_with_a_bad_thread_count_says_one_line(tmp_path):
    """NUMBA_NUM_THREADS=0 broke `import numba` itself: a 40-line traceback on main."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "0"}
    p = subprocess.run([sys.executable, "-m", "spinweb_fe", "check", FAST[0]], env=env,
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert "NUMBA_NUM_THREADS" in one_line(p.stderr)


def test_library_noise_is_one_line_each(tmp_path, capsys):
    """A bad MPLBACKEND (a traceback on main), an rc file that is not one (a line per bad
    line: 120 for /etc/passwd) and a NUMBA_OPT numba cannot parse (an 11-line warning): the
    plot is drawn, and each says one line."""
    assert main(["run", *FAST, "-o", str(tmp_path / "r")]) == 0
    capsys.readouterr()
    rc = tmp_path / "matplotlibrc"
    rc.write_text("".join(f"not a key {i}\n" for i in range(50)))
    env = {**os.environ, "MPLBACKEND": "foo", "MATPLOTLIBRC": str(rc), "NUMBA_OPT": "x",
           "MPLCONFIGDIR": str(tmp_path / "mpl")}
    p = subprocess.run([sys.executable, "-m", "spinweb_fe", "plot",
                        str(tmp_path / "r" / "results.h5"), "-o", str(tmp_path / "p.png")],
                       env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "p.png").stat().st_size > 0
    lines = p.stderr.strip().splitlines()
    assert "Traceback" not in p.stderr and len(lines) <= 3, p.stderr
    assert any("MPLBACKEND" in x for x in lines) and any("NUMBA_OPT" in x for x in lines)


def test_a_stop_inside_a_c_callback_is_the_stop(capsys):
    """SIGTERM during a cold compile (4 of 16 on main): the handler's exception was raised
    inside LLVM's object-cache callback, where Python prints it ('Exception ignored ...',
    a traceback) and numba goes on to fail with an error of its own (RuntimeError: no
    compiled object yet). Now nothing is printed and the stop is what comes out."""
    callback = ctypes.CFUNCTYPE(None)(lambda: os.kill(os.getpid(), signal.SIGTERM))

    def compile_like_numba():
        callback()  # the signal's handler runs inside the callback
        raise RuntimeError("no compiled object yet for <Library 'element_block'>")

    with pytest.raises(RunInterrupted) as info:
        with StopSignals() as stop:
            with stop.immediate():
                compile_like_numba()
    assert info.value.signame == "SIGTERM" and "set-up" in str(info.value)
    assert "Exception ignored" not in capsys.readouterr().err


def test_a_second_sigint_inside_a_callback_is_the_stop(capsys):
    """The same outside the set-up: Ctrl-C twice while numba compiles a kernel of the loop."""
    callback = ctypes.CFUNCTYPE(None)(lambda: os.kill(os.getpid(), signal.SIGINT))
    with pytest.raises(RunInterrupted) as info:
        with StopSignals() as stop:
            os.kill(os.getpid(), signal.SIGINT)  # the first: a flag
            assert stop() == "SIGINT"
            callback()  # the second raises KeyboardInterrupt inside the callback
            raise RuntimeError("no compiled object yet")
    assert info.value.signame == "SIGINT"
    assert "Exception ignored" not in capsys.readouterr().err


def test_an_unexpected_error_is_one_line(monkeypatch, capsys):
    """An error the CLI does not expect (a bug) is one line naming it, exit 1; -v logs the
    traceback."""
    from spinweb_fe.cli import check

    def broken(args):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(check, "run", broken)
    assert main(["check", FAST[0]]) == 1
    line = one_line(capsys.readouterr().err)
    assert line.startswith("spinweb: check failed: internal error: ZeroDivisionError: float "
                           "division by zero"), line
    assert main(["-v", "check", FAST[0]]) == 1
    assert "Traceback" in capsys.readouterr().err


@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_a_signal_during_start_up_is_one_line(signame):
    """A signal while the command line is still being imported: a KeyboardInterrupt
    traceback (SIGINT) or a silent exit 143 (SIGTERM) on main. The signal is sent by an
    import hook when spinweb_fe.cli starts to load, so the moment is exact."""
    code = ("import importlib.abc, os, runpy, signal, sys\n"
            "class Hook(importlib.abc.MetaPathFinder):\n"
            "    def find_spec(self, name, path, target=None):\n"
            "        if name == 'spinweb_fe.cli':\n"
            f"            os.kill(os.getpid(), signal.{signame})\n"
            "        return None\n"
            "sys.meta_path.insert(0, Hook())\n"
            f"sys.argv = ['spinweb', 'check', {FAST[0]!r}]\n"
            "runpy.run_module('spinweb_fe', run_name='__main__')\n")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 1
    assert one_line(p.stderr) == f"spinweb: interrupted by {signame}"
