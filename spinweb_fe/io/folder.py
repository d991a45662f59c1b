"""A result folder belongs to one run at a time: its lock, the earlier result kept aside
until the new run's first flush, and the checks made before anything in it is touched.

- ``DIR/run.lock`` is held with ``flock`` (exclusive) for the whole run; it names the run
  (pid, host, start, command) and is removed when the run ends. The kernel drops the lock
  when the process dies, so a lock file that nobody holds is the trace of a killed run.
- A fresh run into a folder that holds a result moves that result (``results.h5``,
  ``web.pvd``, ``frames/``, ``checkpoint.h5``) into ``DIR/.previous/`` and deletes it only
  once its own first rows are flushed; a run that fails or is stopped before that puts the
  earlier result back. A ``.previous`` left by a killed run is put back by the next run.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import socket
import sys
import time
from pathlib import Path

from spinweb_fe.errors import InputError, RunError

LOCK_NAME = "run.lock"
ASIDE_NAME = ".previous"
#: what a run writes into its folder (moved aside as a whole, put back as a whole)
RESULT_ITEMS = ("results.h5", "web.pvd", "frames", "checkpoint.h5")
LOCK_WAIT_S = 0.5  # a reader's probe holds the lock for microseconds: retry this long


def check_writable(folder) -> Path:
    """Raise InputError unless ``folder`` is (or can be created as) a writable folder."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise InputError(folder, "", "exists and is not a folder")
    probe = folder
    while not probe.exists():  # the nearest existing ancestor must let us create it
        if probe.parent == probe:
            break
        probe = probe.parent
    if not probe.is_dir():
        raise InputError(folder, "", f"cannot be created: {probe} is not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        what = "is not writable" if probe == folder else f"cannot be created ({probe} is " \
                                                           "not writable)"
        raise InputError(folder, "", what)
    return folder


def holder(folder) -> dict | None:
    """What ``DIR/run.lock`` says about the live run that holds ``folder`` (None: none).

    The answer has ``pid``, ``host``, ``started`` and ``command`` when the lock file could
    be read; an empty dict when a run holds the lock but has not written them yet."""
    path = Path(folder) / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                return json.loads(os.read(fd, 4096).decode() or "{}")
            except ValueError:
                return {}
        fcntl.flock(fd, fcntl.LOCK_UN)
        return None
    finally:
        os.close(fd)


def describe(info: dict) -> str:
    """'pid 1234 on host, started 2026-01-01T10:00:00: spinweb run ...'."""
    if not info:
        return "a run that is starting"
    return (f"pid {info.get('pid')} on {info.get('host')}, started {info.get('started')}: "
            f"{info.get('command')}")


def busy(folder, info) -> RunError:
    return RunError(f"{folder} is in use by another run ({describe(info)}); "
                    "nothing was changed")


class FolderLock:
    """The exclusive lock of a result folder (a context manager; creates the folder).

    Raises
    ------
    RunError
        If another live run holds it (named, one line); nothing in the folder changed.
    """

    def __init__(self, folder):
        self.folder = Path(folder)
        self.path = self.folder / LOCK_NAME
        self.fd = None
        self.created = False

    def acquire(self):
        self.created = not self.folder.exists()
        self.folder.mkdir(parents=True, exist_ok=True)
        deadline = time.monotonic() + LOCK_WAIT_S
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                if time.monotonic() > deadline:
                    raise busy(self.folder, holder(self.folder) or {}) from None
                time.sleep(0.01)
                continue
            try:  # the file we locked must still be the one at the path (not unlinked)
                same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
                "command": " ".join(["spinweb", *sys.argv[1:]])
                if Path(sys.argv[0]).name in ("spinweb", "__main__.py") else " ".join(sys.argv)}
        os.ftruncate(fd, 0)
        os.write(fd, (json.dumps(info) + "\n").encode())
        self.fd = fd
        return self

    def release(self):
        if self.fd is None:
            return
        try:
            self.path.unlink(missing_ok=True)
        finally:
            os.close(self.fd)
            self.fd = None
        if self.created:  # a claim that wrote nothing leaves no folder behind
            try:
                self.folder.rmdir()
            except OSError:
                pass

    def __enter__(self):
        return self.acquire()

    def __exit__(self, *exc):
        self.release()
        return False


class Aside:
    """The earlier result of a folder, moved to ``DIR/.previous`` while a new run starts.

    Call :meth:`drop` once the new run's first rows are on disk (the earlier result is
    deleted), :meth:`restore` if the new run ends before that (the new files are deleted
    and the earlier ones put back). ``.previous/MANIFEST`` lists what was moved, written
    before the moves, so that a run killed halfway through any of this is undone by the
    next one (:meth:`recover`). Only ever used under the folder's lock.
    """

    def __init__(self, folder):
        self.folder = Path(folder)
        self.dir = self.folder / ASIDE_NAME
        self.moved = []
        self.done = False

    @staticmethod
    def recover(folder):
        """Put back a ``.previous`` that a killed run left (its own files never got a
        first flush), finish a drop that was cut short; True if something was put back."""
        aside = Aside(folder)
        _remove(aside.folder / (ASIDE_NAME + "-dropped"))
        if not aside.dir.is_dir():
            return False
        try:
            aside.moved = json.loads((aside.dir / "MANIFEST").read_text())
        except (OSError, ValueError):  # no manifest: what is there was moved
            aside.moved = [n for n in RESULT_ITEMS if os.path.lexists(aside.dir / n)]
        aside.restore()
        return True

    def move(self):
        found = [n for n in RESULT_ITEMS if os.path.lexists(self.folder / n)]
        if not found:
            self.done = True
            return self
        self.dir.mkdir()
        (self.dir / "MANIFEST").write_text(json.dumps(found))
        for name in found:
            os.replace(self.folder / name, self.dir / name)
            self.moved.append(name)
        return self

    def drop(self):
        if self.done:
            return
        self.done = True
        trash = self.folder / (ASIDE_NAME + "-dropped")
        os.replace(self.dir, trash)  # one rename: a kill can no longer bring it back
        shutil.rmtree(trash, ignore_errors=True)

    def restore(self):
        if self.done:
            return
        self.done = True
        for name in RESULT_ITEMS:
            if name in self.moved and not os.path.lexists(self.dir / name):
                continue  # already back (a restore cut short), or never moved
            _remove(self.folder / name)  # the new run's file
            if name in self.moved:
                os.replace(self.dir / name, self.folder / name)
        _remove(self.dir)


def _remove(path: Path):
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
    except FileNotFoundError:
        pass
    except OSError as exc:
        if exc.errno != errno.ENOENT:
            raise
