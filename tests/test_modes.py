"""``spinweb modes``: the steady spinning state and the small vibrations about it, against
closed forms (the spinning pendulum, the spinning string's Legendre modes, statically
determinate tensions), a convergence rate, the explicit solver, and the command line."""

import math

import h5py
import meshio
import numpy as np
import pytest
from closed_forms import quadquad_line_tensions, string_structure

from meshgen.mesh import lumped_mass
from meshgen.tethers import tethers
from spinweb_fe import case as case_mod
from spinweb_fe.case.scene import deployed, prepare
from spinweb_fe.cli import main
from spinweb_fe.errors import InputError, RunError
from spinweb_fe.linear.modes import InPlane, compute_modes
from spinweb_fe.linear.steady import (Structure, check_mechanism, hub_forces,
                                      solve_steady)
from spinweb_fe.run.modal import analyse, sweep
from spinweb_fe.record.recorders import Recorder
from spinweb_fe.run.loop import Schedule, simulate

E, RHO, AREA = 180e9, 1540.0, 1.025e-5  # Zylon
R0, H = 6.3, 50.0


def tether_case(omega, count=1, elements=20, tip=10.0, E=E, rho=RHO, r0=R0, extra=""):
    return case_mod.loads(f"""
[tethers]
count = {count}
length = {H}
elements = {elements}
[cable]
youngs_modulus = {E!r}
density = {rho!r}
area = {AREA!r}
[tip_mass]
mass = {tip!r}
[hub]
radius = {r0!r}
[fold]
pattern = "straight"
[initial]
omega = {omega!r}
[time]
end = 1.0
[output]
frame_dt = 0
{extra}""")


WEB_CASE = """
[web]
side = 20.0
mesh_width = 2.5
[cable]
youngs_modulus = {E!r}
[tip_mass]
mass = 1.0
[hub]
radius = 2.5
[initial]
omega = {omega!r}
[time]
end = 1.0
"""


# --- closed forms -------------------------------------------------------------------------

@pytest.mark.parametrize("omega, count, tol", [(2.0, 1, 5e-6), (8 * math.pi, 3, 7e-4)])
def test_stiff_light_tether_is_a_spinning_pendulum(omega, count, tol):
    """Massless rod of length L with a tip mass, root on the driven hub at r0: in-plane
    omega sqrt(r0 / L), out-of-plane omega sqrt(1 + r0 / L) (each tether alike). Bounds
    1.5x docs/modes.md's measured 3e-6 (2 rad/s) and 4.4e-4 (8 pi: the cable stretches)."""
    case = tether_case(omega, count, tip=10.0, E=1000 * E, rho=1e-3)
    res = analyse(case, omega, 2 * count, "driven")
    md = res.modes
    for kind, ref in (("in_plane", math.sqrt(R0 / H)), ("out_of_plane", math.sqrt(1 + R0 / H))):
        got = md.ratio[md.kind == kind]
        assert len(got) == count, md.kind
        assert np.allclose(got, ref, rtol=tol), (kind, got, ref)
    assert np.all(md.growth == 0)
    assert np.max(np.abs(md.material_share)) < 1e-3  # pendulum: stiffness all from tension


def legendre_errors(m):
    st_s = string_structure(m)
    st = solve_steady(st_s, 2.0)
    md = compute_modes(st_s, st, 6)
    out = md.ratio[md.kind == "out_of_plane"]
    inp = md.ratio[md.kind == "in_plane"]
    l_odd = np.array([1, 3, 5])
    ref_out = np.sqrt(l_odd * (l_odd + 1) / 2)
    ref_in = np.sqrt(l_odd * (l_odd + 1) / 2 - 1)
    return out[:3], inp[:3], ref_out, ref_in


def test_spinning_string_legendre_modes_converge_at_second_order():
    """A uniform string rooted on the axis with a free end: out-of-plane omega_l / Omega =
    sqrt(l (l + 1) / 2) and in-plane sqrt(l (l + 1) / 2 - 1), l odd. Lumped masses converge
    at second order in the element size (observed orders 1.99-2.00 for m = 20..80)."""
    ms = np.array([20, 40, 80])
    err_out, err_in = [], []
    for m in ms:
        out, inp, ref_out, ref_in = legendre_errors(m)
        assert inp[0] < 1e-4  # the rigid rotation about the root on the axis: a zero mode
        err_out.append(np.abs(out - ref_out) / ref_out)
        err_in.append(np.abs(inp[1:] - ref_in[1:]) / ref_in[1:])
    err_out, err_in = np.array(err_out), np.array(err_in)
    assert np.all(err_out[:, 0] < 1e-7)  # l = 1 is the rigid tilt, exact at any m
    for e in (*err_out[:, 1:].T, *err_in.T):
        slope = np.polyfit(np.log(ms), np.log(e), 1)[0]
        print(f"relative errors {e}, observed order {-slope:.3f}")
        assert -2.05 < slope < -1.95, (slope, e)
        assert e[-1] < 2e-3


def test_steady_tensions_of_the_square_grid_are_its_statics():
    """1000x Zylon web (S = 20 m, t = 2.5 m, 1 kg corners) on a hub: every cable carries the
    centrifugal pull of its own mesh line beyond it (tests/closed_forms.py)."""
    omega = 2.0
    case = case_mod.loads(WEB_CASE.format(E=1000 * E, omega=omega))
    mesh, s = deployed(case)
    st = solve_steady(s, omega)
    ref = quadquad_line_tensions(mesh, omega, RHO * AREA)
    web = ~np.isin(s.elem_nodes, s.tied_idx).all(axis=1)  # not the hub frame
    assert np.max(np.abs(st.tension - ref)[web]) < 1e-6 * ref.max()
    assert len(st.slack) == 0 and st.residual < 1e-6


def test_straight_tether_root_tension():
    """Root reaction omega^2 [m_c (r0 + H) + rho A (r0 H + H^2 / 2)] (stiff cable: the
    3e-6 strain moves the tip out by 2.5e-6 of its radius)."""
    omega, mc = 3.0, 10.0
    case = tether_case(omega, 4, elements=25, tip=mc, E=1000 * E)
    mesh, s = deployed(case)
    st = solve_steady(s, omega)
    root = np.hypot(*hub_forces(s, st).T)
    ref = omega ** 2 * (mc * (R0 + H) + RHO * AREA * (R0 * H + H * H / 2))
    assert np.allclose(root, ref, rtol=1e-5)


def test_finite_strain_single_cable():
    """One Zylon element with a tip mass m at 10 % strain: N = EA (l / L0 - 1) =
    m omega^2 (r0 + l), so l = (EA + m omega^2 r0) / (EA / L0 - m omega^2)."""
    mesh = tethers(1, H, 1, R0, 200.0, "straight")
    ea = E * AREA
    s = Structure(np.array(mesh.node_ref), lumped_mass(mesh, 0.0), np.array(mesh.elem_nodes),
                  np.array(mesh.elem_rest_len), np.array([ea]), np.array([0]), 1.0)
    omega = math.sqrt(0.1 * ea / (200.0 * (R0 + 1.1 * H)))
    st = solve_steady(s, omega)
    l_ref = (ea + 200.0 * omega ** 2 * R0) / (ea / H - 200.0 * omega ** 2)
    assert st.position[1, 0] - R0 == pytest.approx(l_ref, rel=1e-12)
    assert st.max_strain == pytest.approx(0.1, rel=1e-2) and st.residual < 1e-10


def rigid_rotation(mats, st, hub):
    """(d,) reduced vector of the rigid rotation of everything, every node moving by J p
    (with the hub coasting, a null vector of K)."""
    xy = st.position[:, :2]
    q = mats.T.T @ np.column_stack([-xy[:, 1], xy[:, 0]]).ravel()
    if hub == "coasting":
        q[-1] = 1.0
    return q


def test_coasting_hub_rigid_rotation_is_a_zero_mode():
    """With the hub coasting, turning hub and web together costs nothing: K q = 0 for the
    rigid rotation (the prestress term of the tied nodes makes it exact), and G is skew."""
    case = case_mod.loads(WEB_CASE.format(E=E, omega=25.0))
    _, s = deployed(case)
    st = solve_steady(s, 25.0)
    mats = InPlane(s, st, "coasting")
    q = rigid_rotation(mats, st, "coasting")
    assert np.abs(mats.K @ q).max() < 1e-9 * abs(mats.K).max() * np.abs(q).max()
    assert abs(mats.G + mats.G.T).max() == 0 and abs(mats.K - mats.K.T).max() < 1e-9 * abs(
        mats.K).max()
    md = compute_modes(s, st, 3, "coasting")
    assert md.frequency[0] < 1e-4 * 25.0 and md.kind[0] == "in_plane"


def test_out_of_plane_frequencies_scale_with_omega():
    """Out of the plane only the tension stiffens the web, and tension goes as omega^2: the
    ratios omega_k / omega stay put (stiff cable); in-plane ones need EA."""
    case = case_mod.loads(WEB_CASE.format(E=1000 * E, omega=1.0))
    points = sweep(case, "omega", [1.0, 4.0, 16.0], 1.0, 6)
    ratios = [p.modes.ratio[p.modes.kind == "out_of_plane"][:2] for p in points]
    assert np.allclose(ratios[0], ratios[2], rtol=1e-5)
    masses = sweep(case, "tip_mass", [0.0, 5.0], 4.0, 4)
    assert masses[1].modes.frequency[0] < masses[0].modes.frequency[0]


def test_slack_cables_that_leave_a_node_loose_are_a_mechanism():
    """A node on the axis held by two slack cables: in equilibrium, but loose."""
    pos = np.array([[-1.0, 0, 0], [0.0, 0, 0], [1.0, 0, 0], [2.0, 0, 0]])
    s = Structure(pos, np.array([1.0, 1.0, 1.0, 1.0]), np.array([[0, 1], [1, 2], [2, 3]]),
                  np.array([1.5, 1.5, 1.0]), np.full(3, 1e6), np.array([0, 2]), 1.0)
    st = solve_steady(s, 2.0)
    with pytest.raises(RunError, match=r"mechanism: 2 slack elements \(element 0 \(nodes "
                                       r"0-1\), element 1"):
        check_mechanism(s, st)


# --- against the explicit solver ----------------------------------------------------------

class TipRecorder(Recorder):
    def __init__(self, node):
        self.node, self.t, self.pos = node, [], []

    def frame(self, frame):
        self.t.append(frame.time)
        self.pos.append(frame.pos[self.node].copy())


def ring(case, res, k, eps, t_end):
    """Run the explicit solver from the steady state plus eps x mode k (at rest in the
    rotating frame); return the frequency [rad/s] of the tip signal from zero crossings."""
    sc = prepare(case)
    st, omega = sc.state, res.steady.omega
    shape = res.modes.shape[k]
    pos = res.steady.position + eps * shape
    tied = sc.model.hub.tied_idx[0]
    p, u = res.steady.position[tied], eps * shape[tied]
    st.hub.angle[0] = (p[0] * u[1] - p[1] * u[0]) / (p @ p)  # the free hub's part
    st.node_pos[:] = pos
    st.node_vel[:] = np.column_stack([-omega * pos[:, 1], omega * pos[:, 0], np.zeros(len(pos))])
    rec = TipRecorder(int(sc.model.tip_idx[0]))
    out = simulate(sc.model, sc.control, st, sc.dt, Schedule(t_end, 1e-3, 1e-3), [rec])
    t, tip = np.array(rec.t), np.array(rec.pos)
    if res.modes.kind[k] == "out_of_plane":
        y = tip[:, 2]
    else:  # the tip's angle relative to the hub
        y = np.unwrap(np.arctan2(tip[:, 1], tip[:, 0])) - np.interp(
            t, out.history["time"], out.history["hub_angle"])
        y -= y.mean()
    i = np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0)
    crossings = t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])
    assert len(crossings) >= 6
    return math.pi / np.mean(np.diff(crossings))


def test_explicit_solver_rings_at_the_computed_frequencies():
    """A Zylon tether (20 elements, 10 kg tip) spinning at 2 pi rad/s (1.3 % strain), hub
    free in both: perturbed with the computed out-of-plane mode it rings at the computed
    frequency (measured 6e-6 off), and with the lowest in-plane (tether + hub) mode too
    (8e-5 off); bounds 1.5x these (README, docs/modes.md)."""
    omega = 2 * math.pi
    case = tether_case(omega, 1, elements=20, tip=10.0)
    res = analyse(case, omega, 4, "coasting")
    assert res.steady.max_strain > 0.01
    for kind in ("out_of_plane", "in_plane"):
        k = next(i for i, (kd, f) in enumerate(zip(res.modes.kind, res.modes.frequency))
                 if kd == kind and f > 1e-3 * omega)
        got = ring(case, res, k, 0.2, 4.0)
        tol = 9e-6 if kind == "out_of_plane" else 1.2e-4
        assert got == pytest.approx(res.modes.frequency[k], rel=tol), kind


# --- bad input and the command line -------------------------------------------------------

def write_case(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def test_no_spin_is_invalid_input(tmp_path, capsys):
    case_path = write_case(tmp_path, WEB_CASE.format(E=E, omega=0.0))
    out = tmp_path / "out"
    assert main(["modes", case_path, "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "initial.omega" in err and "no out-of-plane stiffness" in err
    assert main(["modes", case_path, "--omega", "0", "-o", str(out)]) == 2
    assert "no out-of-plane stiffness" in capsys.readouterr().err
    assert not out.exists()
    with pytest.raises(InputError, match="no out-of-plane stiffness"):
        solve_steady(string_structure(4), 0.0)


@pytest.mark.parametrize("args", [["--count", "0"], ["--count", "-3"], ["--hub", "stuck"],
                                  ["--sweep", "omega=1:2"], ["--sweep", "length=1:2:3"],
                                  ["--sweep", "omega=-1:1:3"], ["--sweep", "tip_mass=-1:1:3"]])
def test_bad_arguments_exit_2(tmp_path, capsys, args):
    case_path = write_case(tmp_path, WEB_CASE.format(E=E, omega=2.0))
    out = tmp_path / "out"
    assert main(["modes", case_path, "-o", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert not out.exists()


def test_no_steady_state_exits_1_with_the_residual(tmp_path, capsys):
    """A 1e5 kg tip at 8 pi rad/s outgrows the Zylon tether (m omega^2 > EA / H): the
    centrifugal runaway has no equilibrium at any fraction of the load."""
    case = tether_case(8 * math.pi, 1, elements=10, tip=1e5)
    with pytest.raises(RunError, match="no steady state"):
        analyse(case, 8 * math.pi, 2)
    out = tmp_path / "out"
    assert main(["modes", write_case(tmp_path, case.to_toml()), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "relative residual" in err and err.count("\n") == 1
    assert not out.exists()


def test_cli_writes_modes_h5_and_vtus(tmp_path, capsys):
    case_path = write_case(tmp_path, WEB_CASE.format(E=E, omega=2 * math.pi))
    out = tmp_path / "out"
    assert main(["modes", case_path, "-o", str(out), "--count", "5"]) == 0
    text = capsys.readouterr().out
    assert "steady state at omega = 6.28319 rad/s" in text and "out_of_plane" in text
    with h5py.File(out / "modes.h5") as h5:
        assert h5.attrs["omega"] == pytest.approx(2 * math.pi)
        for key in ("format_version", "spinweb_version", "case", "created", "hub"):
            assert key in h5.attrs
        n = h5["mesh/points"].shape[0]
        e = h5["mesh/elements"].shape[0]
        assert h5["frequency"].shape == (5,) and h5["frequency"].attrs["units"] == "rad/s"
        assert h5["shape"].shape == (5, n, 3) and h5["shape"].attrs["units"] == "m"
        assert h5["steady/position"].shape == (n, 3)
        assert h5["steady/tension"].shape == (e,) and h5["steady/tension"].attrs["units"] == "N"
        kinds = [k.decode() for k in h5["kind"][()]]
        assert set(kinds) <= {"in_plane", "out_of_plane"}
        assert np.all(np.diff(h5["frequency"][()]) >= 0)
        shape, pos = h5["shape"][()], h5["steady/position"][()]
        assert np.allclose(np.sqrt((shape ** 2).sum(axis=2)).max(axis=1), 1.0)
        missing = []
        h5.visititems(lambda name, obj: missing.append(name) if isinstance(
            obj, h5py.Dataset) and "units" not in obj.attrs else None)
        assert missing == []
    vtus = sorted((out / "modes").glob("mode_*.vtu"))
    assert [p.name for p in vtus] == [f"mode_{k:03d}.vtu" for k in range(1, 6)]
    for k, path in enumerate(vtus):
        m = meshio.read(path)
        assert np.allclose(m.points, pos)
        assert np.allclose(m.point_data["shape"], shape[k])
        assert m.cells_dict["line"].shape == (e, 2)
    assert (out / "modes.pvd").is_file()


def test_cli_sweep_writes_table_csv_and_plot(tmp_path, capsys):
    case_path = write_case(tmp_path, WEB_CASE.format(E=E, omega=2.0))
    out = tmp_path / "sweep"
    assert main(["modes", case_path, "-o", str(out), "--count", "3",
                 "--sweep", "omega=2:8:3"]) == 0
    assert "omega [rad/s]" in capsys.readouterr().out
    lines = (out / "sweep.csv").read_text().splitlines()
    assert lines[0].startswith("omega [rad/s],tip_mass [kg],mode [1],kind [-],frequency [rad/s]")
    assert len(lines) == 1 + 3 * 3
    assert (out / "sweep.png").stat().st_size > 1000
    assert main(["modes", case_path, "-o", str(out), "--count", "2",
                 "--sweep", "tip_mass=0:2:2", "--hub", "coasting"]) == 0
    assert main(["modes", case_path, "-o", str(out), "--count", "2",  # the old name warns
                 "--sweep", "tip_mass=0:2:2", "--hub", "free"]) == 0
    assert "--hub free is now --hub coasting" in capsys.readouterr().err
    at_rest = write_case(tmp_path, WEB_CASE.format(E=E, omega=0.0), "rest.toml")
    assert main(["modes", at_rest, "-o", str(out), "--count", "2",
                 "--sweep", "omega=1:2:2"]) == 0  # the sweep gives the spin
