"""Tether scenes: n radial cables tied to the hub rim, each with a tip mass.

Numbering: tether j owns nodes j (m+1) + i, i = 0 (root, on the rim) .. m (tip), and
elements j m + i joining its nodes i and i+1.
"""

from __future__ import annotations

import math

import numpy as np

from meshgen.checks import MeshValueError
from meshgen.fold import coil
from meshgen.layers import check_gap
from meshgen.mesh import Mesh
from meshgen.registry import TETHER_FOLDS


def tethers(count: int, length: float, elements: int, hub_radius: float,
            tip_mass: float, pattern: str = "coiled", wrap: str = "trailing",
            layer_gap: float = 0.0) -> Mesh:
    """n tethers of length H, each of m elements, tied to the hub rim.

    Tether j is rooted on the rim at theta_j = 2 pi j / n (radius r0, z = 0) and carries
    the tip mass at its end. ``node_ref`` is straight and radial. ``node_pos`` is the
    same (``straight``) or wound on the rim (``coiled``): the node at arc length s sits at
    angle theta_j - w s / r0 (w = +1 trailing, -1 leading), radius r0; turns overlap
    and chords are shorter than rest lengths (slack, never stretched).

    Parameters
    ----------
    count : int
        Number of tethers n.
    length : float [m]
        Tether length H.
    elements : int
        Elements per tether m (rest length H/m).
    hub_radius : float [m]
        Hub radius r0 > 0.
    tip_mass : float [kg]
    pattern : {'coiled', 'straight'}
    wrap : {'trailing', 'leading'}
    layer_gap : float [m]
        g >= 0: with g > 0 the coil rises along z so that its passes (each tether over
        the others and over its own turns) are at least g apart (docs/mesh.md 2.9).

    Returns
    -------
    Mesh
        Node sets ``hub_tied`` (roots) and ``tips``; element set ``tether_<j>`` per tether;
        arm data: ``node_arm`` = j, ``node_arm_coord`` = s, ``arm_root_angle`` = theta_j,
        ``arm_length`` = H, ``arm_root_coord`` = 0, ``wrap`` = +1 / -1 / 0.
    """
    n, m = int(count), int(elements)
    if n < 1:
        raise MeshValueError("count", f"must be >= 1, got {count}")
    if m < 1:
        raise MeshValueError("elements", f"must be >= 1, got {elements}")
    if not length > 0:
        raise MeshValueError("length", f"must be > 0, got {length:g} m")
    if not hub_radius > 0:
        raise MeshValueError("hub_radius", f"must be > 0, got {hub_radius:g} m")
    if tip_mass < 0:
        raise MeshValueError("tip_mass", f"must be >= 0, got {tip_mass:g} kg")
    if pattern not in TETHER_FOLDS:
        raise MeshValueError("pattern", f"unknown tether fold '{pattern}' "
                             f"(valid: {', '.join(TETHER_FOLDS)})")
    if check_gap(layer_gap) > 0 and pattern != "coiled":
        raise MeshValueError("layer_gap", f"straight tethers have no layers (fold.pattern = "
                             f"'{pattern}')")
    theta = 2.0 * math.pi * np.arange(n) / n
    s = np.arange(m + 1) * (length / m)
    r = hub_radius + s
    ref = np.zeros((n * (m + 1), 3))
    ref[:, 0] = (np.cos(theta)[:, None] * r[None, :]).ravel()
    ref[:, 1] = (np.sin(theta)[:, None] * r[None, :]).ravel()
    first = np.arange(n)[:, None] * (m + 1) + np.arange(m)[None, :]
    elems = np.column_stack([first.ravel(), first.ravel() + 1])
    roots = np.arange(n) * (m + 1)
    tips = roots + m
    pmass = np.zeros(len(ref))
    pmass[tips] = tip_mass
    mesh = Mesh(node_pos=ref, node_ref=ref, elem_nodes=elems,
                elem_rest_len=np.full(n * m, length / m), node_point_mass=pmass,
                node_sets={"hub_tied": roots, "tips": tips},
                elem_sets={f"tether_{j}": np.arange(j * m, (j + 1) * m) for j in range(n)},
                node_arm=np.repeat(np.arange(n), m + 1), node_arm_coord=np.tile(s, n),
                arm_root_angle=theta, arm_length=float(length), arm_root_coord=0.0,
                hub_radius=float(hub_radius), wrap=0)
    return coil(mesh, wrap, layer_gap=layer_gap) if pattern == "coiled" else mesh
