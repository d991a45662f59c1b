"""Result files (HDF5): root attributes and the ``/history`` layout shared by FE and analytic runs.

Every dataset carries a ``units`` attribute (SI). See CONTRACT.md and docs/results.md.
"""

from __future__ import annotations

import time

import h5py
import numpy as np

from spinweb_fe import FORMAT_VERSION, __version__

HISTORY_UNITS = {
    "time": "s",
    "hub_angle": "rad",
    "hub_omega": "rad/s",
    "hub_torque": "N m",
    "kinetic_energy": "J",
    "strain_energy": "J",
    "torque_work": "J",
    "damping_dissipation": "J",
    "contact_dissipation": "J",
    "angular_momentum": "N m s",
    "max_tension": "N",
    "arm_length": "m",
    "arm_angle": "rad",
    "tip_omega": "rad/s",
}

HISTORY_DOC = {
    "time": "simulated time",
    "hub_angle": "hub rotation angle about +z (counter-clockwise positive)",
    "hub_omega": "hub angular velocity omega_centre",
    "hub_torque": "control torque applied to the hub",
    "kinetic_energy": "kinetic energy of everything, hub included",
    "strain_energy": "elastic energy stored in the cables",
    "torque_work": "work done on the hub by the control torque",
    "damping_dissipation": "energy dissipated by axial cable damping",
    "contact_dissipation": "energy lost in cable-hub contact (impact and friction)",
    "angular_momentum": "angular momentum about the spin axis, hub included",
    "max_tension": "largest cable tension",
    "arm_length": "deployed (free) arm length L per arm, as in the analytical model",
    "arm_angle": "arm angle phi from the radial at the root, counter-clockwise positive; "
                 "|phi| > pi/2 while coiled (phi = -(pi/2 + wound angle) for a trailing wrap)",
    "tip_omega": "angular velocity of the tip position about the hub axis",
}


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
    """Write ``/history`` from a dict of arrays (names from HISTORY_UNITS, others allowed with
    a ``(array, units)`` tuple)."""
    g = h5.require_group("history")
    for name, value in history.items():
        if isinstance(value, tuple):
            value, units = value
        else:
            units = HISTORY_UNITS[name]
        if name in g:
            del g[name]
        write_dataset(g, name, value, units, HISTORY_DOC.get(name))
    return g


def open_h5(path, missing="no such file"):
    """Open an HDF5 file for reading; a missing or unreadable file is invalid input (exit 2).

    Parameters
    ----------
    missing : str
        The reason given when the file does not exist.
    """
    from pathlib import Path

    from spinweb_fe.errors import InputError

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
