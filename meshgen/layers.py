"""Stacked layers of the star fold and the coil (``fold.layer_gap``) [reconstructed].

With a gap g = 0 the star fold gathers every mesh line across an arm into one point (the
layers coincide) and the coil winds every turn on the rim in the hub plane. With g > 0
(docs/mesh.md, section 2.9):

- **Columns** (the square web with a square mesh): a node at flat position (x, y) is
  lifted to z = eta G, G = max(|x|, c) - max(|y|, c), eta = h / e (c the hole inradius,
  e the element rest length, h >= g the layer spacing). The layers of one arm level
  stand in a column centred on the hub plane: the leg along the x half-axes above, the
  leg along the y half-axes below, the arm's diagonal node at z = 0; the tied frame
  (G = 0) stays in the hub plane. Every element then climbs by h or 0, so the radial
  run of the arm beyond the frame corner is shortened by the factor s <= sqrt(1 - eta^2)
  (arm coordinate l -> in-plane arc q = l_s + s (l - l_s) from the corner l_s).
- **Coil** (every coiled scene): each turn stays on the rim r0, and the coil rises along
  the hub axis, z += Z(u), u = l - l1 >= 0 the arm coordinate past the rim point l1, by
  at least KAPPA (H(l) + H(l + P) + h) over one pass P (the arm length that winds 2 pi / n,
  the angle between two arm roots), H(l) = eta (a - l) the column half-height: the
  passes of the arms (and the later turns of one arm) over each other and over the
  radial spokes are separated by at least KAPPA h along the axis. Z is the quadratic that
  meets this with equality, Z(u) = A u - C u^2.

The layer spacing h is g enlarged by the steepest tilt of a cable (h = g sqrt(1 + tau^2)),
so that tilted neighbours are still g apart; h, s and the rise are one fixed point
(:func:`layer_plan`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from meshgen.checks import MeshValueError
from meshgen.mesh import Mesh

#: margin of the coil's rise over the sum of two column half-heights and a layer spacing:
#: it covers the chords (a chord's height is linear along it, the rise along the arc)
KAPPA = 1.1


class LayerPlan(NamedTuple):
    """The stacked geometry of one folded or coiled mesh (lengths in m).

    Attributes
    ----------
    gap : float
        g, the least distance between two elements that share no node.
    spacing : float
        h >= g, the distance of two layers in a column along the hub axis.
    eta : float
        h / e: the climb of a column per unit arm coordinate (0: no columns, tethers).
    shrink : float
        s: in-plane arc per unit arm coordinate beyond ``start``.
    start : float
        l_s, where the radial run starts (the frame corner; 0 for tethers).
    rim : float
        l1 = l_s + (l0 - l_s) / s, the arm coordinate that lands on the rim point.
    rise : (float, float)
        (A, C) of the coil's rise Z(u) = A u - C u^2 [m], u = l - l1.
    """

    gap: float
    spacing: float
    eta: float
    shrink: float
    start: float
    rim: float
    rise: tuple

    def arc(self, l: np.ndarray) -> np.ndarray:
        """In-plane arc coordinate q(l) [m] of arm coordinates l."""
        return np.where(l > self.start, self.start + self.shrink * (l - self.start), l)

    def lift(self, l: np.ndarray) -> np.ndarray:
        """The coil's rise Z(l - l1) [m] (0 before the rim point)."""
        u = np.maximum(l - self.rim, 0.0)
        a, c = self.rise
        return a * u - c * u * u


def check_gap(gap: float) -> float:
    """g as a float, MeshValueError if it is negative or not finite."""
    g = float(gap)
    if not (math.isfinite(g) and g >= 0.0):
        raise MeshValueError("layer_gap", f"must be >= 0, got {gap!r} m")
    return g


def layer_plan(mesh: Mesh, gap: float, start: float, columns: bool) -> LayerPlan:
    """The fixed point (h, s, rise) of a mesh with arm data (see the module docstring).

    Parameters
    ----------
    mesh : Mesh
        With ``arm_length`` a, ``arm_root_coord`` l0, ``hub_radius`` r0, n arms and one
        element rest length e.
    gap : float [m]
        g > 0.
    start : float [m]
        l_s, the arm coordinate where the radial lead-in starts (l0 - lead-in).
    columns : bool
        The arms are columns of layers (a folded web), or single cables (tethers).
    """
    rest = mesh.elem_rest_len
    e = float(rest.max())
    if rest.min() < e * (1 - 1e-9):
        raise MeshValueError("layer_gap", "stacked layers need one element length in the "
                             "whole mesh")
    r0, n, a, l0 = mesh.hub_radius, mesh.n_arms, mesh.arm_length, mesh.arm_root_coord
    if columns and e > r0:
        raise MeshValueError("layer_gap", f"needs elements no longer than the hub radius "
                             f"({e:g} m > r0 = {r0:g} m): longer chords cut across the "
                             "coil's columns")

    def plan(h, s):
        eta = h / e if columns else 0.0
        pass_len = 2.0 * math.pi / n * r0 / s          # P: arm coordinate of one pass
        rim = start + (l0 - start) / s
        reach = max(a - rim, 0.0)
        rise = (KAPPA * (2.0 * eta * reach + h) / pass_len, KAPPA * eta / pass_len)
        return LayerPlan(gap, h, eta, s, start, rim, rise)

    h, s = gap, 1.0
    for _ in range(100):
        p = plan(h, s)
        slope = p.eta + p.rise[0]                      # steepest climb per unit l
        if slope >= 0.5:
            raise MeshValueError("layer_gap", f"{gap:g} m is too large for elements of "
                                 f"{e:g} m on a hub of radius {r0:g} m")
        s_new = math.sqrt(1.0 - slope * slope)
        chord = 2.0 * r0 * math.sin(min(0.5 * s_new * e / r0, 0.5 * math.pi))
        tau = math.sqrt(2.0) * slope * e / chord       # a chord next to a spoke: >= it / sqrt 2
        h_new = gap * math.sqrt(1.0 + tau * tau)
        done = abs(h_new - h) <= 1e-15 * h and abs(s_new - s) <= 1e-15
        h, s = h_new, s_new
        if done:
            break
    return plan(h, s)


def check_columns(mesh: Mesh, tol: float) -> None:
    """MeshValueError unless the web can stand in columns: the square web whose cables all
    run along x or y (quadquad), within ``tol`` [m]."""
    d = mesh.node_ref[mesh.elem_nodes[:, 1], :2] - mesh.node_ref[mesh.elem_nodes[:, 0], :2]
    if mesh.n_arms != 4 or np.any(np.abs(d).min(axis=1) > tol):
        raise MeshValueError("layer_gap", "stacked layers need the square web with a square "
                             "mesh (quadquad): its cables run along the half-axes")


def column_height(mesh: Mesh, c: float, eta: float) -> np.ndarray:
    """(n,) z [m] of the columns of a square web with a square mesh (:func:`check_columns`):
    eta G, G = max(|x|, c) - max(|y|, c) from the flat positions (0 on the tied frame)."""
    x, y = np.abs(mesh.node_ref[:, 0]), np.abs(mesh.node_ref[:, 1])
    return eta * (np.maximum(x, c) - np.maximum(y, c))


def check_clearance(c: float, r0: float, plan: LayerPlan) -> None:
    """The hub frame (inradius c) must stand at least one layer spacing off the rim, where
    the coil passes under the frame edges."""
    if c - r0 < plan.spacing:
        raise MeshValueError("layer_gap", f"{plan.gap:g} m needs the hub frame at least "
                             f"r0 + {plan.spacing:.6g} m from the axis, its inradius is "
                             f"{c:g} m for r0 = {r0:g} m (set web.hub_cutout larger)")
