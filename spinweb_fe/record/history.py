"""History columns: name, SI unit and meaning of every ``/history`` dataset (FE and
analytical runs), and the rows a step-loop chunk turns into."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from spinweb_fe.fe.step import REC_COLUMNS
from spinweb_fe.fe.vectors import VEC_LAYOUT


class Column(NamedTuple):
    """A history dataset: its SI unit and what it holds."""

    units: str
    doc: str


COLUMNS = {
    "time": Column("s", "simulated time"),
    "hub_angle": Column("rad", "hub rotation angle about +z (counter-clockwise positive); "
                               "free hub: its turn about its own axis"),
    "hub_omega": Column("rad/s", "hub angular velocity omega_centre (free hub: about its "
                                 "own axis)"),
    "hub_torque": Column("N m", "control torque applied to the hub (about its axis)"),
    "kinetic_energy": Column("J", "kinetic energy of everything, hub included"),
    "strain_energy": Column("J", "elastic energy stored in the cables"),
    "torque_work": Column("J", "work done on the hub by the control torque"),
    "damping_dissipation": Column("J", "energy dissipated by axial cable damping"),
    "contact_dissipation": Column("J", "energy lost in cable-hub contact (impact and friction)"),
    "angular_momentum": Column("N m s", "angular momentum about the spin axis (+z), hub "
                                        "included"),
    "max_tension": Column("N", "largest cable tension"),
    "arm_length": Column("m", "deployed (free) arm length L per arm, as in the analytical "
                              "model"),
    "arm_angle": Column("rad", "arm angle phi from the radial at the root, counter-clockwise "
                               "positive; |phi| > pi/2 while coiled (phi = -(pi/2 + wound "
                               "angle) for a trailing wrap)"),
    "tip_omega": Column("rad/s", "angular velocity of the tip position about the hub axis"),
    "tip_position": Column("m", "position of each arm's tip (corner) node, inertial frame"),
    "payout_front": Column("m", "held coil: arm coordinate of each arm's peel front (its "
                                "base once everything is released)"),
    "payout_speed": Column("m/s", "held coil: rate of each arm's paid-out length"),
    "payout_allowed": Column("m", "rate payout: the paid-out length the law allows"),
    "restraint_work": Column("J", "analytical rate payout: work of the restraint that holds the "
                                  "arm back, E - E0 - torque work"),
    "max_strain": Column("1", "failure strain given: strain of the most utilised element, "
                              "the largest over the steps since the previous row"),
    "max_strain_element": Column("1", "failure strain given: index of that element"),
    "max_strain_arm": Column("1", "failure strain given: arm of that element (-1: none)"),
    "utilisation": Column("1", "failure strain given: largest strain / failure strain over "
                               "the elements and the steps since the previous row"),
    "broken_elements": Column("1", "rupture: number of broken elements"),
    "rupture_dissipation": Column("J", "rupture: strain energy the broken elements held when "
                                       "they broke"),
    "linear_momentum": Column("kg m/s", "out of the plane: total linear momentum, hub "
                                        "included, inertial frame"),
    "angular_momentum_vector": Column("N m s", "out of the plane: total angular momentum "
                                               "about the origin, hub included"),
    "hub_position": Column("m", "out of the plane: the hub centre, inertial frame"),
    "hub_quaternion": Column("1", "out of the plane: the hub's attitude (w, x, y, z), hub "
                                  "frame to inertial"),
    "hub_axis": Column("1", "out of the plane: the hub's spin axis (unit vector), inertial "
                            "frame"),
    "hub_angular_velocity": Column("rad/s", "out of the plane: the hub's angular velocity "
                                            "vector, inertial frame"),
    "out_of_plane_rms": Column("m", "out of the plane: RMS over the web's nodes (not the "
                                    "hub's) of their distance from the hub plane"),
    "out_of_plane_max": Column("m", "out of the plane: the largest distance of a web node "
                                    "from the hub plane"),
    "gravity_gradient_work": Column("J", "gravity gradient: work of the tidal field on "
                                         "nodes and hub"),
}
#: columns that only some scenes or models have (a held coil, a rate payout, a failure
#: strain, rupture)
OPTIONAL = ("payout_front", "payout_speed", "payout_allowed", "restraint_work", "max_strain",
            "max_strain_element", "max_strain_arm", "utilisation", "broken_elements",
            "rupture_dissipation") + tuple(name for name, _ in VEC_LAYOUT)
#: name -> SI unit of every history dataset
HISTORY_UNITS = {name: c.units for name, c in COLUMNS.items()}


def table_rows(table: np.ndarray, nrec: int) -> dict:
    """The scalar columns (REC_COLUMNS) of the first ``nrec`` rows of a step-loop table."""
    return {name: table[:nrec, j].copy() for j, name in enumerate(REC_COLUMNS)}


def vector_rows(vec: np.ndarray, gravity: bool) -> dict:
    """The vector columns (fe.vectors.VEC_LAYOUT) of a step-loop vector table: (T, w)
    arrays, (T,) for width 1; ``gravity_gradient_work`` only with the gravity gradient."""
    out, j = {}, 0
    for name, width in VEC_LAYOUT:
        if name != "gravity_gradient_work" or gravity:
            out[name] = vec[:, j].copy() if width == 1 else vec[:, j:j + width].copy()
        j += width
    return out


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """(T, 3, 3) rotation matrices of (T, 4) unit quaternions (w, x, y, z)."""
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)],
        -2)


def hub_plane(pos, vel, centre, quaternion):
    """(T, p, 3) positions and velocities in the hub's plane: relative to the hub centre and
    turned back by the swing of its attitude (the part that tilts its axis; its turn about
    the axis is kept, as ``hub_angle``), so that the arm measure of a free hub is that of a
    hub on a fixed axis. Velocities are turned only (the hub centre's own velocity, small
    against the tips', is not removed)."""
    q = np.asarray(quaternion, np.float64)
    a = 2.0 * np.arctan2(q[:, 3], q[:, 0])  # the twist about the hub axis
    twist = np.stack([np.cos(a / 2), np.zeros_like(a), np.zeros_like(a), np.sin(a / 2)], -1)
    w1, x1, y1, z1 = q.T
    w2, z2 = twist[:, 0], -twist[:, 3]  # q (x) twist^-1
    swing = np.stack([w1 * w2 - z1 * z2, x1 * w2 + y1 * z2, y1 * w2 - x1 * z2,
                      w1 * z2 + z1 * w2], -1)
    S = quaternion_matrix(swing)
    back = np.einsum("tji,tpj->tpi", S, pos - centre[:, None, :])
    return back, np.einsum("tji,tpj->tpi", S, vel)
