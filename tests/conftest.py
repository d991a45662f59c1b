"""Every test starts with Python's own signal handlers (SIGINT raising KeyboardInterrupt,
SIGTERM the default) and gets back whatever it found afterwards: the signal tests and the
child processes they start (which inherit an ignored signal) must not depend on what an
earlier test in the same process, or a pytest-xdist worker's set-up, left installed."""

import signal

import pytest


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
