"""HDF5 helpers of the result files: root attributes, datasets with units, ``/history``.

Every dataset carries a ``units`` attribute (SI); the history columns are those of
:mod:`spinweb_fe.record.history` (docs/results.md, docs/interface.md).
"""

from __future__ import annotations

import time
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe import FORMAT_VERSION, __version__
from spinweb_fe.errors import InputError
from spinweb_fe.io.folder import describe, holder
from spinweb_fe.record.history import COLUMNS

def write_root_attrs(h5: h5py.File, case, **extra):
    """Root attributes of a result file: format, version, resolved case and extras (dt, steps...)."""
    h5.attrs["format_version"] = FORMAT_VERSION
    h5.attrs["spinweb_version"] = __version__
    h5.attrs["case"] = case.to_toml()
    h5.attrs["created"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    h5.attrs["units_system"] = "SI"
    for k, v in extra.items():
        h5.attrs[k] = v


def write_dataset(group, name, data, units, doc=None, **kw):
    """Create a dataset with its ``units`` (and optional ``description``) attribute."""
    ds = group.create_dataset(name, data=np.asarray(data), **kw)
    ds.attrs["units"] = units
    if doc:
        ds.attrs["description"] = doc
    return ds


def write_history(h5: h5py.File, history: dict):
    """Write ``/history`` from a dict of arrays (names of record.history.COLUMNS, others with
    a ``(array, units)`` tuple)."""
    g = h5.require_group("history")
    for name, value in history.items():
        if isinstance(value, tuple):
            value, units = value
            doc = None
        else:
            units, doc = COLUMNS[name]
        if name in g:
            del g[name]
        write_dataset(g, name, value, units, doc)
    return g


def open_h5(path, missing="no such file"):
    """Open an HDF5 file for reading; a missing or unreadable file is invalid input (exit 2).

    The file is opened without HDF5's file lock, so that the result file of a run that is
    still writing it can be read (a run flushes at every event; :func:`read_result` retries
    a read that meets a flush halfway).

    Parameters
    ----------
    missing : str
        The reason given when the file does not exist.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "", missing)
    try:
        return h5py.File(path, "r", locking=False)
    except OSError as exc:
        raise _unreadable(path, exc) from None


def _unreadable(path, exc) -> InputError:
    """The error for a file that cannot be read: it names the run that writes it, if any."""
    info = holder(path.parent)
    if info is not None:
        return InputError(path, "", f"a run is writing it ({describe(info)}) and it could "
                          "not be read just now; try again")
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return InputError(path, "", f"not a readable HDF5 file ({text})")


def read_result(path, read, missing="no such file", tries=10, wait_s=0.05):
    """``read(h5)`` on the HDF5 file at ``path``, also while a run writes it.

    A run's flush can be halfway when the file is read: a read that fails on the file's
    structure (OSError, RuntimeError) is tried again, ``tries`` times ``wait_s`` apart.

    Raises
    ------
    InputError
        Missing file, or still unreadable (naming the run that writes it, if one does).
    """
    path = Path(path)
    for attempt in range(1, tries + 1):
        try:
            h5 = open_h5(path, missing)
        except InputError:
            if not path.is_file() or attempt == tries:
                raise
        else:
            try:
                with h5:
                    return read(h5)
            except (OSError, RuntimeError) as exc:
                if attempt == tries:
                    raise _unreadable(path, exc) from None
        time.sleep(wait_s)


def history_of(h5) -> dict:
    """``/history`` of an open result file as a dict of arrays, every column cut to the
    shortest one (a run stopped by a failed write may leave one column longer); empty
    when the run stopped before its first rows."""
    g = h5.get("history")
    if g is None or not len(g):
        return {}
    h = {k: g[k][()] for k in g}
    n = min(len(v) for v in h.values())
    return {k: v[:n] for k, v in h.items()}


def read_history(path) -> dict:
    """Read ``/history`` of a result file into a dict of numpy arrays."""
    return read_result(path, history_of)
