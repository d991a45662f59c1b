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

    Parameters
    ----------
    missing : str
        The reason given when the file does not exist.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "", missing)
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        raise InputError(path, "", f"not an HDF5 file ({exc})") from None


def read_history(path) -> dict:
    """Read ``/history`` of a result file into a dict of numpy arrays."""
    with h5py.File(path, "r") as h5:
        return {k: h5["history"][k][()] for k in h5["history"]}
