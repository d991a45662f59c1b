"""Run outputs: ``results.h5`` (histories and frames, appended and flushed at every event)
and the ParaView collection ``web.pvd`` + ``frames/web_NNNNNN.vtu`` (valid after every frame).
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe.io_mesh import write_mesh_group, write_vtu
from spinweb_fe.results import HISTORY_DOC, HISTORY_UNITS, write_root_attrs


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


class ResultWriter:
    """Owns results.h5 and the ParaView collection of one run.

    Histories are appended in chunks (resizable datasets) and flushed, so a run that stops
    early leaves a readable file with everything recorded so far.
    """

    def __init__(self, out_dir, case, model, dt, write_frames=True):
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.model = model
        self.t0 = time.perf_counter()
        self.h5 = h5py.File(self.dir / "results.h5", "w")
        write_root_attrs(self.h5, case, dt=dt, steps=0, wall_time_s=0.0,
                         dt_critical=model.dt_critical, status="running")
        write_mesh_group(self.h5.create_group("mesh"), model.mesh, model.node_mass)
        self.hist = self.h5.create_group("history")
        self.frames = None
        self.pvd_entries = []
        if write_frames:
            (self.dir / "frames").mkdir(exist_ok=True)
            for old in (self.dir / "frames").glob("web_*.vtu"):
                old.unlink()
            g = self.h5.create_group("frames")
            n, m = model.n_nodes, model.n_elems
            self._new(g, "time", (0,), "s")
            self._new(g, "position", (0, n, 3), "m")
            self._new(g, "tension", (0, m), "N")
            self.frames = g
        self.h5.flush()

    @staticmethod
    def _new(group, name, shape, units, doc=None):
        maxshape = (None,) + tuple(shape[1:])
        chunks = (max(1, min(1024, 2 ** 20 // max(1, int(np.prod(shape[1:]))))),) + tuple(shape[1:])
        ds = group.create_dataset(name, shape=shape, maxshape=maxshape, dtype="f8", chunks=chunks)
        ds.attrs["units"] = units
        if doc:
            ds.attrs["description"] = doc
        return ds

    def append_history(self, rows: dict):
        """Append rows: name -> (T,) or (T, n_arms) arrays."""
        for name, arr in rows.items():
            arr = np.asarray(arr, dtype=np.float64)
            if name not in self.hist:
                self._new(self.hist, name, (0,) + arr.shape[1:], HISTORY_UNITS[name],
                          HISTORY_DOC.get(name))
            ds = self.hist[name]
            k = ds.shape[0]
            ds.resize(k + len(arr), axis=0)
            ds[k:] = arr
        self.h5.flush()

    def write_frame(self, t, pos, vel, tension):
        """One VTU frame, one /frames row, then the PVD rewritten atomically."""
        if self.frames is None:
            return
        mesh = self.model.mesh
        k = len(self.pvd_entries)
        rel = f"frames/web_{k:06d}.vtu"
        rest = mesh.elem_rest_len
        length = mesh.elem_length(pos)
        strain = np.where(rest > 0, (length - rest) / np.where(rest > 0, rest, 1.0), 0.0)
        write_vtu(self.dir / rel, pos, mesh.elem_nodes,
                  point_data={"velocity": vel, "displacement": pos - mesh.node_ref,
                              "node_mass": self.model.node_mass},
                  cell_data={"tension": tension, "strain": strain,
                             "slack": (tension <= 0).astype(np.int8)})
        for name, val in (("time", t), ("position", pos), ("tension", tension)):
            ds = self.frames[name]
            ds.resize(k + 1, axis=0)
            ds[k] = val
        self.pvd_entries.append((t, rel))
        write_pvd(self.dir / "web.pvd", self.pvd_entries)
        self.h5.flush()

    def set_attrs(self, **attrs):
        for k, v in attrs.items():
            self.h5.attrs[k] = v
        self.h5.attrs["wall_time_s"] = time.perf_counter() - self.t0
        self.h5.flush()

    def close(self):
        if self.h5:
            self.h5.attrs["wall_time_s"] = time.perf_counter() - self.t0
            self.h5.close()
            self.h5 = None
