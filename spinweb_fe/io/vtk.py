"""ParaView files: VTU line meshes (meshio) and PVD collections.

A VTU file is written atomically (temporary file in the same folder, then rename) with the
permissions the umask gives a new file; temporary files are made new (``O_EXCL``), never
through a link, and the collection is grown only if it is a regular file. A PVD collection
is written whole once and then grown in place, one ``DataSet`` line per frame (:func:`append_pvd`): the cost of a frame
does not grow with the number of frames, and the file is a valid collection after every
call (a failed append puts the previous closing lines back).
"""

from __future__ import annotations

import errno
import os
import stat
import tempfile
from pathlib import Path

import meshio
import numpy as np

from spinweb_fe.io.safe import write_new

PVD_HEAD = ('<?xml version="1.0"?>\n'
            '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">\n'
            "  <Collection>\n")
PVD_TAIL = "  </Collection>\n</VTKFile>\n"


def file_mode() -> int:
    """The permissions of a new file under the current umask (0o666 & ~umask)."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def write_vtu(path, points, elements, point_data=None, cell_data=None):
    """Write a line mesh as VTU, atomically (temporary file in the same folder + rename).

    Parameters
    ----------
    path : str or Path
        Target ``.vtu`` file.
    points : (n, 3) float64 [m]
    elements : (m, 2) int
        Line cells.
    point_data : dict str -> (n,) or (n, d) array, optional
    cell_data : dict str -> (m,) or (m, d) array, optional
    """
    path = Path(path)
    mesh = meshio.Mesh(np.ascontiguousarray(points, np.float64),
                       [("line", np.ascontiguousarray(elements, np.int64))],
                       point_data=dict(point_data or {}),
                       cell_data={k: [np.asarray(v)] for k, v in (cell_data or {}).items()})
    fd, tmp = tempfile.mkstemp(suffix=".vtu", prefix=f".{path.stem}.", dir=path.parent)
    try:
        os.fchmod(fd, file_mode())  # mkstemp makes 0600: readable by others as the umask says
        os.close(fd)
        meshio.write(tmp, mesh, file_format="vtu")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _dataset(t, f) -> str:
    return f'    <DataSet timestep="{t:.9g}" group="" part="0" file="{f}"/>\n'


def write_pvd(path: Path, entries):
    """Write a PVD collection atomically (temp file + rename). entries: [(time, relative file)]."""
    path = Path(path)
    tmp = path.with_suffix(".pvd.tmp")
    try:  # a new file, never through a link planted under its name
        write_new(tmp, (PVD_HEAD + "".join(_dataset(t, f) for t, f in entries)
                        + PVD_TAIL).encode())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def append_pvd(path: Path, entry):
    """Add one (time, relative file) entry to the PVD collection at ``path`` in place.

    The closing lines are overwritten by the new entry and the closing lines again, in one
    write; if that fails (a full disk), the closing lines are put back where they were, so
    the file stays the valid collection it was. A file that does not end as written by
    :func:`write_pvd` is refused (ValueError), and so is one that is not a regular file
    (a link is not followed, a FIFO not waited for).
    """
    tail = PVD_TAIL.encode()
    try:
        fd = os.open(path, os.O_RDWR | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        if exc.errno == errno.ENOENT:
            raise
        raise ValueError(f"{path}: not a collection written by spinweb ({exc.strerror})") \
            from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise ValueError(f"{path}: not a collection written by spinweb (not a file)")
        end = os.lseek(fd, 0, os.SEEK_END)
        pos = end - len(tail)
        if pos < 0 or os.pread(fd, len(tail), pos) != tail:
            raise ValueError(f"{path}: not a collection written by spinweb")
        try:
            _pwrite_all(fd, (_dataset(*entry) + PVD_TAIL).encode(), pos)
        except OSError:
            _pwrite_all(fd, tail, pos)  # overwrites bytes that exist: needs no new space
            os.ftruncate(fd, end)
            raise
    finally:
        os.close(fd)


def _pwrite_all(fd, data: bytes, pos: int):
    view = memoryview(data)
    while view:
        n = os.pwrite(fd, view, pos)
        view, pos = view[n:], pos + n
