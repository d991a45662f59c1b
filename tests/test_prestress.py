"""Force-method prestressability: small trusses with closed forms, counts and verdicts
for the Fig. 2 configurations, and the ``spinweb prestress`` subcommand."""

import argparse
import math

import numpy as np
import pytest
from closed_forms import quadquad_line_tensions

from meshgen.flat import flat_quadquad
from meshgen.mesh import Mesh, lumped_mass
from meshgen.topologies import flat_other
from spinweb_fe.cli import prestress as prestress_cli
from spinweb_fe.errors import InputError
from spinweb_fe.linear.assembly import equilibrium_matrix, free_dof_basis
from spinweb_fe.linear.prestress import analyse

OMEGA, LINE = 8 * math.pi, 1540.0 * 1.025e-5
SQ2 = math.sqrt(2.0)


def _truss(xy, bars, point_mass, tied=()):
    xyz = np.column_stack([np.asarray(xy, float), np.zeros(len(xy))])
    bars = np.asarray(bars)
    rest = np.linalg.norm(xyz[bars[:, 1]] - xyz[bars[:, 0]], axis=1)
    return Mesh(xyz, xyz, bars, rest, np.asarray(point_mass, float),
                node_sets={"hub_tied": np.asarray(tied, np.int64)})


def test_single_bar_axial_and_transverse_load():
    """Support at 0, free node at x = 2 with mass m: t = m omega^2 x, one mechanism."""
    m = _truss([[0, 0], [2, 0], [0, 1]], [[0, 1]], [0, 3.0, 0], tied=[0, 2])
    rep = analyse(m, 2.0, 0.0)
    assert (rep.n_dof, rep.n_bars, rep.rank, rep.n_selfstress, rep.n_mechanisms) == (2, 1, 1, 0, 1)
    assert rep.tension[0] == pytest.approx(3.0 * 4.0 * 2.0, rel=1e-12)
    assert rep.load_residual < 1e-12 and rep.prestressable
    # the same bar along y with the node at x = 2: the load is all transverse
    m = _truss([[2, -1], [2, 0], [0, 5]], [[0, 1]], [0, 3.0, 0], tied=[0, 2])
    rep = analyse(m, 2.0, 0.0)
    assert rep.load_residual == pytest.approx(1.0) and not rep.prestressable


def test_bar_between_two_supports_point_load():
    """Fixed-fixed cable of lengths a + b with an axial point load P at the joint.

    Statics: t1 - t2 = P (one self-stress state, one transverse mechanism). Elastic,
    equal EA: t1 = P b / (a + b), t2 = -P a / (a + b). A pretension makes both positive:
    the LP reaches its bound (a tension-only self-stress exists)."""
    a, b, x = 1.0, 3.0, 2.0
    P = 5.0 * x  # mass 5 kg, omega 1 rad/s, at x = 2 m
    m = _truss([[x - a, 0], [x, 0], [x + b, 0]], [[0, 1], [1, 2]], [0, 5.0, 0], tied=[0, 2])
    rep = analyse(m, 1.0, 0.0)
    assert (rep.n_dof, rep.rank, rep.n_selfstress, rep.n_mechanisms) == (2, 1, 1, 1)
    assert rep.elastic_max_force == pytest.approx(P * b / (a + b), rel=1e-12)
    assert rep.elastic_min_force == pytest.approx(-P * a / (a + b), rel=1e-12)
    assert rep.elastic_n_compressed == 1
    assert rep.capped and rep.prestressable
    assert rep.tension[0] - rep.tension[1] == pytest.approx(P, rel=1e-9)


def test_three_bar_node():
    """Free node at (0,1) tied by bars to (-1,0), (1,0), (0,-1): s = 1, m = 0.

    Self-stress (1, 1, -sqrt2); with the load P upward the best (and, here, also the
    elastic) solution is t = P/(1+sqrt2) in every bar."""
    m = _truss([[0, 1], [-1, 0], [1, 0], [0, -1]], [[0, 1], [0, 2], [0, 3]],
               [2.0, 0, 0, 0], tied=[1, 2, 3])
    rep = analyse(m, 1.0, 0.0)
    P = 2.0
    assert (rep.n_dof, rep.rank, rep.n_selfstress, rep.n_mechanisms) == (2, 2, 1, 0)
    assert rep.method.startswith("LP")
    assert np.allclose(rep.tension, P / (1 + SQ2), rtol=1e-7)
    assert rep.elastic_min_force == pytest.approx(P / (1 + SQ2), rel=1e-9)
    assert not rep.capped and rep.prestressable


@pytest.mark.parametrize("diagonals, s, m", [(0, 0, 1), (1, 0, 0), (2, 1, 0)])
def test_maxwell_square_frame(diagonals, s, m):
    """Free square frame (no hub: determinate supports, dof = 2j - 3 = 5): b - dof = s - m."""
    bars = [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [1, 3]][:4 + diagonals]
    mesh = _truss([[-1, -1], [1, -1], [1, 1], [-1, 1]], bars, [1.0] * 4)
    rep = analyse(mesh, 1.0, 0.0)
    assert rep.n_dof == 5
    assert (rep.n_selfstress, rep.n_mechanisms) == (s, m)
    assert rep.maxwell == s - m
    # corner load m omega^2 (1, 1) is carried by the two sides: t = 1 N in each side
    assert rep.load_compatible
    if diagonals == 0:
        assert np.allclose(rep.tension, 1.0, rtol=1e-12)
        # its shear mechanism is softened more by the spin than stiffened by the sides
        assert rep.n_negative == 1 and not rep.mechanisms_stiffened


def test_equilibrium_matrix_sign():
    """A t = f with t > 0 a tension: a bar pulls its end nodes towards each other."""
    A = equilibrium_matrix(np.array([[0.0, 0.0], [2.0, 0.0]]), np.array([[0, 1]]))
    assert np.allclose(A[:, 0], [-1, 0, 1, 0])
    P = free_dof_basis(np.zeros((3, 2)), [0], roller=(2, np.array([0.6, 0.8])))
    assert P.shape == (3, 6) and np.allclose(P.toarray()[2, 4:], [0.6, 0.8])


def test_quadquad_line_tensions_closed_form():
    """Free square grid: each mesh line carries its own nodes' centrifugal components,
    t(bar x_i -> x_i+1) = sum over the nodes beyond it of m_k omega^2 x_k."""
    mesh = flat_quadquad(100.0, 10.0, 1, 10.0, 0.0)
    rep = analyse(mesh, OMEGA, LINE)
    assert (rep.n_selfstress, rep.n_mechanisms) == (0, 2 * 11 - 3)
    expect = quadquad_line_tensions(mesh, OMEGA, LINE)[rep.bars]
    np.testing.assert_allclose(rep.tension, expect, rtol=1e-9)
    assert rep.prestressable


def _counts(rep):
    return rep.n_dof, rep.n_bars, rep.rank, rep.n_selfstress, rep.n_mechanisms


@pytest.mark.parametrize("n_t", [8, 10])
def test_tritri_counts_closed_form(n_t):
    """Triangulated: m = 0, s = b - (2V - 3) = (N+1)(N-4)/2 + 3."""
    rep = analyse(flat_other("tritri", 100.0, 100.0 / n_t, 1, 10.0), OMEGA, LINE)
    v, e = (n_t + 1) * (n_t + 2) // 2, 3 * n_t * (n_t + 1) // 2
    s = (n_t + 1) * (n_t - 4) // 2 + 3
    assert _counts(rep) == (2 * v - 3, e, 2 * v - 3, s, 0)


@pytest.mark.parametrize("j", [4, 6])
def test_trihex_counts_closed_form(j):
    """Clean honeycomb in the triangle: s = 0, m = 2V - 3 - E."""
    v, e = j * j + 3 * j + 3, 3 * (j + 1) * (j + 2) // 2
    rep = analyse(flat_other("trihex", math.sqrt(3) * j * 10.0, 10.0, 1, 10.0), OMEGA, LINE)
    assert _counts(rep) == (2 * v - 3, e, e, 0, 2 * v - 3 - e)


# S = 100 m, t = 10 m, corner masses 10 kg, free web (no hub): the docs/prestress.md table.
# dof and bars are counts of the mesh (2V - 3, E: checked below against the mesh), s and m
# follow from the rank (s = b - r, m = dof - r, checked below); tritri and trihex also have
# closed forms (the tests above). The rank of the other four, the LP verdict, the load
# compatibility and the elastic compressed counts are REGRESSION PINS: the code's output at
# commit 2ccd0a5 (spinweb prestress), as the docs quote it, with no independent derivation.
TABLE = {  # dof, bars, rank, s, m, prestressable (LP), load compatible, elastic compressed
    "quadquad": ((239, 220, 220, 0, 19), True, True, 0),
    "tritri": ((129, 165, 129, 36, 0), True, True, 30),
    "trihex": ((111, 84, 84, 0, 27), False, False, 0),
    "triquad": ((121, 113, 113, 0, 8), False, True, 5),
    "quadtri": ((295, 400, 295, 105, 0), True, True, 34),
    "quadhex": ((181, 136, 136, 0, 45), False, False, 0),
}


@pytest.mark.parametrize("topology", list(TABLE))
def test_six_configurations(topology):
    mesh = (flat_quadquad(100.0, 10.0, 1, 10.0, 0.0) if topology == "quadquad"
            else flat_other(topology, 100.0, 10.0, 1, 10.0))
    rep = analyse(mesh, OMEGA, LINE)
    counts, ok, compatible, n_el = TABLE[topology]
    assert _counts(rep) == counts
    dof, bars, rank, n_s, n_m = counts
    assert dof == 2 * mesh.n_nodes - 3 and bars == mesh.n_elems   # counted on the mesh
    assert (n_s, n_m) == (bars - rank, dof - rank)                # rank-nullity
    assert rep.maxwell == rep.n_selfstress - rep.n_mechanisms
    assert rep.prestressable == ok and rep.load_compatible == compatible
    assert rep.elastic_n_compressed == n_el
    if compatible:
        # the reported forces are in equilibrium with the spin load
        xy = mesh.node_ref[:, :2]
        full = equilibrium_matrix(xy, mesh.elem_nodes[rep.bars]) @ rep.tension
        f = (OMEGA ** 2 * lumped_mass(mesh, LINE)[:, None] * xy).ravel()
        free = np.ones(mesh.n_nodes, bool)
        free[np.argmin(np.hypot(*xy.T))] = False
        free = np.repeat(free, 2)
        assert np.linalg.norm(full[free] - f[free]) < 1e-6 * np.linalg.norm(f)
        assert not rep.capped
    else:
        assert rep.load_residual > 1e-3 and rep.node_residual_max > 0.1
    if rep.prestressable and rep.n_selfstress == 0:
        assert rep.omega_band == (0.0, math.inf)   # statics alone: tension at any rate
    elif rep.prestressable:
        # tailored rest lengths keep every bar taut only within a few % of the design rate
        lo, hi = rep.omega_band
        assert 0.9 < lo < 1.0 < hi < 1.1


def test_quadquad_hub_stiffens_mechanisms():
    """A point-like support leaves 3 neutral (zero-stiffness) shear modes of the square
    web in the rotating frame; four tied hub nodes stiffen every mechanism."""
    free = analyse(flat_quadquad(100.0, 10.0, 1, 10.0, 0.0), OMEGA, LINE)
    assert (free.n_neutral, free.n_negative) == (3, 0)
    hub = flat_quadquad(100.0, 10.0, 1, 10.0, 10.0)
    tied = [int(np.argmin(np.hypot(*(hub.node_ref[:, :2] - p).T)))
            for p in ([10, 0], [0, 10], [-10, 0], [0, -10])]
    hub = hub.replace(node_sets=dict(hub.node_sets, hub_tied=np.array(tied)))
    rep = analyse(hub, OMEGA, LINE)
    assert rep.prestressable and rep.mechanisms_stiffened


def _cli_args(tmp_path, text, *extra):
    path = tmp_path / "case.toml"
    path.write_text(text)
    parser = argparse.ArgumentParser()
    prestress_cli.add_parser(parser.add_subparsers())
    return parser.parse_args(["prestress", str(path), *extra])


WEB_CASE = """
[web]
topology = "tritri"
side = 100.0
mesh_width = 2.5
[time]
end = 1.0
"""


@pytest.mark.parametrize("topology, verdict", [
    ("tritri", "prestressable only with tailored rest lengths"),
    ("quadhex", "NOT prestressable as is"), ("quadquad", "prestressable by spin: all")])
def test_cli_report(tmp_path, capsys, topology, verdict):
    args = _cli_args(tmp_path, WEB_CASE, "--mesh-width", "12.5",
                     "--set", f'web.topology="{topology}"')
    assert prestress_cli.run(args) == 0
    out = capsys.readouterr().out
    for key in ("free dof", "bars", "rank", "self-stress states", "mechanisms",
                "load residual", "min member force", "max member force", "method"):
        assert key in out
    assert out.splitlines()[-1].startswith("verdict") and verdict in out


def test_cli_tethers_rejected(tmp_path):
    args = _cli_args(tmp_path, "[tethers]\ncount = 4\n[time]\nend = 1.0\n")
    with pytest.raises(InputError, match="tethers scene has no web to prestress"):
        prestress_cli.run(args)


def test_cli_main_exit_codes(tmp_path, capsys):
    from spinweb_fe.cli import main

    web = tmp_path / "web.toml"
    web.write_text(WEB_CASE)
    assert main(["prestress", str(web), "--mesh-width", "25"]) == 0
    tethers = tmp_path / "tethers.toml"
    tethers.write_text("[tethers]\ncount = 4\n[time]\nend = 1.0\n")
    assert main(["prestress", str(tethers)]) == 2
    assert main(["prestress", str(web), "--mesh-width", "80"]) == 2
    err = capsys.readouterr().err
    assert "tethers scene has no web to prestress" in err and "--mesh-width" in err


def test_cli_spin_rate_of_a_run_from_rest(tmp_path, capsys):
    """A run that starts at rest is analysed at its ramp's final rate; with no spin rate at
    all the load would vanish, which is bad input (exit 2), not a verdict."""
    from spinweb_fe.cli import main

    ramp = tmp_path / "ramp.toml"
    ramp.write_text(WEB_CASE + "[initial]\nomega = 0.0\n[control]\nlaw = 'spin_ramp'\n"
                    "omega_max = 4.0\nramp_time = 1.0\n")
    assert main(["prestress", str(ramp), "--mesh-width", "25"]) == 0
    out = capsys.readouterr().out
    assert "omega = 4 rad/s" in out and "|f| = 0 N" not in out
    rest = tmp_path / "rest.toml"
    rest.write_text(WEB_CASE + "[initial]\nomega = 0.0\n")
    assert main(["prestress", str(rest), "--mesh-width", "25"]) == 2
    assert "initial.omega" in capsys.readouterr().err
    assert main(["prestress", str(rest), "--mesh-width", "25", "--omega", "2.0"]) == 0
    assert main(["prestress", str(rest), "--mesh-width", "25", "--omega", "0"]) == 2
    assert "--omega" in capsys.readouterr().err
