"""From generator parameters to the initial mesh of a scene: flat web -> (star fold + coil |
flat), or tethers. Pure: plain parameters in, a Mesh out, MeshValueError (naming the
parameter) on bad input."""

from __future__ import annotations

import numpy as np

from meshgen.checks import MeshValueError
from meshgen.flat import default_cutout, effective_cutout, flat_quadquad
from meshgen.fold import fold_web
from meshgen.layers import check_gap
from meshgen.mesh import Mesh
from meshgen.registry import topology
from meshgen.tethers import tethers
from meshgen.topologies import flat_other, outline_cutout

__all__ = ["flat_web", "quadquad_cutout", "tethers", "web_mesh"]


def flat_web(name: str, side: float, mesh_width: float, elements_per_segment: int,
             corner_mass: float, hub_cutout: float) -> Mesh:
    """The flat web of a topology: quadquad with a square cut-out of half-width
    ``hub_cutout`` (a grid line), the others with a disc of that radius removed."""
    topology(name)
    if name == "quadquad":
        return flat_quadquad(side, mesh_width, elements_per_segment, corner_mass, hub_cutout)
    return flat_other(name, side, mesh_width, elements_per_segment, corner_mass, hub_cutout)


def quadquad_cutout(side: float, mesh_width: float, hub_radius: float,
                    hub_cutout: float | None = None) -> float:
    """Cut-out half-width c [m] of a quadquad web: ``hub_cutout`` (default: the smallest
    grid line at or outside the hub radius) rounded outwards to a grid line."""
    if hub_cutout is None:
        return default_cutout(side, mesh_width, hub_radius)
    return effective_cutout(side, mesh_width, hub_cutout)


def web_mesh(name: str, side: float, mesh_width: float, elements_per_segment: int,
             corner_mass: float, hub_radius: float, hub_cutout: float | None = None,
             pattern: str = "star", wrap: str = "trailing", ties: str = "frame",
             layer_gap: float = 0.0) -> Mesh:
    """Initial mesh of a web scene.

    A quadquad web is tied to the hub as ``ties`` says (``frame``: the whole boundary of the
    cut-out; ``axes``: its 4 nodes on the axes), see docs/mesh.md. A star-folded web of
    another topology gets a hole shaped like its outline (inradius ``hub_cutout``, default
    the hub radius; tritri rounds it out to a mesh line) and is tied by its frame; a flat
    one keeps the disc cut-out with its rim tied.

    Parameters
    ----------
    name : str
        Topology (see :data:`meshgen.registry.TOPOLOGIES`).
    side, mesh_width : float [m]
    elements_per_segment : int
    corner_mass : float [kg]
    hub_radius : float [m]
    hub_cutout : float or None [m]
    pattern : {'star', 'flat'}
    wrap : {'trailing', 'leading'}
    ties : {'frame', 'axes'}
    layer_gap : float [m]
        g >= 0: stack the star fold's layers and the coil's passes at least g apart
        (quadquad, ``star``, ``frame`` only; docs/mesh.md 2.9).

    Returns
    -------
    Mesh
        ``node_pos`` is the initial (folded) state, ``node_ref`` the flat deployed state.
    """
    topology(name)
    if check_gap(layer_gap) > 0 and pattern == "flat":
        raise MeshValueError("layer_gap", "the flat web has no layers (fold.pattern = 'flat')")
    if name == "quadquad":
        c = quadquad_cutout(side, mesh_width, hub_radius, hub_cutout)
        flat = flat_quadquad(side, mesh_width, elements_per_segment, corner_mass, c)
        return fold_web(flat, hub_radius, pattern, wrap, ties, layer_gap)
    cut = hub_radius if hub_cutout is None else hub_cutout
    if pattern == "star":
        # a hole shaped like the outline: its boundary is the hub frame of the fold
        if ties == "axes":
            raise MeshValueError("ties", "ties = 'axes' needs the square web with a square "
                                 f"mesh (topology '{name}'); use 'frame'")
        c = outline_cutout(name, side, mesh_width, cut)
        flat = flat_other(name, side, mesh_width, elements_per_segment, corner_mass, c,
                          hole="outline")
        return fold_web(flat, hub_radius, "star", wrap, "frame", layer_gap)
    # flat: the generator cuts a disc of this radius and ties its rim
    return _tie_innermost(flat_web(name, side, mesh_width, elements_per_segment, corner_mass,
                                   cut), hub_radius)


def _tie_innermost(mesh: Mesh, hub_radius: float) -> Mesh:
    """Flat web of another topology: unless its generator chose hub-tied nodes, tie the
    nodes nearest the centre (all within 1e-6 of the smallest radius)."""
    sets = dict(mesh.node_sets)
    if len(sets.get("hub_tied", ())) == 0:
        r = np.hypot(mesh.node_ref[:, 0], mesh.node_ref[:, 1])
        sets["hub_tied"] = np.flatnonzero(r <= r.min() + 1e-6 * max(1.0, r.min()))
    return mesh.replace(node_sets=sets, hub_radius=float(hub_radius))
