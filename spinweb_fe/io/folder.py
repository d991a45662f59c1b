"""A result folder belongs to one run at a time: its lock, the earlier result kept aside
until the new run's first flush, and the checks made before anything in it is touched.

- ``DIR/run.lock`` is held with ``flock`` (exclusive) for the whole run; it names the run
  (pid, host, start, command) and is removed when the run ends. The kernel drops the lock
  when the process dies, so a lock file that nobody holds is the trace of a killed run.
  A lock that is not a regular file (a link, a FIFO, a folder) is refused in one line; it
  is opened without following links and without blocking.
- A fresh run into a folder that holds a result moves that result (``results.h5``,
  ``web.pvd``, ``frames/``, ``checkpoint.h5``) into ``DIR/.previous/`` and deletes it only
  once its own first rows are flushed; a run that fails or is stopped before that puts the
  earlier result back. A ``.previous`` left by a killed run is put back by the next run;
  only what its ``MANIFEST`` names and it still holds replaces what is in the folder, so
  a ``.previous`` that spinweb did not leave (empty, a link, foreign files, a damaged
  manifest) never costs a result (docs/robustness.md, "Links").
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import stat
import sys
import time
from pathlib import Path

from spinweb_fe.errors import InputError, RunError
from spinweb_fe.io.safe import describe as describe_entry
from spinweb_fe.io.safe import kind, remove, write_new

LOCK_NAME = "run.lock"
SWEEP_LOCK = "sweep.lock"  # a sweep's or a design's folder: one at a time
ASIDE_NAME = ".previous"
MANIFEST = "MANIFEST"
#: what a run writes into its folder (moved aside as a whole, put back as a whole)
RESULT_ITEMS = ("results.h5", "web.pvd", "frames", "checkpoint.h5")
LOCK_WAIT_S = 0.5  # a reader's probe holds the lock for microseconds: retry this long
#: how a lock file is opened: never through a link, never waiting (a FIFO would block)
OPEN_FLAGS = os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC


def check_writable(folder) -> Path:
    """Raise InputError unless ``folder`` is (or can be created as) a writable folder whose
    lock and earlier result spinweb can use (:func:`check_entries`)."""
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
    if probe == folder:
        check_entries(folder)
    return folder


def check_entries(folder, lock_name=LOCK_NAME) -> None:
    """Refuse (InputError, nothing changed) a folder whose lock is not a regular file or
    whose ``.previous`` spinweb did not leave (see :func:`aside_state`)."""
    lock = Path(folder) / lock_name
    if kind(lock) not in ("file", "missing"):
        raise InputError(lock, "", f"is {describe_entry(lock)}, not a lock file spinweb "
                         "made: remove it (nothing was changed)")
    state, why = aside_state(folder)
    if state == "foreign":
        raise InputError(Path(folder) / ASIDE_NAME, "", f"{why}; spinweb keeps an earlier "
                         "result there while a new run starts: move it away (nothing was "
                         "changed)")


def aside_state(folder) -> tuple:
    """(state, reason) of ``folder/.previous``, read only: 'missing'; 'empty' (nothing was
    moved into it: at most a manifest); 'recover' (an earlier result that a killed run left,
    named by a valid manifest); 'foreign' (anything else: a link, a file, files that no
    valid manifest names)."""
    aside = Path(folder) / ASIDE_NAME
    what = kind(aside)
    if what == "missing":
        return "missing", ""
    if what != "folder":
        return "foreign", f"is {describe_entry(aside)}, not a folder spinweb made"
    try:
        names = set(os.listdir(aside)) - {MANIFEST, MANIFEST + ".tmp"}
    except OSError as exc:
        return "foreign", f"cannot be read ({exc.strerror})"
    for name in (MANIFEST, MANIFEST + ".tmp"):
        if kind(aside / name) not in ("file", "link", "missing"):
            return "foreign", f"its {name} is {describe_entry(aside / name)}"
    if not names:
        return "empty", ""
    moved = read_manifest(aside)
    if moved is None:
        return "foreign", "holds files but no valid MANIFEST"
    if not names <= set(moved):
        return "foreign", f"holds {', '.join(sorted(names - set(moved)))}, which its " \
                          "MANIFEST does not name"
    return "recover", ""


def read_manifest(aside) -> list | None:
    """The names ``aside/MANIFEST`` lists (each one of RESULT_ITEMS), or None if it is
    missing, not a regular file or not such a list."""
    path = Path(aside) / MANIFEST
    if kind(path) != "file":
        return None
    try:
        moved = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not (isinstance(moved, list) and all(isinstance(n, str) for n in moved)
            and set(moved) <= set(RESULT_ITEMS)):
        return None
    return moved


def holder(folder, lock_name=LOCK_NAME) -> dict | None:
    """What ``DIR/run.lock`` says about the live run that holds ``folder`` (None: none).

    The answer has ``pid``, ``host``, ``started`` and ``command`` when the lock file could
    be read; an empty dict when a run holds the lock but has not written them yet. A lock
    that is not a regular file is held by no run (opened without following a link and
    without blocking on a FIFO)."""
    path = Path(folder) / lock_name
    try:
        fd = os.open(path, os.O_RDONLY | OPEN_FLAGS)
    except OSError:
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # a FIFO, a socket: no run's lock
            return None
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


def busy(folder, info, what="run") -> RunError:
    return RunError(f"{folder} is in use by another {what} ({describe(info)}); "
                    "nothing was changed")


class FolderLock:
    """The exclusive lock of a result folder (a context manager; creates the folder).

    Parameters
    ----------
    folder : str or Path
    name : str
        The lock file's name (``run.lock``; a sweep's folder: ``sweep.lock``).
    what : str
        What holds it, for the message ('run', 'sweep').

    Raises
    ------
    RunError
        If another live run holds it (named, one line); nothing in the folder changed.
    InputError
        If the lock file is not a regular file (a link, a FIFO, a folder).
    """

    def __init__(self, folder, name=LOCK_NAME, what="run"):
        self.folder = Path(folder)
        self.path = self.folder / name
        self.what = what
        self.fd = None
        self.created = False

    def _open(self) -> int:
        try:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT | OPEN_FLAGS, 0o666)
        except OSError as exc:
            reason = describe_entry(self.path) if kind(self.path) not in ("file", "missing") \
                else exc.strerror
            raise InputError(self.path, "", f"cannot be used as the folder's lock: it is "
                             f"{reason}; remove it (nothing was changed)") from None
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # a FIFO opens: refuse it all the same
            os.close(fd)
            raise InputError(self.path, "", f"cannot be used as the folder's lock: it is "
                             f"{describe_entry(self.path)}; remove it (nothing was changed)")
        return fd

    def acquire(self):
        self.created = not self.folder.exists()
        self.folder.mkdir(parents=True, exist_ok=True)
        deadline = time.monotonic() + LOCK_WAIT_S
        try:
            while True:
                fd = self._open()
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    os.close(fd)
                    if time.monotonic() > deadline:
                        raise busy(self.folder, holder(self.folder, self.path.name) or {},
                                   self.what) from None
                    time.sleep(0.01)
                    continue
                try:  # the file we locked must still be the one at the path (not unlinked)
                    same = os.stat(self.path).st_ino == os.fstat(fd).st_ino
                except FileNotFoundError:
                    same = False
                if same:
                    break
                os.close(fd)
        except BaseException:
            self._forget_folder()
            raise
        info = {"pid": os.getpid(), "host": socket.gethostname(),
                "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
                "command": " ".join(["spinweb", *sys.argv[1:]])
                if Path(sys.argv[0]).name in ("spinweb", "__main__.py") else " ".join(sys.argv)}
        os.ftruncate(fd, 0)
        os.write(fd, (json.dumps(info) + "\n").encode())
        self.fd = fd
        return self

    def _forget_folder(self):
        if self.created:  # a claim that wrote nothing leaves no folder behind
            try:
                self.folder.rmdir()
            except OSError:
                pass

    def release(self):
        if self.fd is None:
            return
        try:
            self.path.unlink(missing_ok=True)
        finally:
            os.close(self.fd)
            self.fd = None
        self._forget_folder()

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
    (whole, by a rename) before the moves, so that a run killed halfway through any of this
    is undone by the next one (:meth:`recover`). Only ever used under the folder's lock.
    """

    def __init__(self, folder):
        self.folder = Path(folder)
        self.dir = self.folder / ASIDE_NAME
        self.moved = []
        self.done = False
        self.started = False  # the new run may have written its files (the moves are done)
        self.made = False  # .previous is this run's (made by move, or left by a killed run)

    @staticmethod
    def recover(folder):
        """Put back a ``.previous`` that a killed run left (its own files never got a
        first flush), finish a drop that was cut short; True if something was put back.

        Raises
        ------
        InputError
            ``.previous`` is not what spinweb leaves (:func:`aside_state`): nothing is
            changed.
        """
        aside = Aside(folder)
        remove(aside.folder / (ASIDE_NAME + "-dropped"))
        state, why = aside_state(folder)
        if state == "missing":
            return False
        if state == "foreign":
            check_entries(folder)  # raises, naming it
        aside.made = True
        if state == "empty":  # nothing was moved: only a manifest (or nothing) to clear
            aside.done = True
            aside._clear()
            return False
        aside.moved = read_manifest(aside.dir)
        aside.started = True  # the killed run's own files may be in the folder
        return aside.restore()

    def move(self):
        found = [n for n in RESULT_ITEMS if os.path.lexists(self.folder / n)]
        if not found:
            self.done = True
            return self
        self.dir.mkdir()  # a new folder (an existing .previous, or a link, is an error)
        self.made = True
        write_new(self.dir / (MANIFEST + ".tmp"), json.dumps(found).encode())
        os.replace(self.dir / (MANIFEST + ".tmp"), self.dir / MANIFEST)
        for name in found:
            os.replace(self.folder / name, self.dir / name)
            self.moved.append(name)
        self.started = True
        return self

    def drop(self):
        if self.done:
            return
        self.done = True
        trash = self.folder / (ASIDE_NAME + "-dropped")
        remove(trash)  # whatever has that name (a link: unlinked, never followed)
        os.replace(self.dir, trash)  # one rename: a kill can no longer bring it back
        remove(trash)

    def restore(self) -> bool:
        """Put back what was moved and is still aside; True if something was. The new run's
        files give way only to an earlier result that is put back: a result that cannot be
        replaced is never deleted."""
        if self.done:
            return False
        self.done = True
        pending = [n for n in RESULT_ITEMS
                   if n in self.moved and os.path.lexists(self.dir / n)]
        if pending and self.started:
            for name in RESULT_ITEMS:  # the new run's files that have no earlier one
                if name not in self.moved:
                    remove(self.folder / name)
        for name in pending:
            if self.started:
                remove(self.folder / name)  # the new run's file
            os.replace(self.dir / name, self.folder / name)
        if self.made:
            self._clear()
        return bool(pending)

    def _clear(self):
        """Remove the manifest and ``.previous`` itself if nothing else is in it."""
        for name in (MANIFEST, MANIFEST + ".tmp"):
            if kind(self.dir / name) in ("file", "link"):
                (self.dir / name).unlink()
        try:
            self.dir.rmdir()
        except OSError:  # gone, or holds what was not moved (the next run names it)
            pass

