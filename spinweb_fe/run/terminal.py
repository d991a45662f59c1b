"""The terminal side of a run: the progress bar and the stop signals."""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time

from spinweb_fe.errors import RunError, RunInterrupted
from spinweb_fe.record.recorders import Recorder
from spinweb_fe.run.progress import enabled as bar_wanted

SETUP = "during set-up, before anything was written"
LINE_EVERY_S = 60.0  # [s] wall time between two progress lines when stderr is no terminal


class Progress(Recorder):
    """Steps, simulated time, steps/s and the ETA of the loop on stderr: a tqdm bar on a
    terminal (not under CI), else one plain line every LINE_EVERY_S of wall time (a long
    batch run shows it is alive). Both start with the loop (the loop tells its start after
    the step loop is compiled or loaded): the ETA is the loop's rate, compile time left
    out."""

    def __init__(self, t_end, enabled=True):
        self.t_end = t_end
        self.enabled = bar_wanted(enabled)
        self.lines = enabled and not self.enabled
        self.bar = None
        self.dt = 1.0
        self.t0 = time.perf_counter()  # wall clock of the loop's start
        self.last_line = self.t0
        self.t_start = 0.0  # simulated time of the loop's start [s]

    def start(self, info):
        self.dt = info.dt
        self.t0 = self.last_line = time.perf_counter()
        self.t_start = info.step0 * info.dt
        if self.enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=info.n_total, initial=info.step0, desc="run", unit="step",
                            unit_scale=True, file=sys.stderr, dynamic_ncols=True,
                            mininterval=0.2, smoothing=0.3)
            self.bar.set_postfix_str(self._time(self.t_start), refresh=False)

    def _time(self, t) -> str:
        return f"t = {t:.4f} / {self.t_end:g} s"

    def rows(self, rows):
        t = float(rows["time"][-1])
        if self.lines:
            self._line(t)
        if self.bar is not None:
            step = min(int(round(t / self.dt)), self.bar.total)
            self.bar.set_postfix_str(self._time(t), refresh=False)
            self.bar.update(step - self.bar.n)

    def _line(self, t):
        now = time.perf_counter()
        if now - self.last_line < LINE_EVERY_S:
            return
        self.last_line = now
        frac = min(t / self.t_end, 1.0)
        el = now - self.t0
        done = t - self.t_start  # simulated in this call (a restart starts later)
        eta = el * (self.t_end - t) / done if done > 0 else float("nan")
        sys.stderr.write(f"t = {t:.6g} / {self.t_end:g} s ({100 * frac:.1f} %), "
                         f"{el / 60:.1f} min so far, ETA {eta / 60:.1f} min\n")
        sys.stderr.flush()

    def end(self, status):
        if self.bar is not None:  # once: the driver also ends it when the loop raised
            self.bar.close()
            self.bar = None


class StopSignals:
    """Context manager: SIGINT and SIGTERM set a flag instead of stopping the process
    (within :meth:`immediate` they stop it at once).

    Calling the object returns the name of the first signal received (or None); the
    solver checks it between two numba chunks. A second SIGINT (Ctrl-C twice, e.g. during
    a long first compilation) raises KeyboardInterrupt at once. The previous handlers are
    restored on exit. Outside the main thread (where Python cannot install handlers) it
    does nothing.
    """

    SIGNALS = ("SIGINT", "SIGTERM")

    def __init__(self):
        self.signame = None
        self.at_once = False
        self._previous = {}
        self._previous_hook = sys.unraisablehook

    def _handler(self, signum, frame):
        if self.signame is None:
            self.signame = signal.Signals(signum).name
            if self.at_once:
                raise RunInterrupted(self.signame, None, SETUP)
        elif signum == signal.SIGINT:
            raise KeyboardInterrupt

    def __call__(self):
        return self.signame

    @contextlib.contextmanager
    def immediate(self):
        """Within this block a signal stops at once (RunInterrupted): for set-up work that
        writes nothing, so that stopping it halfway leaves nothing half-written. What the
        stop turns into where it lands (numba's compiler, inside LLVM's callbacks, reports
        it as an error of its own) is reported as the stop it is."""
        self.at_once = True
        try:
            if self.signame:
                raise RunInterrupted(self.signame, None, SETUP)
            yield
        except Exception as exc:
            if self.signame and not isinstance(exc, RunInterrupted):
                raise RunInterrupted(self.signame, None, SETUP) from None
            raise
        finally:
            self.at_once = False

    def _unraisable(self, unraisable):
        """A stop raised inside a C callback (LLVM's object cache, during a compile) cannot
        unwind it: Python would print it as 'Exception ignored'. It is the stop already
        recorded; anything else goes to the previous hook."""
        if isinstance(unraisable.exc_value, (RunInterrupted, KeyboardInterrupt)):
            return
        self._previous_hook(unraisable)

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for name in self.SIGNALS:
                sig = getattr(signal, name)
                self._previous[sig] = signal.getsignal(sig)
                signal.signal(sig, self._handler)
            self._previous_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def __exit__(self, exc_type, exc, tb):
        for sig, handler in self._previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        if self._previous:
            sys.unraisablehook = self._previous_hook
        self._previous = {}
        if self.signame and isinstance(exc, Exception) and not isinstance(exc, RunError):
            # numba's error where the stop landed (a second SIGINT while it compiles)
            raise RunInterrupted(self.signame, None) from None
        return False
