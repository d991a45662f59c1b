"""Run orchestration: the numba loop between events, recorders at event boundaries.

Python only acts at events (history flush, frames, progress, energy audit); the step loop
runs inside ``kernels.advance``.
"""

from __future__ import annotations

import logging
import math
import os
import signal
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from spinweb_fe import kernels
from spinweb_fe.arms import ArmTracker
from spinweb_fe.control import Control, make_control
from spinweb_fe.errors import InputError, RunError
from spinweb_fe.model import Model, State, choose_dt, initial_state, model_from_case

log = logging.getLogger("spinweb")
ENERGY_LIMIT = 0.5  # stop when the energy balance error exceeds this fraction of the energy scale
ENERGY_WARN = 0.01  # warn (once) above this fraction: results are suspect, reduce time.cfl
ROWS_PER_CHUNK = 256  # history rows between two returns to Python (flush, progress, audit)
WALL_CHUNK_S = 0.2  # ... and at most about this much wall time (signals, progress)
FIRST_CHUNK_STEPS = 64  # steps of the first chunk, before the loop speed is known
MAX_STEPS = 1e10  # more steps than this is a units slip (days of run time), not a case


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
    extra: dict = field(default_factory=dict)


class Workspace:
    """Preallocated buffers of the step loop."""

    def __init__(self, model: Model, rows: int, probes: np.ndarray, threads: int = 1):
        n_probes = len(probes)
        self.probes = probes
        self.force = np.zeros((threads, model.n_nodes, 3))  # one buffer per thread
        self.tension = np.zeros(model.n_elems)
        self.rec = np.zeros((rows, len(kernels.REC_COLUMNS)))
        self.probe_pos = np.zeros((rows, n_probes, 3))
        self.probe_vel = np.zeros((rows, n_probes, 3))


def _advance(model, control, state, ws, dt, nsteps, rec_every):
    return kernels.advance(
        state.pos, state.vel, state.hub, ws.force, ws.tension, model.node_inv_mass,
        model.node_mass, model.elem_nodes, model.elem_rest_len, model.elem_ea, model.elem_cdamp,
        model.tied_idx, model.tied_ref, model.node_contact, model.hub_radius, model.hub_friction,
        model.j_eff, control.code, control.params, dt, nsteps, rec_every, ws.probes,
        ws.rec, ws.probe_pos, ws.probe_vel)


def start(model: Model, control: Control, state: State, dt: float):
    """Shift v_0, omega_0 back half a step (second-order start of central differences)."""
    ws_force = np.zeros((model.n_nodes, 3))
    kernels.start_half_step(state.pos, state.vel, state.hub, ws_force, np.zeros(model.n_elems),
                            model.node_inv_mass, model.elem_nodes, model.elem_rest_len,
                            model.elem_ea, model.elem_cdamp, model.tied_idx, control.code,
                            control.params, model.j_eff, dt)


def current_tension(model: Model, pos, vel):
    """(m,) element tensions [N] at the given positions."""
    f = np.zeros((model.n_nodes, 3))
    t = np.zeros(model.n_elems)
    kernels.eval_elements(pos, vel, model.elem_nodes, model.elem_rest_len, model.elem_ea,
                          model.elem_cdamp, f, t, False)
    return t


PARALLEL_MIN_ELEMENTS = 20000  # below this a parallel region costs more than it saves


def choose_threads(model: Model, requested=None) -> int:
    """Threads for the step loop: ``requested`` (or $SPINWEB_THREADS), else 2 for webs of at
    least PARALLEL_MIN_ELEMENTS elements on a machine with 2+ cores, else 1. Also sets numba's
    thread count."""
    import numba

    if requested is None and os.environ.get("SPINWEB_THREADS"):
        requested = int(os.environ["SPINWEB_THREADS"])
    if requested is None:
        requested = 2 if model.n_elems >= PARALLEL_MIN_ELEMENTS else 1
    threads = max(1, min(int(requested), numba.config.NUMBA_NUM_THREADS))
    numba.set_num_threads(threads)
    return threads


def energy_balance(h):
    """KE + SE - W + D (should stay constant) for a history dict / row table."""
    return (h["kinetic_energy"] + h["strain_energy"] - h["torque_work"]
            + h["damping_dissipation"] + h["contact_dissipation"])


class _EnergyAudit:
    """Energy balance check per chunk of rows: KE + SE - W + D must stay near its first value."""

    def __init__(self, limit, ref=None):
        self.limit = limit
        self.ref = ref  # (balance at the first row [J], energy scale [J]) or None
        self.warned = False

    def check(self, rows, t):
        bal = energy_balance(rows)
        if self.ref is None:
            self.ref = (float(bal[0]), max(abs(rows["kinetic_energy"][0])
                                           + abs(rows["strain_energy"][0]), 1e-30))
        scale = max(self.ref[1], float(np.max(np.abs(rows["torque_work"]))))
        err = float(np.max(np.abs(bal - self.ref[0]))) / scale
        if err > self.limit:
            raise RunError(f"energy balance off by {100 * err:.0f} % of the energy scale "
                           "(numerical instability; reduce time.cfl)", time=t)
        if err > ENERGY_WARN and not self.warned:
            self.warned = True
            log.warning("warning: at t = %.6g s the energy balance is off by %.2g %% of the "
                        "energy scale (slack/taut snapping or hub impacts; a smaller time.cfl "
                        "or a little damping helps, see docs/stability.md)", t, 100 * err)


def arm_memory_of(tracker) -> dict:
    """What an ArmTracker carries from row to row (e.g. the previous arm angle used to keep
    phi continuous): every array attribute, copied. Static arrays (probes) come along; they
    are equal on restart, and a later memory attribute is saved without a change here."""
    return {k: np.array(v) for k, v in vars(tracker).items() if isinstance(v, np.ndarray)}


def simulate(model: Model, control: Control, state: State, dt: float, t_end: float,
             history_dt: float, frame_dt: float = 0.0, on_rows=None, on_frame=None,
             progress=None, energy_limit=ENERGY_LIMIT, *, started=False, stop=None,
             checkpoint_dt=0.0, on_checkpoint=None, energy_ref=None,
             arm_memory=None, threads=None) -> RunResult:
    """Integrate from ``state`` to ``t_end``; Python acts only at event boundaries.

    Parameters
    ----------
    model, control, state : Model, Control, State
        ``state`` is advanced in place. A fresh state holds the initial velocities v_0.
    dt, t_end, history_dt, frame_dt : float [s]
        Time step, end time, history interval and frame interval (0: no frames).
    on_rows : callable(dict) or None
        Called with each chunk of history rows (name -> array).
    on_frame : callable(t, pos, vel, tension) or None
        Called every ``frame_dt`` (and at the end).
    progress : callable(t, steps_per_s) or None
    energy_limit : float
        Relative energy-balance error that stops the run (RunError).
    started : bool
        True if ``state`` already holds half-step velocities v_{n-1/2} (a restart from a
        checkpoint): the central-difference start is then not applied again.
    stop : callable() -> str or None
        Checked at every event boundary; a non-empty answer (e.g. 'SIGTERM') stops the run
        there with status 'interrupted by <answer>'.
    checkpoint_dt : float [s]
        Call ``on_checkpoint`` every ``checkpoint_dt`` of simulated time (0: never), and in
        any case at the end and when stopped.
    on_checkpoint : callable(state, energy_ref, arm_memory) or None
        Called at an event boundary of step n, after the history rows of steps < n and
        before the frame of step n.
    energy_ref : tuple or None
        Energy-audit reference of a restarted run (see :class:`spinweb_fe.checkpoint.Checkpoint`).
    arm_memory : dict or None
        Arm tracker memory of a restarted run (see :func:`arm_memory_of`).
    threads : int or None
        Threads of the step loop (see :func:`choose_threads`); results are bit-identical
        for a given thread count.

    Returns
    -------
    RunResult
        The history recorded by this call, with ``status`` 'completed' or 'interrupted by ...'.
    """
    rec_every = max(1, round(history_dt / dt))
    n_total = int(math.ceil(t_end / dt - 1e-9))
    if state.step > n_total:
        raise ValueError(f"the state is at step {state.step}, after the end step {n_total}")
    frame_every = max(1, round(frame_dt / dt)) if frame_dt > 0 else 0
    ck_every = max(1, round(checkpoint_dt / dt)) if checkpoint_dt > 0 else 0
    tracker = ArmTracker(model.mesh, model.hub_radius)
    for name, value in (arm_memory or {}).items():
        setattr(tracker, name, np.array(value))
    threads = choose_threads(model, threads)
    ws = Workspace(model, ROWS_PER_CHUNK + 1, tracker.probes, threads)
    t_compile = time.perf_counter()
    if not started:
        start(model, control, state, dt)
    _advance(model, control, State(state.pos.copy(), state.vel.copy(), state.hub.copy()),
             ws, dt, 0, rec_every)  # compile / load the loop outside the timed part
    compile_s = time.perf_counter() - t_compile
    chunks = {name: [] for name in kernels.REC_COLUMNS}
    chunks.update(arm_length=[], arm_angle=[], tip_omega=[])
    audit = _EnergyAudit(energy_limit, energy_ref)
    frames, loop_s, status = 0, 0.0, "completed"
    step0 = state.step
    budget = FIRST_CHUNK_STEPS

    def collect(code, nrec, nsteps, elapsed):
        rows = {name: ws.rec[:nrec, j].copy() for j, name in enumerate(kernels.REC_COLUMNS)}
        L, phi, wtip = tracker.update(ws.probe_pos[:nrec], ws.probe_vel[:nrec], rows["hub_angle"])
        rows.update(arm_length=L, arm_angle=phi, tip_omega=wtip)
        for k, v in rows.items():
            chunks[k].append(v)
        if on_rows and nrec:
            on_rows(rows)
        if progress:
            progress(state.time, nsteps / max(elapsed, 1e-9))
        if code != 0:
            raise RunError("non-finite positions or energies (numerical instability; "
                           "reduce time.cfl or time.dt)", time=state.time)
        if nrec:
            audit.check(rows, state.time)

    while True:
        step = state.step
        reason = stop() if stop else None
        if reason:
            if on_checkpoint and step > step0:
                on_checkpoint(state, audit.ref, arm_memory_of(tracker))
            status = f"interrupted by {reason}"
            break
        due = step == n_total or (ck_every and step % ck_every == 0)
        if on_checkpoint and step > step0 and due:
            on_checkpoint(state, audit.ref, arm_memory_of(tracker))
        if on_frame and frame_every and (step % frame_every == 0 or step == n_total):
            on_frame(step * dt, state.pos.copy(), state.vel.copy(),
                     current_tension(model, state.pos, state.vel))
            frames += 1
        if step == n_total:  # the last row: record at t_end on a copy, the state stays at t_end
            final = State(state.pos.copy(), state.vel.copy(), state.hub.copy())
            t0 = time.perf_counter()
            code, nrec = _advance(model, control, final, ws, dt, 1, rec_every)
            loop_s += time.perf_counter() - t0
            collect(code, nrec, 1, time.perf_counter() - t0)
            break
        # next event: a chunk of rows, a frame, a checkpoint, the end, or the wall-time budget
        target = min(n_total, step + ROWS_PER_CHUNK * rec_every, step + budget)
        if frame_every:
            target = min(target, (step // frame_every + 1) * frame_every)
        if ck_every:
            target = min(target, (step // ck_every + 1) * ck_every)
        t0 = time.perf_counter()
        code, nrec = _advance(model, control, state, ws, dt, target - step, rec_every)
        elapsed = time.perf_counter() - t0
        loop_s += elapsed
        # steps that take about WALL_CHUNK_S, growing at most 8-fold per chunk
        budget = max(1, min(8 * budget, int(WALL_CHUNK_S * (target - step) / max(elapsed, 1e-9))))
        collect(code, nrec, target - step, elapsed)
    history = {k: np.concatenate(v) if v else np.zeros(0) for k, v in chunks.items()}
    return RunResult(history, dt, state.step, loop_s, compile_s, state, status, frames,
                     extra={"energy_ref": audit.ref, "stop_reason": reason, "threads": threads})


class Progress:
    """Simulated time, steps/s and ETA on stderr; silent when not a terminal or under CI."""

    def __init__(self, t_end, enabled=True):
        self.t_end = t_end
        self.enabled = enabled and sys.stderr.isatty() and not os.environ.get("CI")
        self.t0 = time.perf_counter()
        self.last = 0.0

    def __call__(self, t, steps_per_s):
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self.last < 0.2 and t < self.t_end:
            return
        self.last = now
        frac = min(t / self.t_end, 1.0)
        el = now - self.t0
        eta = el * (1 - frac) / frac if frac > 0 else float("nan")
        bar = "#" * int(30 * frac)
        sys.stderr.write(f"\r[{bar:<30}] t = {t:8.4f} / {self.t_end:g} s  "
                         f"{steps_per_s:9.3g} steps/s  ETA {eta:6.1f} s ")
        sys.stderr.flush()

    def close(self):
        if self.enabled:
            sys.stderr.write("\n")


def prepare(case):
    """Mesh, model, control, initial state and dt of a case (no output)."""
    from meshgen.build import build_mesh

    mesh = build_mesh(case)
    model = model_from_case(case, mesh)
    control = make_control(case.control, case.source)
    omega0 = case.initial.omega
    if control.law.prescribes_rate:
        _, w_law = control.torque_or_rate(0.0, omega0)
        if abs(w_law - omega0) > 1e-12 * max(1.0, abs(omega0)):
            raise InputError(case.source, "initial.omega",
                             f"must equal the prescribed hub rate at t = 0 ({w_law:g} rad/s) "
                             f"for control.law = '{control.law.name}'")
    _check_model(case, model)
    state = initial_state(model, omega0, case.initial.spin)
    dt = choose_dt(model, case.time.cfl, case.time.dt, case.output.history_dt)
    n_steps = case.time.end / dt
    if not n_steps <= MAX_STEPS:
        raise InputError(case.source, "time.end", f"needs {n_steps:.3g} steps of {dt:.3g} s, "
                         f"more than the limit {MAX_STEPS:.0e} (check time.dt and the cable)")
    return mesh, model, control, state, dt


def _check_model(case, model):
    """Derived values that valid-looking extremes (1e-300, 1e300) can break: InputError."""
    src = case.source
    if not (np.all(np.isfinite(model.node_mass)) and np.all(model.node_mass[model.elem_nodes] > 0)):
        raise InputError(src, "cable.density", "gives node masses that are zero or not finite "
                         "(check cable.density and cable.area)")
    if not np.all(np.isfinite(model.elem_ea)) or not np.all(np.isfinite(model.elem_cdamp)):
        raise InputError(src, "cable.youngs_modulus", "E * A (or the damper) is not finite")
    if not 0 < model.dt_critical < math.inf:
        raise InputError(src, "cable", f"the critical time step is {model.dt_critical:g} s "
                         "(check cable.youngs_modulus and cable.density)")
    if not 0 < model.j_eff < math.inf:
        raise InputError(src, "hub.inertia",
                         f"the hub's effective inertia is {model.j_eff:g} kg m^2")


class RunInterrupted(RunError):
    """A run stopped cleanly by a signal at an event boundary (CLI exit code 1).

    Parameters
    ----------
    signame : str
        'SIGINT' or 'SIGTERM'.
    time : float [s]
        Simulated time of the stop.
    """

    def __init__(self, signame, time):
        super().__init__(f"interrupted by {signame}", time=time)
        self.signame = signame

    def __str__(self):
        return f"interrupted by {self.signame} at t = {self.time:.6g} s"


class StopSignals:
    """Context manager: SIGINT and SIGTERM set a flag instead of stopping the process.

    Calling the object returns the name of the first signal received (or None); the
    solver checks it between two numba chunks. A second SIGINT (Ctrl-C twice, e.g. during
    a long first compilation) raises KeyboardInterrupt at once. The previous handlers are
    restored on exit. Outside the main thread (where Python cannot install handlers) it
    does nothing.
    """

    SIGNALS = ("SIGINT", "SIGTERM")

    def __init__(self):
        self.signame = None
        self._previous = {}

    def _handler(self, signum, frame):
        if self.signame is None:
            self.signame = signal.Signals(signum).name
        elif signum == signal.SIGINT:
            raise KeyboardInterrupt

    def __call__(self):
        return self.signame

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            for name in self.SIGNALS:
                sig = getattr(signal, name)
                self._previous[sig] = signal.getsignal(sig)
                signal.signal(sig, self._handler)
        return self

    def __exit__(self, *exc):
        for sig, handler in self._previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        self._previous = {}
        return False


def thread_counts() -> tuple:
    """Representative thread counts of the step loop on this machine: 1, 2 and the size of
    numba's thread pool, as far as the pool allows (the determinism tests run each)."""
    import numba

    pool = numba.config.NUMBA_NUM_THREADS
    return tuple(sorted({1, min(2, pool), pool}))


def run_case(case, out_dir, progress=True, checkpoint_dt=0.0, resume=None,
             threads=None) -> RunResult:
    """Run a validated case and write results.h5 and the ParaView collection into out_dir.

    Parameters
    ----------
    case : spinweb_fe.case.Case
    out_dir : str or Path
    progress : bool
        Progress bar on a terminal.
    checkpoint_dt : float [s]
        Write ``out_dir/checkpoint.h5`` every ``checkpoint_dt`` of simulated time, at the end
        and when interrupted (0: never).
    resume : spinweb_fe.checkpoint.Checkpoint or None
        Continue this checkpoint's run (see :func:`spinweb_fe.checkpoint.restart_case`).
    threads : int or None
        Threads of the step loop (None: :func:`choose_threads` decides; a restart uses
        the checkpoint's count, which keeps the continuation bit-identical).

    Raises
    ------
    InputError
        Invalid case or mesh (nothing is written).
    RunError
        Instability or I/O failure; :class:`RunInterrupted` on SIGINT / SIGTERM. The results
        written so far stay readable and the root attribute ``status`` says why.
    """
    from spinweb_fe.checkpoint import CHECKPOINT_NAME, Checkpoint, write_checkpoint
    from spinweb_fe.output import ResultWriter

    out_dir = Path(out_dir)
    step0 = resume.steps if resume is not None else 0
    with StopSignals() as stop:
        mesh, model, control, state, dt = prepare(case)
        if resume is not None:
            state = _resumed_state(case, model, dt, resume)
        if stop():
            raise RunInterrupted(stop(), state.time)  # before anything is written
        log.info("%s: %d nodes, %d elements, dt = %.4g s (critical %.4g s, cfl %.3g), %d steps%s",
                 case.title or case.source, model.n_nodes, model.n_elems, dt, model.dt_critical,
                 dt / model.dt_critical, int(math.ceil(case.time.end / dt - 1e-9)),
                 f", from step {state.step}" if resume is not None else "")
        writer = ResultWriter(out_dir, case, model, dt, write_frames=case.output.frame_dt > 0,
                              resume=resume)
        if threads is None and resume is not None:
            threads = resume.threads
        threads = choose_threads(model, threads)
        writer.set_attrs(threads=threads)

        def on_checkpoint(st, energy_ref, arm_memory):
            if not all(np.all(np.isfinite(getattr(st, f))) for f in ("pos", "vel", "hub")):
                raise RunError("non-finite state at a checkpoint (numerical instability)",
                               time=st.time)
            write_checkpoint(out_dir / CHECKPOINT_NAME, Checkpoint(
                state=st, dt=dt, history_rows=writer.rows, frames=len(writer.pvd_entries),
                pvd_entries=list(writer.pvd_entries), case_toml=case.to_toml(),
                case_source=case.source, checkpoint_dt=checkpoint_dt, energy_ref=energy_ref,
                arm_memory=arm_memory, threads=threads, run_id=writer.run_id))

        bar = Progress(case.time.end, progress)
        status = "failed"
        try:
            res = simulate(model, control, state, dt, case.time.end, case.output.history_dt,
                           case.output.frame_dt, on_rows=writer.append_history,
                           on_frame=writer.write_frame, progress=bar, started=resume is not None,
                           stop=stop, checkpoint_dt=checkpoint_dt,
                           on_checkpoint=on_checkpoint if checkpoint_dt > 0 else None,
                           energy_ref=None if resume is None else resume.energy_ref,
                           arm_memory=None if resume is None else resume.arm_memory,
                           threads=threads)
            status = res.status
            if res.status != "completed":
                status = f"{res.status} at t = {state.time:.6g} s"
        except RunError as exc:
            status = f"failed: {exc}"
            raise
        except KeyboardInterrupt:  # a second SIGINT: stopped at once, not at an event
            status = f"interrupted by SIGINT (twice) at t = {state.time:.6g} s"
            raise
        except BaseException as exc:
            status = f"failed: {type(exc).__name__}: {exc}"
            raise
        finally:
            bar.close()
            _finish(writer, steps=state.step, status=status)
    if res.status != "completed":
        raise RunInterrupted(res.extra["stop_reason"], state.time)
    log.info("done: %d steps in %.2f s loop + %.2f s compile (%.3g element-updates/s)",
             res.steps, res.loop_s, res.compile_s,
             model.n_elems * (res.steps - step0) / max(res.loop_s, 1e-9))
    return res


def _finish(writer, **attrs):
    """Final attributes and close; an I/O error here must not hide the run's own error."""
    try:
        writer.set_attrs(**attrs)
    except Exception as exc:  # noqa: BLE001 - reported, the file keeps its last flush
        log.error("could not write the final attributes of results.h5: %s", exc)
    finally:
        writer.close()


def _resumed_state(case, model, dt, ck):
    """The checkpoint's state after checking that it belongs to this case's model."""
    src = str(Path(case.source))
    if dt != ck.dt:
        raise InputError(src, "time", f"the time step {dt!r} s differs from the checkpoint's "
                         f"{ck.dt!r} s: the case changed")
    st = ck.state
    if st.pos.shape != (model.n_nodes, 3) or st.vel.shape != st.pos.shape:
        raise InputError(src, "", f"the checkpoint holds {st.pos.shape[0]} nodes, the case's "
                         f"mesh {model.n_nodes}: the case changed")
    n_total = int(math.ceil(case.time.end / dt - 1e-9))
    if st.step >= n_total:
        raise InputError("--set", "time.end", f"{case.time.end:g} s is not after the checkpoint "
                         f"at t = {st.time:.6g} s (continue with --set time.end=...)")
    return st
