"""History columns: name, SI unit and meaning of every ``/history`` dataset (FE and
analytical runs), and the rows a step-loop chunk turns into."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from spinweb_fe.fe.layout import (AUDIT, CONTACT, DEVICE, ENERGY, ROW, STEP_TERMS, VECTOR,
                                  row_columns)

#: the tables of the features' own columns (fe.layout)
FEATURE_TABLES = (DEVICE, AUDIT, CONTACT)


class Column(NamedTuple):
    """A history dataset: its SI unit and what it holds."""

    units: str
    doc: str


#: the columns the step loop records (fe.layout's tables: scalar row, energy terms, vector
#: row) and those derived from them here and in record/ (arm measures, strength)
COLUMNS = {
    **{c.name: Column(c.units, c.doc) for c in ROW},
    **{t.name: Column(t.units, t.doc) for t in ENERGY},
    "arm_length": Column("m", "deployed (free) arm length L per arm, as in the analytical "
                              "model"),
    "arm_angle": Column("rad", "arm angle phi from the radial at the root, counter-clockwise "
                               "positive; |phi| > pi/2 while coiled (phi = -(pi/2 + wound "
                               "angle) for a trailing wrap)"),
    "tip_omega": Column("rad/s", "angular velocity of the tip position about the hub axis"),
    "tip_position": Column("m", "position of each arm's tip (corner) node, inertial frame"),
    "payout_front": Column("m", "held coil: arm coordinate of each arm's peel front (its "
                                "base once everything is released)"),
    "payout_speed": Column("m/s", "held coil: rate of each arm's paid-out length; NaN across a "
                               "jump of the departure point (a level released at once)"),
    "payout_allowed": Column("m", "gate or reel (payout = gate or rate): the paid-out length "
                                  "the law allows"),
    "max_strain": Column("1", "failure strain given: strain of the most utilised element, "
                              "the largest over the steps since the previous row"),
    "max_strain_element": Column("1", "failure strain given: index of that element"),
    "max_strain_arm": Column("1", "failure strain given: arm of that element (-1: none)"),
    "utilisation": Column("1", "failure strain given: largest strain / failure strain over "
                               "the elements and the steps since the previous row"),
    "broken_elements": Column("1", "rupture: number of broken elements"),
    **{c.name: Column(c.units, c.doc) for table in FEATURE_TABLES for c in table},
    **{c.name: Column(c.units, c.doc) for c in VECTOR},
}
#: columns that only some scenes or models have (a held coil, a rate payout, a failure
#: strain, rupture, an energy term a scene may lack, a feature's columns, the vector row)
OPTIONAL = (("payout_front", "payout_speed", "payout_allowed", "max_strain",
             "max_strain_element", "max_strain_arm", "utilisation", "broken_elements")
            + tuple(t.name for t in ENERGY if not t.step or t.present is not None)
            + tuple(c.name for table in FEATURE_TABLES for c in table)
            + tuple(c.name for c in VECTOR))
#: name -> SI unit of every history dataset
HISTORY_UNITS = {name: c.units for name, c in COLUMNS.items()}


def table_rows(table: np.ndarray, nrec: int, model) -> dict:
    """The scalar columns of the first ``nrec`` rows of a step-loop table: fe.layout.ROW and
    the step's energy terms that ``model`` can have (Term.present)."""
    rows = row_columns(table, nrec)
    for term in STEP_TERMS:
        if term.present is not None and not term.present(model):
            del rows[term.name]
    return rows


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
