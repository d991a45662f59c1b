"""Mesh I/O: the ``/mesh`` group of result files (HDF5) and VTU line meshes (meshio).

``/mesh`` layout (CONTRACT.md; every dataset has a ``units`` attribute):
``points (N,3)`` initial positions, ``reference_points (N,3)`` flat deployed positions,
``elements (E,2)``, ``rest_length (E,)``, ``node_mass (N,)`` (cable + point masses, hub
excluded), ``node_point_mass (N,)``, ``node_sets/<name>``, ``elem_sets/<name>``,
``node_arm (N,)``, ``node_arm_coord (N,)``, ``arm_root_angle (n_arms,)`` and attributes
``arm_length``, ``arm_root_coord``, ``hub_radius`` [m], ``wrap`` (+1 trailing, -1
leading, 0 none).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import meshio
import numpy as np

from meshgen.mesh import Mesh
from spinweb_fe.results import write_dataset

_DATASETS = (  # (dataset name, Mesh field, units, description)
    ("points", "node_pos", "m", "initial node positions"),
    ("reference_points", "node_ref", "m", "flat deployed node positions"),
    ("elements", "elem_nodes", "1", "element connectivity (node indices)"),
    ("rest_length", "elem_rest_len", "m", "unstretched element length (flat web)"),
    ("node_point_mass", "node_point_mass", "kg", "point (corner / tip) masses"),
    ("node_arm", "node_arm", "1", "arm index of each node, -1 if none"),
    ("node_arm_coord", "node_arm_coord", "m", "arm coordinate l (flat web), NaN if none"),
    ("arm_root_angle", "arm_root_angle", "rad", "hub-frame angle of each arm root on the rim"),
)
_ATTRS = ("arm_length", "arm_root_coord", "hub_radius", "wrap")


def write_mesh_group(h5group, mesh: Mesh, node_mass: np.ndarray):
    """Write a mesh into an (empty) HDF5 group, e.g. ``h5.create_group('mesh')``.

    Parameters
    ----------
    h5group : h5py.Group
    mesh : Mesh
    node_mass : (n,) float64 [kg]
        Lumped node masses (cable plus point masses, hub excluded).
    """
    for name, attr, units, doc in _DATASETS:
        write_dataset(h5group, name, getattr(mesh, attr), units, doc)
    write_dataset(h5group, "node_mass", np.asarray(node_mass, np.float64), "kg",
                  "lumped node mass: cable plus point masses, hub excluded")
    for kind, sets in (("node_sets", mesh.node_sets), ("elem_sets", mesh.elem_sets)):
        g = h5group.create_group(kind)
        for name, idx in sets.items():
            write_dataset(g, name, idx, "1", f"{kind[:4]} indices")
    for name in _ATTRS:
        h5group.attrs[name] = getattr(mesh, name)
    h5group.attrs["length_units"] = "m"
    return h5group


def read_mesh_group(h5group) -> Mesh:
    """Read a mesh written by :func:`write_mesh_group` (``node_mass`` is read separately:
    ``h5group['node_mass'][()]``)."""
    kw = {attr: h5group[name][()] for name, attr, _, _ in _DATASETS}
    kw["node_sets"] = {k: v[()] for k, v in h5group["node_sets"].items()}
    kw["elem_sets"] = {k: v[()] for k, v in h5group.get("elem_sets", {}).items()}
    for name in _ATTRS:
        kw[name] = h5group.attrs[name].item()
    kw["wrap"] = int(kw["wrap"])
    return Mesh(**kw)


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
    os.close(fd)
    try:
        meshio.write(tmp, mesh, file_format="vtu")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
