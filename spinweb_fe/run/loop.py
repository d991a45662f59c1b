"""The event loop: the numba step loop runs in chunks between events, and recorders act
only at event boundaries (history rows, frames, checkpoints, the end). Writes no files.
"""

from __future__ import annotations

import copy
import math
import os
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from spinweb_fe.errors import InputError, RunError
from spinweb_fe.fe import step
from spinweb_fe.fe.control import Control
from spinweb_fe.fe.forces import internal_forces, make_work
from spinweb_fe.fe.layout import ARM, ROW_WIDTH, SLOTS, STRENGTH, VEC_WIDTH, VECTOR, named
from spinweb_fe.fe.model import Model
from spinweb_fe.fe.coil.payout import payout_of
from spinweb_fe.fe.state import State
from spinweb_fe.fe.contact.touch import SERVICE
from spinweb_fe.record.arms import ArmTracker
from spinweb_fe.record.energy import ENERGY_LIMIT, EnergyAudit, energy_floor
from spinweb_fe.record.feature import HOOKS
from spinweb_fe.record.history import hub_plane, table_rows
from spinweb_fe.record.recorders import Frame, RunInfo
from spinweb_fe.run.features import features_of, records_vectors
from spinweb_fe.run.warmup import compile_helper

ROWS_PER_CHUNK = 256  # history rows between two returns to Python (flush, progress, audit)
WALL_CHUNK_S = 0.2  # ... and at most about this much wall time (signals, progress)
FIRST_CHUNK_STEPS = 64  # steps of the first chunk, before the loop speed is known
PARALLEL_MIN_ELEMENTS = 20000  # below this a parallel region costs more than it saves


class Schedule(NamedTuple):
    """When things happen [s]: the end, history rows, frames (0: none) and checkpoints
    (0: only at the end and when stopped, if a recorder takes them)."""

    t_end: float
    history_dt: float
    frame_dt: float = 0.0
    checkpoint_dt: float = 0.0


@dataclass
class RunResult:
    """What a run returns: the history (name -> array), timings and the final state."""

    history: dict
    dt: float
    steps: int
    loop_s: float
    compile_s: float
    state: State
    status: str = "completed"
    frames: int = 0
    threads: int = 1
    stop_reason: str | None = None
    memory: dict = field(default_factory=dict)
    features: list = field(default_factory=list)


def start(model: Model, control: Control, state: State, dt: float, work=None):
    """Shift v_0, omega_0 back half a step (second-order start of central differences);
    ``work``: the force passes' scratch (made here if not given)."""
    if work is None:
        work = make_work(model.n_nodes, model.n_elems)
    record = False  # from Python: typed bool, the same compiled passes as current_tension's
    internal_forces(model.elements, model.links, state.node_pos, state.node_vel, work, record)
    step.start_half_step(model.kernel, model.body, control.kernel, state, work.force, dt)


def current_tension(model: Model, pos, vel, broken=None, work=None):
    """(m,) element tensions [N] at the given positions (0 in the ``broken`` elements);
    ``work``: the force passes' scratch to use (made here if not given)."""
    if work is None:
        work = make_work(model.n_nodes, model.n_elems)
    internal_forces(model.elements, model.links, pos, vel, work, True)
    t = work.tension.copy()
    if broken is not None and len(broken):
        t[broken] = 0.0
    return t


def requested_threads(requested=None):
    """``requested``, else $SPINWEB_THREADS as an integer >= 1, else None.

    Raises
    ------
    InputError
        If $SPINWEB_THREADS is set to anything but an integer >= 1.
    """
    text = os.environ.get("SPINWEB_THREADS", "").strip()
    if requested is not None or not text:
        return requested
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise InputError("SPINWEB_THREADS", "", f"must be an integer >= 1, got '{text}'")
    return value


def choose_threads(model: Model, requested=None) -> int:
    """Threads for the step loop: ``requested`` (or $SPINWEB_THREADS), else 2 for webs of at
    least PARALLEL_MIN_ELEMENTS elements on a machine with 2+ cores, else 1. Also sets numba's
    thread count."""
    import numba

    requested = requested_threads(requested)
    if requested is None:
        requested = 2 if model.n_elems >= PARALLEL_MIN_ELEMENTS else 1
    threads = max(1, min(int(requested), numba.config.NUMBA_NUM_THREADS))
    numba.set_num_threads(threads)
    return threads


class _Chunks:
    """The step loop's buffers, its features' hooks, and the turning of its records into
    history rows."""

    def __init__(self, model, control, tracker, rec_every, threads, dt, vectors=False,
                 features=()):
        self.args = (model.kernel, *model.hub_kind, control.kernel)
        self.work = make_work(model.n_nodes, model.n_elems, threads,
                              elem_nodes=model.elements.nodes)
        self.features = list(features)
        # None on one thread, so that numba compiles no thread kernel
        self.threads = None if threads == 1 else threads
        rows = ROWS_PER_CHUNK + 1
        n_probes = len(tracker.probes)
        self.rec = step.Recording(rec_every, tracker.probes, np.zeros((rows, ROW_WIDTH)),
                                  np.zeros((rows, n_probes, 3)), np.zeros((rows, n_probes, 3)),
                                  np.zeros((rows, len(model.coil.arm_ptr) - 1, len(ARM))),
                                  np.zeros((rows, len(STRENGTH) if len(model.strength.fail)
                                            else 0)), SLOTS)
        self.vec = np.zeros((rows, VEC_WIDTH)) if vectors or model.free_hub else None
        self.coiled = len(model.coil.level_nodes) > 0
        payout = payout_of(model.coil)
        self.anchored = payout.anchors  # the arm hangs from its front
        self.law = payout.length_law  # a law limits the paid-out length
        self.row_dt = rec_every * dt
        self.tracker = tracker
        self.model = model
        self.history = []

    def hooks(self, trial=False) -> dict:
        """{hook: kernel data} of the features (fe.step.advance's hook arguments); with
        ``trial``, copies for a step that must not change the run."""
        hooks = {}
        for f in self.features:
            k = f.kernel(hooks)
            if trial and k is not None:
                k = f.trial(k, hooks)
            if f.hook is not None:
                hooks[f.hook] = k
        return hooks

    def loop_args(self, state, dt, nsteps, hooks=None) -> tuple:
        """The arguments of fe.step.advance for ``nsteps`` steps of ``state``."""
        hooks = hooks or {}
        return (*self.args, state, self.work, self.rec, dt, nsteps, self.vec, self.threads,
                *(hooks.get(h) for h in HOOKS))

    def advance(self, state, dt, nsteps) -> tuple:
        """One call of the step loop on its features' kernels: (status, rows recorded)."""
        return step.advance(*self.loop_args(state, dt, nsteps, self.hooks()))

    def call(self, state, dt, nsteps, hooks=None) -> tuple:
        """One call of the step loop: (status, the rows it recorded or None)."""
        hooks = self.hooks() if hooks is None else hooks
        code, nrec = step.advance(*self.loop_args(state, dt, nsteps, hooks))
        return code, (self.rows(nrec, hooks) if nrec else None)

    def run(self, state, dt, nsteps) -> tuple:
        """``nsteps`` steps of ``state``, the loop stopping where a feature needs Python
        (fe.contact.touch.SERVICE) and going on after its service: (status, the calls' rows)."""
        end = int(state.step[0]) + nsteps
        calls = []
        while True:
            code, rows = self.call(state, dt, end - int(state.step[0]))
            if rows is not None:
                calls.append(rows)
            for f in self.features:
                f.service(state)
            if code != SERVICE or int(state.step[0]) >= end:
                return (0 if code == SERVICE else code), calls

    def rows(self, nrec, hooks) -> dict:
        rows = table_rows(self.rec.table, nrec, self.model)
        arms = named(self.rec.arm_table[:nrec], ARM) if self.coiled else None
        pos, vel = self.rec.probe_pos[:nrec], self.rec.probe_vel[:nrec]
        vectors = None
        if self.vec is not None:
            vectors = named(self.vec[:nrec], VECTOR, self.model)
            if self.model.free_hub:  # the arms are measured in the hub's plane
                pos, vel = hub_plane(pos, vel, vectors["hub_position"],
                                     vectors["hub_quaternion"])
        rows.update(self.tracker.columns(rows, pos, vel, arms, self.row_dt, self.anchored,
                                         self.law))
        if vectors is not None:
            rows["tip_position"] = self.rec.probe_pos[:nrec, :self.tracker.n].copy()
            rows.update(vectors)
        for f in self.features:
            rows.update(f.columns(hooks.get(f.hook), self.rec, nrec))
        self.history.append(rows)
        return rows

    def frame(self, state, t) -> Frame:
        """The frame of ``state`` at time ``t`` [s] (copies; the tensions at x_n, none in a
        broken element)."""
        broken = state.strength.broken.copy() if self.model.strength.rupture else None
        return Frame(t, state.node_pos.copy(), state.node_vel.copy(),
                     current_tension(self.model, state.node_pos, state.node_vel, broken,
                                     self.work), broken)

    def joined(self) -> dict:
        names = self.history[0] if self.history else {}
        return {k: np.concatenate([r[k] for r in self.history]) for k in names}


def simulate(model: Model, control: Control, state: State, dt: float, schedule: Schedule,
             recorders=(), *, features=None, resume=None, stop=None, threads=None,
             energy_limit=ENERGY_LIMIT) -> RunResult:
    """Integrate from ``state`` to ``schedule.t_end``; Python acts only at event boundaries.

    Parameters
    ----------
    model, control, state : Model, Control, State
        ``state`` is advanced in place. A fresh state holds the initial velocities v_0.
    dt : float [s]
    schedule : Schedule
    recorders : sequence of spinweb_fe.record.recorders.Recorder
        Told of the start, every chunk of history rows, every frame, every checkpoint and
        the end (see that module). The energy audit (:class:`EnergyAudit`) checks every chunk
        after them.
    features : sequence of spinweb_fe.record.feature.Feature or None
        The run's optional parts (run.features.features_of; None: those of the model
        alone). Each hands the step loop its hook, adds its history columns, is serviced
        when the loop stops for it, and keeps its memory in the checkpoint.
    resume : dict or None
        The memory of a checkpoint (name -> dict of arrays): ``state`` then already holds
        half-step velocities v_{n-1/2} (the central-difference start is not applied again)
        and the arm measure, the features and the recorders continue from their memory.
    stop : callable() -> str or None
        Checked at every event boundary; a non-empty answer (e.g. 'SIGTERM') stops the run
        there with status 'interrupted by <answer>'.
    threads : int or None
        Threads of the step loop (see :func:`choose_threads`); results are bit-identical
        for every thread count (fixed blocks, fixed summation order: fe.forces).
    energy_limit : float
        Relative energy-balance error that stops the run (RunError).

    Returns
    -------
    RunResult
        The history recorded by this call, with ``status`` 'completed' or 'interrupted by ...'.
    """
    rec_every = max(1, round(schedule.history_dt / dt))
    n_total = int(math.ceil(schedule.t_end / dt - 1e-9))
    step0 = int(state.step[0])
    if step0 > n_total:
        raise ValueError(f"the state is at step {step0}, after the end step {n_total}")
    frame_every = max(1, round(schedule.frame_dt / dt)) if schedule.frame_dt > 0 else 0
    ck_every = max(1, round(schedule.checkpoint_dt / dt)) if schedule.checkpoint_dt > 0 else 0
    features = features_of(model, state) if features is None else list(features)
    tracker = ArmTracker(model.mesh, model.hub.radius)
    balance = EnergyAudit(energy_limit, energy_floor(model))
    told = [*recorders, *features]  # everything told of the run's events
    owners = [tracker, balance, *features, *recorders]  # everything with a memory
    for owner in owners:
        if resume and owner.name in resume:
            owner.restore(resume[owner.name])
    threads = choose_threads(model, threads)
    chunks = _Chunks(model, control, tracker, rec_every, threads, dt,
                     records_vectors(model, state), features)
    t_compile = time.perf_counter()
    if resume is None:
        start(model, control, state, dt, chunks.work)
    for f in features:
        f.prepare(state, ROWS_PER_CHUNK + 1)
    # compile / load the loop outside the timed part (a cold start on two cores)
    first = state.copy()
    hooks = chunks.hooks(trial=True)
    with compile_helper(chunks, first, dt, hooks):
        chunks.call(first, dt, 0, hooks)
    compile_s = time.perf_counter() - t_compile
    for r in told:
        r.start(RunInfo(model, dt, n_total, step0, threads))

    def memory():
        return {o.name: o.memory() for o in owners if o.name}

    def collect(code, calls):
        for rows in calls:
            for r in recorders:
                r.rows(rows)
        if code != 0:
            raise RunError("non-finite positions or energies (numerical instability; "
                           "reduce time.cfl or time.dt)", time=float(state.time[0]))
        for rows in calls:
            for f in features:
                f.rows(rows)
            balance.rows(rows)

    frames, loop_s, status, reason = 0, 0.0, "completed", None
    budget = FIRST_CHUNK_STEPS
    while True:
        n = int(state.step[0])
        reason = stop() if stop else None
        if reason:
            if n > step0:
                _checkpoint(told, state, memory)
            status = f"interrupted by {reason}"
            break
        if n > step0 and (n == n_total or (ck_every and n % ck_every == 0)):
            _checkpoint(told, state, memory)
        if frame_every and (n % frame_every == 0 or n == n_total):
            frame = chunks.frame(state, n * dt)
            for r in told:
                r.frame(frame)
            frames += 1
        if n == n_total:  # the last row: record at t_end on copies, the state stays at t_end
            t0 = time.perf_counter()
            code, rows = chunks.call(state.copy(), dt, 1, chunks.hooks(trial=True))
            loop_s += time.perf_counter() - t0
            collect(0 if code == SERVICE else code, [] if rows is None else [rows])
            break
        # next event: a chunk of rows, a frame, a checkpoint, the end, or the wall-time budget
        target = min(n_total, n + ROWS_PER_CHUNK * rec_every, n + budget)
        if frame_every:
            target = min(target, (n // frame_every + 1) * frame_every)
        if ck_every:
            target = min(target, (n // ck_every + 1) * ck_every)
        t0 = time.perf_counter()
        code, calls = chunks.run(state, dt, target - n)
        elapsed = time.perf_counter() - t0
        loop_s += elapsed
        # steps that take about WALL_CHUNK_S, growing at most 8-fold per chunk
        budget = max(1, min(8 * budget, int(WALL_CHUNK_S * (target - n) / max(elapsed, 1e-9))))
        collect(code, calls)
    for r in told:
        r.end(status)
    return RunResult(chunks.joined(), dt, int(state.step[0]), loop_s, compile_s, state, status,
                     frames, threads, reason, memory(), features)


def _checkpoint(told, state, memory):
    """A checkpoint event: everything's memory as it stands, then each told."""
    snapshot = memory()
    for r in told:
        r.checkpoint(state, snapshot)


def time_steps(model: Model, control: Control, state: State, dt: float, threads: int,
               rec_every: int, nsteps: int, features=None) -> tuple:
    """(compile or cache-load time [s], wall time [s] of the steps, the steps run) of the
    step loop with its ``features`` (None: the model's) on a copy of ``state`` (``nsteps``
    give at most ROWS_PER_CHUNK rows; fewer steps run only where the loop stops the run)."""
    features = features_of(model, state) if features is None else list(features)
    choose_threads(model, threads)
    trial = state.copy()
    for f in features:
        f.prepare(state, ROWS_PER_CHUNK + 1)
    # the steps run on copies of the features (the model shared), which serve the loop's
    # stops on the trial state as the run's serve them on its own (a stale list rebuilt):
    # the rate counts the rebuilds, and nothing of the trial reaches the run
    own = copy.deepcopy(features, {id(model): model})
    chunks = _Chunks(model, control, ArmTracker(model.mesh, model.hub.radius), rec_every,
                     threads, dt, records_vectors(model, state), own)
    hooks = chunks.hooks()
    t0 = time.perf_counter()
    with compile_helper(chunks, trial, dt, hooks):  # a cold start on two cores
        chunks.call(trial, dt, 0, hooks)
    t1 = time.perf_counter()
    chunks.run(trial, dt, nsteps)
    return t1 - t0, time.perf_counter() - t1, int(trial.step[0] - state.step[0])
