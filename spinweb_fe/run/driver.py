"""A case to a result folder: checks, scene, estimate, the folder's lock, writers, the event
loop, and the run's final status (docs/robustness.md).

The arguments, $SPINWEB_THREADS, the folder's permissions and a live run in the folder are
checked first; then the run claims the folder (its lock, ``run.lock``: a second run into it
is refused at once, while this one compiles too), and the set-up (the mesh, the compile,
the estimate against the budget) runs; a set-up that refuses the run, or a SIGINT /
SIGTERM during it, releases the claim and changes nothing else. Then an earlier result is
moved aside until this run's first rows are on disk.
"""

from __future__ import annotations

import logging
import math
import sys
from pathlib import Path

import numpy as np

from spinweb_fe.case.scene import prepare
from spinweb_fe.errors import InputError, RunError, RunInterrupted
from spinweb_fe.io.checkpoint import (CHECKPOINT_NAME, Checkpoint, checkpoint_bytes,
                                      write_checkpoint)
from spinweb_fe.io.folder import Aside, FolderLock, busy, check_writable, holder
from spinweb_fe.io.results import ResultWriter, write_failure
from spinweb_fe.io.space import DiskGuard
from spinweb_fe.record import verdict
from spinweb_fe.record.recorders import Recorder
from spinweb_fe.run.estimate import (check_budget, check_memory, estimate, measure_rate)
from spinweb_fe.run.features import check_features, features_of
from spinweb_fe.run.loop import Schedule, choose_threads, requested_threads, simulate
from spinweb_fe.run.terminal import Progress, StopSignals

log = logging.getLogger(__name__)


class Checkpointer(Recorder):
    """Writes ``DIR/checkpoint.h5`` at the loop's checkpoint events (a recorder)."""

    def __init__(self, path, case, writer, dt, checkpoint_dt, threads, guard=None):
        self.path, self.case, self.writer = Path(path), case, writer
        self.dt, self.checkpoint_dt, self.threads = dt, checkpoint_dt, threads
        self.guard = guard

    def checkpoint(self, state, memory):
        t = float(state.time[0])
        arrays = (state.node_pos, state.node_vel, *state.hub, state.totals,
                  *(state.rigid or ()))
        if not all(np.all(np.isfinite(a)) for a in arrays):
            raise RunError("non-finite state at a checkpoint (numerical instability)", time=t)
        rows, entries, run_id = self.writer.written()
        ck = Checkpoint(
            state=state, dt=self.dt, history_rows=rows, frames=len(entries),
            pvd_entries=entries, case_toml=self.case.to_toml(), case_source=self.case.source,
            checkpoint_dt=self.checkpoint_dt, memory=memory, threads=self.threads,
            run_id=run_id)
        if self.guard is not None:
            self.guard.need(checkpoint_bytes(ck), "a checkpoint", t)
        try:
            write_checkpoint(self.path, ck, on_error=self.guard and self.guard.release)
        except (OSError, RuntimeError) as exc:
            raise RunError(f"cannot write {self.path}: {write_failure(exc)}", time=t) from None


class _FirstFlush(Recorder):
    """Drops the folder's earlier result once this run's first rows are on disk."""

    def __init__(self, aside):
        self.aside = aside

    def rows(self, rows):
        self.aside.drop()


def run_case(case, out_dir, progress=True, checkpoint_dt=0.0, resume=None, threads=None,
             force=False):
    """Run a validated case and write results.h5 and the ParaView collection into out_dir.

    Parameters
    ----------
    case : spinweb_fe.case.Case
    out_dir : str or Path
    progress : bool
        Progress bar on a terminal (a line a minute otherwise).
    checkpoint_dt : float [s]
        Write ``out_dir/checkpoint.h5`` every ``checkpoint_dt`` of simulated time, at the end
        and when interrupted (0: never).
    resume : spinweb_fe.io.checkpoint.Checkpoint or None
        Continue this checkpoint's run (see :func:`spinweb_fe.run.restart.restart_case`).
    threads : int or None
        Threads of the step loop (None: :func:`choose_threads` decides; a restart uses
        the checkpoint's count, which keeps the continuation bit-identical).
    force : bool
        Run even if the estimate exceeds the budget (:mod:`spinweb_fe.run.estimate`).

    Returns
    -------
    spinweb_fe.run.loop.RunResult

    Raises
    ------
    InputError
        Invalid case, mesh, environment or folder, or a run beyond the budget (nothing is
        written).
    RunError
        Another run holds the folder (nothing is changed); instability or I/O failure;
        :class:`RunInterrupted` on SIGINT / SIGTERM. The results written so far stay
        readable and the root attribute ``status`` says why.
    """
    out_dir = Path(out_dir)
    step0 = resume.steps if resume is not None else 0
    if threads is None and resume is not None:
        threads = resume.threads
    threads = requested_threads(threads)
    check_writable(out_dir)
    if (info := holder(out_dir)) is not None:
        raise busy(out_dir, info)
    check_memory(case, force)
    with StopSignals() as stop:
        # the folder is claimed before the set-up (a second run into it is refused at once,
        # even while this one compiles); a refused set-up releases the claim and leaves no
        # folder it created
        with FolderLock(out_dir):
            with stop.immediate():  # set-up writes nothing: a signal stops it at once
                mesh, model, control, state, dt = prepare(case)
                check_features(case, model, state)
                features = features_of(model, state, case)
                if checkpoint_dt > 0:
                    _check_checkpointable(case, features)
                if resume is not None:
                    state = _resumed_state(case, model, dt, resume)
                threads = choose_threads(model, threads)
                rec_every = max(1, round(case.output.history_dt / dt))
                notice = progress and sys.stderr.isatty()  # at a terminal: what the wait is
                if notice:
                    sys.stderr.write("step loop: loading it from numba's cache, or compiling "
                                     "it (the first run of a kind of scene: 10-20 s) ...\r")
                    sys.stderr.flush()
                rate, compile_s = measure_rate(model, control, state, dt, threads, rec_every,
                                               features)
                if notice:
                    sys.stderr.write("\x1b[2K")  # clear that line
                est = estimate(case, model, dt, step0, rate, checkpoint_dt > 0)
                check_budget(case, est, out_dir, force)
                log.info("%s: %d nodes, %d elements, dt = %.4g s (critical %.4g s, cfl %.3g), "
                         "%d steps%s", case.title or case.source, model.n_nodes, model.n_elems,
                         dt, model.dt_critical, dt / model.dt_critical, step0 + est.steps,
                         f", from step {step0}" if resume is not None else "")
                for line in est.lines(threads):
                    log.info("%s", line)
                if compile_s > 2.0:
                    log.info("step loop: compiled in %.1f s (numba; later runs of such a scene "
                             "load it from the cache)", compile_s)
            aside = Aside(out_dir)
            if resume is None:
                Aside.recover(out_dir)
                aside.move()
            else:  # a restart continues the folder's own result: nothing is kept aside
                aside.done = True
            try:
                res = _run(case, out_dir, model, control, state, dt, stop, resume, threads,
                           progress, checkpoint_dt, aside, features)
            finally:
                if not aside.done:  # stopped before its first rows: the earlier result back
                    aside.restore()
                    log.info("%s: the earlier result is kept (this run stopped before its "
                             "first rows were written)", out_dir)
    if res.status != "completed":
        raise RunInterrupted(res.stop_reason, float(state.time[0]))
    log.info("done: %d steps in %.2f s loop + %.2f s compile (%.3g element-updates/s)",
             res.steps, res.loop_s, compile_s + res.compile_s,
             model.n_elems * (res.steps - step0) / max(res.loop_s, 1e-9))
    return res


def _run(case, out_dir, model, control, state, dt, stop, resume, threads, progress,
         checkpoint_dt, aside, features):
    """The writers and the event loop, in a folder this run holds."""
    guard = DiskGuard(out_dir)
    try:
        writer = ResultWriter(out_dir, case, model, dt, write_frames=case.output.frame_dt > 0,
                              resume=resume, guard=guard)
    except BaseException:
        guard.release()
        raise
    bar = Progress(case.time.end, progress)
    recorders = [writer, _FirstFlush(aside), bar]
    if checkpoint_dt > 0:
        recorders.append(Checkpointer(out_dir / CHECKPOINT_NAME, case, writer, dt,
                                      checkpoint_dt, threads, guard))
    schedule = Schedule(case.time.end, case.output.history_dt, case.output.frame_dt,
                        checkpoint_dt)
    status = "failed"
    try:
        writer.set_attrs(threads=threads, features=" ".join(f.name for f in features))
        res = simulate(model, control, state, dt, schedule, recorders, features=features,
                       stop=stop, resume=None if resume is None else resume.memory,
                       threads=threads)
        status = res.status
        if res.status != "completed":
            status = f"{res.status} at t = {float(state.time[0]):.6g} s"
        else:
            aside.drop()
    except RunError as exc:
        status = f"failed: {exc}"
        raise
    except KeyboardInterrupt:  # a second SIGINT: stopped at once, not at an event
        status = f"interrupted by SIGINT (twice) at t = {float(state.time[0]):.6g} s"
        raise
    except BaseException as exc:
        status = f"failed: {type(exc).__name__}: {exc}"
        raise
    finally:
        bar.end(status)  # the progress line ends even when the loop raised
        guard.release()  # room for the last attributes and the close
        _write_features(writer, features)
        _judge(writer, case, model, state, status)
        _finish(writer, steps=int(state.step[0]), status=status)
    return res


def _write_features(writer, features):
    """Each feature's part of results.h5 (record.feature: a group, attributes); a failure is
    reported and leaves the rest of the file as it is."""
    for f in features:
        try:
            writer.drain()
            f.write(writer.h5)
            writer.h5.flush()
        except Exception as exc:  # noqa: BLE001 - the result stays; the part is missing
            log.error("could not write the %s: %s", f.name, exc)


def _judge(writer, case, model, state, status):
    """The run's verdict (record.verdict) into results.h5 and the log; a failure here is
    reported and leaves the file as it is (the run's own error, if any, goes on)."""
    from spinweb_fe.io.h5 import history_of

    try:
        writer.drain()
        h = history_of(writer.h5)
        if not h:
            return
        broken = state.strength.broken if model.strength.rupture else None
        crits = verdict.judge(
            h, verdict.reach_of(model.mesh), model.mesh.hub_radius, status=status,
            slack_share=verdict.slack_share(state.node_pos, model.elements.nodes,
                                            model.elements.rest_len, broken),
            out_of_plane="out_of_plane_max" in h, **verdict.case_terms(case.to_dict()),
            **verdict.floors_of(writer.h5.attrs))
        verdict.write_group(writer.h5, crits)
        writer.h5.flush()
        lines = verdict.report(crits)
        log.info("%s", lines[0])
        for line in lines[1:]:
            log.debug("%s", line)
    except Exception as exc:  # noqa: BLE001 - the result stays; the verdict is missing
        log.error("could not judge the run: %s", str(exc).splitlines()[0] if str(exc)
                  else type(exc).__name__)


def _finish(writer, **attrs):
    """Final attributes and close; an I/O error here must not hide the run's own error."""
    try:
        writer.drain()  # the frame in flight when the loop stopped on an error
    except Exception as exc:  # noqa: BLE001 - reported, the file keeps its last flush
        log.error("%s", exc)
    try:
        writer.set_attrs(**attrs)
    except Exception as exc:  # noqa: BLE001 - reported, the file keeps its last flush
        log.error("could not write the final attributes of results.h5: %s", exc)
    finally:
        writer.close()


def _check_checkpointable(case, features):
    """Refuse checkpoints of a run with a feature that cannot be continued from one."""
    for f in features:
        if not f.checkpointable:
            raise InputError("--checkpoint-dt", "", f"the run's {f.name} cannot be continued "
                             f"from a checkpoint ({case.source}): run it without one")


def _resumed_state(case, model, dt, ck):
    """The checkpoint's state after checking that it belongs to this case's model."""
    src = str(Path(case.source))
    if dt != ck.dt:
        raise InputError(src, "time", f"the time step {dt!r} s differs from the checkpoint's "
                         f"{ck.dt!r} s: the case changed")
    st = ck.state
    if st.node_pos.shape != (model.n_nodes, 3) or st.node_vel.shape != st.node_pos.shape:
        raise InputError(src, "", f"the checkpoint holds {st.node_pos.shape[0]} nodes, the "
                         f"case's mesh {model.n_nodes}: the case changed")
    n_total = int(math.ceil(case.time.end / dt - 1e-9))
    if ck.steps >= n_total:
        raise InputError("--set", "time.end", f"{case.time.end:g} s is not after the checkpoint "
                         f"at t = {ck.time:.6g} s (continue with --set time.end=...)")
    return st
