"""Run orchestration: the numba loop between events, recorders at event boundaries.

Python only acts at events (history flush, frames, progress, energy audit); the step loop
runs inside ``kernels.advance``.
"""

from __future__ import annotations

import logging
import math
import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from spinweb_fe import kernels
from spinweb_fe.arms import ArmTracker
from spinweb_fe.control import Control, make_control
from spinweb_fe.errors import InputError, RunError
from spinweb_fe.model import Model, State, choose_dt, initial_state, model_from_case

log = logging.getLogger("spinweb")
ENERGY_LIMIT = 0.5  # stop when the energy balance error exceeds this fraction of the energy scale
ROWS_PER_CHUNK = 256  # history rows between two returns to Python (flush, progress, audit)


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


class _Shifted:
    """View of a Workspace whose record arrays start at row k."""

    def __init__(self, ws, k):
        self.force, self.tension = ws.force, ws.tension
        self.rec, self.probe_pos, self.probe_vel = ws.rec[k:], ws.probe_pos[k:], ws.probe_vel[k:]
        self.probes = ws.probes


def _shift(ws, k):
    return _Shifted(ws, k)


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


def simulate(model: Model, control: Control, state: State, dt: float, t_end: float,
             history_dt: float, frame_dt: float = 0.0, on_rows=None, on_frame=None,
             progress=None, energy_limit=ENERGY_LIMIT, threads=None) -> RunResult:
    """Integrate from ``state`` (initial velocities v_0) to ``t_end``.

    Parameters
    ----------
    threads : int or None
        Threads of the step loop (None: ``choose_threads``).
    on_rows : callable(dict) or None
        Called with each chunk of history rows (name -> array).
    on_frame : callable(t, pos, vel, tension) or None
        Called every ``frame_dt`` (and at the start and the end).
    progress : callable(t, steps_per_s) or None
    """
    rec_every = max(1, round(history_dt / dt))
    n_total = int(math.ceil(t_end / dt - 1e-9))
    frame_every = max(1, round(frame_dt / dt)) if frame_dt > 0 else 0
    tracker = ArmTracker(model.mesh, model.hub_radius)
    threads = choose_threads(model, threads)
    ws = Workspace(model, ROWS_PER_CHUNK + 1, tracker.probes, threads)
    t_compile = time.perf_counter()
    start(model, control, state, dt)
    _advance(model, control, State(state.pos.copy(), state.vel.copy(), state.hub.copy()),
             ws, dt, 0, rec_every)  # compile / load the loop outside the timed part
    compile_s = time.perf_counter() - t_compile
    chunks = {name: [] for name in kernels.REC_COLUMNS}
    chunks.update(arm_length=[], arm_angle=[], tip_omega=[])
    e_ref = None
    frames = 0
    loop_s = 0.0
    status = "completed"
    while True:
        step = state.step
        if on_frame and frame_every and (step % frame_every == 0 or step == n_total):
            on_frame(step * dt, state.pos.copy(), state.vel.copy(),
                     current_tension(model, state.pos, state.vel))
            frames += 1
        target = min(n_total + 1, step + ROWS_PER_CHUNK * rec_every)
        if frame_every and step < n_total:  # stop at the next frame (or the last state)
            target = min(target, (step // frame_every + 1) * frame_every, n_total)
        t0 = time.perf_counter()
        if target > n_total:  # the last row: record at t_end on a copy, the state stays at t_end
            code, nrec = _advance(model, control, state, ws, dt, n_total - step, rec_every)
            if code == 0 and state.step == n_total:
                final = State(state.pos.copy(), state.vel.copy(), state.hub.copy())
                code, extra = _advance(model, control, final, _shift(ws, nrec), dt, 1, rec_every)
                nrec += extra
        else:
            code, nrec = _advance(model, control, state, ws, dt, target - step, rec_every)
        loop_s += time.perf_counter() - t0
        rows = {name: ws.rec[:nrec, j].copy() for j, name in enumerate(kernels.REC_COLUMNS)}
        L, phi, wtip = tracker.update(ws.probe_pos[:nrec], ws.probe_vel[:nrec], rows["hub_angle"])
        rows.update(arm_length=L, arm_angle=phi, tip_omega=wtip)
        for k, v in rows.items():
            chunks[k].append(v)
        if on_rows and nrec:
            on_rows(rows)
        if progress:
            progress(state.time, (target - step) / max(time.perf_counter() - t0, 1e-9))
        if code != 0:
            raise RunError("non-finite positions or energies (numerical instability; "
                           "reduce time.cfl or time.dt)", time=state.time)
        if nrec:
            bal = energy_balance(rows)
            if e_ref is None:
                e_ref = (bal[0], max(abs(rows["kinetic_energy"][0]) + abs(rows["strain_energy"][0]),
                                     1e-30))
            scale = max(e_ref[1], float(np.max(np.abs(rows["torque_work"]))))
            err = float(np.max(np.abs(bal - e_ref[0]))) / scale
            if err > energy_limit:
                raise RunError(f"energy balance off by {100 * err:.0f} % of the energy scale "
                               "(numerical instability; reduce time.cfl)", time=state.time)
        if target > n_total:
            break
    history = {k: np.concatenate(v) if v else np.zeros(0) for k, v in chunks.items()}
    return RunResult(history, dt, state.step, loop_s, compile_s, state, status, frames)


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
    state = initial_state(model, omega0, case.initial.spin)
    dt = choose_dt(model, case.time.cfl, case.time.dt, case.output.history_dt)
    return mesh, model, control, state, dt


def run_case(case, out_dir, progress=True) -> RunResult:
    """Run a validated case and write results.h5 and the ParaView collection into out_dir."""
    from spinweb_fe.output import ResultWriter

    mesh, model, control, state, dt = prepare(case)
    log.info("%s: %d nodes, %d elements, dt = %.4g s (critical %.4g s, cfl %.3g), %d steps",
             case.title or case.source, model.n_nodes, model.n_elems, dt, model.dt_critical,
             dt / model.dt_critical, int(math.ceil(case.time.end / dt - 1e-9)))
    writer = ResultWriter(out_dir, case, model, dt, write_frames=case.output.frame_dt > 0)
    bar = Progress(case.time.end, progress)
    status = "failed"
    try:
        res = simulate(model, control, state, dt, case.time.end, case.output.history_dt,
                       case.output.frame_dt, on_rows=writer.append_history,
                       on_frame=writer.write_frame, progress=bar)
        status = "completed"
    except RunError as exc:
        status = f"failed: {exc}"
        raise
    except KeyboardInterrupt:
        status = "interrupted"
        raise
    finally:
        bar.close()
        writer.set_attrs(steps=state.step, status=status)
        writer.close()
    log.info("done: %d steps in %.2f s loop + %.2f s compile (%.3g element-updates/s)",
             res.steps, res.loop_s, res.compile_s,
             model.n_elems * res.steps / max(res.loop_s, 1e-9))
    return res
