"""Run outputs: ``results.h5`` (histories and frames, appended and flushed at every event)
and the ParaView collection ``web.pvd`` + ``frames/web_NNNNNN.vtu`` (valid after every frame).
"""

from __future__ import annotations

import time
import uuid
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe.io.checkpoint import CHECKPOINT_NAME
from spinweb_fe.io.h5 import write_root_attrs
from spinweb_fe.io.mesh import write_mesh_group
from spinweb_fe.io.vtk import write_pvd, write_vtu
from spinweb_fe.record.history import COLUMNS
from spinweb_fe.record.recorders import Recorder


class ResultWriter(Recorder):
    """Owns results.h5 and the ParaView collection of one run (a recorder of the loop).

    Histories are appended in chunks (resizable datasets) and flushed, so a run that stops
    early leaves a readable file with everything recorded so far.
    """

    def __init__(self, out_dir, case, model, dt, write_frames=True, resume=None):
        """Create ``results.h5`` (or, with ``resume``, reopen it to continue a run).

        Parameters
        ----------
        out_dir : str or Path
            Result folder (created if needed).
        case : spinweb_fe.case.Case
            The validated case (stored as the root attribute ``case``).
        model : spinweb_fe.model.Model
        dt : float [s]
        write_frames : bool
            Write ``/frames``, the VTU files and ``web.pvd``.
        resume : spinweb_fe.checkpoint.Checkpoint or None
            Continue the run of this checkpoint: ``/history`` and ``/frames`` are cut back
            to the checkpoint's row counts, later VTU files are removed, the collection is
            rewritten from the checkpoint's entries, and new rows are appended.
        """
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.model = model
        self.t0 = time.perf_counter()
        self.frames = None
        self.pvd_entries = []
        self.n_rows = 0
        if resume is not None:
            self._reopen(case, resume, write_frames)
            return
        # a checkpoint left by an earlier run in this folder belongs to results we overwrite
        (self.dir / CHECKPOINT_NAME).unlink(missing_ok=True)
        self.h5 = h5py.File(self.dir / "results.h5", "w")
        self.run_id = uuid.uuid4().hex
        write_root_attrs(self.h5, case, dt=dt, steps=0, wall_time_s=0.0,
                         dt_critical=model.dt_critical, status="running", run_id=self.run_id)
        write_mesh_group(self.h5.create_group("mesh"), model.mesh, model.nodes.mass)
        self.hist = self.h5.create_group("history")
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

    def _reopen(self, case, ck, write_frames):
        self.h5 = h5py.File(self.dir / "results.h5", "r+")
        self.run_id = ck.run_id
        self.hist = self.h5.require_group("history")
        for ds in self.hist.values():
            ds.resize(ck.history_rows, axis=0)
        self.n_rows = ck.history_rows
        if write_frames and "frames" in self.h5:
            self.frames = self.h5["frames"]
            for ds in self.frames.values():
                ds.resize(ck.frames, axis=0)
            self.pvd_entries = list(ck.pvd_entries)
            (self.dir / "frames").mkdir(exist_ok=True)
            keep = {f for _, f in self.pvd_entries}
            for old in (self.dir / "frames").glob("web_*.vtu"):
                if f"frames/{old.name}" not in keep:
                    old.unlink()
            write_pvd(self.dir / "web.pvd", self.pvd_entries)
        self.h5.attrs["case"] = case.to_toml()
        self.h5.attrs["status"] = "running"
        self.h5.attrs["restarted_at_time"] = ck.time
        self.h5.attrs["restarted_at_step"] = ck.steps
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

    def rows(self, rows: dict):
        """Append rows: name -> (T,) or (T, n_arms) arrays."""
        for name, arr in rows.items():
            arr = np.asarray(arr, dtype=np.float64)
            if name not in self.hist:
                self._new(self.hist, name, (0,) + arr.shape[1:], *COLUMNS[name])
            ds = self.hist[name]
            k = ds.shape[0]
            ds.resize(k + len(arr), axis=0)
            ds[k:] = arr
        self.n_rows += len(rows["time"]) if "time" in rows else 0
        self.h5.flush()

    def frame(self, frame):
        """One VTU frame, one /frames row, then the PVD rewritten atomically."""
        if self.frames is None:
            return
        t, pos, vel, tension = frame
        mesh = self.model.mesh
        k = len(self.pvd_entries)
        rel = f"frames/web_{k:06d}.vtu"
        rest = mesh.elem_rest_len
        length = mesh.elem_length(pos)
        strain = np.where(rest > 0, (length - rest) / np.where(rest > 0, rest, 1.0), 0.0)
        write_vtu(self.dir / rel, pos, mesh.elem_nodes,
                  point_data={"velocity": vel, "displacement": pos - mesh.node_ref,
                              "node_mass": self.model.nodes.mass},
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
