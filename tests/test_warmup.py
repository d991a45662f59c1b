"""The cold start's compile helper (spinweb_fe.run.warmup): its phases are the loop's, and a
cold run with it gives the same result and leaves no process behind."""

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from spinweb_fe.io.folder import LOCK_NAME
from spinweb_fe.run import warmup

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "cases" / "demo.toml"

#: in a fresh process with an empty numba cache: compile the helper's phases of the demo's
#: scene (one thread) and of the same scene on two threads, then the step loop itself;
#: print which functions the loop's compile compiled
MATCH = textwrap.dedent("""
    import sys
    from numba.core import event as ev
    from spinweb_fe.case import load
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.fe.step import advance
    from spinweb_fe.record.arms import ArmTracker
    from spinweb_fe.run import warmup
    from spinweb_fe.run.loop import _Chunks, choose_threads, records_vectors
    mesh, model, control, state, dt = prepare(load(sys.argv[1]))
    threads = choose_threads(model, int(sys.argv[2]))
    chunks = _Chunks(model, control, ArmTracker(model.mesh, model.hub.radius), 50, threads,
                     dt, records_vectors(model, state))
    args = chunks.loop_args(state, dt, 0)
    assert not warmup.cached(advance, args)
    jobs = warmup.phase_jobs(args[0], (args[1], args[2]), state, chunks.work, chunks.rec,
                             chunks.threads)
    for fn, sig in jobs:
        fn.compile(sig)
    with ev.install_recorder("numba:compile") as rec:
        chunks.advance(state.copy(), dt, 0)
    print("JOBS", *sorted(fn.py_func.__name__ for fn, _ in jobs))
    print("LOOP", *sorted({e.data["dispatcher"].py_func.__name__ for _, e in rec.buffer}))
""")


def fresh_env(tmp_path, **extra):
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), **extra)
    env.pop("SPINWEB_THREADS", None)
    return env


#: in a process on the numba cache a cold run of the demo (one thread) has just filled:
#: compile the helper's phases with the types phase_jobs gives them (a load from the cache
#: where the run's loop compiled or loaded the same types), then print each phase's
#: compiles in the cache (its index's entries for this CPU)
INDEX = textwrap.dedent("""
    import sys
    from spinweb_fe.case import load
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.record.arms import ArmTracker
    from spinweb_fe.run import warmup
    from spinweb_fe.run.loop import _Chunks, choose_threads, records_vectors
    mesh, model, control, state, dt = prepare(load(sys.argv[1], ["time.end=0.1"]))
    threads = choose_threads(model, 1)
    chunks = _Chunks(model, control, ArmTracker(model.mesh, model.hub.radius), 50, threads,
                     dt, records_vectors(model, state))
    args = chunks.loop_args(state, dt, 0)
    for fn, sig in warmup.phase_jobs(args[0], (args[1], args[2]), state, chunks.work,
                                     chunks.rec, chunks.threads):
        fn.compile(sig)
        magic = fn.targetctx.codegen().magic_tuple()
        keys = [k for k in fn._cache._cache_file._load_index() if k[1] == magic]
        print("PHASE", fn.py_func.__name__, len(keys))
""")


# (two threads, a second cold compile of the demo's whole loop, in make validate; one
# thread's phases are checked on the cache of the cold run below, which kills the
# phase-type mutant of tests/mutate.py)
@pytest.mark.fresh_compile
@pytest.mark.slow
def test_the_helpers_phases_are_the_ones_the_loop_compiles_on_two_threads(tmp_path):
    """With the helper's phases compiled first (their types as phase_jobs builds them), the
    step loop's cold compile on two threads compiles none of them again: it loads each
    from the cache. A phase of the list whose types drifted from the loop's would be
    compiled twice (the helper's work lost) and is named here (the node pass takes the
    thread count)."""
    threads = 2
    out = subprocess.run([sys.executable, "-c", MATCH, str(DEMO), str(threads)], cwd=ROOT,
                         env=fresh_env(tmp_path), capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    lines = dict(line.split(" ", 1) for line in out.stdout.splitlines()
                 if line.startswith(("JOBS", "LOOP")))
    jobs, loop = set(lines["JOBS"].split()), set(lines["LOOP"].split())
    assert {"axis_nodes", "release_fronts", "record_arms"} <= jobs
    assert "advance" in loop  # the recorder saw the loop's own compile
    assert not jobs & loop, f"compiled again by the loop: {sorted(jobs & loop)}"


@pytest.mark.fresh_compile
def test_a_cold_run_with_the_helper_gives_the_same_result_and_leaves_nothing(tmp_path):
    """A cold `spinweb run` of the demo (0.1 s) with the helper, then the same run with it
    off (warm cache): exit 0, bit-identical histories; after the first run's exit no
    process of its session is left (the helper stopped with the loop compiled). While the
    cold run compiles (its folder's lock there, no result yet), a second run into its
    folder exits 1 at once, without a compile, and changes nothing (issue #15: the lock is
    taken before the compile, tests/test_folders.py for the warm cases).

    Then the helper's phases, compiled with phase_jobs' types on the cold run's cache, load
    from it: each phase holds one compile there, the loop's. A phase listed with other
    types than the loop passes would hold two (the helper's work lost, the phase compiled
    twice) and is named here."""
    runs = {}
    for name, on in (("helper", "1"), ("plain", "0")):
        out = tmp_path / name
        cmd = [sys.executable, "-m", "spinweb_fe", "run", str(DEMO), "-o", str(out),
               "--no-progress", "--set", "time.end=0.1"]
        env = fresh_env(tmp_path, SPINWEB_COMPILE_HELPER=on)
        proc = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, start_new_session=True)
        if name == "helper":
            _second_run_is_refused(proc, cmd, env, out)
        _, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err.decode()[-2000:]
        for _ in range(50):  # the helper may take a moment to unwind
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.1)
        else:
            os.killpg(proc.pid, signal.SIGKILL)
            pytest.fail("a process of the run's session outlived it")
        with h5py.File(out / "results.h5") as f:
            runs[name] = {k: f["history"][k][()] for k in f["history"]}
    assert runs["helper"].keys() == runs["plain"].keys()
    for key, value in runs["plain"].items():
        assert np.array_equal(runs["helper"][key], value, equal_nan=True), key
    out = subprocess.run([sys.executable, "-c", INDEX, str(DEMO)], cwd=ROOT,
                         env=fresh_env(tmp_path), capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    phases = dict(line.split()[1:] for line in out.stdout.splitlines()
                  if line.startswith("PHASE"))
    assert {"axis_nodes", "release_fronts", "record_arms"} <= phases.keys()
    twice = sorted(name for name, n in phases.items() if n != "1")
    assert not twice, f"compiled with other types than the loop's: {twice}"


def _second_run_is_refused(first, cmd, env, out):
    """While ``first`` (a cold run into ``out``) compiles: a second run into the same
    folder exits 1 within 30 s naming the run in use, and the first goes on."""
    deadline = time.monotonic() + 60
    while not (out / LOCK_NAME).exists():
        assert first.poll() is None and time.monotonic() < deadline, first.communicate()
        time.sleep(0.02)
    assert not (out / "results.h5").exists()  # still in its set-up
    t0 = time.monotonic()
    second = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True,
                            timeout=120)
    assert second.returncode == 1 and "is in use by another run" in second.stderr
    assert not (out / "results.h5").exists() and first.poll() is None  # still compiling
    assert time.monotonic() - t0 < 30  # at once: a process start, no compile


def test_the_helper_is_off_when_asked_or_when_the_loop_is_compiled(tmp_path, monkeypatch):
    """SPINWEB_COMPILE_HELPER=0 turns it off. A compile in memory or in numba's cache counts
    as cached (no helper for a warm process or a warm cache), other types do not; a function
    without a cache cannot be told, and starts no helper."""
    import numba
    from numba import njit

    monkeypatch.setenv(warmup.ENV, "0")
    assert not warmup.wanted()
    monkeypatch.setenv(warmup.ENV, "1")
    assert warmup.wanted() == (sys.platform.startswith("linux")
                               and len(os.sched_getaffinity(0)) >= 2)
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))

    def twice(x):
        return 2 * x

    first = njit(cache=True)(twice)
    assert not warmup.cached(first, (1.0,))
    first(1.0)
    assert warmup.cached(first, (1.0,))  # in memory
    assert warmup.cached(njit(cache=True)(twice), (1.0,))  # in the cache on disk
    assert not warmup.cached(first, (np.zeros(2),))
    assert warmup.cached(njit(twice), (np.zeros(2),))  # no cache: cannot tell
