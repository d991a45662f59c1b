"""Checkpoints: ``DIR/checkpoint.h5``, everything a run needs to continue bit-identically.

A checkpoint is taken at an event boundary (between two numba chunks) at integer step n:
the history rows of steps < n and the frames of steps < n are in ``results.h5``; the frame
and the history row of step n itself are not (the continued run writes them). It holds

- ``/state/<field>``: every array of :class:`spinweb_fe.fe.state.State` (positions x_n,
  half-step velocities v_{n-1/2}, ``hub/angle``, ``hub/rate``, ``totals/...``, ``step``,
  ``time``), bit-exact;
- ``/memory/<recorder>/<key>``: what the arm measure and the recorders carry from row to
  row (:meth:`spinweb_fe.record.recorders.Recorder.memory`: the previous arm angle that
  keeps phi continuous, the energy audit's reference);
- ``/pvd/time``, ``/pvd/file``: the ParaView collection entries written so far;
- root attributes: ``dt``, ``steps``, ``time``, ``history_rows``, ``frames``,
  ``checkpoint_dt``, the thread count ``threads``, the ``run_id`` of the results it belongs
  to, the resolved case as TOML (``case``) and its source file (``case_source``).

The control laws keep no memory of their own, so nothing else is needed. The file is written
to a temporary name (made new, never through a link) and renamed (``os.replace``), so a run
killed while writing leaves the previous checkpoint intact. Version 3 added the free hub's
rigid body (``/state/rigid/...``) and the gravity-gradient work (``/state/totals/gravity_work``); version 4 holds the energy
terms as one array in the order of fe.layout.STEP_TERMS (``/state/totals``) and no rigid
body for a fixed axis, and reads version 3 files too; version 1 files (before the held coil)
and version 2 files (before the free hub) are refused with a one-line reason.
"""

from __future__ import annotations

import dataclasses
import io
import os
import time
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe import __version__
from spinweb_fe.errors import InputError
from spinweb_fe.fe.state import State, from_arrays, to_arrays
from spinweb_fe.io.h5 import open_h5
from spinweb_fe.io.safe import describe, kind, write_new

CHECKPOINT_NAME = "checkpoint.h5"
CHECKPOINT_FORMAT = "spinweb-checkpoint"
CHECKPOINT_VERSION = 4
#: the versions this spinweb continues (fe.state.from_arrays reads version 3's totals)
READS = (3, 4)
#: why an older version cannot be continued
OLD_VERSIONS = {1: "version 1 predates the held coil", 2: "version 2 predates the free hub"}


@dataclass
class Checkpoint:
    """A run's resumable state at an event boundary.

    Attributes
    ----------
    state : State
        Positions x_n (n,3) [m], half-step velocities v_{n-1/2} (n,3) [m/s], hub state,
        totals, step. Already started (v_0 shifted to v_{-1/2}): a restart must not start it
        again.
    dt : float [s]
        Time step of the run.
    history_rows : int
        Rows of ``/history`` written (the rows of steps < the state's step).
    frames : int
        Frames written (``/frames`` rows, VTU files and PVD entries).
    pvd_entries : list of (float, str)
        (time [s], file relative to the result folder) of each frame.
    case_toml : str
        The resolved case (TOML text).
    case_source : str
        The case file the run was started from (messages, relative paths).
    checkpoint_dt : float [s]
        Interval between checkpoints (0: only at the end / on interruption).
    memory : dict of str -> dict of str -> ndarray
        What the arm measure (``'arms'``) and the recorders (by name, e.g. ``'energy'``)
        carry from row to row.
    threads : int
        Threads of the step loop: the continuation uses the same count (bit-identical).
    run_id : str
        The ``run_id`` attribute of the run's results.h5 (a restart checks that they match).
    """

    state: State
    dt: float
    history_rows: int
    frames: int
    pvd_entries: list
    case_toml: str
    case_source: str
    checkpoint_dt: float = 0.0
    memory: dict = dataclasses.field(default_factory=dict)
    threads: int = 1
    run_id: str = ""

    @property
    def steps(self) -> int:
        """Integer step n of the state."""
        return int(self.state.step[0])

    @property
    def time(self) -> float:
        """Simulated time t_n [s]."""
        return float(self.state.time[0])


def write_checkpoint(path, ck: Checkpoint, on_error=None) -> Path:
    """Write ``ck`` to ``path`` atomically (temporary file, then ``os.replace``).

    The HDF5 file is made in memory and its bytes written to the temporary file: a full
    disk fails that write with an OSError, never HDF5's own flush at the file's close (which
    crashed the process, a segmentation fault, when the disk filled there).

    Parameters
    ----------
    on_error : callable() or None
        Called when the write fails, after the temporary file is removed (the run's disk
        guard frees its reserve there, for the run's last writes).

    Returns
    -------
    Path
        The checkpoint file.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    image = io.BytesIO()
    with h5py.File(image, "w") as h5:
        _fill(h5, ck)
    try:
        write_new(tmp, image.getbuffer())  # made new, never through a link
        os.replace(tmp, path)
    except BaseException:
        if on_error is not None:
            on_error()
        tmp.unlink(missing_ok=True)
        raise
    return path


def _fill(h5, ck: Checkpoint):
    a = h5.attrs
    a["format"] = CHECKPOINT_FORMAT
    a["checkpoint_version"] = CHECKPOINT_VERSION
    a["spinweb_version"] = __version__
    a["written"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    a["dt"] = float(ck.dt)
    a["steps"] = ck.steps
    a["time"] = ck.time
    a["history_rows"] = int(ck.history_rows)
    a["frames"] = int(ck.frames)
    a["checkpoint_dt"] = float(ck.checkpoint_dt)
    a["threads"] = int(ck.threads)
    a["run_id"] = ck.run_id
    a["case"] = ck.case_toml
    a["case_source"] = ck.case_source
    g = h5.create_group("state")
    for name, value in to_arrays(ck.state).items():
        g.create_dataset(name, data=np.asarray(value))
    m = h5.create_group("memory")
    for owner, items in ck.memory.items():
        mg = m.create_group(owner)
        for name, value in items.items():
            mg.create_dataset(name, data=np.asarray(value))
    p = h5.create_group("pvd")
    p.create_dataset("time", data=np.array([t for t, _ in ck.pvd_entries], dtype=np.float64))
    p.create_dataset("file", data=np.array([f for _, f in ck.pvd_entries], dtype=object),
                     dtype=h5py.string_dtype())


def checkpoint_bytes(ck: Checkpoint) -> int:
    """About the size of ``ck``'s file [bytes] (arrays, entries, 64 KB of metadata)."""
    arrays = [np.asarray(v) for v in to_arrays(ck.state).values()]
    arrays += [np.asarray(v) for items in ck.memory.values() for v in items.values()]
    return (sum(a.nbytes for a in arrays) + 64 * len(ck.pvd_entries) + len(ck.case_toml)
            + 65536)


def _read(h5) -> tuple:
    """(state, memory) of a checkpoint file."""
    arrays = {}
    h5["state"].visititems(lambda name, obj: arrays.__setitem__(name, np.array(obj[()]))
                           if isinstance(obj, h5py.Dataset) else None)
    memory = {owner: {k: v[()] for k, v in g.items()} for owner, g in h5["memory"].items()}
    return from_arrays(arrays), memory


def read_checkpoint(path) -> Checkpoint:
    """Read a checkpoint written by :func:`write_checkpoint`.

    Raises
    ------
    InputError
        If the file is missing, not a spinweb checkpoint, or incomplete.
    """
    path = Path(path)
    with open_h5(path, "no checkpoint here (run with --checkpoint-dt to write one)") as h5:
        a = h5.attrs
        if a.get("format") != CHECKPOINT_FORMAT:
            raise InputError(path, "format", "not a spinweb checkpoint")
        version = int(a.get("checkpoint_version", -1))
        if version not in READS:
            why = OLD_VERSIONS.get(version, "an unknown version")
            raise InputError(path, "checkpoint_version",
                             f"version {a.get('checkpoint_version')} is not supported "
                             f"(this spinweb reads {CHECKPOINT_VERSION}; {why}: rerun the "
                             "case)")
        try:
            state, memory = _read(h5)
            entries = list(zip((float(t) for t in h5["pvd/time"][()]),
                               (f.decode() if isinstance(f, bytes) else str(f)
                                for f in h5["pvd/file"][()])))
            ck = Checkpoint(
                state=state, dt=float(a["dt"]), history_rows=int(a["history_rows"]),
                frames=int(a["frames"]), pvd_entries=entries, case_toml=str(a["case"]),
                case_source=str(a["case_source"]), checkpoint_dt=float(a["checkpoint_dt"]),
                memory=memory, threads=int(a["threads"]), run_id=str(a["run_id"]))
        except KeyError as exc:
            raise InputError(path, "", f"incomplete checkpoint (missing {exc})") from None
        if int(a["steps"]) != ck.steps or len(entries) != ck.frames:
            raise InputError(path, "", "inconsistent checkpoint (steps or frames)")
    return ck


def check_run_entries(out_dir):
    """Refuse (InputError, nothing changed) a folder whose result files are not the regular
    files (and ``frames`` not the folder) that a run writes: a restart changes them in
    place, and must not change what a link points to."""
    for name, want in (("results.h5", "file"), ("web.pvd", "file"), (CHECKPOINT_NAME, "file"),
                       ("frames", "folder")):
        path = Path(out_dir) / name
        if kind(path) not in (want, "missing"):
            raise InputError(path, "", f"is {describe(path)}, not the {want} a run writes: "
                             "spinweb does not follow it (nothing was changed)")


def check_results_for_restart(out_dir, ck):
    """Check (read-only) that ``out_dir/results.h5`` can be continued from checkpoint ``ck``.

    Raises
    ------
    InputError
        If the file is missing or unreadable, belongs to another run (``run_id``), or holds
        fewer history rows or frames than the checkpoint counts, or another time step.
    """
    check_run_entries(out_dir)
    path = Path(out_dir) / "results.h5"
    if not path.is_file():
        raise InputError(path, "", "no such file: nothing to continue")
    try:
        h5 = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(path, "", f"not a readable HDF5 file ({exc})") from None
    with h5:
        if h5.attrs.get("run_id") != ck.run_id:
            raise InputError(path, "run_id", "the results are not those of the checkpoint's run")
        if float(h5.attrs.get("dt", float("nan"))) != ck.dt:
            raise InputError(path, "dt", f"differs from the checkpoint's dt = {ck.dt!r} s")
        rows = {name: ds.shape[0] for name, ds in h5.get("history", {}).items()}
        short = [name for name, k in rows.items() if k < ck.history_rows]
        if ck.history_rows and (short or not rows):
            raise InputError(path, "history", f"holds fewer rows than the checkpoint's "
                             f"{ck.history_rows}: results and checkpoint do not belong together")
        n_frames = h5["frames/time"].shape[0] if "frames/time" in h5 else 0
        if n_frames < ck.frames:
            raise InputError(path, "frames", f"holds {n_frames} frames, the checkpoint "
                             f"counts {ck.frames}")
