"""Files in a result folder made without following links (docs/robustness.md, "Links").

A result folder may hold entries that the tool did not make: a symbolic link planted under
the name of a file the tool writes (``.reserve``, ``run.lock``, ``checkpoint.h5.tmp``,
``web.pvd.tmp``, ``.previous``), a FIFO, a folder. Writing through such a link would change
the file it points to, outside the folder; deleting through it would delete there. So every
file the tool creates or replaces in a folder is made here:

- :func:`create` removes whatever entry has the name (the link itself, never its target)
  and makes a new file with ``O_CREAT | O_EXCL | O_NOFOLLOW``: the kernel refuses to open an
  entry that appeared in between, and never follows a link;
- :func:`real_dir` makes or accepts a folder only if it is one (not a link to one);
- :func:`remove` deletes an entry of the folder: a link is unlinked, a real folder removed
  with its contents (``shutil.rmtree`` does not follow the links inside);
- :func:`check_regular` refuses an entry that is not a regular file (a link, a FIFO, a
  socket, a device, a folder) before the tool opens it to change it.
"""

from __future__ import annotations

import errno
import os
import shutil
import stat
from pathlib import Path

NEW_FLAGS = os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC


class NotOurs(OSError):
    """An entry of the folder is not what the tool makes under that name (a link, a FIFO,
    a folder where a file belongs); its message names the entry and what it is."""


def kind(path) -> str:
    """What the entry at ``path`` is, without following a link: 'file', 'folder', 'link',
    'FIFO', 'socket', 'device' or 'missing'."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return "missing"
    if stat.S_ISREG(mode):
        return "file"
    if stat.S_ISDIR(mode):
        return "folder"
    if stat.S_ISLNK(mode):
        return "link"
    if stat.S_ISFIFO(mode):
        return "FIFO"
    if stat.S_ISSOCK(mode):
        return "socket"
    return "device"


def describe(path) -> str:
    """'a symbolic link to /elsewhere', 'a FIFO', ... (for one-line messages)."""
    what = kind(path)
    if what == "link":
        try:
            return f"a symbolic link (to {os.readlink(path)})"
        except OSError:
            return "a symbolic link"
    return {"file": "a file", "folder": "a folder"}.get(what, f"a {what}")


def check_regular(path, missing_ok=True) -> None:
    """Raise :class:`NotOurs` unless ``path`` is a regular file (or, with ``missing_ok``,
    nothing)."""
    what = kind(path)
    if what == "file" or (what == "missing" and missing_ok):
        return
    raise NotOurs(errno.EINVAL, f"{path} is {describe(path)}, not a file spinweb writes: "
                  "remove it")


def remove(path) -> None:
    """Delete the entry at ``path`` (a folder with its contents); a link is unlinked, its
    target left alone; nothing there is fine."""
    path = Path(path)
    try:
        if kind(path) == "folder":
            shutil.rmtree(path)
        else:
            path.unlink()
    except FileNotFoundError:
        pass


def make_room(path) -> Path:
    """Remove the entry at ``path`` so that a new file can be made there exclusively (a
    link is unlinked, never followed); a folder of that name is left (IsADirectoryError)."""
    path = Path(path)
    if kind(path) == "folder":
        raise IsADirectoryError(errno.EISDIR, f"{path} is a folder, not a file spinweb "
                                "writes: remove it")
    remove(path)
    return path


def create(path, mode: int = 0o666, flags: int = os.O_WRONLY) -> int:
    """A new, empty regular file at ``path`` (:func:`make_room`, then ``flags`` | O_CREAT |
    O_EXCL | O_NOFOLLOW); returns its file descriptor."""
    return os.open(make_room(path), flags | NEW_FLAGS, mode)


def write_new(path, data: bytes, mode: int = 0o666) -> None:
    """Write ``data`` to a new file at ``path`` (:func:`create`); removed if that fails."""
    fd = create(path, mode)
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
    except BaseException:
        os.close(fd)
        Path(path).unlink(missing_ok=True)
        raise
    os.close(fd)


def real_dir(path) -> Path:
    """The folder at ``path``, made if missing; :class:`NotOurs` if the name holds anything
    else (a link to a folder included: its files would be written and deleted elsewhere)."""
    path = Path(path)
    try:
        path.mkdir()
    except FileExistsError:
        pass
    if kind(path) != "folder":
        raise NotOurs(errno.ENOTDIR, f"{path} is {describe(path)}, not a folder spinweb "
                      "made: remove it")
    return path


def same_file(path, fd: int) -> bool:
    """True if the open file ``fd`` is the regular file at ``path`` (not reached through a
    link, not replaced since)."""
    try:
        st, here = os.fstat(fd), os.lstat(path)
    except OSError:
        return False
    return stat.S_ISREG(here.st_mode) and (st.st_dev, st.st_ino) == (here.st_dev, here.st_ino)
