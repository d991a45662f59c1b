"""The environment a command starts in: variables that would break numba, OpenMP or
matplotlib refused in one line, and other libraries' messages kept to one line each
(docs/robustness.md, "Hostile environment").

numba reads its ``NUMBA_*`` variables when it is imported: a thread count that is not a
positive integer ends in a traceback there, an unknown threading layer or one that is not
installed at the first parallel call; a value it cannot parse it ignores with a warning of a
dozen lines. matplotlib refuses an unknown ``MPLBACKEND`` with a traceback and logs a line
per bad line of an rc file. So, before a command starts:

- :func:`check_environment` refuses (InputError, exit code 2, one line naming the variable)
  ``NUMBA_NUM_THREADS`` and ``OMP_NUM_THREADS`` that are not positive integers and a
  ``NUMBA_THREADING_LAYER`` that numba does not have or cannot load;
- ``MPLBACKEND`` is set to ``Agg`` (every figure is drawn into a file), with one line when
  it said something else;
- :class:`OneLine` keeps another library's log messages to its first warning, on one line,
  and :func:`show_warning` prints a Python warning as one line (``-v`` shows them all).
"""

from __future__ import annotations

import logging
import os
import re

from spinweb_fe.errors import InputError

log = logging.getLogger(__name__)

SOURCE = "environment"
#: numba's threading layers: the names it reads and the library each needs
LAYERS = ("default", "safe", "forksafe", "threadsafe", "workqueue", "omp", "tbb")
#: the commands that draw (matplotlib)
DRAWING = ("plot", "render", "sweep", "design", "modes", "prestress")


def _positive_ints(text: str, sep: str = ",") -> bool:
    return all(re.fullmatch(r"\s*[1-9][0-9]{0,5}\s*", part) for part in text.split(sep))


def check_environment(command: str, environ=None) -> None:
    """Refuse the variables that would break a command (InputError naming the variable);
    set ``MPLBACKEND`` to Agg."""
    env = os.environ if environ is None else environ
    threads = env.get("NUMBA_NUM_THREADS")
    if threads is not None and not re.fullmatch(r"\s*[1-9][0-9]{0,5}\s*", threads):
        raise InputError(SOURCE, "NUMBA_NUM_THREADS", f"must be an integer >= 1 (numba's "
                         f"thread count), got {threads!r}")
    omp = env.get("OMP_NUM_THREADS")
    if omp is not None and not _positive_ints(omp):
        raise InputError(SOURCE, "OMP_NUM_THREADS", f"must be an integer >= 1 (or a comma "
                         f"list of them), got {omp!r}")
    layer = env.get("NUMBA_THREADING_LAYER")
    if layer is not None:
        if layer.strip().lower() not in LAYERS:
            raise InputError(SOURCE, "NUMBA_THREADING_LAYER", f"unknown layer {layer!r} "
                             f"(numba's: {', '.join(LAYERS)})")
        if layer.strip().lower() in ("omp", "tbb"):  # libraries that may be missing
            _check_layer(layer)
    backend = env.get("MPLBACKEND")
    if backend is not None and backend.strip().lower() != "agg":
        env["MPLBACKEND"] = "Agg"
        if command in DRAWING:
            log.warning("MPLBACKEND=%r is not used: spinweb draws into files (Agg)", backend)


def _check_layer(layer: str) -> None:
    """Start numba's threads with the requested layer (it fails there, not at import)."""
    try:
        from numba.np.ufunc import parallel

        parallel._launch_threads()
    except (ValueError, ImportError, OSError) as exc:
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise InputError(SOURCE, "NUMBA_THREADING_LAYER", f"{layer!r} cannot be loaded "
                         f"here ({text})") from None


class OneLine(logging.Filter):
    """Other libraries' log records: warnings and worse only, the first of each library,
    on one line (its first), with a note that more were hidden."""

    def __init__(self):
        super().__init__()
        self.seen = set()

    def filter(self, record: logging.LogRecord) -> bool:
        if record.name.split(".")[0] == "spinweb_fe":
            return True
        if record.levelno < logging.WARNING:
            return False
        top = record.name.split(".")[0]
        if top in self.seen:
            return False
        self.seen.add(top)
        first = (record.getMessage().strip().splitlines() or [""])[0]
        record.msg, record.args = f"{top}: {first} (its further messages hidden; -v shows " \
                                  "them)", None
        return True


_shown = set()


#: numpy's floating-point warnings: the checks that follow name the key (debug only)
FLOATING = re.compile(r"(divide by zero|overflow|underflow|invalid value) encountered")


def show_warning(message, category, filename, lineno, file=None, line=None):
    """``warnings.showwarning`` on one line (the first of the message), each text once;
    numpy's floating-point warnings (inf or nan on the way to a check that refuses the
    value, naming its key) at debug level."""
    first = (str(message).strip().splitlines() or [category.__name__])[0]
    if issubclass(category, RuntimeWarning) and FLOATING.search(first):
        log.debug("warning: %s (%s:%s)", first, filename, lineno)
        return
    if first in _shown:
        return
    _shown.add(first)
    log.warning("warning: %s", first)
