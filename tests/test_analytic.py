"""The analytical model (paper Eqs. 4-8): kinematics, balances, limits, budgets, CLI."""

import argparse
import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from spinweb_fe import case as case_mod
from spinweb_fe.analytic import solve as analytic
from spinweb_fe.analytic.solve import drifts, integrate
from spinweb_fe.fe.control import free, make_control
from spinweb_fe.analytic.models import (HALF_PI, ArmParams, accelerations, invariants,
                                        root_tension, tip_rate)
from spinweb_fe.record.history import HISTORY_UNITS

W0 = 8 * math.pi
PAPER = ArmParams(n=4, H=50.0, r0=6.3, J_hub=3969.0, m_tip=10.0, m_lin=126.7 / 4)
ROOT = Path(__file__).resolve().parents[1]
#: the consistent model's angular momentum and energy balances, relative (measured up to
#: 4.0e-9 over every law, spin, wrap and the Fig. 8 cases: DOP853 at rtol = atol = 1e-10)
BALANCE = 6e-9


def straight_tension(p: ArmParams, omega: float) -> float:
    """Closed-form root tension [N] of a straight radial arm in steady spin at omega:
    N = omega^2 [m_tip (r0 + H) + m_lin (r0 + H/3) + m_uni (r0 + H/2)]."""
    r0, H = p.r0, p.H
    return omega ** 2 * (p.m_tip * (r0 + H) + p.m_lin * (r0 + H / 3.0) + p.m_uni * (r0 + H / 2.0))


def rigid_inertia(p: ArmParams, phi: float = 0.0) -> float:
    """Inertia [kg m^2] of hub + fully uncoiled arms frozen at angle phi (rigid rotation)."""
    m_f, S, I = p.moments(p.H)
    return p.J0 + p.n * (I + 2.0 * p.r0 * S * math.cos(phi))


def case_text(scene="web", law="free", end=0.5, spin="all", fold=""):
    head = ('[web]\nside = 100.0\nmesh_width = 2.5\nareal_density = 1.267e-2\n'
            if scene == "web" else '[tethers]\ncount = 4\nlength = 50.0\nelements = 50\n')
    ctrl = {"free": "", "torque_feedback": "M0 = 2.5132741e6\nomega0 = 25.132741228718345\n",
            "spin_ramp": "omega_max = 25.132741228718345\nramp_time = 0.3\n",
            "constant_torque": "torque = 2e5\n"}[law]
    return (f'{head}[tip_mass]\nmass = 10.0\n[hub]\nradius = 6.3\nmass = 100.0\n'
            f'[initial]\nomega = 25.132741228718345\nspin = "{spin}"\n'
            f'[control]\nlaw = "{law}"\n{ctrl}[fold]\n{fold}'
            f'[time]\nend = {end}\n[output]\nhistory_dt = 1e-3\n')


# ---- kinematics: the closed-form T, K and tip rate against a particle discretisation

def _positions(p, theta, phi, coiled, s):
    """Material points at arm coordinate s (from the root), written from the geometry."""
    s = np.asarray(s, float)
    if coiled:
        sig = math.copysign(1.0, phi)
        alpha = sig * phi - HALF_PI
        wound = s <= p.r0 * alpha
        ang = np.where(wound, theta + sig * s / p.r0, theta + sig * alpha)
        base = p.r0 * np.column_stack([np.cos(ang), np.sin(ang)])
        beta = theta + sig * alpha
        u = sig * np.array([-math.sin(beta), math.cos(beta)])
        return base + np.where(wound, 0.0, s - p.r0 * alpha)[:, None] * u
    base = p.r0 * np.array([math.cos(theta), math.sin(theta)])
    u = np.array([math.cos(theta + phi), math.sin(theta + phi)])
    return base + s[:, None] * u


def _particle_invariants(p, phi, omega, psi, coiled, nq=40):
    """T and K from Gauss quadrature over the wound and free parts, velocities by
    differencing material positions along (theta, phi)(t)."""
    h = 1e-6
    L = p.H - p.r0 * (abs(phi) - HALF_PI) if coiled else p.H
    pieces = [(0.0, p.H - L), (p.H - L, p.H)] if coiled else [(0.0, p.H)]
    x, w = np.polynomial.legendre.leggauss(nq)
    s, ws = [], []
    for a, b in pieces:
        if b > a:
            s.append(0.5 * (b - a) * x + 0.5 * (a + b))
            ws.append(0.5 * (b - a) * w)
    s, ws = np.concatenate(s + [[p.H]]), np.concatenate(ws + [[1.0]])
    rho = 2 * p.m_lin / p.H ** 2 * (p.H - s) + p.m_uni / p.H
    mass = ws * rho
    mass[-1] = p.m_tip                     # the tip point mass
    dphi = psi - omega
    x1 = _positions(p, 0.3 + omega * h, phi + dphi * h, coiled, s)
    x0 = _positions(p, 0.3 - omega * h, phi - dphi * h, coiled, s)
    r, v = _positions(p, 0.3, phi, coiled, s), (x1 - x0) / (2 * h)
    T = 0.5 * p.J_hub * omega ** 2 + p.n * 0.5 * np.sum(mass * np.sum(v * v, axis=1))
    hz = r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0]
    K = p.J_hub * omega + p.n * np.sum(mass * hz)
    return T, K, hz[-1] / np.sum(r[-1] ** 2)


@pytest.mark.parametrize("phi, coiled", [(-9.0, True), (-2.5, True), (3.1, True),
                                         (0.7, False), (-1.2, False), (2.0, False)])
def test_invariants_match_particles(phi, coiled):
    p = ArmParams(n=3, H=40.0, r0=5.0, J_hub=900.0, m_tip=7.0, m_lin=20.0, m_uni=3.0)
    omega, psi = 4.0, -2.5
    T, K, tip = _particle_invariants(p, phi, omega, psi, coiled)
    E_ref, K_ref = invariants(p, phi, omega, psi, coiled)
    assert E_ref == pytest.approx(T, rel=1e-8)
    assert K_ref == pytest.approx(K, rel=1e-8)
    assert tip_rate(p, phi, omega, psi, coiled) == pytest.approx(tip, rel=1e-7)


# ---- budgets and closed forms (physics-notes section 5)

def test_paper_budgets():
    assert PAPER.J0 == pytest.approx(10585, abs=1)
    assert PAPER.J0 * W0 == pytest.approx(2.66e5, rel=2e-3)
    assert 0.5 * PAPER.J0 * W0 ** 2 == pytest.approx(3.34e6, rel=2e-3)
    J = rigid_inertia(PAPER)
    assert J == pytest.approx(2.152e5, rel=1e-3)
    w = PAPER.J0 * W0 / J
    assert w == pytest.approx(1.24, abs=5e-3)
    assert 0.5 * J * w ** 2 / (0.5 * PAPER.J0 * W0 ** 2) == pytest.approx(0.049, abs=1e-3)
    assert straight_tension(PAPER, W0) == pytest.approx(8.15e5, rel=1e-3)
    E0, K0 = invariants(PAPER, -(HALF_PI + 50 / 6.3), W0, W0, True)
    assert (E0, K0) == (pytest.approx(3.343e6, rel=1e-3), pytest.approx(2.660e5, rel=1e-3))


@pytest.mark.parametrize("model", ["printed", "consistent"])
def test_straight_arm_steady_tension(model):
    p = ArmParams(n=4, H=50.0, r0=6.3, J_hub=3969.0, m_tip=10.0, m_lin=31.675, m_uni=0.8)
    wd, pd, M = accelerations(model, p, 0.0, W0, W0, False, torque=0.0)
    assert abs(wd) < 1e-12 and abs(pd) < 1e-12 and M == 0.0     # relative equilibrium
    N = root_tension(p, 0.0, W0, W0, 0.0, False)
    assert N == pytest.approx(straight_tension(p, W0), rel=1e-14)
    # straight, radial and co-rotating at the start: it stays so, at the closed-form tension
    r = integrate(p, free(), model=model, t_end=0.2, history_dt=0.01, coiled=False,
                 omega_init=W0)
    h = r.history
    assert np.allclose(h["arm_angle"], 0.0, atol=1e-12)
    assert np.allclose(h["max_tension"], straight_tension(p, W0), rtol=1e-12)
    assert np.allclose(h["tip_omega"], W0, rtol=1e-12)


# ---- conservation in free deployment

@pytest.mark.parametrize("scene", ["tethers", "web"])
def test_consistent_conserves_K_and_E(scene):
    c = case_mod.loads(case_text(scene, end=2.0))
    r = analytic.solve_case(c, model="consistent")
    dk, de = drifts(r)
    print(f"\n{scene}: consistent max|dK|/K0 = {np.abs(dk).max():.2e}, "
          f"max|dE|/E0 = {np.abs(de).max():.2e}, switches at "
          f"{[round(s[0], 4) for s in r.switches]}")
    assert not r.stopped and len(r.switches) >= 3       # it uncoils, swings, re-coils
    # README / docs/analytic.md: "a few 1e-9" (measured 4.2e-9 / 1.3e-9 over these 2 s)
    assert np.abs(dk).max() < 5e-9 and np.abs(de).max() < 2e-9
    L = r.history["arm_length"][:, 0]
    assert L.max() == pytest.approx(50.0) and L.min() > 0


#: docs/analytic.md, section 2 "Flaws": max |K - K0| and |E - E0| up to 0.1, 0.25, 0.5, 5 s of
#: the paper's web free at 8 pi (the run of docs/make_analytic_figs.py), scaled as
#: analytic.drifts scales them over the 5 s run
DRIFT_MARKS = (0.1, 0.25, 0.5, 5.0)
DRIFT_TABLE = {("printed", "K"): (0.60, 1.02, 1.23, 1.84),
               ("printed", "E"): (0.29, 0.30, 0.31, 0.42),
               ("consistent", "K"): (4e-10, 1e-9, 2e-9, 4e-9),
               ("consistent", "E"): (1e-9, 1e-9, 1e-9, 2e-9)}


@pytest.mark.parametrize("model", ["printed", "consistent"])
def test_drift_table_of_the_paper_web(model):
    """The printed model's drifts are regression pins of the code's output at the two digits
    the docs quote (there is no reference for them to be right against; they were made by
    docs/make_analytic_figs.py at commit 2ccd0a5 and still hold). The consistent model's
    balance errors must stay within 1.5x the one-digit values quoted (round-off of DOP853 at
    1e-10)."""
    c = case_mod.loads(case_text("web", end=5.0))
    r = analytic.solve_case(c, model=model)
    dk, de = drifts(r)
    t = r.history["time"]
    for name, d in (("K", dk), ("E", de)):
        got = [np.abs(d[t <= tm + 1e-12]).max() for tm in DRIFT_MARKS]
        print(f"\n{model} {name}: {['%.3g' % g for g in got]}")
        for g, quoted in zip(got, DRIFT_TABLE[model, name]):
            if model == "printed":
                assert g == pytest.approx(quoted, abs=0.005)
            else:
                assert g < 1.5 * quoted


def test_point_mass_printed_is_consistent():
    """With massless tethers Eqs. 4-6 and the coiling substitutions are exact."""
    p = ArmParams(n=4, H=50.0, r0=6.3, J_hub=3969.0, m_tip=10.0)
    hs = [integrate(p, free(), model=m, t_end=1.0, history_dt=0.01).history
          for m in ("printed", "consistent")]
    for key in ("arm_length", "arm_angle", "hub_omega", "max_tension"):
        assert np.allclose(hs[0][key], hs[1][key], rtol=1e-6, atol=1e-6 * np.abs(hs[1][key]).max())


@pytest.mark.parametrize("model", ["printed", "consistent"])
def test_distributed_tends_to_point_mass(model):
    def final(m_lin):
        p = ArmParams(n=4, H=50.0, r0=6.3, J_hub=3969.0, m_tip=10.0, m_lin=m_lin)
        h = integrate(p, free(), model=model, t_end=0.6, history_dt=0.01).history
        return np.array([h["arm_length"][-1, 0], h["arm_angle"][-1, 0], h["hub_omega"][-1]])
    ref = final(0.0)
    errs = [np.abs(final(m) - ref).max() for m in (1e-1, 1e-2, 1e-3)]
    print(f"\n{model}: |distributed - point mass| for m_w/n = 0.1, 0.01, 0.001 kg: {errs}")
    assert errs[2] < 1e-3 and errs[1] / errs[2] > 5 and errs[0] / errs[1] > 5


@pytest.mark.parametrize("model", ["printed", "consistent"])
def test_start_length_convergence(model):
    vals = []
    for f in (1e-2, 1e-3, 1e-4):
        h = integrate(PAPER, free(), model=model, t_end=0.3, history_dt=0.01,
                     L0=f * PAPER.H).history
        vals.append(np.array([h["arm_length"][-1, 0], h["hub_omega"][-1], h["arm_angle"][-1, 0]]))
    d1, d2 = np.abs(vals[1] - vals[0]).max(), np.abs(vals[2] - vals[1]).max()
    print(f"\n{model}: change for L0/H 1e-2 -> 1e-3: {d1:.2e}, 1e-3 -> 1e-4: {d2:.2e}")
    assert d2 < 1e-2 and d1 / d2 > 10


# ---- control laws, spins and wraps

@pytest.mark.parametrize("law", ["free", "torque_feedback", "spin_ramp", "constant_torque"])
@pytest.mark.parametrize("scene", ["tethers", "web"])
def test_all_laws_balance(law, scene):
    c = case_mod.loads(case_text(scene, law, end=0.6))
    r = analytic.solve_case(c, model="consistent")
    h = r.history
    assert not r.stopped and h["time"][-1] == pytest.approx(0.6)
    dk, de = drifts(r)
    assert np.abs(dk).max() < BALANCE and np.abs(de).max() < BALANCE
    if law == "spin_ramp":
        assert h["hub_omega"][-1] == pytest.approx(W0) and np.abs(h["hub_torque"]).max() > 0
        i = int(0.15 / 1e-3)
        assert h["hub_omega"][i] == pytest.approx(W0 * 0.5, rel=1e-9)
    if law == "constant_torque":
        assert np.all(h["hub_torque"] == 2e5)


@pytest.mark.parametrize("extra", ["leading", "spin_hub", "straight"])
def test_wraps_and_spins(extra):
    fold = {"leading": 'wrap = "leading"\n', "straight": 'pattern = "straight"\n'}.get(extra, "")
    c = case_mod.loads(case_text("tethers", end=0.6, fold=fold,
                                 spin="hub" if extra == "spin_hub" else "all"))
    r = analytic.solve_case(c)
    dk, de = drifts(r)
    assert np.abs(dk).max() < BALANCE and np.abs(de).max() < BALANCE
    phi = r.history["arm_angle"][:, 0]
    if extra == "leading":
        assert phi[0] > HALF_PI
    if extra == "spin_hub":      # inelastic coupling of the coil to the hub at t = 0
        assert r.info["start_loss"] > 0
        assert r.history["angular_momentum"][0] == pytest.approx(3969.0 * W0, rel=1e-9)
    if extra == "straight":
        assert phi[0] == 0.0 and np.allclose(phi, 0.0, atol=1e-8)


def test_regime_switches_are_exact():
    r = integrate(PAPER, free(), t_end=1.0, history_dt=1e-3)
    assert [s[2] for s in r.switches[:3]] == ["coiled", "pivoting", "coiled"]
    assert all(abs(abs(s[1]) - HALF_PI) < 1e-15 for s in r.switches[1:])
    L = r.history["arm_length"][:, 0]
    assert L.max() <= 50.0 and np.abs(np.diff(L)).max() < 0.5    # continuous


def test_trailing_spin_ramp_captured_start():
    """From rest a trailing coil stays captured until the spin can unwind it."""
    r = integrate(PAPER, make_control("spin_ramp", {"omega_max": W0, "ramp_time": 2.0}), t_end=1.0,
                 history_dt=1e-2)
    assert r.switches[0][2] == "coiled" and 0 < r.switches[0][0] < 0.02
    assert r.history["arm_length"][-1, 0] > 20.0
    assert r.history["max_tension"].min() > 0


# ---- command line

def test_cli_writes_analytic_h5(tmp_path, capsys):
    from spinweb_fe.cli import analytic as cli
    case_file = tmp_path / "web.toml"
    case_file.write_text(case_text("web", end=0.2))
    for model in ("consistent", "printed"):
        out = tmp_path / model
        args = argparse.Namespace(case=str(case_file), sets=["output.history_dt=0.002"],
                                  output=str(out), model=model, rtol=1e-10, atol=1e-10,
                                  start_length=None, massless_tethers=False)
        assert cli.run(args) == 0
        line = capsys.readouterr().out
        assert "max|K drift|" in line and f"model={model}" in line
        with h5py.File(out / "analytic.h5", "r") as f:
            assert f.attrs["model"] == model and f.attrs["rtol"] == 1e-10
            assert "case" in f.attrs and "format_version" in f.attrs
            g = f["history"]
            for name in ("time", "hub_angle", "hub_omega", "hub_torque", "kinetic_energy",
                         "strain_energy", "torque_work", "damping_dissipation",
                         "angular_momentum", "max_tension", "arm_length", "arm_angle",
                         "tip_omega"):
                assert g[name].attrs["units"] == HISTORY_UNITS[name]
            assert g["time"].shape == (101,) and g["arm_angle"].shape == (101, 4)


def test_cli_bad_model(tmp_path):
    from spinweb_fe.cli import analytic as cli
    from spinweb_fe.errors import InputError
    case_file = tmp_path / "t.toml"
    case_file.write_text(case_text("tethers", end=0.1))
    args = argparse.Namespace(case=str(case_file), sets=[], output=str(tmp_path), model="exact",
                              rtol=1e-10, atol=1e-10, start_length=None, massless_tethers=False)
    with pytest.raises(InputError):
        cli.run(args)


@pytest.mark.parametrize("path", sorted((ROOT / "cases").glob("analytic_fig8_*.toml")),
                         ids=lambda p: p.stem)
def test_fig8_cases_run(path):
    c = case_mod.load(path, ["time.end=1.0", "output.history_dt=0.01"])
    r = analytic.solve_case(c)
    dk, de = drifts(r)
    assert not r.stopped and np.abs(dk).max() < BALANCE and np.abs(de).max() < BALANCE
