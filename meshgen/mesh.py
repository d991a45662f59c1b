"""The mesh value: an immutable set of arrays, MATLAB-style (node matrix, element matrix).

Every meshgen stage (flat web -> star fold -> coil on hub) is a pure function that takes
a Mesh and returns a new one; only ``node_pos`` (and the fold metadata) change between
stages. Rest lengths always come from the flat web and never from ``node_pos``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import numpy as np

#: per number of web corners n (the star fold's arms): cos(pi/n) and tan(pi/n), exact
#: where float allows (math.tan(pi/4) is not 1.0)
POLYGON_COS = {3: 0.5, 4: 0.5 ** 0.5}
POLYGON_TAN = {3: 3.0 ** 0.5, 4: 1.0}


def _frozen(a, dtype):
    a = np.ascontiguousarray(a, dtype=dtype)
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class Mesh:
    """A cable mesh.

    Attributes
    ----------
    node_pos : (n, 3) float64 [m]
        Current (initial) positions: flat, folded or coiled.
    node_ref : (n, 3) float64 [m]
        Reference positions: the flat, deployed web (tethers: straight and radial).
    elem_nodes : (m, 2) int64
        Element connectivity (node indices).
    elem_rest_len : (m,) float64 [m]
        Unstretched length of each element, from the flat web.
    node_point_mass : (n,) float64 [kg]
        Point (corner / tip) masses; the cable mass is added by :func:`lumped_mass`.
    node_sets : mapping str -> int64 array
        Named node sets; at least ``tips`` and ``hub_tied`` (possibly empty).
    elem_sets : mapping str -> int64 array
        Named element sets.
    node_arm : (n,) int64
        Arm (or tether) index of each node, -1 if the node belongs to no arm.
    node_arm_coord : (n,) float64 [m]
        Arm coordinate l of each node: distance from the arm root along the arm,
        measured in the flat web (tethers: distance from the tether root); NaN if none.
    arm_root_angle : (n_arms,) float64 [rad]
        Hub-frame angle of the point where each arm meets the hub rim (the root of the
        analytical model's arm).
    arm_length : float [m]
        Arm length H in arm coordinates (the arm coordinate of the tip).
    arm_root_coord : float [m]
        Arm coordinate of the root point on the rim (0 for tethers; for the star-folded
        web the coil starts past the gathered root region, see docs/mesh.md). The free
        arm length of the analytical model is ``arm_length - arm_root_coord``.
    hub_radius : float [m]
        Hub radius r0 (0 if the scene has no hub).
    wrap : int
        +1 if the arms are coiled trailing (clockwise, against a positive spin), -1 if
        leading, 0 if not coiled.
    """

    node_pos: np.ndarray
    node_ref: np.ndarray
    elem_nodes: np.ndarray
    elem_rest_len: np.ndarray
    node_point_mass: np.ndarray
    node_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    elem_sets: Mapping[str, np.ndarray] = field(default_factory=dict)
    node_arm: np.ndarray = None
    node_arm_coord: np.ndarray = None
    arm_root_angle: np.ndarray = None
    arm_length: float = 0.0
    arm_root_coord: float = 0.0
    hub_radius: float = 0.0
    wrap: int = 0

    def __post_init__(self):
        n = len(self.node_pos)
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("node_pos", _frozen(self.node_pos, np.float64).reshape(n, 3))
        set_("node_ref", _frozen(self.node_ref, np.float64).reshape(n, 3))
        set_("elem_nodes", _frozen(self.elem_nodes, np.int64).reshape(-1, 2))
        set_("elem_rest_len", _frozen(self.elem_rest_len, np.float64))
        set_("node_point_mass", _frozen(self.node_point_mass, np.float64))
        set_("node_arm", _frozen(np.full(n, -1) if self.node_arm is None else self.node_arm,
                                 np.int64))
        set_("node_arm_coord", _frozen(np.full(n, np.nan) if self.node_arm_coord is None
                                       else self.node_arm_coord, np.float64))
        set_("arm_root_angle", _frozen(np.zeros(0) if self.arm_root_angle is None
                                       else self.arm_root_angle, np.float64))
        sets = {"tips": np.zeros(0, np.int64), "hub_tied": np.zeros(0, np.int64)}
        sets.update({k: v for k, v in self.node_sets.items()})
        set_("node_sets", MappingProxyType({k: _frozen(v, np.int64) for k, v in sets.items()}))
        set_("elem_sets", MappingProxyType({k: _frozen(v, np.int64)
                                            for k, v in self.elem_sets.items()}))
        if len(self.elem_rest_len) != len(self.elem_nodes):
            raise ValueError("elem_rest_len and elem_nodes differ in length")
        if len(self.node_point_mass) != n:
            raise ValueError("node_point_mass and node_pos differ in length")

    @property
    def n_nodes(self) -> int:
        return len(self.node_pos)

    @property
    def n_elems(self) -> int:
        return len(self.elem_nodes)

    @property
    def n_arms(self) -> int:
        return len(self.arm_root_angle)

    def replace(self, **changes) -> "Mesh":
        """A new Mesh with some fields replaced (the value itself never changes)."""
        return dataclasses.replace(self, **changes)

    def elem_length(self, pos=None) -> np.ndarray:
        """(m,) current element lengths [m] for ``pos`` (default ``node_pos``)."""
        p = self.node_pos if pos is None else pos
        d = p[self.elem_nodes[:, 1]] - p[self.elem_nodes[:, 0]]
        return np.sqrt(np.einsum("ij,ij->i", d, d))


def lumped_mass(mesh: Mesh, line_density) -> np.ndarray:
    """(n,) node masses [kg]: half of each element's cable mass to each end, plus point masses.

    Parameters
    ----------
    line_density : float or (m,) float64 [kg/m]
        Cable mass per unit length, rho * A (one value, or one per element).
    """
    m = np.array(mesh.node_point_mass, dtype=np.float64)
    half = 0.5 * line_density * mesh.elem_rest_len
    np.add.at(m, mesh.elem_nodes[:, 0], half)
    np.add.at(m, mesh.elem_nodes[:, 1], half)
    return m
