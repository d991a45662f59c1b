"""The energy balance of a run and its audit."""

from __future__ import annotations

import logging

import numpy as np

from spinweb_fe.errors import RunError
from spinweb_fe.fe.layout import ENERGY
from spinweb_fe.record.recorders import Recorder

log = logging.getLogger(__name__)

ENERGY_LIMIT = 0.5  # stop when the energy balance error exceeds this fraction of the energy scale
ENERGY_WARN = 0.01  # warn (once) above this fraction: results are suspect, reduce time.cfl
#: the energy floor's displacement, in units in the last place of the largest coordinate
FLOOR_ULPS = 100.0


def energy_floor(model) -> float:
    """The least energy scale of a run [J]: what round-off alone can put into the web.

    A scene at rest has no energy to measure the balance against (no initial energy, no
    torque work), and round-off in the positions (a unit in the last place of the largest
    coordinate X: eps X) moves its nodes and strains its elements by itself: the paper's
    free web at rest holds 1e-22 J after a millisecond, which against an initial 8e-23 J
    read as 'energy balance off by 387 %'. The floor is the strain energy of every element
    stretched by FLOOR_ULPS such units, sum(EA / L) (FLOOR_ULPS eps X)^2 / 2: 1.5e-15 J for
    that web (round-off 1e4 times below it), 4e-18 J for the demo, far below any energy a
    moving scene or an instability has (joules).
    """
    x = max(float(np.max(np.abs(model.mesh.node_ref), initial=0.0)),
            float(np.max(np.abs(model.mesh.node_pos), initial=0.0)))
    dx = FLOOR_ULPS * float(np.finfo(np.float64).eps) * x
    rest = np.asarray(model.elements.rest_len)
    stiff = np.asarray(model.elements.ea)[rest > 0] / rest[rest > 0]
    return 0.5 * float(np.sum(stiff)) * dx * dx


def momentum_floor(model, energy: float) -> float:
    """The least angular-momentum scale [N m s] that goes with ``energy`` (the
    :func:`energy_floor`): sqrt(2 I E), I = sum(m r^2) about the hub axis."""
    pos = np.asarray(model.mesh.node_ref)
    inertia = float(np.sum(np.asarray(model.nodes.mass) * (pos[:, 0] ** 2 + pos[:, 1] ** 2)))
    return float(np.sqrt(2.0 * inertia * energy))


def energy_balance(h):
    """KE + SE + sum(sign * term) over the energy terms of fe.layout.ENERGY (works in,
    dissipations out), which should stay constant, for a history dict; a term the history
    does not have (a scene without it) counts zero, a term per arm (T, n_arms) its sum."""
    bal = h["kinetic_energy"] + h["strain_energy"]
    for term in ENERGY:
        if term.name in h:
            value = np.asarray(h[term.name])
            bal = bal + term.sign * (value.sum(axis=1) if value.ndim == 2 else value)
    return bal


def energy_reference(h) -> tuple:
    """(balance at the first row [J], the initial energy |KE| + |SE| there [J])."""
    return (float(energy_balance(h)[0]),
            max(abs(float(h["kinetic_energy"][0])) + abs(float(h["strain_energy"][0])), 1e-30))


def balance_error(h, ref=None, floor=0.0) -> float:
    """Largest relative energy-balance error of the rows ``h``: max |B - B_0| over the rows,
    divided by the energy scale max(initial |KE| + |SE|, max |torque work| of the rows,
    ``floor``). A run from rest has no initial energy: the torque work sets the scale; a
    scene at rest has neither: the floor (:func:`energy_floor`, a result file's attribute
    ``energy_floor``) does. ``ref``: :func:`energy_reference` of the run's first row
    (default: that of ``h``)."""
    b0, s0 = energy_reference(h) if ref is None else ref
    scale = max(s0, float(np.max(np.abs(h["torque_work"]))), floor)
    return float(np.max(np.abs(energy_balance(h) - b0))) / scale


class EnergyAudit(Recorder):
    """Energy balance check per chunk of rows: KE + SE - W + D must stay near its first value.

    The error is measured against the energy scale: the first row's KE + SE, or the largest
    torque work so far if that is larger (a run from rest), or ``floor`` (a scene at rest:
    :func:`energy_floor`) if that is larger still. Above ``limit`` the run stops
    (RunError); above ENERGY_WARN it warns once.
    """

    name = "energy"

    def __init__(self, limit=ENERGY_LIMIT, floor=0.0):
        self.limit = limit
        self.floor = floor
        self.ref = None  # (balance at the first row [J], energy scale [J])
        self.warned = False
        self.work_seen = 0.0  # largest |torque work| of every row so far [J]

    def rows(self, rows):
        if not len(rows["time"]):
            return
        t = float(rows["time"][-1])
        if self.ref is None:
            self.ref = energy_reference(rows)
        # the scale is the largest torque work of the whole run so far, not of this chunk
        self.work_seen = max(self.work_seen, float(np.max(np.abs(rows["torque_work"]))))
        err = balance_error(rows, (self.ref[0], max(self.ref[1], self.work_seen, self.floor)))
        if err > self.limit:
            raise RunError(f"energy balance off by {100 * err:.0f} % of the energy scale "
                           "(numerical instability; reduce time.cfl)", time=t)
        if err > ENERGY_WARN and not self.warned:
            self.warned = True
            log.warning("warning: at t = %.6g s the energy balance is off by %.2g %% of the "
                        "energy scale (slack/taut snapping or hub impacts; a smaller time.cfl "
                        "or a little damping helps, see docs/stability.md)", t, 100 * err)

    def memory(self):
        if self.ref is None:
            return {}
        return {"ref": np.asarray(self.ref, dtype=np.float64),
                "work_seen": np.array([self.work_seen]),
                "warned": np.array([1.0 if self.warned else 0.0])}

    def restore(self, memory):
        if "ref" in memory:
            self.ref = tuple(float(x) for x in memory["ref"])
        if "work_seen" in memory:  # (checkpoints of earlier versions: from the next rows on)
            self.work_seen = float(np.asarray(memory["work_seen"]).ravel()[0])
        if "warned" in memory:
            self.warned = bool(np.asarray(memory["warned"]).ravel()[0] > 0.5)
