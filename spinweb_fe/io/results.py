"""Run outputs: ``results.h5`` (histories and frames, appended and flushed) and the ParaView
collection ``web.pvd`` + ``frames/web_NNNNNN.vtu`` (valid after every frame).

History rows are kept in memory and written (one resize and write per column, one flush)
every ROWS_WRITE_S of wall time or ROWS_WRITE_MAX rows, the first rows at once, and always
before a checkpoint, at the end and when the run stops on an error.

A frame's ``/frames`` row is written and flushed at its event; its VTU file and PVD entry are
written by one background thread while the step loop (numba, without the GIL) runs the next
chunk. At most one frame is in flight: the next frame, a checkpoint, the end and a failure
wait for it first, and an error of that thread stops the run like any failed write.

Before each write the free disk space is checked (:class:`spinweb_fe.io.space.DiskGuard`);
a write that fails anyway is undone: every dataset is cut back to what the last flush
holds, the partial frame file is removed, and the run stops with a :class:`RunError`.
"""

from __future__ import annotations

import logging
import math
import time
import uuid
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe.errors import RunError
from spinweb_fe.io.checkpoint import CHECKPOINT_NAME
from spinweb_fe.io.h5 import write_root_attrs
from spinweb_fe.io.mesh import write_mesh_group
from spinweb_fe.io.safe import NotOurs, check_regular, make_room, real_dir, same_file
from spinweb_fe.io.space import DiskFull, no_space, too_large
from spinweb_fe.io.vtk import append_pvd, write_pvd, write_vtu
from spinweb_fe.record.energy import energy_floor, momentum_floor
from spinweb_fe.record.history import COLUMNS
from spinweb_fe.record.recorders import Recorder
from spinweb_fe.record.strength import strength_cells

CHUNK_VALUES = 2 ** 15  # float64 values per dataset chunk (256 KB): bounded file growth
PVD_LINE = 100  # [bytes] about one PVD entry
ROWS_WRITE_S = 0.5  # [s] wall time between two writes of history rows
# ... and at most this many rows per write, the loop's rows per chunk (run.loop): a write
# that fails in HDF5 must leave no more in its caches than the reserve file gives room for
ROWS_WRITE_MAX = 256
log = logging.getLogger(__name__)


def _growth(ds, arr) -> int:
    """Bytes that appending ``arr`` (rows along axis 0) to dataset ``ds`` (None: a new one)
    can add to the file: the new chunks it allocates, each written whole."""
    per_row = max(1, int(np.prod(arr.shape[1:])))
    k = 0 if ds is None else ds.shape[0]
    c = ds.chunks[0] if ds is not None else max(1, min(1024, CHUNK_VALUES // per_row))
    new_chunks = -(-(k + len(arr)) // c) - -(-k // c)
    return 8 * (new_chunks * c * per_row + len(arr) * per_row)


def write_failure(exc) -> str:
    """One line for a failed write: 'no space left on device', 'file too large' or 'I/O
    error: ...'."""
    if no_space(exc):
        return "no space left on device"
    if too_large(exc):
        return "file too large (the file-size limit, ulimit -f)"
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return f"I/O error: {text}"


class ResultWriter(Recorder):
    """Owns results.h5 and the ParaView collection of one run (a recorder of the loop).

    Histories are appended in chunks (resizable datasets) and flushed, so a run that stops
    early leaves a readable file with everything written so far.
    """

    def __init__(self, out_dir, case, model, dt, write_frames=True, resume=None, guard=None):
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
        guard : spinweb_fe.io.space.DiskGuard or None
            Checks the free space before each write (None: no check).
        """
        self.dir = Path(out_dir)
        self.dir.mkdir(parents=True, exist_ok=True)
        self.model = model
        self.t0 = time.perf_counter()
        self.frames = None
        self.pvd_entries = []
        self.n_rows = 0  # history rows written
        self._rows = []  # chunks of history rows not written yet
        self._rows_kept = 0
        self._rows_written = -math.inf  # wall clock of the last write: the first is at once
        self.guard = guard
        self._ds = {}  # open datasets by path
        self._pool = None  # the frame writer thread, started at the first frame
        self._pending = None  # (future, time, file) of the frame whose VTU is being written
        self.vtu_bytes = 80 * model.n_nodes + 42 * model.n_elems + 4096  # uncompressed VTU
        if resume is not None:
            self._reopen(case, resume, write_frames)
            self.flushed = (self.n_rows, len(self.pvd_entries))
            return
        # a checkpoint left by an earlier run in this folder belongs to results we overwrite
        (self.dir / CHECKPOINT_NAME).unlink(missing_ok=True)
        self._need(8 * (10 * model.n_nodes + 3 * model.n_elems) + 65536, "the mesh", None)
        self.h5 = None
        try:
            self._create(case, dt, write_frames)
        except (OSError, RuntimeError) as exc:
            if self.guard is not None:
                self.guard.release()
            if self.h5 is not None:
                try:
                    self.h5.close()
                except (OSError, RuntimeError):
                    pass
                self.h5 = None
            raise RunError(f"cannot write to {self.dir}: {write_failure(exc)}") from None
        self.flushed = (0, 0)  # (history rows, frames) on disk

    def _create(self, case, dt, write_frames):
        model = self.model
        # made new (O_EXCL), never through a link planted under its name
        self.h5 = h5py.File(make_room(self.dir / "results.h5"), "x")
        self.run_id = uuid.uuid4().hex
        floor = energy_floor(model)
        write_root_attrs(self.h5, case, dt=dt, steps=0, wall_time_s=0.0,
                         dt_critical=model.dt_critical, status="running", run_id=self.run_id,
                         energy_floor=floor, momentum_floor=momentum_floor(model, floor))
        write_mesh_group(self.h5.create_group("mesh"), model.mesh, model.nodes.mass)
        self.hist = self.h5.create_group("history")
        if write_frames:
            real_dir(self.dir / "frames")  # a folder of this run's, not a link to another
            for old in (self.dir / "frames").glob("web_*.vtu"):
                old.unlink()
            g = self.h5.create_group("frames")
            n, m = model.n_nodes, model.n_elems
            self._new(g, "time", (0,), "s")
            self._new(g, "position", (0, n, 3), "m")
            self._new(g, "tension", (0, m), "N")
            if model.strength.rupture:
                self._new(g, "broken", (0, m), "1", "1: the element has broken")
            self.frames = g
        self.h5.flush()

    def _reopen(self, case, ck, write_frames):
        path = self.dir / "results.h5"
        check_regular(path, missing_ok=False)
        self.h5 = h5py.File(path, "r+")
        if not same_file(path, self.h5.id.get_vfd_handle()):  # replaced by a link meanwhile
            self.h5.close()
            raise NotOurs(0, f"{path} changed while it was opened: not continued")
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
            real_dir(self.dir / "frames")
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
        chunks = (max(1, min(1024, CHUNK_VALUES // max(1, int(np.prod(shape[1:]))))),) \
            + tuple(shape[1:])
        ds = group.create_dataset(name, shape=shape, maxshape=maxshape, dtype="f8", chunks=chunks)
        ds.attrs["units"] = units
        if doc:
            ds.attrs["description"] = doc
        return ds

    def rows(self, rows: dict):
        """Take rows (name -> (T,) or (T, n_arms) arrays); write what is kept when the last
        write is ROWS_WRITE_S old (the first rows at once) or ROWS_WRITE_MAX rows are kept."""
        rows = {name: np.asarray(arr, dtype=np.float64) for name, arr in rows.items()}
        n = len(next(iter(rows.values()), ()))
        if self._rows and (rows.keys() != self._rows[0].keys()
                           or self._rows_kept + n > ROWS_WRITE_MAX):
            self._write_rows()
        self._rows.append(rows)
        self._rows_kept += n
        if (time.perf_counter() - self._rows_written >= ROWS_WRITE_S
                or self._rows_kept >= ROWS_WRITE_MAX):
            self._write_rows()

    def _take_rows(self) -> dict:
        """The rows kept in memory, joined (and forgotten here)."""
        kept, self._rows, self._rows_kept = self._rows, [], 0
        if len(kept) <= 1:
            return kept[0] if kept else {}
        return {name: np.concatenate([r[name] for r in kept]) for name in kept[0]}

    def _write_rows(self):
        """Append the rows kept in memory to /history and flush."""
        rows = self._take_rows()
        if not rows:
            return
        t = float(rows["time"][-1]) if len(rows.get("time", ())) else None
        self._need(sum(_growth(self._ds.get(f"history/{name}"), arr)
                       for name, arr in rows.items()),
                   "history rows", t)
        try:
            self._append_rows(rows)
            self.h5.flush()
        except (OSError, RuntimeError) as exc:
            self._failed(exc, t)
        self.flushed = (self.n_rows, self.flushed[1])
        self._rows_written = time.perf_counter()

    def _append_rows(self, rows):
        for name, arr in rows.items():
            ds = self._ds.get(f"history/{name}")
            if ds is None:
                if name not in self.hist:
                    self._new(self.hist, name, (0,) + arr.shape[1:], *COLUMNS[name])
                ds = self._open(f"history/{name}")
            k = ds.shape[0]
            ds.resize(k + len(arr), axis=0)
            ds[k:] = arr
        self.n_rows += len(rows["time"]) if "time" in rows else 0

    def frame(self, frame):
        """One /frames row (flushed), then, in the writer thread, the VTU file and one more
        entry in the PVD (the frame before is waited for first)."""
        if self.frames is None:
            return
        self._settle()
        t = frame.time
        k = len(self.pvd_entries)
        rel = f"frames/web_{k:06d}.vtu"
        rows = (("time", t), ("position", frame.pos), ("tension", frame.tension))
        if frame.broken is not None:
            rows += (("broken", frame.broken),)
        self._need(self.vtu_bytes + PVD_LINE + sum(
            _growth(self._open(f"frames/{name}"), np.asarray(val, np.float64)[None])
            for name, val in rows),
            "a frame", t)
        try:  # results.h5 first, then the VTU file, then the collection that lists it
            for name, val in rows:
                ds = self._open(f"frames/{name}")
                ds.resize(k + 1, axis=0)
                ds[k] = val
            self.h5.flush()
        except (OSError, RuntimeError) as exc:
            self._failed(exc, t)
        if self._pool is None:
            self._pool = ThreadPoolExecutor(1, thread_name_prefix="spinweb-frames")
        self._pending = (self._pool.submit(self._write_frame, frame, rel), t, rel)

    def _write_frame(self, frame, rel):
        """The VTU file of ``frame`` and its PVD entry (in the writer thread; ``frame``'s
        arrays are its own copies)."""
        t, pos, vel, tension = frame.time, frame.pos, frame.vel, frame.tension
        mesh = self.model.mesh
        rest = mesh.elem_rest_len
        length = mesh.elem_length(pos)
        strain = np.where(rest > 0, (length - rest) / np.where(rest > 0, rest, 1.0), 0.0)
        write_vtu(self.dir / rel, pos, mesh.elem_nodes,
                  point_data={"velocity": vel, "displacement": pos - mesh.node_ref,
                              "node_mass": self.model.nodes.mass},
                  cell_data={"tension": tension, "strain": strain,
                             "slack": (tension <= 0).astype(np.int8),
                             **strength_cells(self.model, strain, frame.broken)})
        self.vtu_bytes = int(1.25 * (self.dir / rel).stat().st_size) + 4096
        pvd = self.dir / "web.pvd"
        try:
            if self.pvd_entries:
                append_pvd(pvd, (t, rel))
            else:
                write_pvd(pvd, [(t, rel)])
        except (ValueError, FileNotFoundError):  # changed by someone else: rewrite it
            write_pvd(pvd, [*self.pvd_entries, (t, rel)])

    def _wait(self):
        """Wait for the frame in flight: count it if its VTU file and PVD entry were
        written, else remove its file and return (exception, time)."""
        if self._pending is None:
            return None
        future, t, rel = self._pending
        self._pending = None
        exc = future.exception()
        if exc is None:
            self.pvd_entries.append((t, rel))
            self.flushed = (self.flushed[0], len(self.pvd_entries))
            return None
        (self.dir / rel).unlink(missing_ok=True)
        return exc, t

    def _settle(self):
        """Wait for the frame in flight; its failure stops the run as a failed write would."""
        failure = self._wait()
        if failure is not None:
            exc, t = failure
            if isinstance(exc, (OSError, RuntimeError)):
                self._failed(exc, t)
            raise exc

    def checkpoint(self, state, memory):
        """Everything up to the checkpoint on disk (see :meth:`written`)."""
        self._settle()
        self._write_rows()

    def written(self) -> tuple:
        """(history rows, PVD entries (time [s], file), run_id) on disk now: the frame in
        flight and the rows kept in memory are written first, so a checkpoint taken from
        this continues exactly after them (whatever the recorders' order)."""
        self._settle()
        self._write_rows()
        return self.n_rows, list(self.pvd_entries), self.run_id

    def end(self, status):
        self._settle()
        self._write_rows()

    def drain(self):
        """Wait for the frame in flight and write the rows kept in memory (the run stopped on
        an error: the driver calls this before the final attributes). Rows that would not
        fit on the disk are dropped; raises RunError if a write failed."""
        self._settle()
        try:
            self._write_rows()
        except DiskFull as exc:
            log.debug("history rows not written: %s", exc)

    def _open(self, path):
        """The dataset at ``path``, kept open for the whole run: closing a dataset writes its
        chunk cache, and a write that fails there (a full disk) cannot be caught."""
        ds = self._ds.get(path)
        if ds is None:
            ds = self._ds[path] = self.h5[path]
        return ds

    def _need(self, nbytes, what, t):
        if self.guard is not None:  # a frame in flight may not have taken its room yet
            inflight = self.vtu_bytes + PVD_LINE if self._pending is not None else 0
            self.guard.need(nbytes + inflight, what, t)

    def _failed(self, exc, t):
        """A write failed: free the reserve, cut every dataset back to the last flush,
        flush that, and stop the run (RunError naming the cause)."""
        self._wait()  # a frame in flight: counted if written, else its file removed
        if self.guard is not None:
            self.guard.release()
        kept = self._take_rows()
        if kept:  # rows still in memory: written if they fit now (the reserve is free)
            try:
                self._append_rows(kept)
                self.h5.flush()
                self.flushed = (self.n_rows, self.flushed[1])
            except (OSError, RuntimeError):
                pass
        rows, frames = self.flushed
        self._flush_quietly()  # what could not be written: written now, or dropped
        for path, ds in list(self._ds.items()):
            k = min(rows if path.startswith("history/") else frames, ds.shape[0])
            try:
                ds.resize(k, axis=0)
            except (OSError, RuntimeError):  # its chunk index lost the chunk that failed
                self._rebuild(path, ds, k)
        try:
            self.h5.flush()
        except (OSError, RuntimeError) as again:
            log.error("could not flush results.h5 after the failed write: %s",
                      str(again).splitlines()[0])
        raise RunError(f"cannot write to {self.dir}: {write_failure(exc)} (results.h5 keeps the "
                       f"{rows} history rows and {frames} frames written before)",
                       time=t) from None

    def _rebuild(self, path, ds, k):
        """Replace a dataset that cannot be cut back by a copy of its first ``k`` rows
        (readers cut every column to the shortest if even that fails)."""
        try:
            data, attrs = ds[:k], dict(ds.attrs)
            group, name = path.rsplit("/", 1)
            del self.h5[path]
            new = self._new(self.h5[group], name, data.shape, attrs.pop("units", "1"),
                            attrs.pop("description", None))
            new.resize(k, axis=0)
            new[:] = data
            self._ds[path] = new
        except (OSError, RuntimeError, KeyError) as exc:
            log.debug("could not cut %s back to %d rows: %s", path, k, exc)

    def _flush_quietly(self):
        try:
            self.h5.flush()
        except (OSError, RuntimeError):
            pass

    def set_attrs(self, **attrs):
        for k, v in attrs.items():
            self.h5.attrs[k] = v
        self.h5.attrs["wall_time_s"] = time.perf_counter() - self.t0
        self.h5.flush()

    def close(self):
        if self.h5 and (self._pending is not None or self._rows):  # drain() was not called
            try:
                self.drain()
            except RunError as exc:
                log.error("%s", exc)
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        if self.h5:
            h5, self.h5, self._ds = self.h5, None, {}
            try:
                h5.attrs["wall_time_s"] = time.perf_counter() - self.t0
                h5.close()
            except (OSError, RuntimeError) as exc:  # HDF5's last flush: one line, not its own
                raise RunError(f"cannot write to {self.dir}: {write_failure(exc)}") from None
