"""History columns: name, SI unit and meaning of every ``/history`` dataset (FE and
analytical runs), and the rows a step-loop chunk turns into."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from spinweb_fe.fe.step import REC_COLUMNS


class Column(NamedTuple):
    """A history dataset: its SI unit and what it holds."""

    units: str
    doc: str


COLUMNS = {
    "time": Column("s", "simulated time"),
    "hub_angle": Column("rad", "hub rotation angle about +z (counter-clockwise positive)"),
    "hub_omega": Column("rad/s", "hub angular velocity omega_centre"),
    "hub_torque": Column("N m", "control torque applied to the hub"),
    "kinetic_energy": Column("J", "kinetic energy of everything, hub included"),
    "strain_energy": Column("J", "elastic energy stored in the cables"),
    "torque_work": Column("J", "work done on the hub by the control torque"),
    "damping_dissipation": Column("J", "energy dissipated by axial cable damping"),
    "contact_dissipation": Column("J", "energy lost in cable-hub contact (impact and friction)"),
    "angular_momentum": Column("N m s", "angular momentum about the spin axis, hub included"),
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
}
#: columns that only some scenes or models have (a held coil, a rate payout, a failure
#: strain, rupture)
OPTIONAL = ("payout_front", "payout_speed", "payout_allowed", "restraint_work", "max_strain",
            "max_strain_element", "max_strain_arm", "utilisation", "broken_elements",
            "rupture_dissipation")
#: name -> SI unit of every history dataset
HISTORY_UNITS = {name: c.units for name, c in COLUMNS.items()}


def table_rows(table: np.ndarray, nrec: int) -> dict:
    """The scalar columns (REC_COLUMNS) of the first ``nrec`` rows of a step-loop table."""
    return {name: table[:nrec, j].copy() for j, name in enumerate(REC_COLUMNS)}
