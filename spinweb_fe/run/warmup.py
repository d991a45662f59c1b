"""A cold start on two cores: the step loop's largest phases compiled by a forked helper.

numba compiles the step loop (fe.step.advance) as one tree: typing the loop compiles each
phase it calls when it meets it, one after the other, on one core (the demo's cold start
spends about 15 s there, docs/performance.md). When numba's cache holds no step loop for the
scene's types and the machine has a second core, :func:`compile_helper` forks a process
that compiles the loop's largest phases into numba's cache, the last of the loop first,
while this process types the loop from its start. Where this process then meets a phase the
helper has finished, numba loads it from the cache instead of compiling it.

The helper only compiles: a phase loaded from the cache is the machine code this process
would have compiled, so nothing it does changes a result. Its output goes nowhere, it
ignores SIGINT (the run handles that), it is stopped as soon as the loop is compiled and
dies with this process. A phase whose types the list below no longer matches is compiled
twice, which costs time but nothing else (tests/test_warmup.py checks that the list matches
the loop). Linux only (elsewhere a run compiles as before), and the phases of a fixed axis
only (a free hub's are not listed). SPINWEB_COMPILE_HELPER=0 turns the helper off.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import signal
import sys
import threading

import numpy as np

from spinweb_fe.fe import step
from spinweb_fe.fe.coil.devices import axis_devices
from spinweb_fe.fe.hub.axis import AxisKick, NodeMotion, axis_nodes
from spinweb_fe.fe.coil.bundles import open_bundles
from spinweb_fe.fe.coil.levels import release_fronts

ENV = "SPINWEB_COMPILE_HELPER"
PR_SET_PDEATHSIG = 1


def phase_jobs(kernel, hub_kind, state, work, rec, threads) -> list:
    """(compiled function, argument types) of the step loop's phases the helper compiles,
    in the order it compiles them (the loop meets them in the reverse order), each with the
    types fe.step.advance passes: ``kernel`` the Model's kernel view, ``hub_kind`` its
    (axis, body), ``work``, ``rec`` and ``threads`` the loop's own (run.loop._Chunks).
    Empty for a free hub."""
    from numba import typeof
    from numba.core import types

    if hub_kind[0] is None:  # a free hub
        return []
    coil, cs, pos, mass = kernel.coil, state.coil, state.node_pos, state.node_mass
    elems, nodes = kernel.elements, kernel.nodes
    mv = NodeMotion(pos, state.node_vel, mass, state.node_inv_mass)
    jobs = [
        (axis_devices, (kernel.devices, cs, elems, nodes, kernel.hub, mv, state.hub, 0.0,
                        0.0)),
        (open_bundles, (kernel.bundles, cs, nodes, mass, state.node_inv_mass, 0.0)),
        (release_fronts, (coil, cs, elems, nodes, pos, mass, state.node_inv_mass, 0.0, 0.0,
                          state.strength.broken, types.Omitted(None))),
        (axis_nodes, (nodes, kernel.hub, mv, AxisKick(0.0, 0.0, 0.0, 0.0), work, 0.0,
                      np.zeros(5), True, threads)),
        (step.record_arms, (coil, cs, rec.arm_table[0], 0.0, rec.slots.arm)),
    ]
    return [(fn, tuple(a if isinstance(a, types.Type) else typeof(a) for a in args))
            for fn, args in jobs]


def cached(dispatcher, args) -> bool:
    """True if ``dispatcher`` holds, in memory or in numba's cache for this CPU, a compile
    for the types of ``args`` (also when that cannot be told: then no helper is started)."""
    from numba import typeof

    try:
        sig = tuple(typeof(a) for a in args)
        if sig in dispatcher.overloads:
            return True
        magic = dispatcher.targetctx.codegen().magic_tuple()
        index = dispatcher._cache._cache_file._load_index()
        return any(key[0] == sig and key[1] == magic for key in index)
    except Exception:  # numba's cache internals changed: no helper
        return True


def wanted() -> bool:
    """The helper is on (SPINWEB_COMPILE_HELPER is not 0) and can help: Linux (a forked
    child there needs nothing of the parent's threads, and dies with it) and this process
    may run on two or more cores (its CPU affinity)."""
    if os.environ.get(ENV, "1").strip() == "0" or not sys.platform.startswith("linux"):
        return False
    return len(os.sched_getaffinity(0)) >= 2


def _helper(jobs, parent) -> None:
    """The forked process: compile ``jobs`` into numba's cache, then leave without running
    anything of the parent's (no atexit, no buffered output). ``parent``: the run's pid."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, _stop)
        with contextlib.suppress(Exception):  # die with the parent (Linux)
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
        if os.getppid() != parent:  # the run ended before the signal was set
            return
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, 1)
        os.dup2(null, 2)
        for fn, sig in jobs:
            fn.compile(sig)
    except BaseException:  # a stop, or anything else: the parent compiles what is left
        pass
    finally:
        os._exit(0)


def _stop(signum, frame):
    raise SystemExit(0)  # unwinds numba's compile (its cache files are written whole)


@contextlib.contextmanager
def compile_helper(chunks, state, dt, hooks=None):
    """Around the first call of the step loop ``chunks`` (run.loop._Chunks) on ``state`` with
    its features' ``hooks``: start the helper if the loop is not compiled yet for these
    types and :func:`wanted`, and stop it when the block ends. Yields the helper's pid
    (None: no helper)."""
    args = chunks.loop_args(state, dt, 0, hooks)
    pid = None
    if wanted() and not cached(step.advance, args):
        jobs = phase_jobs(args[0], (args[1], args[2]), state, chunks.work, chunks.rec,
                          chunks.threads)
        if jobs:
            parent = os.getpid()
            pid = os.fork()
            if pid == 0:
                _helper(jobs, parent)
    try:
        yield pid
    finally:
        if pid:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGTERM)
            threading.Thread(target=_reap, args=(pid,), daemon=True).start()


def _reap(pid):
    with contextlib.suppress(ChildProcessError):
        os.waitpid(pid, 0)
