"""Every test starts with Python's own signal handlers (SIGINT raising KeyboardInterrupt,
SIGTERM the default) and gets back whatever it found afterwards: the signal tests and the
child processes they start (which inherit an ignored signal) must not depend on what an
earlier test in the same process, or a pytest-xdist worker's set-up, left installed.

Under pytest-xdist (``make test``: two workers on two cores) the cold start's compile helper
(spinweb_fe.run.warmup) is off, as in a sweep's workers (spinweb_fe.sweep.run): both cores
are busy already, and a helper forked beside a worker's loop compile competes with the
other worker for a core and compiles the phases the loop compiles at the same moment (a
cold suite logged 55 s of such compiles). tests/test_warmup.py and
tests/test_guards_start.py switch it on where they test it.

Tests marked ``fresh_compile`` (a cold compile into a numba cache of their own, about
18 s, whatever ran before: one in make test, tests/test_warmup.py) are collected first: pytest-xdist's worksteal gives each worker
a contiguous share of the list and the idle one steals from the other's end, so a long test
at the end of a share leaves the other core idle (two of them ran last on one worker, the
other idle for 26 s of a 283 s suite).

Each worker's BLAS (numpy's OpenBLAS) runs on one thread: two threads a worker on two cores
spin while the other worker holds the core (the prestress tests' SVD took 6.4 and 5.6 s of
CPU in the suite, 0.2 s each alone; a warm suite about 24 s more in all). OpenBLAS reads
the setting when numpy loads, and the workers import this file before numpy."""

import os
import signal

import pytest

if os.environ.get("PYTEST_XDIST_WORKER"):
    os.environ.setdefault("SPINWEB_COMPILE_HELPER", "0")
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # (the module's text)


@pytest.fixture(autouse=True)
def _default_signal_handlers():
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    try:
        yield
    finally:
        for s, handler in saved.items():
            if handler is not None:
                signal.signal(s, handler)


def pytest_collection_modifyitems(config, items):
    """The ``fresh_compile`` tests first (a stable sort: the rest keep their order)."""
    items.sort(key=lambda item: item.get_closest_marker("fresh_compile") is None)
