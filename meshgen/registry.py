"""The named choices of mesh generation, each defined once: topologies (web outline and
mesh cell), web folds, tether folds, coil directions and hub attachments.

Adding a topology is an entry in ``TOPOLOGIES`` and, for a new mesh cell, a lattice in
:mod:`meshgen.topologies`; the case schema, the area rule and the analytical mapping read
this table.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from meshgen.checks import MeshValueError


class Topology(NamedTuple):
    """A web/mesh configuration of the paper's Fig. 2.

    Attributes
    ----------
    name : str
    corners : int
        Corners of the web outline (3: equilateral triangle, 4: square): the star fold's arms.
    cell : str
        Mesh cell: 'quad', 'tri' or 'hex'.
    doc : str
    """

    name: str
    corners: int
    cell: str
    doc: str


TOPOLOGIES = {t.name: t for t in (
    Topology("quadquad", 4, "quad", "square web, square mesh (the paper's choice)"),
    Topology("tritri", 3, "tri", "triangular web, triangular mesh"),
    Topology("trihex", 3, "hex", "triangular web, hexagonal mesh"),
    Topology("triquad", 3, "quad", "triangular web, square mesh"),
    Topology("quadtri", 4, "tri", "square web, triangular mesh"),
    Topology("quadhex", 4, "hex", "square web, hexagonal mesh"),
)}

#: cable length per unit web area of an infinite mesh, times the mesh width t, per cell:
#: 2 for squares of side t, 2 sqrt(3) for triangles of edge t, 2 / sqrt(3) for hexagons
LENGTH_PER_AREA_T = {"quad": 2.0, "tri": 2.0 * math.sqrt(3.0), "hex": 2.0 / math.sqrt(3.0)}

#: star-folded or flat web
WEB_FOLDS = {"star": "star fold into n arms, coiled on the hub",
             "flat": "the deployed web, flat"}
#: tethers straight and radial, or wound on the hub rim
TETHER_FOLDS = {"straight": "straight and radial", "coiled": "wound on the hub rim"}
#: the folds that wind the arms on the hub (a coiled scene: its stowage, the analytical
#: model's coiled start)
COILED_FOLDS = ("star", "coiled")
#: coil direction relative to a positive spin: +1 trailing (clockwise), -1 leading
WRAP_SIGN = {"trailing": 1, "leading": -1}
#: hub attachment of the star-folded web
TIES = {"frame": "every node of the hole boundary (a rigid frame around the hub)",
        "axes": "the 4 nodes where the half-axes leave the hole (square web, square mesh)"}


def topology(name: str) -> Topology:
    """The registry entry of ``name`` (MeshValueError naming the valid ones)."""
    try:
        return TOPOLOGIES[name]
    except KeyError:
        raise MeshValueError("topology", f"unknown topology '{name}' "
                             f"(valid: {', '.join(TOPOLOGIES)})") from None


def cable_length_per_area(name: str, mesh_width: float) -> float:
    """Cable length per unit web area [1/m] of the topology's infinite mesh of width t."""
    return LENGTH_PER_AREA_T[topology(name).cell] / mesh_width


def area_from_areal_density(name: str, areal_density: float, mesh_width: float,
                            density: float) -> float:
    """Cable cross-section area [m^2] that gives a web the areal density rho_A [kg/m^2]:
    A = rho_A / (rho lambda), lambda = :func:`cable_length_per_area` (the paper's rule
    A = rho_A t / (2 rho) for the square mesh)."""
    return areal_density / (density * cable_length_per_area(name, mesh_width))
