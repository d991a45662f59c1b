"""Central-difference solver against closed forms: oscillator period, second-order
convergence in dt, conservation of angular momentum and energy."""

import math

import numpy as np
import pytest

from meshgen.mesh import Mesh
from spinweb_fe.fe.control import free
from spinweb_fe.fe.model import build_model
from spinweb_fe.fe.state import initial_state
from spinweb_fe.record.energy import energy_balance
from spinweb_fe.run.loop import Schedule, simulate

E, RHO, A = 180e9, 1540.0, 1.025e-5
FREE = free()


def oscillator(delta, prestrain=0.1, point_mass=5.0):
    """Mass between two tied anchors on two prestretched cables (both stay taut)."""
    x0 = 1.0 + prestrain
    pos = np.array([[-x0, 0, 0], [delta, 0, 0], [x0, 0, 0]], float)
    ref = pos.copy()
    ref[1, 0] = 0.0
    mesh = Mesh(node_pos=pos, node_ref=ref, elem_nodes=[[0, 1], [1, 2]], elem_rest_len=[1.0, 1.0],
                node_point_mass=[0, point_mass, 0], node_sets={"hub_tied": [0, 2], "tips": [1]},
                arm_root_angle=[0.0])
    return build_model(mesh, E, RHO, A, hub_radius=0.0, hub_inertia=1e30)


def run_oscillator(dt, t_end, delta=1e-3):
    model = oscillator(delta)
    state = initial_state(model, 0.0, "hub")
    res = simulate(model, FREE, state, dt, Schedule(t_end, dt))
    return model, res


def test_oscillator_half_period_and_energy():
    """Released from +delta, the mass is at -delta after half a period (closed form
    T = 2 pi sqrt(m / 2k)) up to the scheme's phase error. Central differences with the
    second-order start solve the linear oscillator exactly at the frequency
    w_h = (2/dt) asin(w dt/2): x_n = delta cos(w_h n dt) to round-off (dt = T/200: 8e-9 off
    -delta at T/2). The energy balance (prestrain included) is conserved to O(dt^2): measured
    4.9e-8, bound 1e-7."""
    delta = 1e-3
    model = oscillator(delta)
    w = math.sqrt(2 * E * A / model.nodes.mass[1])
    period = 2 * math.pi / w
    dt = period / 200
    state = initial_state(model, 0.0, "hub")
    res = simulate(model, FREE, state, dt, Schedule(period / 2, dt))
    assert state.node_pos[1, 0] == pytest.approx(-delta, rel=2e-8)
    w_h = 2 / dt * math.asin(w * dt / 2)
    t = res.history["time"]
    np.testing.assert_allclose(res.history["tip_position"][:, 0, 0], delta * np.cos(w_h * t),
                               rtol=0, atol=1e-9 * delta)
    e = energy_balance(res.history)
    assert np.max(np.abs(e - e[0])) / e[0] < 1e-7
    assert np.allclose(res.history["angular_momentum"], 0.0, atol=1e-12)


def test_second_order_convergence_in_dt():
    """Error at t = 2.25 periods (where the phase error shows fully) against delta cos(w t):
    the fitted log-log slope must be 2 (+-0.1)."""
    delta = 1e-3
    w = math.sqrt(2 * E * A / oscillator(delta).nodes.mass[1])
    t_end = 2.25 * 2 * math.pi / w
    errs, dts = [], []
    for n in (40, 80, 160, 320):
        dt = 2 * math.pi / w / n
        mdl = oscillator(delta)
        state = initial_state(mdl, 0.0, "hub")
        simulate(mdl, FREE, state, dt, Schedule(t_end, dt))
        t = state.step[0] * dt
        errs.append(abs(state.node_pos[1, 0] - delta * math.cos(w * t)))
        dts.append(dt)
    slope = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    assert 1.9 < slope < 2.1, (slope, errs)
