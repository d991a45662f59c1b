"""Guards of the payout devices (issue #47): the law tables interpolated on the interval
that holds t (the FE kernel and the analytical twin, against numpy's interp and hand-worked
values, at the points and between them), and the device's damping correction, which must
take out exactly the damping power the element pass booked for the device's elements (the
tension-only clamp included), and the brake's slip in a step, bounded by a length."""

import math

import numpy as np
import pytest

from spinweb_fe.analytic.payout import Brake, Payout
from spinweb_fe.fe.coil.brake import SLIP_SPEED
from spinweb_fe.fe.coil.devices import axis_devices
from spinweb_fe.fe.coil.levels import law_value
from spinweb_fe.fe.hub.axis import NodeMotion
from spinweb_fe.record.recorders import Recorder

TT = np.array([0.0, 0.1, 0.3, 0.6, 1.0])
VV = np.array([0.0, 2.0, 3.0, 9.0, 9.5])


def test_the_fe_law_is_linear_on_the_interval_that_holds_t():
    """law_value against numpy.interp (a second implementation) at the table's points, in
    every interval, before the first point and after the last: equal to 1e-15 of the
    values (measured: identical); a hand-worked pair too (t = 0.2: 2.5, t = 0.45: 6)."""
    ts = np.concatenate([TT, np.linspace(-0.2, 1.3, 301), TT + 1e-9, TT - 1e-9])
    got = np.array([law_value(TT, VV, t) for t in ts])
    assert np.abs(got - np.interp(ts, TT, VV)).max() <= 1e-15 * VV.max()
    assert law_value(TT, VV, 0.2) == pytest.approx(2.5, rel=1e-15)
    assert law_value(TT, VV, 0.45) == pytest.approx(6.0, rel=1e-15)


def test_the_analytical_payout_takes_the_slope_of_the_segment_starting_at_t():
    """Payout.at: the length as numpy.interp gives it and the slope of the segment that
    starts at t, so at a table point the next segment's (t = 0.1: 5 m/s, not the 20 m/s
    before it), 0 before the first point and from the last on. Hand-worked values."""
    p = Payout(TT, VV)
    cases = {-0.5: (0.0, 0.0), 0.0: (0.0, 20.0), 0.05: (1.0, 20.0), 0.1: (2.0, 5.0),
             0.2: (2.5, 5.0), 0.3: (3.0, 20.0), 0.45: (6.0, 20.0), 0.6: (9.0, 1.25),
             0.8: (9.25, 1.25), 1.0: (9.5, 0.0), 2.0: (9.5, 0.0)}
    for t, (length, slope) in cases.items():
        got = p.at(t)
        assert got[0] == pytest.approx(length, rel=1e-14, abs=1e-15), t
        assert got[1] == pytest.approx(slope, rel=1e-14, abs=1e-15), t
    assert p.breaks(0.7) == [0.1, 0.3, 0.6]
    b = Brake(TT, 1e3 * VV)
    assert [b.at(t) for t in (-1.0, 0.2, 0.45, 3.0)] == pytest.approx([0.0, 2.5e3, 6e3, 9.5e3])


def test_the_device_damping_correction_takes_out_what_the_element_pass_booked():
    """The reel on the coiled tethers with a damper (zeta 0.05), 3 ms into the payout: each
    arm's front element is held by its device, which replaces the element pass's force and
    must take out the pass's damping power for it. The outer nodes are given shortening
    speeds of 100-400 m/s, so that the damper would push on two of the four (N_el + c L'
    below zero: the tension-only clamp holds them at zero tension). The correction equals
    minus the pass's damping power of those four elements (support.eval_elements on them
    alone) to 1e-12 (measured: identical)."""
    from support import eval_elements

    from spinweb_fe import case as case_mod
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.fe.coil.payout import device_forces
    from spinweb_fe.fe.forces import make_work
    from spinweb_fe.fe.model import Elements
    from spinweb_fe.run.loop import Schedule, simulate

    from test_payout import ARMS

    sc = prepare(case_mod.load(ARMS, ["stowage.payout='rate'", "stowage.payout_rate=20.0",
                                      "cable.damping_ratio=0.05", "time.end=0.003"]))
    st = sc.state
    simulate(sc.model, sc.control, st, sc.dt, Schedule(0.003, 1e-3))
    kern = sc.model.kernel
    coil, cs, el = kern.coil, st.coil, kern.elements
    assert np.all(cs.front == 1)
    pos, vel = st.node_pos.copy(), st.node_vel.copy()
    sel = []
    for k in range(len(coil.arm_ptr) - 1):
        lev = coil.arm_ptr[k] + cs.front[k]
        for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
            a, b = coil.test_from[q], coil.test_to[q]
            u = (pos[b] - pos[a]) / np.linalg.norm(pos[b] - pos[a])
            vel[b] = vel[a] - 100.0 * (len(sel) + 1) * u
            sel.append(coil.test_elem[q])
    sel = np.array(sel)
    ends = el.nodes[sel]
    d = pos[ends[:, 1]] - pos[ends[:, 0]]
    length = np.linalg.norm(d, axis=1)
    ldot = np.einsum("ij,ij->i", d, vel[ends[:, 1]] - vel[ends[:, 0]]) / length
    n_el = el.ea[sel] * (length * el.inv_rest[sel] - 1.0)
    assert np.all(n_el > 0)
    pushing = n_el + el.cdamp[sel] * ldot < 0
    assert 0 < pushing.sum() < len(sel)  # the clamp holds some of them, not all
    sub = Elements(ends, el.rest_len[sel], el.inv_rest[sel], el.ea[sel], el.cdamp[sel],
                   el.damped)
    _, _, booked = eval_elements(sub, pos, vel, np.zeros_like(pos), np.zeros(len(sel)), True)
    work = make_work(len(pos), len(el.nodes))
    _, dpow, _ = device_forces(coil, cs, el, pos, vel, work, True, st.strength.broken)
    assert booked > 1e6
    assert dpow == pytest.approx(-booked, rel=1e-12)


class _Snapshots(Recorder):
    name = "snapshots"

    def __init__(self):
        self.states = []

    def checkpoint(self, state, memory):
        self.states.append(state.copy())


def test_the_brakes_slip_in_a_step_is_bounded_by_a_length():
    """A brake of zero force on the coiled tethers, states every 0.2 ms over the first 6 ms
    (dt = 18 us), each given one more device phase (fe.coil.devices.axis_devices, arm 0):
    the return mapping's slip x through D in a step is at most the line's
    largest stretch at D plus SLIP_SPEED x dt x the fastest speed at which its taut
    material leaves D (both worked out here with numpy from the state: D on the coil, its
    velocity omega e_z x x_D, each front element's stretch d - phi L0), to 1.4e-10 of it
    (1.5x the measured 9.6e-11: the two computations' round-off); the slip reaches the
    bound in 30 of the 30 states (measured: the line above the force up to the speed
    limit), at least 20 asserted."""
    from test_payout import ARMS

    from spinweb_fe import case as case_mod
    from spinweb_fe.case.scene import prepare
    from spinweb_fe.run.loop import Schedule, simulate

    sc = prepare(case_mod.load(ARMS, ["stowage.payout='brake'", "stowage.brake_force=0.0",
                                      "time.end=0.006"]))
    m, dt = sc.model, sc.dt
    kern = m.kernel
    coil, el = kern.coil, kern.elements
    snaps = _Snapshots()
    simulate(m, sc.control, sc.state, dt, Schedule(0.006, 1e-3, 0.0, 2e-4), [snaps])
    reached = slips = 0
    for s in snaps.states:
        k = 0  # the first arm the device phase moves (the hub's rate then is the state's)
        lev = coil.arm_ptr[k] + s.coil.front[k]
        if lev >= coil.arm_ptr[k + 1] or s.coil.front[k] == 0:
            continue
        w, th = s.hub.rate[0], s.hub.angle[0]
        s_old, s_f = s.coil.s_dev[k], coil.level_coord[lev]
        r = s.coil.dev_ref[k]
        xd = np.array([math.cos(th) * r[0] - math.sin(th) * r[1],
                       math.sin(th) * r[0] + math.cos(th) * r[1], r[2]])  # D in the world
        vd = np.array([-w * xd[1], w * xd[0], 0.0])
        stretch = v_max = 0.0
        for q in range(coil.test_ptr[lev], coil.test_ptr[lev + 1]):
            e, b, s_to = coil.test_elem[q], coil.test_to[q], coil.test_to_coord[q]
            u = s.node_pos[b] - xd
            d = np.linalg.norm(u)
            ell = el.rest_len[e] * min(max((s_to - s_old) / (s_to - s_f), 0.0), 1.0)
            if d > ell and s_old > s_f:
                stretch = max(stretch, d - ell)
                v_max = max(v_max, (s.node_vel[b] - vd) @ u / d)
        bound = stretch + SLIP_SPEED * v_max * dt
        after = s.copy()
        axis_devices(kern.devices, after.coil, el, kern.nodes, kern.hub,
                     NodeMotion(after.node_pos, after.node_vel, after.node_mass,
                                after.node_inv_mass), after.hub, float(s.time[0]), dt)
        if after.coil.front[k] != s.coil.front[k]:
            continue  # the whole level passed D (at most the level: the bracket's end)
        x = s_old - after.coil.s_dev[k]
        slips += x > 0
        assert x <= bound * (1.0 + 1.4e-10), (x, bound)
        reached += x > 0 and x >= bound * (1.0 - 1.4e-10)
    assert slips >= 25 and reached >= 20
