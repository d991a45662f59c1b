"""Guards of a run's start (issue #47): the steady start at the scheme's own discrete rate,
the fixed axis's first half step, and the compile helper (it compiles, and it is stopped).
Tiny scenes, a few hundred steps; a numba function of one line for the helper."""

import math
import os
import time

import numpy as np
import pytest
from numba import njit

from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.run import warmup
from spinweb_fe.run.loop import Schedule, current_tension, simulate

TETHERS = ("[tethers]\nelements = 8\n[fold]\npattern = 'straight'\n[initial]\n"
           "state = 'steady'\n[time]\nend = 0.1\ncfl = 0.9\n[output]\nframe_dt = 0\n")


def test_a_steady_start_turns_rigidly_at_the_schemes_own_rate():
    """Four straight tethers of 8 elements at 8 pi rad/s, dt = 5e-4 s (omega dt = 0.0126):
    started at the equilibrium solved at 2 sin(omega dt / 2) / dt with velocities
    sin(omega dt) / dt about the axis, the central differences turn the web rigidly, x_n =
    R(n omega dt) x_0, to round-off: after 200 steps within 1.8e-13 m of 68 m (measured
    1.24e-13) and every tension within 8e-14 of the largest (measured 5.5e-14), both 1.45x.
    Solved at omega itself the web rings at (omega dt)^2 / 12 (4e-4 m, 5e-6 of the
    tension); started at omega's velocities, 2e-3 m and 2e-5."""
    sc = prepare(case_mod.loads(TETHERS))
    m, st, dt = sc.model, sc.state, sc.dt
    assert dt == 5e-4 and st.hub.rate[0] == pytest.approx(8 * math.pi)
    x0 = st.node_pos.copy()
    before = current_tension(m, st.node_pos, st.node_vel)
    assert before.min() > 0
    n = 200
    simulate(m, sc.control, st, dt, Schedule(n * dt, n * dt / 4))
    c, s = math.cos(8 * math.pi * n * dt), math.sin(8 * math.pi * n * dt)
    turned = np.column_stack([c * x0[:, 0] - s * x0[:, 1], s * x0[:, 0] + c * x0[:, 1],
                              x0[:, 2]])
    assert np.abs(st.node_pos - turned).max() < 1.8e-13
    after = current_tension(m, st.node_pos, st.node_vel)
    assert np.abs(after - before).max() < 8e-14 * before.max()


@pytest.mark.parametrize("law, sets", [
    ("constant_torque", ["control.law='constant_torque'", "control.torque=3000.0"]),
    ("free", ["control.law='free'"])])
def test_the_fixed_axis_starts_half_a_step_back(law, sets):
    """The first half step of a fixed axis: omega_{-1/2} = omega_0 - dt/2 (M + tau) / J
    with tau the z-moment of the tied nodes' forces at x_0 (numpy's cross product here;
    the steady tethers' free nodes turned 0.05 rad ahead, so that the lines lean),
    and v_{-1/2} = v_0 - dt/2 f / m of the free nodes, both to round-off (1e-15 relative:
    the same sums in another order). Steady tethers under a torque of 3 kN m, and free."""
    from support import eval_elements

    from spinweb_fe.fe.step import start_half_step

    case = case_mod.loads(TETHERS.replace("state = 'steady'", "state = 'steady'\nomega = 5.0"),
                          sets)
    sc = prepare(case)
    m, st, dt = sc.model, sc.state, sc.dt
    tied = np.asarray(m.hub.tied_idx)
    free = np.ones(m.n_nodes, bool)
    free[tied] = False
    c, s = math.cos(0.05), math.sin(0.05)  # the free nodes turned ahead: the lines lean
    p = st.node_pos[free].copy()
    st.node_pos[free, 0], st.node_pos[free, 1] = c * p[:, 0] - s * p[:, 1], \
        s * p[:, 0] + c * p[:, 1]
    w0, v0 = float(st.hub.rate[0]), st.node_vel.copy()
    force = np.zeros_like(st.node_pos)
    eval_elements(m.elements, st.node_pos, st.node_vel, force, np.zeros(0), False)
    tau = float(np.cross(st.node_pos[tied], force[tied])[:, 2].sum())
    assert abs(tau) > 1.0  # the tethers pull on the hub
    J = float(st.hub.inertia[0])
    M = 3000.0 if law == "constant_torque" else 0.0
    start_half_step(m.kernel, None, sc.control.kernel, st, force.copy(), dt)
    want = w0 - 0.5 * dt * (M + tau) / J
    assert st.hub.rate[0] == pytest.approx(want, rel=1e-15, abs=1e-15 * abs(w0))
    assert abs(st.hub.rate[0] - w0) > 1e-6 * abs(w0)
    a = force[free] / m.nodes.mass[free, None]
    assert np.allclose(st.node_vel[free], v0[free] - 0.5 * dt * a, rtol=0,
                       atol=1e-15 * np.abs(v0).max())


def _double(x):
    return 2.0 * x


class _Chunks:
    """The step loop's stand-in: compile_helper asks it for the loop's arguments and
    hands its workspaces to phase_jobs (replaced here)."""

    work = rec = threads = None

    def loop_args(self, state, dt, start, hooks):
        return (None, None, None)


class _Slow:
    """A job that takes 60 s to 'compile': the helper must be stopped long before."""

    def compile(self, sig):
        time.sleep(60.0)


def _gone(pid, wait=5.0):
    """True once process ``pid`` is no more (reaped by compile_helper's thread)."""
    end = time.time() + wait
    while time.time() < end:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.02)
    return False


def test_the_compile_helper_compiles_its_jobs_into_the_cache(tmp_path, monkeypatch):
    """The forked helper compiles a job into numba's cache (an index and a compiled file
    appear, and a fresh dispatcher of the function finds the compile there: cached), then
    exits by itself."""
    import numba

    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    fn = njit(cache=True)(_double)
    sig = (numba.float64,)
    assert not warmup.cached(fn, (1.0,))
    monkeypatch.setattr(warmup, "wanted", lambda: True)
    monkeypatch.setattr(warmup, "cached", lambda d, a: False)
    monkeypatch.setattr(warmup, "phase_jobs", lambda *a: [(fn, sig)])
    with warmup.compile_helper(_Chunks(), None, 1e-3) as pid:
        assert pid
        _, status = os.waitpid(pid, 0)  # the helper ends when its jobs are compiled
    assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0
    files = {p.suffix for p in tmp_path.rglob("*")}
    assert {".nbi", ".nbc"} <= files
    monkeypatch.undo()
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    assert warmup.cached(njit(cache=True)(_double), (1.0,))


def test_the_compile_helper_is_stopped_when_the_loop_is_compiled(monkeypatch):
    """A helper still compiling when the block ends (a job of 60 s) is stopped at once:
    gone within 5 s of the block's end, and not before it."""
    monkeypatch.setattr(warmup, "wanted", lambda: True)
    monkeypatch.setattr(warmup, "cached", lambda d, a: False)
    monkeypatch.setattr(warmup, "phase_jobs", lambda *a: [(_Slow(), ())])
    t0 = time.time()
    with warmup.compile_helper(_Chunks(), None, 1e-3) as pid:
        assert pid
        time.sleep(0.2)
        os.kill(pid, 0)  # still running (raises if not)
    assert _gone(pid), "the helper outlived the block"
    assert time.time() - t0 < 10.0
