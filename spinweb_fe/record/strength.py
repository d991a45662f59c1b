"""Strength margins of a run: the history columns of the strength check, the run-log warning
when the utilisation first exceeds 1, and the strength cell data of a frame.

The step loop (:mod:`spinweb_fe.fe.rupture`) records per history row the peak utilisation
eps / eps_f over the elements and the steps since the previous row, its strain and element,
the broken elements so far and the energy they held at their breaks. Here they become the
columns ``utilisation``, ``max_strain``, ``max_strain_element``, ``max_strain_arm`` (every
scene with ``cable.failure_strain``) and ``broken_elements``, ``rupture_dissipation``
(with ``cable.rupture = true``).
"""

from __future__ import annotations

import logging

import numpy as np

from spinweb_fe.fe.layout import STRENGTH, named
from spinweb_fe.record.feature import Feature

log = logging.getLogger(__name__)


def elem_arm(mesh) -> np.ndarray:
    """(m,) int64 arm of each element: that of its first node, else of its second (-1: the
    element belongs to no arm, e.g. the web's cross at the hub)."""
    a = mesh.node_arm[mesh.elem_nodes]
    return np.where(a[:, 0] >= 0, a[:, 0], a[:, 1]).astype(np.int64)


def strength_columns(model, rows: dict) -> dict:
    """History columns of a chunk's strength rows (fe.layout.STRENGTH by name, each (T,)) of
    a scene with a failure strain: the broken count and the rupture dissipation with
    rupture on; the arm of the peak's element added."""
    elem = rows["max_strain_element"].astype(np.int64)
    arms = elem_arm(model.mesh)
    cols = {k: rows[k] for k in ("utilisation", "max_strain", "max_strain_element")}
    cols["max_strain_arm"] = np.where(elem >= 0, arms[np.maximum(elem, 0)], -1).astype(float)
    if model.strength.rupture:
        cols["broken_elements"] = rows["broken_elements"]
        cols["rupture_dissipation"] = rows["rupture_dissipation"]
    return cols


def strength_cells(model, strain: np.ndarray, broken) -> dict:
    """VTU cell data of a frame: ``utilisation`` max(strain, 0) / eps_f (NaN in a broken
    element, which has none) and, with rupture on, ``broken`` (1: broken). Empty without a
    failure strain."""
    fail = model.strength.fail
    if not len(fail):
        return {}
    util = np.maximum(strain, 0.0) / fail
    if broken is None:
        return {"utilisation": util}
    broken = np.asarray(broken, dtype=bool)
    return {"utilisation": np.where(broken, np.nan, util), "broken": broken.astype(np.int8)}


class StrengthCheck(Feature):
    """The strength check of a scene with a failure strain (a feature; its kernel data is
    the Model's ``strength``, its state the State's): the history columns of the step's
    strength rows (fe.layout.STRENGTH, :func:`strength_columns`), and a warning in the run
    log when the utilisation first exceeds 1 (its memory keeps the warning from repeating
    after a restart)."""

    name = "strength"
    layout = STRENGTH
    state_fields = ("strength/broken", "strength/peak", "strength/dissipation",
                    "strength/count")

    def __init__(self, model=None):
        self.model = model
        self.warned = False

    def columns(self, kernel, rec, nrec: int) -> dict:
        return strength_columns(self.model, named(rec.strength_table[:nrec], STRENGTH))

    def rows(self, rows):
        u = rows.get("utilisation")
        if self.warned or u is None:
            return
        over = np.flatnonzero(u > 1.0)
        if not len(over):
            return
        self.warned = True
        k = over[0]
        what = ("breaks (it carries nothing from now on)" if "broken_elements" in rows
                else "would break (cable.rupture = true breaks it)")
        log.warning("warning: at t = %.6g s element %d (arm %d) is strained to %.4g, %.3g times "
                    "its failure strain: the cable %s", rows["time"][k],
                    int(rows["max_strain_element"][k]), int(rows["max_strain_arm"][k]),
                    rows["max_strain"][k], u[k], what)

    def memory(self):
        return {"warned": np.array([self.warned])}

    def restore(self, memory):
        if "warned" in memory:
            self.warned = bool(np.asarray(memory["warned"]).ravel()[0])
