"""``python -m spinweb_fe`` and the ``spinweb`` command (:func:`entry`).

SIGINT and SIGTERM stop the start-up quietly: until the command line is imported (numpy,
argparse: tens of milliseconds) a signal prints one line and exits 1, instead of Python's
KeyboardInterrupt traceback; then :func:`spinweb_fe.cli.main` handles them.
"""

import os
import signal
import sys


def _starting(signum, frame):
    os.write(2, f"spinweb: interrupted by {signal.Signals(signum).name}\n".encode())
    os._exit(1)


for _sig in (signal.SIGINT, signal.SIGTERM):
    if signal.getsignal(_sig) is not signal.SIG_IGN:  # (an ignored signal stays ignored)
        signal.signal(_sig, _starting)

from spinweb_fe.cli import main  # noqa: E402 - after the handlers

if signal.getsignal(signal.SIGINT) is _starting:
    signal.signal(signal.SIGINT, signal.default_int_handler)  # main's KeyboardInterrupt


def entry():
    """The console script ``spinweb``."""
    sys.exit(main())


if __name__ == "__main__":
    entry()
