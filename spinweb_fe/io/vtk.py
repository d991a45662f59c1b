"""ParaView files: VTU line meshes (meshio) and PVD collections, each written atomically
(temporary file in the same folder, then rename)."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import meshio
import numpy as np


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


def write_pvd(path: Path, entries):
    """Write a PVD collection atomically (temp file + rename). entries: [(time, relative file)]."""
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    lines += [f'    <DataSet timestep="{t:.9g}" group="" part="0" file="{f}"/>' for t, f in entries]
    lines += ["  </Collection>", "</VTKFile>", ""]
    tmp = path.with_suffix(".pvd.tmp")
    tmp.write_text("\n".join(lines))
    os.replace(tmp, path)
