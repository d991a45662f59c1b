"""Element and step kernels against closed forms (STYLE.md: stretched chain, compressed chain,
rigid rotation, force balance)."""

import math

import numpy as np
import pytest

from spinweb_fe.fe import step
from spinweb_fe.fe.hub.contact import contact_node
from spinweb_fe.fe.control import LAWS, KernelLaw, eval_control, make_control
from spinweb_fe.fe.model import Elements
from support import eval_elements

EA = 1.845e6


def chain(n_el, stretch):
    """Straight chain along x of n_el elements of rest length 1 m, uniformly stretched."""
    pos = np.zeros((n_el + 1, 3))
    pos[:, 0] = np.arange(n_el + 1) * (1.0 + stretch)
    nodes = np.array([[i, i + 1] for i in range(n_el)], dtype=np.int64)
    return pos, nodes, np.ones(n_el), np.full(n_el, EA), np.zeros(n_el)


def forces(pos, nodes, rest, ea, cd, vel=None):
    f = np.zeros_like(pos)
    t = np.zeros(len(nodes))
    vel = np.zeros_like(pos) if vel is None else vel
    elems = Elements(np.asarray(nodes, np.int64), rest, 1.0 / rest, ea, cd, bool(np.any(cd > 0)))
    se, tmax, p = eval_elements(elems, pos, vel, f, t, True)
    return f, t, se, tmax, p


def test_stretched_chain_end_forces_and_zero_interior():
    eps = 1e-3
    f, t, se, tmax, _ = forces(*chain(10, eps))
    np.testing.assert_allclose(t, EA * eps, rtol=1e-12)
    np.testing.assert_allclose(f[0], [EA * eps, 0, 0], rtol=1e-12)  # pulled towards the chain
    np.testing.assert_allclose(f[-1], [-EA * eps, 0, 0], rtol=1e-12)
    assert np.max(np.abs(f[1:-1])) < 1e-9 * EA * eps
    assert se == pytest.approx(10 * 0.5 * EA * eps**2, rel=1e-12)
    assert tmax == pytest.approx(EA * eps, rel=1e-12)


def test_compressed_and_zero_length_chain_carry_nothing():
    for stretch in (-1e-3, -1.0):  # shortened, and fully gathered (zero length)
        f, t, se, _, _ = forces(*chain(5, stretch))
        assert np.all(f == 0) and np.all(t == 0) and se == 0


def test_rigid_motion_changes_no_strain():
    """A random rigid motion (rotation about a random axis, random translation): the
    unstretched chain stays strain-free, the stretched one keeps its tensions EA eps, and
    its end forces turn with it (f -> R f)."""
    rng = np.random.default_rng(1)
    R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    shift = rng.normal(size=3) * 10
    for eps in (0.0, 1e-3):
        pos, nodes, rest, ea, cd = chain(6, eps)
        f0, t0, se0, _, _ = forces(pos, nodes, rest, ea, cd)
        f, t, se, _, _ = forces(pos @ R.T + shift, nodes, rest, ea, cd)
        np.testing.assert_allclose(t, EA * eps, rtol=1e-9, atol=1e-6)
        assert se == pytest.approx(6 * 0.5 * EA * eps ** 2, rel=1e-9, abs=1e-12)
        np.testing.assert_allclose(f, f0 @ R.T, atol=1e-9 * EA * max(eps, 1e-6))


def test_internal_forces_sum_to_zero_and_have_no_moment():
    rng = np.random.default_rng(2)
    pos = rng.normal(size=(30, 3)) * 3
    nodes = rng.integers(0, 30, size=(80, 2))
    nodes = nodes[nodes[:, 0] != nodes[:, 1]]
    rest = np.full(len(nodes), 1.0)
    cd = np.full(len(nodes), 50.0)
    vel = rng.normal(size=(30, 3))
    f, t, *_ = forces(pos, nodes, rest, np.full(len(nodes), EA), cd, vel)
    scale = np.abs(t).max()
    assert np.abs(f.sum(axis=0)).max() < 1e-9 * scale
    assert np.abs(np.cross(pos, f).sum(axis=0)).max() < 1e-8 * scale * 3


def test_damping_acts_only_in_tension_and_dissipates():
    pos, nodes, rest, ea, _ = chain(1, 1e-3)
    vel = np.zeros_like(pos)
    vel[1, 0] = 2.0  # elongating at 2 m/s
    cd = np.array([100.0])
    f, t, se, _, p = forces(pos, nodes, rest, ea, cd, vel)
    assert t[0] == pytest.approx(EA * 1e-3 + 200.0)
    assert p == pytest.approx(200.0 * 2.0)
    pos2, *_ = chain(1, -1e-3)  # slack: no damping force either
    f, t, *_ = forces(pos2, nodes, rest, ea, cd, vel)
    assert t[0] == 0.0


def test_contact_impulse_is_radial_and_keeps_node_outside():
    pos = np.array([[1.0, 0.0, 0.0]])
    vel = np.array([[-3.0, 2.0, 0.0]])
    m = np.array([2.0])
    lz0 = m[0] * (pos[0, 0] * vel[0, 1] - pos[0, 1] * vel[0, 0])
    w, diss = contact_node(0, pos, vel, np.zeros((1, 3)), m[0], 1.0, 0.0, 10.0, 0.0, 0.0,
                                0.1)
    p1 = pos[0] + 0.1 * vel[0]
    assert math.hypot(p1[0], p1[1]) == pytest.approx(1.0, rel=1e-12)
    assert m[0] * (pos[0, 0] * vel[0, 1] - pos[0, 1] * vel[0, 0]) == pytest.approx(lz0, rel=1e-14)
    # no force this step: the dissipation is the kinetic energy the impulse removed
    assert w == 0.0 and diss == pytest.approx(0.5 * m[0] * (13.0 - vel[0] @ vel[0]), rel=1e-12)


def test_contact_friction_moment_goes_to_the_hub():
    pos = np.array([[1.0, 0.0, 0.0]])
    vel = np.array([[-3.0, 2.0, 0.0]])
    m = np.array([2.0])
    j, w0 = 10.0, 0.5
    L0 = m[0] * (pos[0, 0] * vel[0, 1] - pos[0, 1] * vel[0, 0]) + j * w0
    w, diss = contact_node(0, pos, vel, np.zeros((1, 3)), m[0], 1.0, 0.3, j, w0, 0.0, 0.1)
    L1 = m[0] * (pos[0, 0] * vel[0, 1] - pos[0, 1] * vel[0, 0]) + j * w
    assert L1 == pytest.approx(L0, rel=1e-14)
    assert w > w0  # the sliding node drags the hub forward
    # and loses exactly the kinetic energy of node and hub that the impulses removed
    e0 = 0.5 * m[0] * 13.0 + 0.5 * j * w0 ** 2
    assert diss == pytest.approx(e0 - 0.5 * m[0] * (vel[0] @ vel[0]) - 0.5 * j * w * w, rel=1e-12)


@pytest.mark.parametrize("name,values,expect", [
    ("free", {}, (False, 0.0)),
    ("torque_feedback", {"M0": 100.0, "omega0": 4.0}, (False, 50.0)),
    ("constant_torque", {"torque": 7.0}, (False, 7.0)),
    ("spin_ramp", {"omega_max": 10.0, "ramp_time": 4.0}, (True, 5.0)),
])
def test_control_laws(name, values, expect):
    """Hand-computed values at t = 2 s, omega = 2 rad/s."""
    assert make_control(name, values).torque_or_rate(2.0, 2.0) == expect


@pytest.mark.parametrize("name", sorted(LAWS))
def test_kernel_branch_of_each_law_is_its_analytical_form(name):
    """The registry's analytical form and the kernel branch of every law agree at times and
    rates around the law's breaks (exactly: the same arithmetic)."""
    law = LAWS[name]
    params = np.array([1.7 + k for k in range(len(law.keys))] + [0.0])
    for t in (0.0, 0.3, 1.2, 2.69, 2.7, 2.71, 9.0):
        for w in (-3.0, 0.0, 0.4, 6.0):
            prescribed, value = eval_control(KernelLaw(law.code, params), t, w)
            assert prescribed == law.prescribes_rate
            expect = law.rate(params, t)[0] if prescribed else law.torque(params, t, w)
            assert value == expect, (name, t, w)


def test_the_step_loop_releases_the_gil():
    """The result writer's frame thread runs while a chunk runs (io.results)."""
    assert step.advance.targetoptions.get("nogil") is True
