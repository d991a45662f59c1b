"""Mesh files: the ``/mesh`` group of result files (HDF5) and the ``spinweb mesh`` files.

``/mesh`` layout (docs/interface.md; every dataset has a ``units`` attribute):
``points (N,3)`` initial positions, ``reference_points (N,3)`` flat deployed positions,
``elements (E,2)``, ``rest_length (E,)``, ``node_mass (N,)`` (cable + point masses, hub
excluded), ``node_point_mass (N,)``, ``node_sets/<name>``, ``elem_sets/<name>``,
``node_arm (N,)``, ``node_arm_coord (N,)``, ``arm_root_angle (n_arms,)`` and attributes
``arm_length``, ``arm_root_coord``, ``hub_radius`` [m], ``wrap`` (+1 trailing, -1
leading, 0 none).
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np

from meshgen.mesh import Mesh
from spinweb_fe.io.h5 import write_dataset, write_root_attrs
from spinweb_fe.io.vtk import write_vtu

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


def write_mesh_files(case, mesh: Mesh, node_mass: np.ndarray, folder) -> list:
    """Write ``mesh.h5`` (root attributes + ``/mesh``), ``mesh_folded.vtu`` and
    ``mesh_flat.vtu`` into ``folder``.

    Point data: ``node_mass`` [kg], ``arm`` [-], ``arm_coord`` [m]; cell data:
    ``rest_length`` [m], ``strain`` [-] (current length / rest length - 1).

    Returns
    -------
    list of Path
        The three files written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    h5_path = folder / "mesh.h5"
    with h5py.File(h5_path, "w") as h5:
        write_root_attrs(h5, case)
        write_mesh_group(h5.create_group("mesh"), mesh, node_mass)
    point_data = {"node_mass": node_mass, "arm": mesh.node_arm.astype(np.int32),
                  "arm_coord": mesh.node_arm_coord}
    paths = [h5_path]
    for name, pos in (("mesh_folded.vtu", mesh.node_pos), ("mesh_flat.vtu", mesh.node_ref)):
        strain = mesh.elem_length(pos) / mesh.elem_rest_len - 1.0
        write_vtu(folder / name, pos, mesh.elem_nodes, point_data,
                  {"rest_length": mesh.elem_rest_len, "strain": strain})
        paths.append(folder / name)
    return paths
