"""Free disk space for a run's output: checked before each write, with a small reserve.

HDF5 cannot recover from a write that fails halfway: it drops the chunk it could not
write and leaves dirty metadata that it tries to write again at close, which crashes the
process when the disk is still full. So a run never lets a write fail if it can help it:
:meth:`DiskGuard.need` stops the run (a :class:`DiskFull` run error) *before* a write that
would not fit, and a small reserve file, deleted when a write fails anyway (another
program filled the disk), gives the final flush and close the room they need. A file-size
limit (``ulimit -f``) is the same fault by another road: a write beyond it fails (EFBIG), so
the guard also stops the run before results.h5 would grow beyond the limit less a margin.
"""

from __future__ import annotations

import errno
import math
import os
import resource
import shutil
from pathlib import Path

from spinweb_fe.errors import RunError
from spinweb_fe.io.safe import write_new

MARGIN = 256 * 1024        # [bytes] kept free beyond each write (metadata, the final close)
RESERVE = 512 * 1024       # [bytes] reserve file, freed when a write fails anyway
RESERVE_NAME = ".reserve"
RESULTS_NAME = "results.h5"


class DiskFull(RunError):
    """Not enough free space for the next write (raised before writing)."""


def no_space(exc) -> bool:
    """True if ``exc`` (OSError, or h5py's RuntimeError) reports a full disk or quota."""
    if getattr(exc, "errno", None) in (errno.ENOSPC, errno.EDQUOT):
        return True
    text = str(exc)
    return "No space left on device" in text or "errno = 28" in text


def too_large(exc) -> bool:
    """True if ``exc`` reports a file grown beyond the file-size limit (EFBIG; Python
    ignores SIGXFSZ, so the write fails instead of the process being killed)."""
    if getattr(exc, "errno", None) == errno.EFBIG:
        return True
    text = str(exc)
    return "File too large" in text or "errno = 27" in text


def size_limit() -> float:
    """The largest file this process may write [bytes]: the soft RLIMIT_FSIZE (``ulimit
    -f``), infinity when there is none."""
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return math.inf if soft == resource.RLIM_INFINITY else float(soft)


def fmt_bytes(n) -> str:
    """1536 -> '1.5 KB' (powers of 1024)."""
    n = float(n)
    for unit in ("B", "KB", "MB", "GB", "TB"):
        if abs(n) < 1024 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PB"


def free_bytes(folder) -> int:
    """Bytes free to this user on the file system of ``folder`` (or its nearest ancestor)."""
    p = Path(folder)
    while not p.exists() and p.parent != p:
        p = p.parent
    return shutil.disk_usage(p).free


class DiskGuard:
    """Checks the free space of a result folder before each write; owns its reserve file.

    Parameters
    ----------
    folder : Path
        The result folder (it exists: the run holds its lock).
    reserve : int [bytes]
        Size of the reserve file (0: none).
    """

    def __init__(self, folder, reserve=RESERVE):
        self.folder = Path(folder)
        self.path = self.folder / RESERVE_NAME
        self.size = 0
        if reserve > 0 and free_bytes(self.folder) > reserve + MARGIN:
            try:  # a new file, never through a link planted under its name
                write_new(self.path, b"\0" * reserve)  # real blocks, not a sparse file
                self.size = reserve
            except OSError:
                pass

    def need(self, nbytes, what="the next output", time=None):
        """Raise :class:`DiskFull` unless ``nbytes`` (plus MARGIN) fit on the disk, and
        ``results.h5`` grown by them (plus MARGIN and RESERVE: HDF5's last flush and close
        need room in the file itself, which no reserve file can give) stays within the
        file-size limit (:func:`size_limit`; counted against results.h5 for every write,
        which may only stop a run early)."""
        free = free_bytes(self.folder)
        if nbytes + MARGIN > free:
            raise DiskFull(f"no space left on device for {what} ({fmt_bytes(nbytes)} needed, "
                           f"{fmt_bytes(free)} free on {self.folder})", time=time)
        limit = size_limit()
        if limit < math.inf:
            try:
                size = os.lstat(self.folder / RESULTS_NAME).st_size
            except OSError:
                size = 0
            if size + nbytes + MARGIN + RESERVE > limit:
                raise DiskFull(f"the file-size limit (ulimit -f) of {fmt_bytes(limit)} is "
                               f"reached for {what} (results.h5 holds {fmt_bytes(size)}, "
                               f"{fmt_bytes(nbytes)} more needed)", time=time)

    def release(self):
        """Delete the reserve file (before the last flush of a failed write, and at the end)."""
        if self.size:
            self.path.unlink(missing_ok=True)
            self.size = 0
