"""The single entry point from a validated case to the initial mesh."""

from __future__ import annotations

import numpy as np

from meshgen.checks import MeshValueError, check_mesh
from meshgen.flat import default_cutout, effective_cutout, flat_web
from meshgen.fold import fold_web
from meshgen.mesh import Mesh
from meshgen.tethers import tethers
from meshgen.topologies import flat_other, outline_cutout
from spinweb_fe.errors import InputError

# generator parameter -> case key, per scene
_WEB_KEYS = {"side": "web.side", "mesh_width": "web.mesh_width",
             "elements_per_segment": "web.elements_per_segment",
             "hub_cutout": "web.hub_cutout", "hub_radius": "hub.radius",
             "topology": "web.topology", "pattern": "fold.pattern", "wrap": "fold.wrap",
             "ties": "fold.ties", "corner_mass": "tip_mass.mass"}
_TETHER_KEYS = {"count": "tethers.count", "length": "tethers.length",
                "elements": "tethers.elements", "hub_radius": "hub.radius",
                "tip_mass": "tip_mass.mass", "pattern": "fold.pattern", "wrap": "fold.wrap"}


def build_mesh(case) -> Mesh:
    """Initial mesh of a case: flat web -> (star fold + coil | flat), or tethers.

    A quadquad web is tied to the hub as ``fold.ties`` says (``frame``: the whole
    boundary of the cut-out; ``axes``: its 4 nodes on the axes), see docs/mesh.md. A
    star-folded web of another topology gets a hole shaped like its outline (inradius
    ``web.hub_cutout``, default the hub radius; tritri rounds it out to a mesh line) and
    is tied by its frame; a flat one keeps the disc cut-out with its rim tied.

    Parameters
    ----------
    case : spinweb_fe.case.Case
        Validated case.

    Returns
    -------
    Mesh
        ``node_pos`` is the initial (folded) state, ``node_ref`` the flat deployed state.

    Raises
    ------
    InputError
        If a generator rejects the case (key named) or the mesh violates an invariant of
        :func:`meshgen.checks.check_mesh`.
    """
    keys = _WEB_KEYS if case.scene == "web" else _TETHER_KEYS
    try:
        mesh = _build_web(case) if case.scene == "web" else _build_tethers(case)
    except MeshValueError as exc:
        raise InputError(case.source, keys.get(exc.param, case.scene), exc.reason) from None
    problems = check_mesh(mesh)
    if problems:
        raise InputError(case.source, case.scene, "invalid mesh: " + "; ".join(problems))
    return mesh


def resolved_cutout(case) -> float:
    """Cut-out half-width c [m] of a quadquad web case: web.hub_cutout (or the hub radius
    by default) rounded outwards to a grid line."""
    web = case.web
    if web.hub_cutout is None:
        return default_cutout(web.side, web.mesh_width, case.hub.radius)
    return effective_cutout(web.side, web.mesh_width, web.hub_cutout)


def _build_web(case) -> Mesh:
    web, hub, fold = case.web, case.hub, case.fold
    if web.topology == "quadquad":
        flat = flat_web(web, case.tip_mass.mass, resolved_cutout(case))
        return fold_web(flat, hub.radius, fold.pattern, fold.wrap, fold.ties)
    cut = hub.radius if web.hub_cutout is None else web.hub_cutout
    if fold.pattern == "star":
        # a hole shaped like the outline: its boundary is the hub frame of the fold
        if fold.ties == "axes":
            raise MeshValueError("ties", "ties = 'axes' needs the square web with a square "
                                 f"mesh (web.topology = '{web.topology}'); use 'frame'")
        c = outline_cutout(web.topology, web.side, web.mesh_width, cut)
        flat = flat_other(web.topology, web.side, web.mesh_width, web.elements_per_segment,
                          case.tip_mass.mass, c, hole="outline")
        return fold_web(flat, hub.radius, "star", fold.wrap, "frame")
    # flat: the generator cuts a disc of this radius and ties its rim
    return _tie_innermost(flat_web(web, case.tip_mass.mass, cut), hub.radius)


def _tie_innermost(mesh: Mesh, hub_radius: float) -> Mesh:
    """Flat web of another topology: unless its generator chose hub-tied nodes, tie the
    nodes nearest the centre (all within 1e-6 of the smallest radius)."""
    sets = dict(mesh.node_sets)
    if len(sets.get("hub_tied", ())) == 0:
        r = np.hypot(mesh.node_ref[:, 0], mesh.node_ref[:, 1])
        sets["hub_tied"] = np.flatnonzero(r <= r.min() + 1e-6 * max(1.0, r.min()))
    return mesh.replace(node_sets=sets, hub_radius=float(hub_radius))


def _build_tethers(case) -> Mesh:
    t = case.tethers
    return tethers(t.count, t.length, t.elements, case.hub.radius, case.tip_mass.mass,
                   case.fold.pattern, case.fold.wrap)
