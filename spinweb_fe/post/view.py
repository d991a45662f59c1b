"""The camera of ``spinweb render``: the top view, or the oblique view that shows the web's
out-of-plane shape.

Both are parallel projections of the inertial frame. ``top`` looks down the spin axis
(+z towards the viewer, x to the right, y up). ``oblique`` looks at the x-y plane from
:data:`ELEVATION_DEG` = 30 degrees above it, from the -y side: the line of sight is
(0, cos 30, -sin 30), x stays to the right and the picture's vertical is
(0, sin 30, cos 30), so a point at (x, y, z) is drawn at (x, y sin 30 + z cos 30): a flat
disc becomes an ellipse half as tall as it is wide, and a height z is drawn 0.87 z high.
``z_scale`` multiplies z (the inertial out-of-plane coordinate) before the projection, for
display only; it is 1 unless asked for, and only the oblique view takes it (the top view
looks along z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from spinweb_fe.errors import InputError

VIEWS = ("top", "oblique")
ELEVATION_DEG = 30.0  # oblique view: the line of sight's angle below the x-y plane
MARGIN = 1.12  # view half-width / largest extent of the web from the axis (or box centre)


@dataclass(frozen=True)
class View:
    """A camera: ``name`` in :data:`VIEWS`, ``z_scale`` > 0 the display factor on z.

    Raises
    ------
    InputError
        An unknown view; a z_scale that is not a finite number > 0, or != 1 with the top view.
    """

    name: str = "top"
    z_scale: float = 1.0

    def __post_init__(self):
        if self.name not in VIEWS:
            raise InputError("--view", "", f"unknown view '{self.name}' (valid: "
                             f"{', '.join(VIEWS)})")
        z = self.z_scale
        if isinstance(z, bool) or not isinstance(z, (int, float)) or not math.isfinite(z) \
                or z <= 0:
            raise InputError("--z-scale", "", f"must be a finite number > 0, got {z!r}")
        if self.name == "top" and z != 1:
            raise InputError("--z-scale", "", "scales the out-of-plane coordinate of "
                             "--view oblique; the top view looks along it (give --view "
                             "oblique)")

    @property
    def oblique(self) -> bool:
        return self.name == "oblique"

    @property
    def right(self) -> np.ndarray:
        """Unit vector of the picture's horizontal, inertial frame."""
        return np.array([1.0, 0.0, 0.0])

    @property
    def up(self) -> np.ndarray:
        """Unit vector of the picture's vertical, inertial frame."""
        if not self.oblique:
            return np.array([0.0, 1.0, 0.0])
        e = math.radians(ELEVATION_DEG)
        return np.array([0.0, math.sin(e), math.cos(e)])

    @property
    def toward_camera(self) -> np.ndarray:
        """Unit vector from the scene towards the camera (minus the line of sight)."""
        if not self.oblique:
            return np.array([0.0, 0.0, 1.0])
        e = math.radians(ELEVATION_DEG)
        return np.array([0.0, -math.cos(e), math.sin(e)])

    def display(self, xyz) -> np.ndarray:
        """Copy of the points ``xyz`` (..., 3) [m] with z times ``z_scale``."""
        out = np.array(xyz, dtype=float)
        if self.z_scale != 1:
            out[..., 2] *= self.z_scale
        return out

    def screen(self, xyz) -> np.ndarray:
        """(..., 2) picture coordinates [m] (horizontal, vertical) of display points."""
        xyz = np.asarray(xyz, dtype=float)
        return np.stack([xyz @ self.right, xyz @ self.up], axis=-1)

    def caption(self) -> str:
        """What the title says about the view: '' for the top view."""
        if not self.oblique:
            return ""
        text = f"oblique: from -y, {ELEVATION_DEG:g} deg above the x-y plane"
        if self.z_scale != 1:
            text += f"; z drawn x {self.z_scale:g}"
        return text

    def vertical_label(self) -> str:
        """Label of the picture's vertical axis (matplotlib)."""
        if not self.oblique:
            return "y [m]"
        e = math.radians(ELEVATION_DEG)
        z = "z" if self.z_scale == 1 else f"({self.z_scale:g} z)"
        return f"{math.sin(e):.2f} y + {math.cos(e):.2f} {z} [m]"


def screen_box(view: View, points) -> tuple[np.ndarray, np.ndarray]:
    """(centre (2,), half-size (2,)) [m] of the picture box that holds the display points
    ``points`` (..., 3) with the margin :data:`MARGIN` on each half-size."""
    uv = view.screen(points).reshape(-1, 2)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = np.maximum(MARGIN * 0.5 * (hi - lo), 1e-9)
    return centre, half
