"""Flat webs of the other Fig. 2 configurations: closed-form counts, outline, symmetry."""

import math

import numpy as np
import pytest

from meshgen.checks import MeshValueError, check_mesh
from meshgen.registry import cable_length_per_area
from meshgen.topologies import TOPOLOGIES, flat_other, web_outline

SQ3 = math.sqrt(3.0)
LATTICE_DEGREE = {"tri": 6, "quad": 4, "hex": 3}


def _shape_cell(topology):
    return ("tri", topology[3:]) if topology.startswith("tri") else ("quad", topology[4:])


def _inside_distance(xy, corners):
    """Signed distance to the outline (positive inside) of points in a convex polygon."""
    d = np.roll(corners, -1, axis=0) - corners
    inward = np.column_stack([-d[:, 1], d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
    return np.min(np.einsum("nkj,kj->nk", xy[:, None, :] - corners[None], inward), axis=1)


@pytest.mark.parametrize("n_t, k", [(10, 1), (8, 1), (9, 1), (6, 3), (4, 2)])
def test_tritri_counts_closed_form(n_t, k):
    """S/t = N: (N+1)(N+2)/2 mesh nodes, 3N(N+1)/2 segments, k elements each."""
    side = 100.0
    m = flat_other("tritri", side, side / n_t, k)
    v, e = (n_t + 1) * (n_t + 2) // 2, 3 * n_t * (n_t + 1) // 2
    assert (m.n_nodes, m.n_elems) == (v + (k - 1) * e, k * e)
    assert np.allclose(m.elem_rest_len, side / n_t / k, rtol=1e-12)
    assert len(m.elem_sets["boundary"]) == 3 * n_t * k
    assert check_mesh(m) == []


@pytest.mark.parametrize("j, k", [(3, 1), (4, 1), (5, 1), (6, 1), (7, 2)])
def test_trihex_counts_closed_form(j, k):
    """S = sqrt(3) j t: whole and half hexagons; Euler's formula gives V = j^2 + 3j + 3,
    E = 3(j+1)(j+2)/2 (j^2 interior nodes, 3j boundary nodes, 3 corners)."""
    t = 10.0
    m = flat_other("trihex", SQ3 * j * t, t, k)
    v, e = j * j + 3 * j + 3, 3 * (j + 1) * (j + 2) // 2
    assert (m.n_nodes, m.n_elems) == (v + (k - 1) * e, k * e)
    seg = np.sort(np.round(m.elem_rest_len * k / t, 9))
    # half edges t/2 to the boundary, whole edges t, boundary sqrt(3)t and sqrt(3)t/2
    assert set(np.unique(seg)) == {0.5, 1.0, round(SQ3 / 2, 9), round(SQ3, 9)}
    assert check_mesh(m) == []


@pytest.mark.parametrize("topology", TOPOLOGIES)
@pytest.mark.parametrize("side, t", [(100.0, 10.0), (100.0, 12.5), (60.0, 4.0)])
def test_outline_corners_and_boundary(topology, side, t):
    shape, cell = _shape_cell(topology)
    m = flat_other(topology, side, t, corner_mass=10.0)
    corners = web_outline(shape, side)
    xy = m.node_ref[:, :2]
    assert np.all(m.node_ref[:, 2] == 0.0) and np.array_equal(m.node_pos, m.node_ref)
    # every node inside the outline, a node at each corner carrying the corner mass
    assert np.all(_inside_distance(xy, corners) >= -1e-9 * side)
    tips = m.node_sets["tips"]
    assert np.array_equal(tips, m.node_sets["corners"]) and len(tips) == len(corners)
    assert np.allclose(np.sort(xy[tips], axis=0), np.sort(corners, axis=0), atol=1e-9)
    assert m.node_point_mass.sum() == pytest.approx(10.0 * len(corners))
    assert np.all(m.node_point_mass[tips] == 10.0)
    # the boundary cable is one closed cycle through the corners, as long as the perimeter
    bnd = m.elem_nodes[m.elem_sets["boundary"]]
    assert np.all(np.bincount(bnd.ravel())[np.unique(bnd)] == 2)
    assert set(tips) <= set(bnd.ravel())
    perimeter = len(corners) * side
    assert m.elem_rest_len[m.elem_sets["boundary"]].sum() == pytest.approx(perimeter, rel=1e-12)
    # no tiny segments; away from the outline the lattice is intact
    assert m.elem_rest_len.min() > 0.25 * t
    deg = np.bincount(m.elem_nodes.ravel(), minlength=m.n_nodes)
    deep = _inside_distance(xy, corners) > 1.5 * t
    assert np.all(deg[deep] == LATTICE_DEGREE[cell])
    assert np.all(deg >= 2)
    assert check_mesh(m) == []


@pytest.mark.parametrize("topology", TOPOLOGIES)
def test_symmetry(topology):
    """Mirror x -> -x always; C3 about the centroid for the tri web with tri/hex meshes;
    mirror y -> -y for the square web. The mass centre is then at the origin."""
    shape, cell = _shape_cell(topology)
    m = flat_other(topology, 100.0, 7.0)
    xy = m.node_ref[:, :2]

    def same(a, b):
        key = lambda p: np.lexsort(np.round(p / 1e-6).T)  # noqa: E731
        return np.allclose(a[key(a)], b[key(b)], atol=1e-6)

    assert same(xy, xy * [-1, 1])
    if shape == "quad":
        assert same(xy, xy * [1, -1])
    elif cell in ("tri", "hex"):
        c, s = math.cos(2 * math.pi / 3), math.sin(2 * math.pi / 3)
        assert same(xy, xy @ np.array([[c, s], [-s, c]]))
    if topology != "triquad":   # a square grid is not C3-symmetric
        mid = 0.5 * (xy[m.elem_nodes[:, 0]] + xy[m.elem_nodes[:, 1]])
        com = (m.elem_rest_len[:, None] * mid).sum(0) / m.elem_rest_len.sum()
        assert np.allclose(com, 0.0, atol=1e-9 * 100)


@pytest.mark.parametrize("topology", TOPOLOGIES)
def test_cable_length_per_area(topology):
    """Interior cable length / web area tends to the lattice value
    (2 sqrt3/t, 2/t, 2/(sqrt3 t))."""
    shape, _ = _shape_cell(topology)
    side, t = 100.0, 2.0
    m = flat_other(topology, side, t)
    area = side * side * (SQ3 / 4 if shape == "tri" else 1.0)
    inner = np.setdiff1d(np.arange(m.n_elems), m.elem_sets["boundary"])
    lam = m.elem_rest_len[inner].sum() / area
    assert lam == pytest.approx(cable_length_per_area(topology, t), rel=0.03)


@pytest.mark.parametrize("topology", TOPOLOGIES)
def test_hub_cutout(topology):
    m0 = flat_other(topology, 100.0, 5.0, 2)
    m = flat_other(topology, 100.0, 5.0, 2, hub_cutout=11.0)
    r = np.hypot(m.node_ref[:, 0], m.node_ref[:, 1])
    assert r.min() >= 11.0 - 1e-9 and m.n_nodes < m0.n_nodes
    tied = m.node_sets["hub_tied"]
    assert len(tied) >= 3 and np.all(r[tied] < 11.0 + 5.0 + 1e-9)
    assert len(m0.node_sets["hub_tied"]) == 0
    assert check_mesh(m) == []


def test_rest_lengths_subdivided():
    m1 = flat_other("quadhex", 100.0, 8.0, 1)
    m3 = flat_other("quadhex", 100.0, 8.0, 3)
    assert m3.n_elems == 3 * m1.n_elems and m3.n_nodes == m1.n_nodes + 2 * m1.n_elems
    assert m3.elem_rest_len.sum() == pytest.approx(m1.elem_rest_len.sum(), rel=1e-12)
    assert np.allclose(m3.elem_length(), m3.elem_rest_len, rtol=1e-12)


@pytest.mark.parametrize("kwargs, param", [
    (dict(topology="quadquad"), "topology"), (dict(mesh_width=60.0), "mesh_width"),
    (dict(elements_per_segment=0), "elements_per_segment"),
    (dict(corner_mass=-1.0), "corner_mass"), (dict(hub_cutout=80.0), "hub_cutout")])
def test_bad_input(kwargs, param):
    args = dict(topology="tritri", side=100.0, mesh_width=10.0) | kwargs
    with pytest.raises(MeshValueError) as exc:
        flat_other(**args)
    assert exc.value.param == param
