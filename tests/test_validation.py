"""FE solver against the consistent analytical model (docs/validation.md).

Fast checks (a few seconds): stiff tethers over the first 0.2 s of the uncoiling. Slow checks
(``make validate``): the whole uncoiling phase, mesh convergence, the spin ramp, and the
web-arm comparison whose known discrepancy is pinned so a change is noticed. The mappings and
error norms are those of spinweb_fe.analytic.compare, which benchmarks/validate_analytic.py
uses for the tables in docs/validation.md.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from spinweb_fe import case as case_mod
from spinweb_fe.analytic import compare as V
from spinweb_fe.analytic.models import params_from_case
from spinweb_fe.case.scene import prepare
from spinweb_fe.cli import main

ROOT = Path(__file__).resolve().parents[1]

STIFF_ARMS = ROOT / "cases" / "paper_free_arms_stiff.toml"
VALIDATION_CASES = sorted((ROOT / "cases" / "validation").glob("*.toml"))


def errors(case, window, model="consistent", variant=None, params=None, fe=None):
    if fe is None:
        fe = V.fe_run(case, variant=variant)[0]
    an, _ = V.analytic_twin(case, params=params, model=model)
    return V.error_table(fe, an, {"w": window})["w"], fe, an


# ---------------------------------------------------------------------------- fast


@pytest.fixture(scope="module")
def stiff_tethers_02():
    """4 stiff tethers of 50 elements, free at 8 pi, to 0.32 s: the whole uncoiling (about 3 s
    of wall time)."""
    cs = case_mod.load(STIFF_ARMS, ["time.end=0.32"])
    return cs, errors(cs, (0.0, 0.2))


def test_stiff_tethers_follow_consistent_model(stiff_tethers_02):
    # 1.5 x the measured (held coil, 50 elements, 0-0.2 s, arm 0): L 0.057 m, phi 0.0031
    # rad max, hub rate 0.072 rad/s and tip rate 0.077 rad/s RMS (docs/testing.md)
    _, (err, fe, an) = stiff_tethers_02
    assert err["L"]["max"] < 0.085           # m, of 31.7 m paid out by 0.2 s
    assert err["phi"]["max"] < 0.0046        # rad, of 5 rad unwound
    assert err["omega_centre"]["rms"] < 0.11  # rad/s, of a 44 rad/s despin
    assert err["omega_tip"]["rms"] < 0.12
    # the arm really uncoiled and the hub really despun in both
    assert fe["arm_length"][-1, 0] > 30.0 and an["arm_length"][-1, 0] > 30.0
    assert fe["hub_omega"][-1] < -15.0


def test_fe_resolves_inertia_errors(stiff_tethers_02):
    """The tolerance has teeth: over the whole uncoiling (to 0.316 s) the FE hub rate is closer
    to the consistent model than to the same model with 10 % more hub inertia (which moves
    omega_centre by about 0.5 rad/s RMS; L(t) is the yo-yo kinematics r0 omega0 t and does not
    depend on the inertias), and the pay-out is the yo-yo rate r0 omega0."""
    import dataclasses

    cs, (_, fe, _) = stiff_tethers_02
    p = params_from_case(cs)
    err_c, _, _ = errors(cs, (0.0, 0.316), fe=fe)
    err_j, _, _ = errors(cs, (0.0, 0.316), fe=fe, params=dataclasses.replace(p, J_hub=1.1 * p.J_hub))
    # 1.5 x the measured over the whole uncoiling: L 0.097 m, phi 0.0031 rad
    assert err_c["L"]["max"] < 0.15 and err_c["phi"]["max"] < 0.0046
    assert err_c["omega_centre"]["rms"] < 0.6 * err_j["omega_centre"]["rms"]
    i = int(round(0.1 / cs.output.history_dt))
    assert fe["arm_length"][i, 0] == pytest.approx(6.3 * 8 * math.pi * 0.1, rel=0.02)


@pytest.mark.parametrize("case", VALIDATION_CASES, ids=[c.stem for c in VALIDATION_CASES])
def test_validation_cases_run(case, tmp_path):
    import h5py

    assert main(["run", str(case), "-o", str(tmp_path / case.stem), "--set", "time.end=0.004",
                 "--set", "output.history_dt=0.001", "--set", "output.frame_dt=0.002",
                 "--no-progress"]) == 0
    with h5py.File(tmp_path / case.stem / "results.h5", "r") as h5:
        assert h5.attrs["status"] == "completed"
        np.testing.assert_allclose(h5["history/time"][()], np.arange(5) * 1e-3, atol=1e-12)
        assert h5["frames/time"].shape == (3,)
        assert np.all(np.isfinite(h5["history/kinetic_energy"][()]))


# ---------------------------------------------------------------------------- slow


@pytest.mark.slow
def test_stiff_tethers_uncoiling_converges():
    """Max error of phi over the uncoiling falls with the mesh (25 -> 50 -> 100 elements)."""
    out = []
    for k in (25, 50, 100):
        cs = case_mod.load(STIFF_ARMS, [f"tethers.elements={k}", "time.end=0.32"])
        out.append(errors(cs, (0.0, 0.316))[0])
    phi = [e["phi"]["max"] for e in out]
    L = [e["L"]["max"] for e in out]
    assert phi[0] > 2.5 * phi[1] > 2.5 * 1.2 * phi[2]
    assert L[2] < 0.15 and phi[2] < 0.01


@pytest.mark.slow
def test_stiff_tethers_first_cycle():
    """Swing through the radial and re-coil the other way (0.32-0.7 s) at cfl 0.15."""
    cs = case_mod.load(STIFF_ARMS, ["time.cfl=0.15", "time.end=0.7"])
    err, fe, an = errors(cs, (0.0, 0.65))
    assert err["L"]["rms"] < 0.5 and err["omega_centre"]["rms"] < 0.5
    assert np.min(fe["hub_omega"]) < -20.0  # despun through zero, as the model


@pytest.mark.slow
def test_stiff_tethers_spin_ramp():
    cs = case_mod.load(ROOT / "cases" / "validation" / "ramp_arms_stiff.toml",
                     ["tethers.elements=25", "time.end=2.0"])
    err, fe, an = errors(cs, (0.0, 2.0))
    assert err["L"]["rms"] < 2.0 and err["omega_tip"]["rms"] < 3.0


@pytest.mark.slow
def test_held_web_follows_the_arm_while_it_uncoils():
    """The star-folded stiff web with its coil held follows the mapped rigid arm over the
    uncoiling (docs/validation.md 3.2, t = 5 m, to 0.20 s: L 1.0 m, phi 0.14 rad, hub
    1.9 rad/s RMS); the loose coil of the last version does not (L 5 m, phi 1.4 rad, hub
    9.7 rad/s RMS, its hub still spinning forwards at 0.3 s). Limits about 1.5x the study."""
    sets = ["web.mesh_width=5.0", "time.end=0.3"]
    cs = case_mod.load(ROOT / "cases" / "paper_free_web_stiff.toml", sets)
    mesh, model = prepare(cs)[:2]
    p = V.web_params(cs, mesh, model)[0]
    err, fe, an = errors(cs, (0.0, 0.2), params=p)
    assert err["L"]["rms"] < 1.5 and err["phi"]["rms"] < 0.22
    assert err["omega_centre"]["rms"] < 3.0
    loose = case_mod.load(ROOT / "cases" / "paper_free_web_stiff.toml",
                          sets + ["stowage.coil='loose'"])
    err_l, fe_l, _ = errors(loose, (0.0, 0.2), params=p)
    assert err_l["omega_centre"]["rms"] > 3 * err["omega_centre"]["rms"]
    assert fe_l["hub_omega"][-1] > an["hub_omega"][-1] + 10.0


def test_triangular_web_follows_three_arm_model():
    """The 3-arm star fold of the stiff triangular web, root region tied to the hub, against
    the consistent 3-arm model (mapped as the square web) once the ramp is over. Study
    (benchmarks/validate_analytic.py --only tri, t = 5 m, 2-4 s): L rms 0.95 m of 29.4 m,
    phi rms 0.36 rad; over this test's 2-3 s: 0.95 m, 0.17 rad, omega_tip 1.9 rad/s. As
    folded the errors are 20x larger (the slack root region). The ramp window checks the
    arm measure's spine on a mesh whose lines cross the half-axes (docs/validation.md 3.4).
    Measured here (2026-12): 2-3 s L 0.95 m, phi 0.17 rad, omega_tip 1.87 rad/s; ramp 0-2 s
    L 0.78 m, phi 0.17 rad, omega_tip 0.77 rad/s (the study's rigid-root row); bounds 1.3x."""
    sets = ["cable.youngs_modulus=180e12", "web.mesh_width=5.0", "time.end=3.0"]
    cs = case_mod.load(ROOT / "cases" / "tri_ramp_web.toml", sets)
    mesh, model = prepare(cs)[:2]
    p = V.web_params(cs, mesh, model)[0]
    assert p.n == 3 and p.H == pytest.approx(50.0 - mesh.arm_root_coord)
    err, fe, an = errors(cs, (2.0, 3.0), params=p, variant="rigid_root")
    assert err["L"]["rms"] < 1.25                # m, of H = 29.4 m
    assert err["phi"]["rms"] < 0.23              # rad, of an in-plane swing of +-1.3 rad
    assert err["omega_tip"]["rms"] < 2.5         # rad/s, of a 14-37 rad/s oscillation
    # during the ramp (uncoiling, 7.5 rad unwound)
    ramp = V.error_table(fe, an, {"ramp": (0.0, 2.0)})["ramp"]
    assert ramp["L"]["rms"] < 1.0 and ramp["phi"]["rms"] < 0.22 and ramp["omega_tip"]["rms"] < 1.0
    assert np.min(an["arm_angle"][-1000:, 0]) < -1.0 < 1.0 < np.max(an["arm_angle"][-1000:, 0])
