"""The layouts of what the step loop records, one table each: the scalar history row, the
energy terms of the balance, the vector row (runs that can leave the plane), the per-arm
coil row and the strength row.

Each table names its columns with their SI unit and meaning; :data:`SLOTS` gives every
column its index, and the kernels take those indices as an argument (``Recording.slots``),
never as module globals. The readers (``record/history.py``, ``record/energy.py``,
``record/arms.py``, ``record/strength.py``) turn the recorded arrays into named columns
through the same tables.

Adding a work or dissipation term is one :data:`ENERGY` entry plus the kernel line that
accumulates it (``incr[slots.term.<name>] = ...`` in the step): the state's ``totals`` grow
by one, the row writer, the history and the energy balance follow the table.
"""

from __future__ import annotations

from collections import namedtuple
from typing import Callable, NamedTuple


class Col(NamedTuple):
    """A recorded quantity: its name (the ``/history`` dataset), width, SI unit, meaning;
    ``present``: None for a column every run of its table has, else whether a Model has it
    (written to the history only then)."""

    name: str
    width: int
    units: str
    doc: str
    present: Callable | None = None


class Term(NamedTuple):
    """An energy term of the balance KE + SE + sum(sign * term) = const.

    ``sign`` -1: work done on the system (an input), +1: energy it loses (a dissipation).
    ``step``: True if the step loop accumulates it in ``State.totals`` (a column of the
    scalar row), else it is a column of its feature's table (:attr:`col`: the strength row,
    the devices' per-arm row, the contact's row). ``present``: for a step term only some
    scenes have, whether a Model has it (its history column is written only then).
    """

    name: str
    sign: int
    units: str
    doc: str
    step: bool = True
    present: Callable | None = None

    @property
    def col(self) -> Col:
        """The term as a column of its feature's table."""
        return Col(self.name, 1, self.units, self.doc)


#: the scalar row, before the energy terms (each a column of width 1)
ROW = (
    Col("time", 1, "s", "simulated time"),
    Col("hub_angle", 1, "rad", "hub rotation angle about +z (counter-clockwise positive); free "
                               "hub: its turn about its own axis"),
    Col("hub_omega", 1, "rad/s", "hub angular velocity omega_centre (free hub: about its own "
                                 "axis)"),
    Col("hub_torque", 1, "N m", "control torque applied to the hub (about its axis)"),
    Col("kinetic_energy", 1, "J", "kinetic energy of everything, hub included"),
    Col("strain_energy", 1, "J", "elastic energy stored in the cables"),
    Col("angular_momentum", 1, "N m s", "angular momentum about the spin axis (+z), hub "
                                        "included"),
    Col("max_tension", 1, "N", "largest cable tension"),
)

#: the energy terms of the balance, in the order of ``State.totals`` (the step's terms)
ENERGY = (
    Term("torque_work", -1, "J", "work done on the hub by the control torque"),
    Term("damping_dissipation", 1, "J", "energy dissipated by axial cable damping"),
    Term("contact_dissipation", 1, "J", "energy lost in cable-hub contact (impact and "
                                        "friction)"),
    Term("rupture_dissipation", 1, "J", "rupture: strain energy the broken elements held "
                                        "when they broke", step=False),
    Term("brake_work", -1, "J", "reel or brake (payout = rate or brake): each arm's device's "
                                "work on its line so far, per arm (negative: energy it took)",
         step=False),
    Term("gravity_gradient_work", -1, "J", "gravity gradient: work of the tidal field on "
                                           "nodes and hub",
         present=lambda model: model.env.n > 0.0),
    Term("cable_contact_energy", 1, "J", "cable-cable contact (contact.cables): energy "
                                         "stored in its penalty springs now", step=False),
    Term("cable_contact_dissipation", 1, "J", "cable-cable contact (contact.cables): kinetic "
                                              "energy its impulses took from pairs that "
                                              "would have passed through each other",
         step=False),
)
TERMS = {t.name: t for t in ENERGY}
STEP_TERMS = tuple(t for t in ENERGY if t.step)

#: the vector row of runs that can leave the plane (a free hub, a perturbation)
VECTOR = (
    Col("linear_momentum", 3, "kg m/s", "out of the plane: total linear momentum, hub "
                                        "included, inertial frame"),
    Col("angular_momentum_vector", 3, "N m s", "out of the plane: total angular momentum "
                                               "about the origin, hub included"),
    Col("hub_position", 3, "m", "out of the plane: the hub centre, inertial frame"),
    Col("hub_quaternion", 4, "1", "out of the plane: the hub's attitude (w, x, y, z), hub "
                                  "frame to inertial"),
    Col("hub_axis", 3, "1", "out of the plane: the hub's spin axis (unit vector), inertial "
                            "frame"),
    Col("hub_angular_velocity", 3, "rad/s", "out of the plane: the hub's angular velocity "
                                            "vector, inertial frame"),
    Col("out_of_plane_rms", 1, "m", "out of the plane: RMS over the web's nodes (not the "
                                    "hub's) of their distance from the hub plane"),
    Col("out_of_plane_max", 1, "m", "out of the plane: the largest distance of a web node "
                                    "from the hub plane"),
    Col("axis_torque", 3, "N m", "out of the plane, hub on a fixed axis: the torque the axis "
                                 "exerts on the hub about its centre (what holds it against "
                                 "the out-of-plane pull of the cables and the tidal torque)",
        present=lambda model: model.body is None),
)

#: per arm, the payout devices' columns (a reel or brake at D: fe.coil.payout)
DEVICE = (
    Col("brake_tension", 1, "N", "reel or brake: the line tension at each arm's departure "
                                 "point"),
    TERMS["brake_work"].col,
)

#: per arm of a held coil (the step records them; record/arms.py reads them by name), its
#: devices' columns last
ARM = (
    Col("front", 1, "m", "arm coordinate of the peel front (its base once all is released)"),
    Col("next", 1, "m", "arm coordinate of the next outer level"),
    Col("rim", 1, "1", "1 if the front lies on the hub rim"),
    Col("held_back", 1, "1", "1 if the payout law holds the front back"),
    Col("allowed", 1, "m", "paid-out length the payout law allows (NaN: free payout)"),
) + DEVICE

#: the strength row of scenes with a failure strain (fe.rupture)
STRENGTH = (
    Col("utilisation", 1, "1", "largest strain / failure strain since the previous row"),
    Col("max_strain", 1, "1", "strain of that element"),
    Col("max_strain_element", 1, "1", "index of that element"),
    Col("broken_elements", 1, "1", "broken elements so far"),
    TERMS["rupture_dissipation"].col,
)

#: the crossing audit's row (audit.crossings, or the candidate list of contact.cables)
AUDIT = (Col("crossings", 1, "1", "audit.crossings: crossings of two cable elements so far"),)

#: the cable contact's row (contact.cables: fe.contact.penalty.ContactKernel.rows)
CONTACT = (TERMS["cable_contact_energy"].col, TERMS["cable_contact_dissipation"].col)


def _offsets(cols) -> dict:
    out, j = {}, 0
    for c in cols:
        out[c.name] = j
        j += c.width
    return out


def width(cols) -> int:
    """Numbers in a row of ``cols``."""
    return sum(c.width for c in cols)


RowSlots = namedtuple("RowSlots", [c.name for c in ROW] + ["energy"])
TermSlots = namedtuple("TermSlots", [t.name for t in STEP_TERMS])
VecSlots = namedtuple("VecSlots", [c.name for c in VECTOR])
ArmSlots = namedtuple("ArmSlots", [c.name for c in ARM])
StrengthSlots = namedtuple("StrengthSlots", [c.name for c in STRENGTH])


class Slots(NamedTuple):
    """Every layout's column indices, as the kernels take them."""

    row: tuple
    term: tuple
    vec: tuple
    arm: tuple
    strength: tuple


#: the row's energy block follows its ROW columns, in STEP_TERMS order
ROW_WIDTH = width(ROW) + len(STEP_TERMS)
VEC_WIDTH = width(VECTOR)
SLOTS = Slots(RowSlots(**_offsets(ROW), energy=width(ROW)),
              TermSlots(*range(len(STEP_TERMS))), VecSlots(**_offsets(VECTOR)),
              ArmSlots(**_offsets(ARM)), StrengthSlots(**_offsets(STRENGTH)))


def named(table, cols, model=None) -> dict:
    """{name: column} of ``table`` (..., width(cols)) laid out as ``cols``: (T, ...) arrays
    for width 1, (T, ..., w) otherwise (copies); with a ``model``, only the columns it has
    (Col.present)."""
    out, j = {}, 0
    for c in cols:
        if model is None or c.present is None or c.present(model):
            out[c.name] = (table[..., j] if c.width == 1 else table[..., j:j + c.width]).copy()
        j += c.width
    return out


def row_columns(table, nrec) -> dict:
    """The scalar row's columns and its step energy terms (every term, present or not)."""
    out = named(table[:nrec, :width(ROW)], ROW)
    e0 = width(ROW)
    for k, term in enumerate(STEP_TERMS):
        out[term.name] = table[:nrec, e0 + k].copy()
    return out
