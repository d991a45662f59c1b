"""Guards against plausible bugs (issue #17): each test holds a kernel, a control law or the
analytical model against a value derived independently of the code (a closed form, a
conservation law, or a hand derivation written out here), so that a small change of the
physics fails an assertion rather than only the run's energy audit. ``tests/mutate.py``
applies such changes to a copy of the package and checks that these tests catch them
(docs/testing.md)."""

import dataclasses
import logging
import math
from pathlib import Path

import numpy as np
import pytest

from meshgen.mesh import Mesh
from meshgen.tethers import tethers
from spinweb_fe import case as case_mod
from spinweb_fe.analytic.models import (HALF_PI, ArmParams, accelerations, root_tension)
from spinweb_fe.errors import InputError, RunError
from spinweb_fe.fe.control import free as free_law
from spinweb_fe.fe.control import make_control
from spinweb_fe.fe.hub.axis import place_rigid
from spinweb_fe.fe.hub.contact import contact_node
from spinweb_fe.fe.layout import SLOTS, row_columns
from spinweb_fe.fe.model import Elements, build_model, choose_dt
from spinweb_fe.fe.state import initial_state
from spinweb_fe.record.energy import ENERGY_LIMIT, ENERGY_WARN, EnergyAudit, energy_balance
from spinweb_fe.run.loop import Schedule, simulate, start
from support import eval_elements

E, RHO, A = 180e9, 1540.0, 1.025e-5
EA = E * A


# ---------------------------------------------------------------- element law: the damper

def one_element(stretch, vel_j, cdamp):
    """A single element of rest length 1 m along x, node 1 moving at ``vel_j`` along x."""
    pos = np.array([[0.0, 0, 0], [1.0 + stretch, 0, 0]])
    vel = np.array([[0.0, 0, 0], [vel_j, 0, 0]])
    elems = Elements(np.array([[0, 1]], np.int64), np.ones(1), np.ones(1), np.full(1, EA),
                     np.full(1, cdamp), True)
    f, t = np.zeros((2, 3)), np.zeros(1)
    se, tmax, p = eval_elements(elems, pos, vel, f, t, True)
    return f, t[0], se, tmax, p


def test_taut_damped_element_shortening_fast_carries_exactly_zero_tension():
    """Strain 1e-3 (elastic 1845 N), damper 100 N s/m, shortening at 40 m/s: EA eps + c dL/dt
    = 1845 - 4000 N < 0, and a cable cannot push: tension and forces are exactly 0. The
    damper then absorbs the whole elastic force, so its dissipated power is
    N_el |dL/dt| = 1845 N * 40 m/s; the strain energy is still EA eps^2 L0 / 2."""
    eps, v = 1e-3, -40.0
    f, t, se, tmax, p = one_element(eps, v, 100.0)
    assert t == 0.0 and tmax == 0.0
    assert np.all(f == 0.0)
    assert p == pytest.approx(EA * eps * abs(v), rel=1e-12)
    assert se == pytest.approx(0.5 * EA * eps ** 2, rel=1e-12)
    # shortening slowly the total stays positive: N = EA eps + c dL/dt
    f, t, *_ = one_element(eps, -2.0, 100.0)
    assert t == pytest.approx(EA * eps - 200.0, rel=1e-12)


# ---------------------------------------------------------------- cable-hub contact

def contact(pos, vel, force=(0.0, 0.0, 0.0), m=2.0, r0=1.0, mu=0.0, j=10.0, w0=0.0, dw=0.0,
            dt=0.1):
    pos = np.array([pos], float)
    vel = np.array([vel], float)
    w, diss = contact_node(0, pos, vel, np.array([force], float), m, r0, mu, j, w0, dw, dt)
    return pos[0], vel[0], w, diss


def landing_impulse(x, vx, vy, dt, r0):
    """Hand derivation for a node at (x, 0) with velocity (vx, vy) heading inside the rim:
    the radial velocity change dv (along +x) with |(x + dt (vx + dv), dt vy)| = r0."""
    return (math.sqrt(r0 * r0 - (dt * vy) ** 2) - x) / dt - vx


def test_frictionless_contact_removes_only_the_normal_velocity():
    """Node at (1, 0) on a hub of radius 1 m, velocity (-3, 2) m/s, dt 0.1 s: the radial
    impulse lands it on the rim, the tangential velocity is untouched and the dissipated
    energy is exactly the kinetic energy the impulse removed (no force this step)."""
    dvn = landing_impulse(1.0, -3.0, 2.0, 0.1, 1.0)
    _, v, w, diss = contact((1.0, 0, 0), (-3.0, 2.0, 0))
    assert v[0] == pytest.approx(-3.0 + dvn, rel=1e-12) and v[1] == 2.0 and w == 0.0
    assert diss == pytest.approx(0.5 * 2.0 * (9.0 - v[0] ** 2), rel=1e-12)


def test_sliding_contact_impulse_is_mu_times_the_normal_impulse():
    """Coulomb contact that slides (the stick impulse, 2 / (1/m + r^2/J) = 3.33 N s, exceeds
    the bound): the tangential impulse is mu m dv_n, so v_t drops by mu dv_n, and the hub
    takes the opposite moment, J dw = mu m dv_n r. The dissipation is the loss of the total
    kinetic energy of node and hub."""
    m, mu, j, w0 = 2.0, 0.3, 10.0, 0.5
    dvn = landing_impulse(1.0, -3.0, 2.0, 0.1, 1.0)
    p_t = mu * m * dvn
    assert 2.0 - w0 > 0 and (2.0 - w0) / (1 / m + 1 / j) > p_t  # the bound is active
    _, v, w, diss = contact((1.0, 0, 0), (-3.0, 2.0, 0), m=m, mu=mu, j=j, w0=w0)
    assert v[0] == pytest.approx(-3.0 + dvn, rel=1e-12)
    assert v[1] == pytest.approx(2.0 - p_t / m, rel=1e-12)
    assert w == pytest.approx(w0 + p_t * 1.0 / j, rel=1e-12)
    e0 = 0.5 * m * (9.0 + 4.0) + 0.5 * j * w0 ** 2
    e1 = 0.5 * m * (v[0] ** 2 + v[1] ** 2) + 0.5 * j * w ** 2
    assert diss == pytest.approx(e0 - e1, rel=1e-12)


def test_sticking_contact_leaves_no_slip():
    """With a large mu the tangential impulse is the stick impulse: afterwards the node moves
    with the hub surface, v_t = omega r (the hub's own response included), and the total
    angular momentum m r v_t + J omega is unchanged."""
    m, j, w0 = 2.0, 10.0, 0.5
    _, v, w, _ = contact((1.0, 0, 0), (-3.0, 2.0, 0), m=m, mu=10.0, j=j, w0=w0)
    assert v[1] == pytest.approx(w * 1.0, rel=1e-12)
    assert m * v[1] + j * w == pytest.approx(m * 2.0 + j * w0, rel=1e-14)
    assert w == pytest.approx((m * 2.0 + j * w0) / (m + j), rel=1e-12)


def test_a_node_resting_on_the_hub_under_a_steady_pull_dissipates_nothing():
    """A node at rest on the rim, pulled inwards by F: the step's force gives it
    v = -dt F/m, the contact takes exactly that back (it stays on the rim, at rest). In the
    continuous problem nothing moves, so nothing is dissipated: the kinetic energy the
    impulse removes, m (dt F/m)^2 / 2, is the work dt F . dv / 2 of the step's own force."""
    m, F, dt = 2.0, 1e4, 1e-3
    pos, v, w, diss = contact((1.0, 0, 0), (-dt * F / m, 0, 0), force=(-F, 0, 0), m=m, dt=dt)
    assert np.allclose(v, 0.0, atol=1e-9)
    assert abs(diss) < 1e-9 * 0.5 * m * (dt * F / m) ** 2


def test_contact_never_pushes_a_node_outwards():
    """A node slightly inside the rim but moving outwards gets no impulse (the constraint
    only stops inward motion)."""
    pos, v, w, diss = contact((0.999, 0, 0), (0.001, 0.0, 0), dt=0.01)
    assert np.array_equal(v, [0.001, 0.0, 0.0]) and diss == 0.0 and w == 0.0


# ---------------------------------------------------------------- the hub and what moves with it

def test_tied_nodes_move_rigidly_with_the_hub():
    """x = R(theta) x_ref and v = omega e_z x x, written out component by component."""
    rng = np.random.default_rng(5)
    ref = rng.normal(size=(4, 3))
    pos, vel = np.zeros((6, 3)), np.ones((6, 3))
    idx = np.array([1, 2, 4, 5])
    theta, omega = 0.9, -3.0
    place_rigid(pos, vel, idx, ref, theta, omega)
    c, s = math.cos(theta), math.sin(theta)
    x = c * ref[:, 0] - s * ref[:, 1]
    y = s * ref[:, 0] + c * ref[:, 1]
    np.testing.assert_allclose(pos[idx], np.column_stack([x, y, ref[:, 2]]), rtol=1e-14)
    np.testing.assert_allclose(vel[idx], np.column_stack([-omega * y, omega * x, 0 * x]),
                               rtol=1e-14)
    assert np.all(pos[[0, 3]] == 0.0) and np.all(vel[[0, 3]] == 1.0)


def tether_scene(law, values, friction=0.0, pattern="coiled", omega=0.0, inertia=200.0):
    """Four 10 m Zylon tethers of 10 elements with 2 kg tips coiled on a 1 m hub (tied
    roots, contact on), spinning at ``omega`` with the hub, under the control law ``law``."""
    mesh = tethers(4, 10.0, 10, 1.0, 2.0, pattern)
    model = build_model(mesh, E, RHO, A, hub_radius=1.0, hub_inertia=inertia,
                        hub_friction=friction)
    state = initial_state(model, omega, "all")
    dt = choose_dt(model, 0.5, history_dt=1e-3)
    return model, make_control(law, values), state, dt


def test_constant_torque_work_is_torque_times_the_angle_turned():
    """The work of a constant torque M is M times the hub angle turned. The scheme turns the
    hub by dt omega_{k+1/2} per step and counts the work of step k with the half-step mean
    rate, W_N = M dt sum_k (omega_{k-1/2} + omega_{k+1/2}) / 2; summing,
    W_N = M [theta_N - theta_0 - dt/2 (omega_{N-1/2} - omega_{-1/2})]: to round-off, with
    the tethers pulling on the hub."""
    M = 4000.0
    model, control, state, dt = tether_scene("constant_torque", {"torque": M}, omega=10.0)
    first = state.copy()
    start(model, control, first, dt)
    w_start = first.hub.rate[0]  # omega_{-1/2}
    res = simulate(model, control, state, dt, Schedule(0.05, dt))
    theta, w_end = state.hub.angle[0], state.hub.rate[0]
    expect = M * (theta - dt / 2 * (w_end - w_start))
    assert theta > 0.1 and res.history["max_tension"].max() > 500.0
    assert state.totals[SLOTS.term.torque_work] == pytest.approx(expect, rel=1e-12)


@pytest.mark.parametrize("law,values,friction,omega", [
    ("constant_torque", {"torque": 4000.0}, 0.0, 10.0),
    ("torque_feedback", {"M0": 2e4, "omega0": 8.0}, 0.0, 10.0),
    ("torque_feedback", {"M0": 2e4, "omega0": 8.0}, 0.3, 10.0),
    ("spin_ramp", {"omega_max": 20.0, "ramp_time": 0.02}, 0.0, 0.0),
])
def test_controlled_runs_angular_momentum_is_the_torque_impulse(law, values, friction, omega):
    """dK/dt = M: the discrete angular momentum sum m x_n x v_{n+1/2} + J omega_{n+1/2} gains
    exactly dt M_n per step (internal forces, tied nodes and contact impulses have no net
    moment), and the history row K_n is the mean of K_{n-1/2} and K_{n+1/2}, so with a row at
    every step K_n - K_0 is the trapezoid sum of dt M over the rows: equal to round-off. For
    the spin ramp the reported torque is the one the law takes, so this also checks it."""
    model, control, state, dt = tether_scene(law, values, friction, omega=omega)
    h = simulate(model, control, state, dt, Schedule(0.04, dt)).history
    K, M = h["angular_momentum"], h["hub_torque"]
    assert np.allclose(np.diff(h["time"]), dt, rtol=1e-9)
    # the tethers pull on the hub (tied roots) and slide on it (contact) while it turns
    assert h["max_tension"].max() > 500.0 and h["contact_dissipation"][-1] > 0.1
    impulse = np.concatenate([[0.0], np.cumsum(0.5 * dt * (M[1:] + M[:-1]))])
    scale = np.abs(K).max()
    assert np.abs(impulse).max() > 0.05 * scale  # the torque does change K
    assert np.abs(K - K[0] - impulse).max() < 1e-11 * scale
    if law == "constant_torque":
        assert np.abs(K - K[0] - values["torque"] * h["time"]).max() < 1e-11 * scale


def test_spin_ramp_rate_and_angle_are_the_laws_closed_form():
    """A prescribed ramp omega = omega_max t / T is imposed at the half steps, so the recorded
    rate (the mean of the two half-step rates) is omega_max t_n / T exactly during the ramp,
    and the hub angle, a midpoint sum of a linear rate, is omega_max t_n^2 / (2 T) exactly;
    after the ramp omega_max and omega_max (t - T/2)."""
    wmax, T = 20.0, 0.02
    model, control, state, dt = tether_scene("spin_ramp", {"omega_max": wmax, "ramp_time": T})
    h = simulate(model, control, state, dt, Schedule(0.04, dt)).history
    t, w, theta = h["time"], h["hub_omega"], h["hub_angle"]
    ramp, after = t < T - 0.5 * dt, t > T + 0.5 * dt
    assert ramp.sum() > 50 and after.sum() > 50
    np.testing.assert_allclose(w[ramp], wmax * t[ramp] / T, rtol=1e-12, atol=1e-12 * wmax)
    np.testing.assert_allclose(theta[ramp], wmax * t[ramp] ** 2 / (2 * T), rtol=1e-10,
                               atol=1e-12)
    np.testing.assert_allclose(w[after], wmax, rtol=1e-12)
    np.testing.assert_allclose(theta[after], wmax * (t[after] - T / 2), rtol=1e-9)


def two_masses(pos, vel, rest=1.0):
    """Two free point masses of 5 kg joined by one Zylon element of rest length ``rest``,
    around a hub of radius 1 m (contact on, inertia 10 kg m^2, nothing tied)."""
    pos = np.asarray(pos, float)
    mesh = Mesh(node_pos=pos, node_ref=pos, elem_nodes=[[0, 1]], elem_rest_len=[rest],
                node_point_mass=[5.0, 5.0], node_sets={"hub_tied": [], "tips": [1]},
                arm_root_angle=[0.0])
    model = build_model(mesh, E, RHO, A, hub_radius=1.0, hub_inertia=10.0)
    state = initial_state(model, 0.0, "hub")
    state.node_vel[:] = vel
    return model, state


def test_a_mass_thrown_at_the_hub_loses_exactly_its_kinetic_energy():
    """Two free masses on a slack element (1 m apart, rest length 2 m) fly radially at the
    hub at 10 m/s: the contact stops them on the rim (no bounce, no penetration) and the
    contact dissipation is all of their kinetic energy, so the energy balance KE + D stays
    at its initial value to round-off."""
    model, state = two_masses([[2.0, 0.0, 0.0], [3.0, 0.0, 0.0]], [[-10.0, 0, 0]] * 2, rest=2.0)
    m = model.nodes.mass
    e0 = 0.5 * m.sum() * 100.0
    dt = choose_dt(model, 0.5, history_dt=1e-3)
    h = simulate(model, free_law(), state, dt, Schedule(0.3, 1e-3)).history
    assert h["kinetic_energy"][0] == pytest.approx(e0, rel=1e-12)
    assert h["kinetic_energy"][-1] < 1e-20 * e0  # at rest on the rim
    assert h["contact_dissipation"][-1] == pytest.approx(e0, rel=1e-12)
    np.testing.assert_allclose(energy_balance(h), e0, rtol=1e-12)
    r = np.hypot(state.node_pos[:, 0], state.node_pos[:, 1])
    np.testing.assert_allclose(r, 1.0, rtol=1e-12)


def test_damped_oscillation_dissipates_what_it_loses():
    """The cable node between two tied anchors on prestretched cables (never slack), pulled
    aside by 0.05 m and released, with critical element damping: the dampers take the
    oscillation's energy (a fifth of the total), and KE + SE + D stays constant to the
    scheme's truncation (the damper sees v_{n-1/2}; at dt = T/200 measured 1e-3 of the
    energy, 0.5 % of D; bound 1 % of D)."""
    x0 = 1.1
    pos = np.array([[-x0, 0, 0], [0.05, 0, 0], [x0, 0, 0]])
    ref = pos.copy()
    ref[1, 0] = 0.0
    mesh = Mesh(node_pos=pos, node_ref=ref, elem_nodes=[[0, 1], [1, 2]],
                elem_rest_len=[1.0, 1.0], node_point_mass=[0, 0, 0],
                node_sets={"hub_tied": [0, 2], "tips": [1]}, arm_root_angle=[0.0])
    model = build_model(mesh, E, RHO, A, damping_ratio=1.0, hub_radius=0.0, hub_inertia=1e30)
    state = initial_state(model, 0.0, "hub")
    period = 2 * math.pi * math.sqrt(model.nodes.mass[1] / (2 * EA / 1.0))
    dt = period / 200
    h = simulate(model, free_law(), state, dt, Schedule(3 * period, dt)).history
    e = energy_balance(h)
    e0 = e[0]
    assert h["damping_dissipation"][-1] > 0.15 * e0
    assert np.abs(e - e0).max() < 1e-2 * h["damping_dissipation"][-1]


def test_a_row_holds_the_means_of_the_half_step_values():
    """Row n of the step loop holds the probe position x_n and the velocity
    (v_{n-1/2} + v_{n+1/2}) / 2, and the kinetic energy and angular momentum as the means of
    their half-step values (second order at t_n; docs/solver.md, docs/results.md)."""
    from spinweb_fe.record.arms import ArmTracker
    from spinweb_fe.run.loop import _Chunks

    model, state = two_masses([[2.0, 0.0, 0.0], [2.0, 1.1, 0.0]], [[0.0, 0, 0], [3.0, -4.0, 0]])
    control = free_law()
    dt = 1e-5
    start(model, control, state, dt)
    tracker = ArmTracker(model.mesh, model.hub.radius)
    chunks = _Chunks(model, control, tracker, 1, 1, dt)
    k = int(np.flatnonzero(tracker.probes == 1)[0])
    x = state.node_pos.copy()
    x0, v0, vs0 = x[1], state.node_vel[1].copy(), state.node_vel.copy()
    code, nrec = chunks.advance(state, dt, 1)
    assert (code, nrec) == (0, 1)
    v1, vs1 = state.node_vel[1], state.node_vel
    assert np.abs(v1 - v0).max() > 0.1  # the stretched element pulls in this step
    np.testing.assert_array_equal(chunks.rec.probe_pos[0, k], x0)
    np.testing.assert_allclose(chunks.rec.probe_vel[0, k], 0.5 * (v0 + v1), rtol=1e-14)
    m = model.nodes.mass
    ke = [0.5 * np.sum(m * np.sum(v * v, axis=1)) for v in (vs0, vs1)]
    lz = [np.sum(m * (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0])) for v in (vs0, vs1)]
    row = {k: v[0] for k, v in row_columns(chunks.rec.table, 1).items()}
    assert ke[1] != pytest.approx(ke[0], rel=1e-3)
    assert row["kinetic_energy"] == pytest.approx(0.5 * (ke[0] + ke[1]), rel=1e-13)
    assert row["angular_momentum"] == pytest.approx(0.5 * (lz[0] + lz[1]), rel=1e-13)


def test_held_coil_takes_the_moment_of_the_forces_on_it():
    """A held coil turns with the hub, so the element forces on its nodes act on the hub:
    held_moment is their z-moment sum x f_y - y f_x over the held nodes (computed here with
    numpy), and over a short held-coil run (the free level pulling on the coil from the
    first steps) the angular momentum of hub, coil and free nodes is conserved to round-off
    (the energy audit is switched off: this is the check)."""
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.fe.coil import levels as coil_mod

    text = (TETHER_CASE.replace("'straight'", "'coiled'").replace("omega = 2.0", "omega = 25.0")
            .replace("elements = 10", "elements = 50"))
    cs = case_mod.loads(text + "[time]\nend = 0.03\n")
    scene = prepare(cs)
    model, control, state, dt = scene.model, scene.control, scene.state, scene.dt
    coil = model.coil
    held = np.concatenate([coil.level_nodes[coil.level_ptr[coil.arm_ptr[k] + state.coil.front[k]]:
                                            coil.level_ptr[coil.arm_ptr[k + 1]]]
                           for k in range(len(coil.arm_ptr) - 1)])
    assert len(held) > 10
    rng = np.random.default_rng(3)
    f = rng.normal(size=(model.n_nodes, 3))
    pos = state.node_pos
    expect = np.sum(pos[held, 0] * f[held, 1] - pos[held, 1] * f[held, 0])
    got = coil_mod.held_moment(coil.arm_ptr, state.coil.front, coil.level_ptr, coil.level_nodes,
                               pos, f)
    assert got == pytest.approx(expect, rel=1e-12)
    h = simulate(model, control, state, dt, Schedule(0.03, 1e-4), energy_limit=np.inf).history
    assert h["max_tension"].max() > 100.0 and np.any(state.coil.front > 1)  # it pulls, pays out
    K = h["angular_momentum"]
    assert np.abs(K - K[0]).max() < 1e-12 * abs(K[0])


# ---------------------------------------------------------------- analytical model

def eq7_free_part(p, L, nq=30):
    """Mass and first moment about the base of the free part (the outer L metres of the
    arm, tip included) by Gauss quadrature of the line density 2 m_lin/H^2 (H - s) +
    m_uni/H, s the arm coordinate from the root: independent of ArmParams.moments."""
    x, wq = np.polynomial.legendre.leggauss(nq)
    s = p.H - L + 0.5 * L * (x + 1.0)
    rho = 2 * p.m_lin / p.H ** 2 * (p.H - s) + p.m_uni / p.H
    dm = 0.5 * L * wq * rho
    lb = s - (p.H - L)  # distance from the base
    return dm.sum() + p.m_tip, (dm * lb).sum() + p.m_tip * L, s, dm, lb


P_DIST = ArmParams(n=3, H=40.0, r0=5.0, J_hub=900.0, m_tip=7.0, m_lin=20.0, m_uni=3.0)


@pytest.mark.parametrize("phi", [0.7, -1.2, 1.5])
def test_root_tension_under_angular_acceleration(phi):
    """Pivoting arm, hub accelerating: the root tension is minus the along-arm component of
    the free part's momentum rate, N = -sum dm a . u, u the arm direction. The acceleration
    of every material point comes from differencing its position along a trajectory with
    the given (omega, omega', Psi, Psi'), x(t) = r0 e(theta) + l e(theta + phi); the mass
    points from :func:`eq7_free_part`. Hand form: N = m_f r0 (omega^2 cos phi - omega'
    sin phi) + S Psi^2 (independent of Psi')."""
    p = P_DIST
    omega, wdot, psi, pdot = 4.0, 37.0, -2.5, 11.0
    m_f, S, s, dm, lb = eq7_free_part(p, p.H)
    l = np.concatenate([lb, [p.H]])
    mass = np.concatenate([dm, [p.m_tip]])

    def x(t):
        th = 0.3 + omega * t + 0.5 * wdot * t * t
        ps = 0.3 + phi + psi * t + 0.5 * pdot * t * t
        return (p.r0 * np.array([math.cos(th), math.sin(th)])[None, :]
                + l[:, None] * np.array([math.cos(ps), math.sin(ps)])[None, :])

    h = 1e-4
    acc = (x(h) - 2 * x(0.0) + x(-h)) / (h * h)
    u = np.array([math.cos(0.3 + phi), math.sin(0.3 + phi)])
    N_particles = -np.sum(mass * (acc @ u))
    N_hand = m_f * p.r0 * (omega ** 2 * math.cos(phi) - wdot * math.sin(phi)) + S * psi ** 2
    assert N_particles == pytest.approx(N_hand, rel=1e-6)
    assert abs(wdot * math.sin(phi)) * m_f * p.r0 > 0.1 * abs(N_hand)  # the term matters
    assert root_tension(p, phi, omega, psi, wdot, False) == pytest.approx(N_hand, rel=1e-12)


@pytest.mark.parametrize("phi", [-(HALF_PI + 3.0), HALF_PI + 5.5])
def test_printed_model_coiled_rows_with_distributed_mass(phi):
    """The printed model while coiled, for an arm with distributed mass (where the wound mass
    matters), derived by hand from the printed equations: in Eqs. 5/8a and 6/8b put
    omega -> Psi, omega' -> Psi', phi -> sigma pi/2, L' = -sigma r0 phi', L'' = -sigma r0
    phi''; then Eq. 5/8a gives the tension N = -sigma r0 m_f omega' + S Psi^2, and Eq. 4,
    J_hub omega' = M + n N r0 sigma, becomes (J_hub + n r0^2 m_f) omega' = M + n sigma r0
    S Psi^2 (J_z is the hub alone: the inertia of the free part at the rim, not the initial
    one); Eq. 6/8b gives S Psi' = -2 sigma r0 m_f Psi (omega - Psi/2). m_f and S of the free
    part by quadrature."""
    p = P_DIST
    sigma = math.copysign(1.0, phi)
    L = p.H - p.r0 * (abs(phi) - HALF_PI)
    m_f, S, *_ = eq7_free_part(p, L)
    assert 5.0 < L < 30.0
    omega, psi, M = 4.0, -2.5, 150.0
    wd = (M + p.n * sigma * p.r0 * S * psi ** 2) / (p.J_hub + p.n * p.r0 ** 2 * m_f)
    pd = -2 * sigma * p.r0 * m_f * psi * (omega - psi / 2) / S
    got = accelerations("printed", p, phi, omega, psi, True, torque=M)
    assert got[0] == pytest.approx(wd, rel=1e-12) and got[1] == pytest.approx(pd, rel=1e-12)
    N = -sigma * p.r0 * m_f * wd + S * psi ** 2
    assert p.J_hub * wd == pytest.approx(M + p.n * N * p.r0 * sigma, rel=1e-12)
    assert root_tension(p, phi, omega, psi, wd, True) == pytest.approx(N, rel=1e-12)
    # prescribed acceleration: the torque it takes, from the same hub row
    got = accelerations("printed", p, phi, omega, psi, True, omega_dot=wd)
    assert got[2] == pytest.approx(M, rel=1e-12)


# ---------------------------------------------------------------- the energy audit

def rows(t, ke):
    z = np.zeros(len(t))
    return {"time": np.asarray(t, float), "kinetic_energy": np.asarray(ke, float),
            "strain_energy": z, "torque_work": z, "damping_dissipation": z,
            "contact_dissipation": z}


def test_energy_warning_is_logged_once_above_one_percent(caplog):
    """Above ENERGY_WARN (1 %) the audit warns once with the time and the size; below it and
    on later chunks it stays quiet; above ENERGY_LIMIT (50 %) it stops the run."""
    assert (ENERGY_WARN, ENERGY_LIMIT) == (0.01, 0.5)  # docs/stability.md
    audit = EnergyAudit()
    with caplog.at_level(logging.WARNING, logger="spinweb_fe"):
        audit.rows(rows([0.0, 0.001], [100.0, 100.9]))  # 0.9 %: quiet
        assert caplog.records == []
        audit.rows(rows([0.002, 0.003], [101.0, 102.0]))  # 2 %: warns
        audit.rows(rows([0.004], [110.0]))  # 10 %: already warned
        audit.rows(rows([0.005], [140.0]))  # 40 %: still below the limit
    assert len(caplog.records) == 1
    assert caplog.records[0].getMessage() == (
        "warning: at t = 0.003 s the energy balance is off by 2 % of the energy scale "
        "(slack/taut snapping or hub impacts; a smaller time.cfl or a little damping helps, "
        "see docs/stability.md)")
    with pytest.raises(RunError) as err:
        audit.rows(rows([0.006], [160.0]))
    assert err.value.time == 0.006
    assert str(err.value) == ("stopped at t = 0.006 s: energy balance off by 60 % of the "
                              "energy scale (numerical instability; reduce time.cfl)")


def test_a_run_from_rest_is_audited_against_its_torque_work():
    """No initial energy: the scale is the largest torque work so far, so a balance error
    of 2 J against 100 J of work is 2 %."""
    z = np.zeros(3)
    h = {"time": np.array([0.0, 1.0, 2.0]), "kinetic_energy": np.array([0.0, 50.0, 102.0]),
         "strain_energy": z, "torque_work": np.array([0.0, 50.0, 100.0]),
         "damping_dissipation": z, "contact_dissipation": z}
    from spinweb_fe.record.energy import balance_error

    assert balance_error(h) == pytest.approx(0.02, rel=1e-12)
    assert np.array_equal(energy_balance(h), [0.0, 0.0, 2.0])


def test_the_audit_scale_is_the_torque_work_of_the_whole_run():
    """A run from rest spun up by 1e6 J of torque work, then braked back to zero work: the
    later chunks are still measured against 1e6 J (a 2e4 J balance error is 2 %, a warning,
    not a stop), and the scale and the warning survive a restart (memory / restore)."""
    def chunk(t, ke, w):
        z = np.zeros(len(t))
        return {"time": np.array(t), "kinetic_energy": np.array(ke), "strain_energy": z,
                "torque_work": np.array(w), "damping_dissipation": z,
                "contact_dissipation": z}

    audit = EnergyAudit()
    audit.rows(chunk([0.0, 1.0], [0.0, 1e6], [0.0, 1e6]))
    audit.rows(chunk([2.0, 3.0], [5e5, 2e4], [5e5, 0.0]))  # 2 % of the run's scale: warns
    assert audit.warned and audit.work_seen == 1e6
    again = EnergyAudit()
    again.restore(audit.memory())
    assert again.warned and again.work_seen == 1e6 and again.ref == audit.ref
    again.rows(chunk([4.0], [4e4], [0.0]))  # 4 %: no stop, no second warning
    with pytest.raises(RunError):
        again.rows(chunk([5.0], [6e5], [0.0]))  # 60 % of 1e6 J


# ---------------------------------------------------------------- input limits and files

TETHER_CASE = ("[tethers]\ncount = 4\nlength = 50.0\nelements = 10\n[tip_mass]\nmass = 10.0\n"
               "[hub]\nradius = 6.3\nmass = 100.0\n[initial]\nomega = 2.0\n"
               "[fold]\npattern = 'straight'\n")


def test_a_byte_order_mark_is_accepted(tmp_path):
    """A UTF-8 byte-order mark before the first key (some editors write one) is not part of
    the TOML: the case loads as without it."""
    text = TETHER_CASE + "[time]\nend = 0.1\n"
    plain, bom = tmp_path / "plain" / "c.toml", tmp_path / "bom" / "c.toml"
    for path, data in ((plain, text.encode()), (bom, b"\xef\xbb\xbf" + text.encode())):
        path.parent.mkdir()
        path.write_bytes(data)
    assert bom.read_bytes()[:3] == b"\xef\xbb\xbf"
    assert dataclasses.replace(case_mod.load(bom), source="") == dataclasses.replace(
        case_mod.load(plain), source="")


def test_frame_count_limit():
    """time.end / output.frame_dt above MAX_FRAMES (1e5) is refused, naming the key."""
    from spinweb_fe.case.schema import MAX_FRAMES

    assert MAX_FRAMES == 100_000  # docs/robustness.md
    ok = TETHER_CASE + "[time]\nend = 1.0\n[output]\nframe_dt = 2e-5\n"  # 5e4 frames
    assert case_mod.loads(ok).output.frame_dt == 2e-5
    with pytest.raises(InputError) as err:
        case_mod.loads(TETHER_CASE + "[time]\nend = 1.0\n[output]\nframe_dt = 5e-6\n")
    assert err.value.key == "output.frame_dt"
    assert err.value.reason == "gives 2e+05 frames up to time.end, more than the limit 1e+05"


def test_step_count_limit():
    """A run of more than MAX_STEPS (1e10) steps is a units slip: refused in prepare, naming
    time.end (here 1e7 s at a step of about 3.7e-5 s: 2.7e11 steps)."""
    from spinweb_fe.case.scene import MAX_STEPS, prepare

    assert MAX_STEPS == 1e10  # docs/robustness.md
    text = TETHER_CASE + "[time]\nend = {end}\n[output]\nhistory_dt = {end}\nframe_dt = 0.0\n"
    scene = prepare(case_mod.loads(text.format(end=1e4)))  # 2.7e8 steps: allowed
    assert 1e8 < 1e4 / scene.dt < MAX_STEPS
    with pytest.raises(InputError) as err:
        prepare(case_mod.loads(text.format(end=1e7)))
    assert err.value.key == "time.end"
    assert "more than the limit 1e+10" in err.value.reason


def test_every_planted_bug_still_has_its_target():
    """tests/mutate.py plants each bug by replacing a line that must occur exactly once in
    its file: a refactor that moves the line would silently turn the mutant into an error
    of the script (15 of them had gone stale when the two step loops became one)."""
    import os

    if os.environ.get("SPINWEB_MUTATION_COPY"):  # tests/mutate.py's copy: one line is gone
        pytest.skip("a mutated copy, whose planted line replaced its target")
    import mutate  # tests/mutate.py: pytest puts tests/ on the path

    root = Path(__file__).parent.parent
    stale = [(m.id, m.path) for m in mutate.MUTANTS
             if not (root / m.path).exists() or (root / m.path).read_text().count(m.old) != 1]
    assert not stale, stale
