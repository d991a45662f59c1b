"""The event loop: the numba step loop runs in chunks between events, and recorders act
only at event boundaries (history rows, frames, checkpoints, the end). Writes no files.
"""

from __future__ import annotations

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
from spinweb_fe.fe.payout import PAYOUTS
from spinweb_fe.fe.state import State
from spinweb_fe.fe.touch import SERVICE
from spinweb_fe.record.arms import ArmTracker
from spinweb_fe.record.energy import ENERGY_LIMIT, EnergyAudit, energy_floor
from spinweb_fe.record.history import hub_plane, table_rows
from spinweb_fe.record.recorders import Frame, RunInfo
from spinweb_fe.record.strength import StrengthMonitor, strength_columns
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


def start(model: Model, control: Control, state: State, dt: float, work=None):
    """Shift v_0, omega_0 back half a step (second-order start of central differences);
    ``work``: the force passes' scratch (made here if not given)."""
    if work is None:
        work = make_work(model.n_nodes, model.n_elems)
    record = False  # from Python: typed bool, the same compiled passes as current_tension's
    internal_forces(model.elements, model.links, state.node_pos, state.node_vel, work, record)
    step.start_half_step(model.kernel, model.body, control.kernel, state, work.force, dt)


def records_vectors(model: Model, state: State) -> bool:
    """Whether a run records the vector columns (momentum vectors, the hub's pose, the
    distances from the hub plane): a free hub, the gravity gradient, or a scene not exactly
    in the plane (some node with z or v_z not 0). A fixed-axis scene in the plane without
    the tidal field stays there exactly (its forces have no z part), and its step loop is
    the one without them."""
    return bool(model.free_hub or model.env.n > 0.0 or np.any(state.node_pos[:, 2] != 0.0)
                or np.any(state.node_vel[:, 2] != 0.0))


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
    """The step loop's buffers and the turning of its records into history rows."""

    def __init__(self, model, control, tracker, rec_every, threads, dt, vectors=False):
        self.args = (model.kernel, *model.hub_kind, control.kernel)
        self.work = make_work(model.n_nodes, model.n_elems, threads,
                              elem_nodes=model.elements.nodes)
        # the gravity gradient's node forces on a fixed axis (None: numba compiles none of
        # the field's phases; a free hub takes the field in its own)
        self.tidal = (np.zeros((model.n_nodes, 3)) if model.env.n > 0.0 and not model.free_hub
                      else None)
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
        code = model.coil.payout_code
        self.rate = code != PAYOUTS["free"].code  # a device anchors the arm at its front
        self.law = code in (PAYOUTS["gate"].code, PAYOUTS["rate"].code)  # a length law
        self.devices = code in (PAYOUTS["rate"].code, PAYOUTS["brake"].code)
        self.row_dt = rec_every * dt
        self.tracker = tracker
        self.model = model
        self.history = []

    def loop_args(self, state, dt, nsteps, audit=None, contact=None) -> tuple:
        """The arguments of fe.step.advance for ``nsteps`` steps of ``state``."""
        return (*self.args, state, self.work, self.rec, dt, nsteps, self.vec, self.threads,
                audit, contact, self.tidal)

    def advance(self, state, dt, nsteps, audit=None, contact=None):
        return step.advance(*self.loop_args(state, dt, nsteps, audit, contact))

    def rows(self, nrec) -> dict:
        rows = table_rows(self.rec.table, nrec, self.model)
        arms = named(self.rec.arm_table[:nrec], ARM) if self.coiled else None
        pos, vel = self.rec.probe_pos[:nrec], self.rec.probe_vel[:nrec]
        vectors = None
        if self.vec is not None:
            vectors = named(self.vec[:nrec], VECTOR, self.model)
            if self.model.free_hub:  # the arms are measured in the hub's plane
                pos, vel = hub_plane(pos, vel, vectors["hub_position"],
                                     vectors["hub_quaternion"])
        rows.update(self.tracker.columns(rows, pos, vel, arms, self.row_dt, self.rate,
                                         self.law))
        if self.devices:
            rows["brake_tension"], rows["brake_work"] = arms["tension"], arms["work"]
        if vectors is not None:
            rows["tip_position"] = self.rec.probe_pos[:nrec, :self.tracker.n].copy()
            rows.update(vectors)
        if len(self.model.strength.fail):
            rows.update(strength_columns(self.model, named(self.rec.strength_table[:nrec],
                                                           STRENGTH)))
        self.history.append(rows)
        return rows

    def joined(self) -> dict:
        names = self.history[0] if self.history else {}
        return {k: np.concatenate([r[k] for r in self.history]) for k in names}


def simulate(model: Model, control: Control, state: State, dt: float, schedule: Schedule,
             recorders=(), *, resume=None, stop=None, threads=None,
             energy_limit=ENERGY_LIMIT, crossings=None, contact=None) -> RunResult:
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
    resume : dict or None
        The memory of a checkpoint (name -> dict of arrays): ``state`` then already holds
        half-step velocities v_{n-1/2} (the central-difference start is not applied again)
        and the arm measure and the recorders continue from their memory.
    stop : callable() -> str or None
        Checked at every event boundary; a non-empty answer (e.g. 'SIGTERM') stops the run
        there with status 'interrupted by <answer>'.
    threads : int or None
        Threads of the step loop (see :func:`choose_threads`); results are bit-identical
        for every thread count (fixed blocks, fixed summation order: fe.forces).
    energy_limit : float
        Relative energy-balance error that stops the run (RunError).
    crossings : spinweb_fe.record.crossings.CrossingAudit or None
        Count the crossings of elements: the step loop tests each step (fe.touch) and stops
        when the audit's candidate list needs a rebuild (history column ``crossings``, the
        running count).
    contact : spinweb_fe.fe.cable_contact.CableContact or None
        Cable-cable contact on the audit's candidate pairs (needs ``crossings``): its forces
        at x_n join the step's kick; history column ``cable_contact_energy``.

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
    tracker = ArmTracker(model.mesh, model.hub.radius)
    audit = EnergyAudit(energy_limit, energy_floor(model))
    monitor = StrengthMonitor()
    owners = [tracker, audit, monitor, *recorders]  # everything with a memory
    if crossings is not None:
        owners.append(crossings)
    for owner in owners:
        if resume and owner.name in resume:
            owner.restore(resume[owner.name])
    threads = choose_threads(model, threads)
    chunks = _Chunks(model, control, tracker, rec_every, threads, dt,
                     records_vectors(model, state))
    t_compile = time.perf_counter()
    if resume is None:
        start(model, control, state, dt, chunks.work)
    room = ROWS_PER_CHUNK + 1  # history rows of a call
    if crossings is not None:
        crossings.build(state, room)

    def kernels():
        if crossings is None:
            return None, None
        if contact is None:
            return crossings.kernel, None
        if crossings.pair_codes is not contact.codes:  # the list was rebuilt
            contact.sync(crossings.pair_codes, crossings.pair_dist)
        return crossings.kernel, contact.kernel(crossings.kernel, room)

    # compile / load the loop outside the timed part (a cold start on two cores)
    first, touching = state.copy(), kernels()
    with compile_helper(chunks, first, dt, *touching):
        chunks.advance(first, dt, 0, *touching)
    compile_s = time.perf_counter() - t_compile
    for r in recorders:
        r.start(RunInfo(model, dt, n_total, step0, threads))

    def advance(nsteps):
        if crossings is None:
            return chunks.advance(state, dt, nsteps)
        end = int(state.step[0]) + nsteps
        while int(state.step[0]) < end:  # the loop stops where the audit's list went stale
            audit_k, contact_k = kernels()
            code, nrec = chunks.advance(state, dt, end - int(state.step[0]), audit_k,
                                        contact_k)
            if code == SERVICE:
                code = 0
            crossings.take(state)
            if nrec or code:
                collect(code, nrec, (audit_k, contact_k))
        return 0, 0

    def memory():
        return {o.name: o.memory() for o in owners if o.name}

    def collect(code, nrec, touched=None):
        rows = chunks.rows(nrec)
        if touched is not None:  # the audit's and the contact's columns of these rows
            audit_k, contact_k = touched
            if audit_k is not None:
                rows["crossings"] = audit_k.row_count[:nrec].astype(float)
            if contact_k is not None:
                rows["cable_contact_energy"] = contact_k.rows[:nrec, 0].copy()
                rows["cable_contact_dissipation"] = contact_k.rows[:nrec, 1].copy()
        if nrec:
            for r in recorders:
                r.rows(rows)
        if code != 0:
            raise RunError("non-finite positions or energies (numerical instability; "
                           "reduce time.cfl or time.dt)", time=float(state.time[0]))
        if nrec:
            audit.rows(rows)
            monitor.rows(rows)

    frames, loop_s, status, reason = 0, 0.0, "completed", None
    budget = FIRST_CHUNK_STEPS
    while True:
        n = int(state.step[0])
        reason = stop() if stop else None
        if reason:
            if n > step0:
                _checkpoint(recorders, state, memory())
            status = f"interrupted by {reason}"
            break
        if n > step0 and (n == n_total or (ck_every and n % ck_every == 0)):
            _checkpoint(recorders, state, memory())
        if frame_every and (n % frame_every == 0 or n == n_total):
            broken = state.strength.broken.copy() if model.strength.rupture else None
            frame = Frame(n * dt, state.node_pos.copy(), state.node_vel.copy(),
                          current_tension(model, state.node_pos, state.node_vel, broken,
                                          chunks.work), broken)
            for r in recorders:
                r.frame(frame)
            frames += 1
        if n == n_total:  # the last row: record at t_end on a copy, the state stays at t_end
            touched = None
            if crossings is not None:  # the columns at t_end, from copies: the state stays
                audit_k, contact_k = kernels()
                audit_k = _copied(audit_k)
                contact_k = None if contact_k is None else \
                    contact_k._replace(pos0=audit_k.pos0, stats=contact_k.stats.copy(),
                                       reach=contact_k.reach.copy(),
                                       hold=contact_k.hold.copy(),
                                       vel0=contact_k.vel0.copy(),
                                       spin=contact_k.spin.copy())
                touched = (audit_k, contact_k)
            t0 = time.perf_counter()
            code, nrec = chunks.advance(state.copy(), dt, 1, *(touched or (None, None)))
            loop_s += time.perf_counter() - t0
            collect(0 if code == SERVICE else code, nrec, touched)
            break
        # next event: a chunk of rows, a frame, a checkpoint, the end, or the wall-time budget
        target = min(n_total, n + ROWS_PER_CHUNK * rec_every, n + budget)
        if frame_every:
            target = min(target, (n // frame_every + 1) * frame_every)
        if ck_every:
            target = min(target, (n // ck_every + 1) * ck_every)
        t0 = time.perf_counter()
        code, nrec = advance(target - n)
        elapsed = time.perf_counter() - t0
        loop_s += elapsed
        # steps that take about WALL_CHUNK_S, growing at most 8-fold per chunk
        budget = max(1, min(8 * budget, int(WALL_CHUNK_S * (target - n) / max(elapsed, 1e-9))))
        if crossings is None:  # (an audited advance collects its rows itself)
            collect(code, nrec)
    for r in recorders:
        r.end(status)
    return RunResult(chunks.joined(), dt, int(state.step[0]), loop_s, compile_s, state, status,
                     frames, threads, reason, memory())


def _copied(kernel):
    """A tuple of arrays with every array copied (the audit's, for a trial step)."""
    return type(kernel)(*(v.copy() if isinstance(v, np.ndarray) else v for v in kernel))


def _checkpoint(recorders, state, memory):
    for r in recorders:
        r.checkpoint(state, memory)


def time_steps(model: Model, control: Control, state: State, dt: float, threads: int,
               rec_every: int, nsteps: int) -> tuple:
    """(compile or cache-load time [s], wall time [s] of ``nsteps`` steps) of the step loop
    on a copy of ``state`` (``nsteps`` give at most ROWS_PER_CHUNK rows)."""
    choose_threads(model, threads)
    chunks = _Chunks(model, control, ArmTracker(model.mesh, model.hub.radius), rec_every,
                     threads, dt, records_vectors(model, state))
    trial = state.copy()
    t0 = time.perf_counter()
    with compile_helper(chunks, trial, dt):  # a cold start on two cores
        chunks.advance(trial, dt, 0)
    t1 = time.perf_counter()
    chunks.advance(trial, dt, nsteps)
    return t1 - t0, time.perf_counter() - t1
