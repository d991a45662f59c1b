"""Checkpoints: ``DIR/checkpoint.h5``, everything a run needs to continue bit-identically.

A checkpoint is taken at an event boundary (between two numba chunks) at integer step n:
the history rows of steps < n and the frames of steps < n are in ``results.h5``; the frame
and the history row of step n itself are not (the continued run writes them). It holds

- ``/state/<field>``: every array of :class:`spinweb_fe.model.State` (positions x_n,
  half-step velocities v_{n-1/2}, the hub / accumulator vector), float64, bit-exact;
- ``/arms/<attr>``: the arm tracker's memory (its array attributes, e.g. the previous arm
  angle that keeps phi continuous across rows);
- ``/pvd/time``, ``/pvd/file``: the ParaView collection entries written so far;
- root attributes: ``dt``, ``steps``, ``time``, ``history_rows``, ``frames``,
  ``checkpoint_dt``, the energy-audit reference ``energy_ref`` (absent before the first
  row), the thread count ``threads``, the ``run_id`` of the results it belongs to, the
  resolved case as TOML (``case``) and its source file (``case_source``).

The control laws keep no memory outside the hub vector, so nothing else is needed. The file
is written to a temporary name and renamed (``os.replace``), so a run killed while writing
leaves the previous checkpoint intact.
"""

from __future__ import annotations

import dataclasses
import os
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from spinweb_fe import __version__
from spinweb_fe.errors import InputError
from spinweb_fe.model import State
from spinweb_fe.results import open_h5

CHECKPOINT_NAME = "checkpoint.h5"
CHECKPOINT_FORMAT = "spinweb-checkpoint"
CHECKPOINT_VERSION = 1


@dataclass
class Checkpoint:
    """A run's resumable state at an event boundary.

    Attributes
    ----------
    state : State
        Positions x_n (n,3) [m], half-step velocities v_{n-1/2} (n,3) [m/s], hub vector.
        Already started (v_0 shifted to v_{-1/2}): a restart must not start it again.
    dt : float [s]
        Time step of the run.
    history_rows : int
        Rows of ``/history`` written (the rows of steps < ``state.step``).
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
    energy_ref : tuple of float or None
        (energy balance at the first row [J], energy scale [J]) of the energy audit.
    threads : int
        Threads of the step loop: the continuation uses the same count (bit-identical).
    run_id : str
        The ``run_id`` attribute of the run's results.h5 (a restart checks that they match).
    arm_memory : dict of str -> ndarray
        The arm tracker's array attributes (its memory from row to row, e.g. the previous
        arm angle that keeps phi continuous; see :func:`spinweb_fe.solver.arm_memory_of`).
    """

    state: State
    dt: float
    history_rows: int
    frames: int
    pvd_entries: list
    case_toml: str
    case_source: str
    checkpoint_dt: float = 0.0
    energy_ref: tuple | None = None
    arm_memory: dict = dataclasses.field(default_factory=dict)
    threads: int = 1
    run_id: str = ""

    @property
    def steps(self) -> int:
        """Integer step n of the state."""
        return self.state.step

    @property
    def time(self) -> float:
        """Simulated time t_n [s]."""
        return self.state.time


def _state_fields():
    return [f.name for f in dataclasses.fields(State)]


def write_checkpoint(path, ck: Checkpoint) -> Path:
    """Write ``ck`` to ``path`` atomically (temporary file, then ``os.replace``).

    Returns
    -------
    Path
        The checkpoint file.
    """
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    with h5py.File(tmp, "w") as h5:
        a = h5.attrs
        a["format"] = CHECKPOINT_FORMAT
        a["checkpoint_version"] = CHECKPOINT_VERSION
        a["spinweb_version"] = __version__
        a["written"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
        a["dt"] = float(ck.dt)
        a["steps"] = int(ck.steps)
        a["time"] = float(ck.time)
        a["history_rows"] = int(ck.history_rows)
        a["frames"] = int(ck.frames)
        a["checkpoint_dt"] = float(ck.checkpoint_dt)
        a["threads"] = int(ck.threads)
        a["run_id"] = ck.run_id
        a["case"] = ck.case_toml
        a["case_source"] = ck.case_source
        if ck.energy_ref is not None:
            a["energy_ref"] = np.asarray(ck.energy_ref, dtype=np.float64)
        g = h5.create_group("state")
        for name in _state_fields():
            g.create_dataset(name, data=np.asarray(getattr(ck.state, name), dtype=np.float64))
        m = h5.create_group("arms")
        for name, value in ck.arm_memory.items():
            m.create_dataset(name, data=np.asarray(value))
        p = h5.create_group("pvd")
        p.create_dataset("time", data=np.array([t for t, _ in ck.pvd_entries], dtype=np.float64))
        p.create_dataset("file", data=np.array([f for _, f in ck.pvd_entries], dtype=object),
                         dtype=h5py.string_dtype())
    os.replace(tmp, path)
    return path


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
        if int(a.get("checkpoint_version", -1)) != CHECKPOINT_VERSION:
            raise InputError(path, "checkpoint_version",
                             f"version {a.get('checkpoint_version')} is not supported "
                             f"(this spinweb reads {CHECKPOINT_VERSION})")
        try:
            arrays = {name: np.array(h5["state"][name][()], dtype=np.float64)
                      for name in _state_fields()}
            entries = list(zip((float(t) for t in h5["pvd/time"][()]),
                               (f.decode() if isinstance(f, bytes) else str(f)
                                for f in h5["pvd/file"][()])))
            ck = Checkpoint(
                state=State(**arrays), dt=float(a["dt"]), history_rows=int(a["history_rows"]),
                frames=int(a["frames"]), pvd_entries=entries, case_toml=str(a["case"]),
                case_source=str(a["case_source"]), checkpoint_dt=float(a["checkpoint_dt"]),
                energy_ref=(tuple(float(x) for x in a["energy_ref"])
                            if "energy_ref" in a else None),
                arm_memory={k: v[()] for k, v in h5["arms"].items()},
                threads=int(a["threads"]), run_id=str(a["run_id"]))
        except KeyError as exc:
            raise InputError(path, "", f"incomplete checkpoint (missing {exc})") from None
        if int(a["steps"]) != ck.steps or len(entries) != ck.frames:
            raise InputError(path, "", "inconsistent checkpoint (steps or frames)")
    return ck


#: keys that a restart may change (everything else would break bit-identical continuation)
RESTART_KEYS = {"time.end", "title"}


def _flat(d):
    """{'a': {'b': 1}} -> {'a.b': 1} (case dicts have two levels)."""
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update({f"{k}.{kk}": vv for kk, vv in v.items()})
        else:
            out[k] = v
    return out


def restart_case(out_dir, sets=(), progress=True, checkpoint_dt=None, threads=None):
    """Continue the run in ``out_dir`` from ``out_dir/checkpoint.h5``.

    ``results.h5`` is cut back to the checkpoint's history rows and frames, and the run
    continues from the stored state (already started: no second half-step shift), so the
    histories equal those of an uninterrupted run bit for bit.

    Parameters
    ----------
    out_dir : str or Path
        Folder of the interrupted run.
    sets : iterable of str
        ``key=value`` overrides; only ``time.end`` (and ``title``) may change.
    checkpoint_dt : float or None [s]
        Checkpoint interval of the continued run (None: the checkpoint's).
    threads : int or None
        Threads of the continued run (None: the checkpoint's; another count continues
        correctly but not bit-identically).

    Returns
    -------
    spinweb_fe.solver.RunResult
        The continued part of the run.
    """
    from spinweb_fe import case as case_mod
    from spinweb_fe.output import check_results_for_restart
    from spinweb_fe.solver import run_case

    out_dir = Path(out_dir)
    ck_path = out_dir / CHECKPOINT_NAME
    ck = read_checkpoint(ck_path)
    raw = case_mod.apply_overrides(tomllib.loads(ck.case_toml), sets)
    case = case_mod.validate(raw, ck.case_source)
    before = _flat(case_mod.validate(tomllib.loads(ck.case_toml), ck.case_source).to_dict())
    after = _flat(case.to_dict())
    changed = sorted(k for k in set(before) | set(after)
                     if before.get(k) != after.get(k) and k not in RESTART_KEYS)
    if changed:
        raise InputError("--set", changed[0], "cannot change on --restart (only time.end can)")
    check_results_for_restart(out_dir, ck)
    dt_ck = ck.checkpoint_dt if checkpoint_dt is None else checkpoint_dt
    return run_case(case, out_dir, progress=progress, checkpoint_dt=dt_ck, resume=ck,
                    threads=threads)
