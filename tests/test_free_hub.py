"""The free rigid hub (fe.hub.rigid, fe.free_step), the perturbations (case.perturb) and the
gravity gradient (fe.tidal), against closed forms and conservation laws.

Most scenes here are a hub with two 1 m tethers of negligible mass (1e-15 kg per node, so
the hub is, to 1e-14, a rigid body alone) or stiff tethers of negligible cable mass with a
tip mass (a pendulum on the rim). Their steps are set by the test, not by ``time.cfl``: the
cable's wave-speed step means nothing for massless cables, and the test chooses a step
small enough for the closed form it checks.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import prepare
from spinweb_fe.fe.tidal import MU_EARTH, body_tidal, orbit, tidal_accel, vertical
from spinweb_fe.record.energy import energy_balance
from spinweb_fe.record.history import quaternion_matrix
from spinweb_fe.run.loop import Schedule, simulate

R_ORBIT = 6.771e6  # [m] 400 km altitude
CASES = Path(__file__).resolve().parents[1] / "cases"


def hub_alone(omega, *, dt, end, inertia="", extra="", every=10, motion="free"):
    """History of a hub (free, or ``motion``) with two massless 1 m tethers, spinning at
    ``omega``."""
    text = f"""
[tethers]
count = 2
length = 1.0
elements = 1
[cable]
density = 1e-9
youngs_modulus = 1e-8
area = 1e-6
[tip_mass]
mass = 0.0
[fold]
pattern = "straight"
[hub]
motion = "{motion}"
radius = 1.0
mass = 10.0
{inertia}
[initial]
omega = {omega}
{extra}
[time]
end = {end}
[output]
history_dt = {dt * every}
frame_dt = 0
"""
    scene = prepare(case_mod.loads(text))
    return simulate(scene.model, scene.control, scene.state, dt,
                    Schedule(end, dt * every)).history


def in_plane_angle(b, normal):
    """Unwrapped angle [rad] of the vectors b (T, 3) about ``normal`` (their azimuth)."""
    e1 = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    return np.unwrap(np.arctan2(b @ e2, b @ e1))


def test_torque_free_axisymmetric_hub_cones_precesses_and_nutates():
    """I1 = I2 = 2, I3 = 3 kg m^2, spin 2 rad/s, transverse rate 0.1 rad/s: the spin axis
    cones about the fixed K at atan(I1 w_t / (I3 W3)), precesses at |K| / I1 in space, and
    the transverse rate turns in the body at W3 (I3 - I1) / I1. Each within 1e-4 at dt =
    2.5 ms (measured 3.5e-6, 2.3e-6, 7.0e-6: the splitting's O(dt^2), 1e-4 / 4 per halving
    of the step); K conserved to round-off (measured 9e-17); the energy error O(dt^2)
    (ratio 4.0 per halving)."""
    I1, I3, W3, wt = 2.0, 3.0, 2.0, 0.1
    errors = []
    for dt in (5e-3, 2.5e-3):
        h = hub_alone(W3, dt=dt, end=20.0, inertia=f"inertia = {I3}\ninertia_transverse = {I1}",
                      extra=f"[perturbation]\nhub_tilt_rate = {wt}")
        K, b, t = h["angular_momentum_vector"], h["hub_axis"], h["time"]
        k = K[0] / np.linalg.norm(K[0])
        assert np.max(np.linalg.norm(K - K[0], axis=1)) < 1e-14 * np.linalg.norm(K[0])
        assert np.allclose(np.linalg.norm(b, axis=1), 1.0, atol=1e-14)
        half = np.arccos(np.clip(b @ k, -1, 1)).mean()
        precession = np.polyfit(t, in_plane_angle(b, k), 1)[0]
        R = quaternion_matrix(h["hub_quaternion"])
        wb = np.einsum("tji,tj->ti", R, h["hub_angular_velocity"])  # body frame
        nutation = np.polyfit(t, np.unwrap(np.arctan2(wb[:, 1], wb[:, 0])), 1)[0]
        ke = h["kinetic_energy"]
        errors.append(np.ptp(ke) / ke[0])
    assert half == pytest.approx(math.atan(I1 * wt / (I3 * W3)), rel=1e-4)
    assert precession == pytest.approx(np.linalg.norm(K[0]) / I1, rel=1e-4)
    assert nutation == pytest.approx(W3 * (I3 - I1) / I1, rel=1e-4)
    assert 3.5 < errors[0] / errors[1] < 4.5  # second order in dt


@pytest.mark.parametrize("principal, tumbles", [([3.0, 1.5, 2.0], True),
                                                ([1.0, 1.5, 2.0], False)])
def test_a_hub_spun_about_its_intermediate_axis_tumbles(principal, tumbles):
    """Spin 2 rad/s about hub-frame z with a 1e-3 rad/s transverse rate: with I_z the
    intermediate moment the axis flips over (the Dzhanibekov effect: b3 . +z goes below -0.9
    within 30 s; the e-folding time 1/(W sqrt((I_x-I_z)(I_z-I_y)/(I_x I_y))) is 1.2 s); with
    I_z the largest it stays within 1e-3 rad of +z (the coning angle I_x w_t / (I_z W),
    5e-4 rad). K is conserved to round-off in both."""
    h = hub_alone(2.0, dt=2e-3, end=30.0, inertia=f"principal_inertia = {principal}",
                  extra="[perturbation]\nhub_tilt_rate = 1e-3")
    K = h["angular_momentum_vector"]
    assert np.max(np.linalg.norm(K - K[0], axis=1)) < 1e-13 * np.linalg.norm(K[0])
    bz = h["hub_axis"][:, 2]
    if tumbles:
        assert bz.min() < -0.9
    else:
        assert np.arccos(bz.min()) < 1e-3


def pendulum_case(n, motion, omega, inertia, end, perturb=""):
    """n stiff tethers of one 10 m element with a 10 kg tip on a 5 m hub (cable mass
    1e-8 kg, axial frequency 316 rad/s)."""
    return case_mod.loads(f"""
[tethers]
count = {n}
length = 10.0
elements = 1
[cable]
density = 1e-3
youngs_modulus = 1e12
area = 1e-6
[tip_mass]
mass = 10.0
[fold]
pattern = "straight"
[hub]
motion = "{motion}"
radius = 5.0
mass = 100.0
inertia = {inertia}
[initial]
omega = {omega}
{perturb}
[time]
end = {end}
[output]
history_dt = 2e-3
frame_dt = 0
""")


def crossing_frequency(t, y):
    """Angular frequency [rad/s] from the mean spacing of the zero crossings of y - mean."""
    y = y - y.mean()
    i = np.where(np.sign(y[:-1]) * np.sign(y[1:]) < 0)[0]
    tz = t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])
    assert len(tz) >= 10
    return math.pi / np.mean(np.diff(tz))


def kick_tips(mesh, state, speed):
    """Add ``speed`` [m/s] to every tip along its in-plane tangent (in-plane libration)."""
    for i in np.asarray(mesh.node_sets["tips"]):
        x = state.node_pos[i]
        state.node_vel[i] += speed * np.array([-x[1], x[0], 0.0]) / math.hypot(x[0], x[1])


def test_tether_on_a_steady_hub_librates_at_the_pendulum_frequencies():
    """One stiff light tether (L = 10 m, tip 10 kg) on a hub of r0 = 5 m held at 1 rad/s
    (1e12 kg m^2): in-plane libration Omega sqrt(r0/L) and out-of-plane oscillation
    Omega sqrt(1 + r0/L), within 1 % (measured 0.09 % and 0.05 %: the strain of 1.5e-3 and
    the finite amplitude). The out-of-plane motion comes from a [perturbation] vz of the
    tip (tilt about -y: the tether lies on x), the in-plane from a tangential kick."""
    W, r0, L = 1.0, 5.0, 10.0
    case = pendulum_case(1, "fixed_axis", W, 1e12, 60.0,
                         "[perturbation]\nshape = 'tilt'\nvz_amplitude = 0.01")
    scene = prepare(case)
    kick_tips(scene.mesh, scene.state, 0.01)
    assert scene.state.node_vel[scene.mesh.node_sets["tips"][0], 2] == pytest.approx(0.01)
    h = simulate(scene.model, scene.control, scene.state, 2e-3, Schedule(60.0, 2e-3)).history
    t, tip = h["time"], h["tip_position"][:, 0]
    K = h["angular_momentum_vector"]  # its z part is the scalar history's (hub included)
    assert np.allclose(K[:, 2], h["angular_momentum"], rtol=1e-12, atol=0)
    swing = np.unwrap(np.arctan2(tip[:, 1], tip[:, 0])) - h["hub_angle"]
    assert crossing_frequency(t, swing) == pytest.approx(W * math.sqrt(r0 / L), rel=1e-2)
    assert crossing_frequency(t, tip[:, 2]) == pytest.approx(W * math.sqrt(1 + r0 / L),
                                                             rel=1e-2)


def test_tethers_on_a_free_hub_librate_with_the_hub():
    """Two such tethers on a free hub of J = 1000 kg m^2 at 1 rad/s: the in-plane mode that
    swings both tips one way turns the hub the other, at
    Omega sqrt((r0/L)(J + n m (r0 + L)^2)/J) = 1.658 rad/s, within 2 % (measured 0.05 %)."""
    W, r0, L, J, m, n = 1.0, 5.0, 10.0, 1000.0, 10.0, 2
    scene = prepare(pendulum_case(n, "free", W, J, 60.0))
    kick_tips(scene.mesh, scene.state, 0.01)
    h = simulate(scene.model, scene.control, scene.state, 2e-3, Schedule(60.0, 2e-3)).history
    tip = h["tip_position"][:, 0] - h["hub_position"]
    swing = np.unwrap(np.arctan2(tip[:, 1], tip[:, 0])) - h["hub_angle"]
    expect = W * math.sqrt((r0 / L) * (J + n * m * (r0 + L) ** 2) / J)
    assert crossing_frequency(h["time"], swing) == pytest.approx(expect, rel=2e-2)
    assert np.max(np.abs(h["hub_axis"][:, 2] - 1.0)) < 1e-12  # it stays in the plane


def planar_tethers(motion, coiled, friction=0.0):
    """Four 20 m tethers on a 1e9 kg hub at 2 rad/s (the hub cannot be pushed sideways):
    straight under a constant torque of 500 N m, or held-coiled and free; ``friction``: the
    cable-hub contact's Coulomb coefficient."""
    return prepare(case_mod.loads(planar_text(motion, coiled, friction)))


def planar_text(motion, coiled, friction=0.0):
    """The case text of :func:`planar_tethers`."""
    if coiled:
        fold, control = "[fold]\npattern = 'coiled'\n[stowage]\ncoil = 'held'", "law = 'free'"
    else:
        fold, control = "[fold]\npattern = 'straight'", "law = 'constant_torque'\ntorque = 500.0"
    return f"""
[tethers]
count = 4
length = 20.0
elements = 20
{fold}
[hub]
motion = "{motion}"
mass = 1e9
inertia = 3969.0
friction = {friction}
[control]
{control}
[initial]
omega = 2.0
[time]
end = 0.3
[output]
frame_dt = 0
"""


def run_scene(scene, end=0.3):
    return simulate(scene.model, scene.control, scene.state, scene.dt,
                    Schedule(end, 1e-3)).history


def rel_diff(a, b, key, rows=None):
    """Largest |a - b| of a history dataset (over the first ``rows``) / largest |a|."""
    d = np.abs(a[key] - b[key]).reshape(len(a[key]), -1).max(axis=1)
    return (d if rows is None else d[:rows]).max() / np.max(np.abs(a[key]))


def test_fixed_and_free_hubs_agree_on_planar_runs():
    """Planar, symmetric scenes: a free hub neither tilts nor moves, and agrees with the
    fixed axis to round-off. Straight tethers under a constant torque: 1e-11 relative over
    the run (measured 8e-13). A held coil with contact, frictionless and with Coulomb
    friction 0.3 (which dissipates 36 times more in contact): 1e-11 to t = 0.1 s (measured
    3.8e-13 / 3.3e-13 for the hub rate), the contact dissipation 1e-9 (2.6e-10 / 4.2e-11);
    later, contact events amplify round-off (a threshold crossed a step earlier), so over
    the whole run the difference is bounded by 10 times what a 1e-15 change of the initial
    velocities does to the fixed-axis run itself (measured: up to 2x)."""
    a = run_scene(planar_tethers("fixed_axis", False))
    b = run_scene(planar_tethers("free", False))
    for key in ("hub_omega", "hub_angle", "kinetic_energy", "torque_work", "tip_position",
                "angular_momentum"):
        assert rel_diff(a, b, key) < 1e-11, key
    assert np.max(np.abs(b["hub_position"])) < 1e-12
    dissipated = []
    for friction in (0.0, 0.3):
        a = run_scene(planar_tethers("fixed_axis", True, friction))
        b = run_scene(planar_tethers("free", True, friction))
        for key in ("hub_omega", "tip_position", "kinetic_energy"):
            assert rel_diff(a, b, key, rows=100) < 1e-11, (friction, key)
        assert rel_diff(a, b, "contact_dissipation", rows=100) < 1e-9, friction
        nudged = planar_tethers("fixed_axis", True, friction)
        nudged.state.node_vel[:] *= 1 + 1e-15
        c = run_scene(nudged)
        assert rel_diff(a, c, "hub_omega") > 0  # the scene does amplify round-off
        for key in ("hub_omega", "tip_position"):
            assert rel_diff(a, b, key) < 10 * rel_diff(a, c, key), (friction, key)
        assert np.max(np.abs(b["hub_position"])) < 1e-9
        assert np.max(np.abs(b["hub_axis"][:, 2] - 1.0)) < 1e-14
        dissipated.append(b["contact_dissipation"][-1])
    assert dissipated[1] > 10 * dissipated[0]  # the friction acts


def test_tidal_force_and_torque_are_those_of_the_points():
    """The body's tidal force M g(X) and torque 3 n^2 e x (I_s e) equal the sums over a cloud
    of point masses of m g(x) and m (x - X) x g(x) (the field is linear in x, so the
    identity is exact: 1e-12 relative, round-off of 200 terms)."""
    rng = np.random.default_rng(3)
    env = orbit(R_ORBIT, 0.4)
    x = rng.normal(size=(200, 3)) * [30.0, 20.0, 5.0] + [3.0, -2.0, 1.0]
    m = rng.uniform(0.1, 2.0, 200)
    M = m.sum()
    X = (m[:, None] * x).sum(axis=0) / M
    r = x - X
    Is = np.eye(3) * np.sum(m * np.sum(r * r, axis=1)) - (m[:, None] * r).T @ r
    t = 1234.5
    e = vertical(env, t)
    g = np.array([tidal_accel(env.n ** 2, e, *xi) for xi in x])
    F, T = body_tidal(env, t, M, X, Is)
    assert np.allclose(F, (m[:, None] * g).sum(axis=0), rtol=0, atol=1e-12 * np.abs(F).max())
    Tp = (m[:, None] * np.cross(r, g)).sum(axis=0)
    assert np.allclose(T, Tp, rtol=0, atol=1e-12 * np.abs(Tp).max())
    assert env.n == pytest.approx(math.sqrt(MU_EARTH / R_ORBIT ** 3), rel=1e-15)


def test_the_gravity_gradient_precesses_a_spinning_hub_about_the_orbit_normal():
    """An axisymmetric hub (I_t = 2, I_s = 3 kg m^2) spinning at 0.2 rad/s with its axis 30
    degrees from the orbit normal N, over one orbit at 400 km: the orbit-averaged torque
    -(3/2) n^2 (I_s - I_t) cos(beta) N x b turns the axis about N at
    -(3/2) (n^2 / W) ((I_s - I_t) / I_s) cos(beta) (retrograde for a disc-like hub); the
    angle it turns over exactly one orbit (the 2n terms average out) within 1 % (measured
    0.3 %: the first-order averaging neglects terms of order n / W = 6e-3). The axis stays
    at 30 degrees from N within 0.1 degree."""
    I_t, I_s, W, beta = 2.0, 3.0, 0.2, math.radians(30.0)
    n = math.sqrt(MU_EARTH / R_ORBIT ** 3)
    period = 2 * math.pi / n
    dt = period / 55000
    h = hub_alone(W, dt=dt, end=period, every=100,
                  inertia=f"inertia = {I_s}\ninertia_transverse = {I_t}",
                  extra=f"[environment]\ngravity_gradient = true\norbit_radius = {R_ORBIT}\n"
                        f"orbit_tilt = {beta}")
    N = np.array([0.0, -math.sin(beta), math.cos(beta)])  # e1 x e2 of fe.tidal.orbit
    b = h["hub_axis"]
    assert h["time"][-1] == pytest.approx(period, abs=2 * dt)
    turned = in_plane_angle(b, N)
    expect = -1.5 * n * n / W * (I_s - I_t) / I_s * math.cos(beta) * h["time"][-1]
    assert turned[-1] - turned[0] == pytest.approx(expect, rel=1e-2)
    cone = np.degrees(np.arccos(np.clip(b @ N, -1, 1)))
    assert np.max(np.abs(cone - 30.0)) < 0.1


@pytest.mark.parametrize("motion", ["free", "fixed_axis"])
def test_the_energy_balance_counts_the_gravity_gradient_work(motion):
    """Two 50 m tethers with 10 kg tips on a hub spinning at 0.02 rad/s, free or on a fixed
    axis (which does no work: it holds the hub's tilt and place, not its turn), a quarter
    of a 400 km orbit (1386 s): the tidal field does 0.13 J of work against 13.9 J of
    kinetic energy; KE + SE - W_torque - W_gravity + D stays constant to O(dt^2) (drift
    8.2e-5 J at cfl 0.8, 1.9e-5 J at 0.4 on either hub: below 1e-3 of the work, ratio 4.2
    per halving)."""
    drift = []
    for cfl in (0.8, 0.4):
        scene = prepare(case_mod.loads(f"""
[tethers]
count = 2
length = 50.0
elements = 5
[cable]
youngs_modulus = 1e7
[fold]
pattern = "straight"
[hub]
motion = "{motion}"
[initial]
omega = 0.02
[environment]
gravity_gradient = true
altitude = 400e3
orbit_tilt = 0.5
[time]
end = 1386.0
cfl = {cfl}
[output]
history_dt = 1.0
frame_dt = 0
"""))
        h = run_scene(scene, 1386.0)
        e = energy_balance(h)
        drift.append(np.max(np.abs(e - e[0])))
        work = np.ptp(h["gravity_gradient_work"])
        assert work > 0.1
    assert drift[0] < 1e-3 * work
    assert 3.0 < drift[0] / drift[1] < 5.0


def test_a_fixed_axis_holds_the_tidal_torque_of_its_hub():
    """A hub alone (two massless 1 m tethers) on a fixed axis in an orbit whose normal is
    tilted 0.5 rad from the spin axis: the axis exerts minus the hub's tidal torque,
    -3 n^2 (J - I_t) e_z (e_y, -e_x, 0) with e(t) the local vertical (1e-9 relative: the
    closed form of an axisymmetric body; measured 1e-14), and the hub's rate stays (its own
    tidal torque has no part about its axis)."""
    h = hub_alone(2.0, dt=0.01, end=200.0, every=500, inertia="inertia = 3.0\n"
                  "inertia_transverse = 2.0", extra=f"[environment]\ngravity_gradient = true\n"
                  f"orbit_radius = {R_ORBIT}\norbit_tilt = 0.5", motion="fixed_axis")
    env = orbit(R_ORBIT, 0.5)
    e = np.array([vertical(env, t) for t in h["time"]])
    expect = -3.0 * env.n ** 2 * (3.0 - 2.0) * e[:, 2:3] * np.column_stack(
        [e[:, 1], -e[:, 0], np.zeros(len(e))])
    got = h["axis_torque"]
    assert np.max(np.abs(expect)) > 1e-7
    assert np.max(np.abs(got - expect)) < 1e-9 * np.max(np.abs(expect))
    assert np.ptp(h["hub_omega"]) < 1e-12


def test_fixed_and_heavy_free_hubs_agree_in_the_gravity_gradient():
    """The planar tethers of test_fixed_and_free_hubs_agree_on_planar_runs in a 400 km
    orbit in their plane, the hub on a fixed axis and free (1e9 kg): two independent codes
    of the tidal field (the fixed axis's per node, the free body's as the body's force and
    torque) agree on the hub rate, the tips and the field's work to 1e-11 relative
    (measured 3e-13, 8e-16, 1.6e-12)."""
    runs = {}
    for motion in ("fixed_axis", "free"):
        text = planar_text(motion, False) + ("[environment]\ngravity_gradient = true\n"
                                            f"orbit_radius = {R_ORBIT}\n")
        runs[motion] = run_scene(prepare(case_mod.loads(text.replace("end = 0.3",
                                                                     "end = 0.1"))), 0.1)
    a, b = runs["fixed_axis"], runs["free"]
    assert np.ptp(a["gravity_gradient_work"]) > 0.0
    for key in ("hub_omega", "tip_position", "kinetic_energy", "gravity_gradient_work"):
        assert rel_diff(a, b, key) < 1e-11, key


def web_case(sets):
    return case_mod.load(Path(__file__).resolve().parents[1] / "cases" / "paper_free_web.toml",
                         ["time.end=0.2", *sets])


def flat_web(sets):
    """The paper's 100 m web, flat (deployed), 2.5 m mesh."""
    return case_mod.loads("[web]\n[fold]\npattern = 'flat'\n[time]\nend = 0.1\n", list(sets))


def test_tilt_turns_the_web_rigidly_so_its_tips_reach_the_amplitude():
    """shape = tilt on the flat web: the tips reach +-z_amplitude (1e-12 m), the tied nodes
    stay in the hub plane, every element keeps its length (a rigid turn), vz_amplitude
    gives the tips the matching rate, and the spin velocity is that of the turned
    positions (so the web has no linear momentum: 1e-9 of its sum m |v|)."""
    case = flat_web(["perturbation.z_amplitude=2.0", "perturbation.vz_amplitude=0.5"])
    scene = prepare(case)
    pos, vel, mesh = scene.state.node_pos, scene.state.node_vel, scene.mesh
    tips = np.asarray(mesh.node_sets["tips"])
    assert np.max(np.abs(pos[tips, 2])) == pytest.approx(2.0, abs=1e-12)
    assert np.all(pos[mesh.node_sets["hub_tied"], 2] == 0.0)
    el = scene.model.elements.nodes
    flat = np.asarray(mesh.node_pos)
    before = np.linalg.norm(flat[el[:, 1]] - flat[el[:, 0]], axis=1)
    after = np.linalg.norm(pos[el[:, 1]] - pos[el[:, 0]], axis=1)
    web = scene.model.nodes.inv_mass > 0
    inside = web[el[:, 0]] & web[el[:, 1]]
    assert np.allclose(after[inside], before[inside], rtol=0, atol=1e-12)
    assert np.max(np.abs(vel[tips, 2])) == pytest.approx(0.5 * math.cos(math.asin(2 / 50)),
                                                         rel=1e-12)
    free = scene.state.node_inv_mass > 0  # the spin of the turned positions
    omega = case.initial.omega
    assert np.allclose(vel[free, 0], -omega * pos[free, 1], rtol=0, atol=1e-9)
    m = scene.state.node_mass[free]
    p = (m[:, None] * vel[free]).sum(axis=0)  # a symmetric web turned rigidly: no momentum
    assert np.linalg.norm(p) < 1e-9 * np.sum(m * np.linalg.norm(vel[free], axis=1))


def test_random_shape_is_reproducible_and_zero_at_the_hub():
    """shape = random: the same seed gives the same field bit for bit, another seed another;
    max |z| over the web is z_amplitude, the field is 0 at the hub ties, smooth (no element
    changes its length by more than 1 % of z_amplitude over a 2.5 m element... the field's
    shortest wavelength is half the web's radius)."""
    def z(seed):
        return prepare(flat_web(["perturbation.shape='random'", "perturbation.z_amplitude=1.0",
                                 f"perturbation.seed={seed}"])).state.node_pos[:, 2].copy()
    a, b, c = z(7), z(7), z(8)
    assert np.array_equal(a, b) and not np.allclose(a, c)
    assert np.max(np.abs(a)) == pytest.approx(1.0, rel=1e-12)
    mesh = prepare(flat_web([])).mesh
    assert np.all(a[mesh.node_sets["hub_tied"]] == 0.0)
    el = np.asarray(mesh.elem_nodes)
    assert np.max(np.abs(a[el[:, 1]] - a[el[:, 0]])) < 0.5  # 2.5 m elements, wavelength >= 18 m


def test_mode_shape_is_the_lowest_out_of_plane_mode_and_rings_at_its_frequency():
    """shape = mode on one straight tether (20 elements, tip 10 kg) on a driven hub at
    2 rad/s: z is the lowest out-of-plane mode of spinweb modes (same shape, 1e-9), and the
    run, started in the plane from the steady (stretched) state with that z, oscillates at
    that mode's frequency within 1 % (from the tip's zero crossings; the amplitude 1 cm is
    linear). From the unstretched state the axial ringing would modulate the tension by
    +-100 % and shift the frequency by 20 %."""
    from spinweb_fe.run.modal import analyse

    text = """
[tethers]
count = 1
length = 30.0
elements = 20
[fold]
pattern = "straight"
[hub]
inertia = 1e12
[initial]
omega = 2.0
[perturbation]
shape = "mode"
z_amplitude = 0.01
[time]
end = 30.0
[output]
frame_dt = 0
history_dt = 2e-3
"""
    case = case_mod.loads(text)
    scene = prepare(case)
    modes = analyse(case, 2.0, 6).modes
    k = int(np.flatnonzero(modes.kind == "out_of_plane")[0])
    shape = modes.shape[k][:, 2]
    z = scene.state.node_pos[:, 2]
    ratio = z[np.abs(shape) > 1e-3] / shape[np.abs(shape) > 1e-3]
    assert np.ptp(ratio) < 1e-9 * np.abs(ratio).max()
    assert np.max(np.abs(z)) == pytest.approx(0.01, rel=1e-12)
    analysis = analyse(case, 2.0, 1)
    xy = analysis.steady.position[:, :2]
    scene.state.node_pos[:, :2] = xy
    scene.state.node_vel[:, 0] = -2.0 * xy[:, 1]
    scene.state.node_vel[:, 1] = 2.0 * xy[:, 0]
    h = run_scene(scene, 30.0)
    assert np.ptp(h["max_tension"]) < 0.02 * h["max_tension"].mean()
    tip = h["tip_position"][:, 0, 2]
    assert crossing_frequency(h["time"], tip) == pytest.approx(modes.frequency[k], rel=1e-2)


def test_tip_mass_scale_and_delay_make_one_arm_different():
    """tip_mass_scale = 3 on arm 2 triples that tip's point mass only; delay = 0.1 s on arm 1
    holds its whole coil on the hub until 0.1 s while the others pay out, then lets it go;
    the run keeps its energy balance (0.1 %) and the arm's payout front starts after 0.1 s."""
    base = prepare(web_case([]))
    scene = prepare(web_case(["perturbation.arm=2", "perturbation.tip_mass_scale=3.0"]))
    dm = scene.model.nodes.mass - base.model.nodes.mass
    tips = np.asarray(base.mesh.node_sets["tips"])
    tip2 = tips[base.mesh.node_arm[tips] == 2]
    assert np.allclose(dm[tip2], 2 * base.mesh.node_point_mass[tip2], rtol=1e-14)
    assert np.count_nonzero(dm) == len(tip2)
    scene = prepare(web_case(["perturbation.arm=1", "perturbation.delay=0.1",
                              "time.end=0.2"]))
    h = run_scene(scene, 0.2)
    front = h["payout_front"]
    t = h["time"]
    held = t < 0.1 - 1e-9
    assert np.all(front[held, 1] == front[0, 1])
    assert np.all(front[held][-1, [0, 2, 3]] < front[0, [0, 2, 3]])  # measured from the root
    assert front[-1, 1] < front[0, 1]
    e = energy_balance(h)
    assert np.max(np.abs(e - e[0])) < 1e-3 * e[0]


def test_a_perturbed_web_on_a_free_hub_keeps_its_momenta_and_energy():
    """The paper's free deployment on a free hub with a 1 m tilt and a 0.01 rad/s hub tilt
    rate, to 0.3 s, frictionless and with Coulomb friction 0.3 on the hub: the web leaves
    the plane (max |z| from the hub plane grows past 1 m), the hub's axis tilts; linear and
    angular momentum vectors are conserved to round-off (1e-11 relative, measured 1.2e-14 /
    1.0e-14: every contact impulse, normal and tangential, acts on node and hub alike), the
    energy balance within 0.1 % (measured 6.5e-4 / 2.9e-4, as the fixed-axis run's contact
    transitions) with the friction's loss booked (contact dissipation 26 kJ / 108 kJ)."""
    lost = []
    for friction in (0.0, 0.3):
        scene = prepare(web_case(["time.end=0.3", "hub.motion='free'",
                                  "perturbation.z_amplitude=1.0",
                                  "perturbation.hub_tilt_rate=0.01",
                                  f"hub.friction={friction}"]))
        h = run_scene(scene, 0.3)
        L = h["angular_momentum_vector"]
        assert np.max(np.linalg.norm(L - L[0], axis=1)) < 1e-11 * np.linalg.norm(L[0])
        P = h["linear_momentum"]
        assert np.max(np.linalg.norm(P, axis=1)) < 1e-11 * np.linalg.norm(L[0]) / 50.0
        assert h["out_of_plane_max"].max() > 1.0
        assert np.degrees(np.arccos(h["hub_axis"][:, 2].min())) > 0.5
        e = energy_balance(h)
        assert np.max(np.abs(e - e[0])) < 1e-3 * e[0]
        lost.append(h["contact_dissipation"][-1])
    assert lost[1] > 2 * lost[0]


def test_a_free_hub_run_continues_bit_identically_from_its_checkpoint(tmp_path):
    """Stop a free-hub run with a held coil, a tilt and the gravity gradient at a checkpoint
    (0.1 s) and continue it to 0.2 s: every history dataset, the vector ones included, is
    identical to the uninterrupted run's (the body's state is in the checkpoint)."""
    import h5py

    from spinweb_fe.cli import main

    case = tmp_path / "free.toml"
    case.write_text("""
[tethers]
count = 3
length = 20.0
elements = 20
[hub]
motion = "free"
principal_inertia = [2500.0, 3000.0, 4000.0]
[perturbation]
hub_tilt_rate = 0.05
vz_amplitude = 0.1
[environment]
gravity_gradient = true
altitude = 400e3
[initial]
omega = 3.0
[time]
end = 0.2
[output]
frame_dt = 0.05
""")
    whole, part = tmp_path / "whole", tmp_path / "part"
    common = [str(case), "--no-progress", "--checkpoint-dt", "0.05"]
    assert main(["run", *common, "-o", str(whole)]) == 0
    assert main(["run", *common, "-o", str(part), "--set", "time.end=0.1"]) == 0
    assert main(["run", "--restart", str(part), "--set", "time.end=0.2", "--no-progress"]) == 0
    with h5py.File(whole / "results.h5") as a, h5py.File(part / "results.h5") as b:
        assert "hub_quaternion" in a["history"] and "gravity_gradient_work" in a["history"]
        assert set(a["history"]) == set(b["history"])
        for key in a["history"]:
            assert np.array_equal(a["history"][key][()], b["history"][key][()]), key
        assert a["history/hub_axis"][-1, 2] < 1.0  # it did nutate


def test_the_out_of_plane_panels(tmp_path, capsys):
    """spinweb plot --panels out_of_plane draws a free-hub run's distance from the hub
    plane, tip heights, hub tilt and transverse rate (a picture with ink on each of the four
    panels); a planar fixed-axis result has no such histories: one line, exit 2."""
    import matplotlib.image as mpimg

    from spinweb_fe.cli import main

    case = tmp_path / "c.toml"
    case.write_text("[tethers]\ncount = 3\nlength = 20.0\nelements = 10\n[hub]\n"
                    "motion = 'free'\n[perturbation]\nhub_tilt_rate = 0.05\n[time]\n"
                    "end = 0.05\n[output]\nframe_dt = 0\n")
    assert main(["run", str(case), "-o", str(tmp_path / "free"), "--no-progress"]) == 0
    out = tmp_path / "oop.png"
    assert main(["plot", str(tmp_path / "free" / "results.h5"), "-o", str(out),
                 "--panels", "out_of_plane"]) == 0
    img = mpimg.imread(out)[..., :3]
    h, w = img.shape[:2]
    for quarter in (img[:h // 2, :w // 2], img[:h // 2, w // 2:], img[h // 2:, :w // 2],
                    img[h // 2:, w // 2:]):
        assert np.mean(quarter.sum(axis=2) < 2.0) > 0.005  # lines and labels on each panel
    case.write_text(case.read_text().replace("motion = 'free'", "motion = 'fixed_axis'")
                    .replace("hub_tilt_rate = 0.05", ""))
    assert main(["run", str(case), "-o", str(tmp_path / "fixed"), "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["plot", str(tmp_path / "fixed" / "results.h5"), "-o", str(out),
                 "--panels", "out_of_plane"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no out-of-plane histories" in err[0]


def test_the_spin_ramp_prescribes_the_body_axis_rate_of_a_nutating_hub():
    """A spin ramp (0 -> 4 rad/s over 1 s) on a free, nutating hub (transverse rate
    0.05 rad/s) with three tethers: the body-axis rate b3 . omega follows the law at every
    row to 1e-9 rad/s (the torque about b3 is chosen each step to give the law's rate at the
    half step; the row's rate is the mean of the half steps, exact for a linear ramp), the
    torque acts about b3 only, and the energy balance (torque work included) holds to
    1e-3."""
    scene = prepare(case_mod.loads("""
[tethers]
count = 3
length = 20.0
elements = 10
[fold]
pattern = "straight"
[hub]
motion = "free"
[control]
law = "spin_ramp"
omega_max = 4.0
ramp_time = 1.0
[initial]
omega = 0.0
[perturbation]
hub_tilt_rate = 0.05
[time]
end = 0.8
[output]
frame_dt = 0
"""))
    h = run_scene(scene, 0.8)
    t = h["time"]
    w3 = np.einsum("td,td->t", h["hub_axis"], h["hub_angular_velocity"])
    assert np.max(np.abs(w3 - 4.0 * t)[1:]) < 1e-9
    assert np.max(np.abs(h["hub_omega"] - w3)) < 1e-12
    e = energy_balance(h)
    assert np.max(np.abs(e - e[0])) < 1e-3 * h["torque_work"].max()
    assert np.degrees(np.arccos(h["hub_axis"][:, 2].min())) > 0.1  # it does nutate


def test_a_torque_about_the_body_axis_spins_a_nutating_hub_up_and_calms_it():
    """Constant torque M = 0.6 N m about the body axis of a nutating axisymmetric hub (I1 = 2,
    I3 = 3 kg m^2, spin 2 rad/s, transverse 0.1 rad/s), 10 s: Euler's equations keep the
    body-frame transverse rate at 0.1 rad/s (measured within 1.1e-6) while the axial rate
    grows as W + M t / I3 (within 1e-7: measured 1.5e-8, the splitting's O(dt^2)), so the
    nutation angle falls to atan(I1 w_t / (I3 w3(t)))
    (within 1 %: the mean over the last 5 rows)."""
    I1, I3, W, wt, M = 2.0, 3.0, 2.0, 0.1, 0.6
    h = hub_alone(W, dt=2e-3, end=10.0, inertia=f"inertia = {I3}\ninertia_transverse = {I1}",
                  extra=f"[perturbation]\nhub_tilt_rate = {wt}\n[control]\n"
                        f"law = 'constant_torque'\ntorque = {M}")
    R = quaternion_matrix(h["hub_quaternion"])
    wb = np.einsum("tji,tj->ti", R, h["hub_angular_velocity"])
    assert np.max(np.abs(np.hypot(wb[:, 0], wb[:, 1]) - wt)) < 1e-5
    assert np.max(np.abs(wb[:, 2] - (W + M / I3 * h["time"]))) < 1e-7
    K, b = h["angular_momentum_vector"], h["hub_axis"]
    angle = np.arccos(np.einsum("td,td->t", b, K) / np.linalg.norm(K, axis=1))
    end = W + M / I3 * h["time"][-1]
    assert angle[-5:].mean() == pytest.approx(math.atan(I1 * wt / (I3 * end)), rel=1e-2)


def _moved(scene, tilt, shift):
    """The scene's initial state turned by ``tilt`` [rad] about +x and moved by ``shift``
    (3,) [m]: positions, velocities, and the free body's centre, momenta and attitude."""
    c, s = math.cos(tilt), math.sin(tilt)
    Q = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    st, rs = scene.state, scene.state.rigid
    st.node_pos[:] = st.node_pos @ Q.T + shift
    st.node_vel[:] = st.node_vel @ Q.T
    rs.position[:] = Q @ rs.position + shift
    rs.velocity[:] = Q @ rs.velocity
    rs.momentum[:] = Q @ rs.momentum
    w1, x1 = math.cos(tilt / 2), math.sin(tilt / 2)
    w2, x2, y2, z2 = rs.quaternion
    rs.quaternion[:] = [w1 * w2 - x1 * x2, w1 * x2 + x1 * w2, w1 * y2 - x1 * z2,
                        w1 * z2 + x1 * y2]
    return Q


def test_a_moved_and_tilted_free_hub_releases_its_coil_as_the_upright_one():
    """The held coil's release test looks outward from the hub's own axis (fe.coil.levels.pulls
    in the hub frame): the paper's coiled tethers on a free hub, and the same scene moved
    by 2 m and tilted by 0.1 rad, release their levels at the same steps (15 levels per
    arm in 0.1 s), and the tips follow the transformed paths to round-off of the
    transformation: 1e-9 of the arm length (measured 2e-12 m at 0.1 s; the slack arms on
    the free hub amplify round-off about tenfold per 10 ms after that, so the window stops
    there). With the release test about the world's z axis the moved scene's fronts go at
    other steps from the third row on, and its tips are 1e-3 m off at the fifth."""
    def scene():
        return prepare(case_mod.load(CASES / "paper_free_arms.toml",
                                     ["hub.motion='free'", "time.end=0.1"]))

    upright, moved = scene(), scene()
    shift = np.array([2.0, -0.5, 1.0])
    Q = _moved(moved, 0.1, shift)
    a = simulate(upright.model, upright.control, upright.state, upright.dt,
                 Schedule(0.1, 1e-3)).history
    b = simulate(moved.model, moved.control, moved.state, moved.dt, Schedule(0.1, 1e-3)).history
    fronts = a["payout_front"]
    assert fronts[-1].max() < fronts[0].min() - 10.0  # the arms paid out many levels
    np.testing.assert_array_equal(b["payout_front"], fronts)
    back = (b["tip_position"] - shift) @ Q
    assert np.max(np.abs(back - a["tip_position"])) < 1e-9 * 50.0
    for key in ("hub_omega", "kinetic_energy", "strain_energy", "max_tension"):
        assert rel_diff(a, b, key) < 1e-9, key


@pytest.mark.parametrize("tilt", [0.0, 0.3])
def test_the_contact_predicts_the_hub_centre_about_an_offset_centre_of_mass(tilt):
    """fe.hub.body.hull_of: the hub centre the node pass tests contact against at t + dt, for a
    body whose centre of mass lies 0.8 m off the hub centre (an unbalanced web) and turns at
    25 rad/s: within dt^2 omega^2 |c| of the exact rigid motion (the centre turns about the
    centre of mass; a prediction that only translates it is off by dt omega |c|)."""
    from spinweb_fe.fe.hub.body import hull_of
    from spinweb_fe.fe.hub.rigid import RigidState, rotation

    dt, w = 1e-4, np.array([tilt, 0.0, 25.0])
    q = np.array([np.cos(0.2), 0.0, np.sin(0.2) * np.sin(0.4), np.sin(0.2) * np.cos(0.4)])
    com = np.array([0.8, 0.0, 0.0])  # hub frame: the centre of mass off the hub centre
    rs = RigidState(np.array([1.0, -2.0, 0.5]), np.array([0.3, 0.1, -0.2]), q, np.zeros(3),
                    np.ones(1), com, np.eye(3), np.eye(3), np.ones(3))
    R = rotation(q)
    hull = hull_of(rs, R, w, dt)
    # exact: X moves with V, the body turns by dt |w| about w (Rodrigues)
    angle = dt * np.linalg.norm(w)
    k = w / np.linalg.norm(w)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    turn = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    exact = rs.position + dt * rs.velocity - turn @ R @ com
    assert np.allclose(hull[0], rs.position - R @ com, rtol=0, atol=1e-15)
    assert np.linalg.norm(hull[2] - exact) < dt * dt * 625.0 * 0.8  # O(dt^2), vs dt w |c|
