"""The crossing audit (``[audit] crossings = true``): every time two cable elements pass
through each other during a run, counted and logged (issue #26; docs/results.md).

The step loop tests each step itself (fe.contact.touch: after each step, the candidate element
pairs with the exact continuous test of :func:`spinweb_fe.fe.contact.crossing.pair_crossings`; the
nodes move on straight lines over a step, as the central-difference update moves them), and
stops for this class to rebuild the list. The candidates come from the hash-grid broad
phase with a skin, rebuilt when a node has moved more than 3/4 of the skin since the last
build, in a frame that turns with the web (fe.contact.bounds: distances do not change in a
rigidly turning frame, so the spin itself never forces a rebuild), or when a held level
went free. Between builds each pair keeps a certificate, a proven least distance lowered by
what each step could close (fe.contact.bounds), and only the pairs whose certificate
cannot rule a meeting out are tested exactly. Which pairs take part:

- every element, the coil's held ones and the hub's tied ones too (released cables sweep
  over the coil and through the hub's frame: a list of released material alone let them
  pass through it unseen, docs/contact.md), but no pair of two elements that both move
  with the hub (both ends held or tied): those cannot cross while they are held, and a
  level that goes free rebuilds the list;
- a pair closer than ``touch`` [m] when it enters the list (the star fold's stacked layers
  start coincident, z = 0, without a layer gap, and leave the coil so) is left out until
  it is farther apart than the skin at a rebuild: two coincident cables have no side of
  each other to cross from, and layers that part slowly would otherwise cross back and
  forth at round-off.

A crossing's time is the step's start plus its fraction of the step; its direction is the
sign of the signed volume of the two elements' ends after it.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from spinweb_fe.fe.contact.bounds import ROUND, no_motion
from spinweb_fe.fe.contact.broad import RIGID, candidate_pairs, sift_pairs
from spinweb_fe.fe.layout import AUDIT, named
from spinweb_fe.fe.contact.touch import REBUILD, AuditKernel, audit_step
from spinweb_fe.fe.contact.clock import AUDIT_CLOCK, AUDIT_TALLY
from spinweb_fe.record.feature import Feature, copied
from spinweb_fe.record.profile import Profile

log = logging.getLogger(__name__)

#: largest default broad-phase skin [m]
SKIN = 0.5
#: the default skin is at most this share of the median element's rest length
SKIN_PER_ELEMENT = 0.2
#: default distance [m] below which a pair entering the list is left out until it separates
TOUCH = 1e-3
#: room of the step loop's log (crossings logged between two calls at most)
LOG_ROOM = 4096
#: the skin grows by this factor at a rebuild that came sooner than :data:`SOON` steps after
#: the last (a fast web uses up a thin skin in a few steps), and shrinks by it back towards
#: the starting skin when a list lasts :data:`LATE` steps; at most :data:`SKIN_GROWTH` times
#: the starting skin, and not while the list holds :data:`PAIRS_MAX` pairs per element
SKIN_STEP = 1.5
SOON, LATE = 100, 800
SKIN_GROWTH = 8.0
PAIRS_MAX = 60


def default_skin(model) -> float:
    """The broad phase's default skin [m]: the smaller of :data:`SKIN` and
    :data:`SKIN_PER_ELEMENT` of the median element's rest length. The list's pairs grow
    with the skin (on a stacked web, with the layers it spans) and its rebuilds with the
    inverse; on the paper's web (2.5 m elements) 0.5 m costs least, on the 0.5 m
    elements of the 80 400-element web 0.1 m or less (docs/performance.md)."""
    rest = np.asarray(getattr(model.elements, "rest_len", ()))
    if not len(rest):
        return SKIN
    return float(min(SKIN, SKIN_PER_ELEMENT * np.median(rest)))


def held_nodes(model, state) -> np.ndarray:
    """(n,) bool: nodes on the hub's coil now (levels not yet released)."""
    coil, front = model.coil, state.coil.front
    held = np.zeros(model.n_nodes, bool)
    for k in range(len(coil.arm_ptr) - 1):
        first = coil.arm_ptr[k] + front[k]
        last = coil.arm_ptr[k + 1]
        if first < last:
            held[coil.level_nodes[coil.level_ptr[first]:coil.level_ptr[last]]] = True
    return held


class CrossingAudit(Feature):
    """Counts and logs the crossings of a run's elements (see the module's text); the
    candidate list the cable contact shares (a feature: hook ``audit``).

    Attributes
    ----------
    count : int
        Crossings so far.
    log : dict of lists
        ``time`` [s], ``element_a``, ``element_b``, ``direction`` (+1 / -1) of each crossing
        (at most fe.contact.touch.LOG_PER_STEP per step).
    rebuilds : int
        Broad-phase builds so far.
    """

    name = "crossings"
    hook = "audit"
    layout = AUDIT

    def __init__(self, model, skin: float | None = None, touch: float = TOUCH, rows: int = 1):
        self.model = model
        self.elem_nodes = np.array(model.elements.nodes, dtype=np.int64)  # (writable: one type)
        self.skin = float(skin) if skin is not None else default_skin(model)
        self.base_skin = self.skin  # the skin adapts to the web's speed (:meth:`adapt`)
        self.skin_given = skin is not None  # (the case's, which the contact keeps)
        #: the widest skin, per starting skin (1: fixed; the contact fixes it: its passes
        #: cost 60-110 ns a listed pair, so a longer list costs it more than the rebuilds)
        self.growth = SKIN_GROWTH
        self._built_at = 0
        self.touch = float(touch)
        self.count, self.rebuilds = 0, 0
        self.log = {"time": [], "element_a": [], "element_b": [], "direction": []}
        self.pairs = np.zeros((0, 2), np.int64)
        self.pair_codes, self.pair_dist = np.zeros(0, np.int64), np.zeros(0)
        self.ignored = np.zeros(0, np.int64)
        self._codes = None
        self._rows = rows
        self._restored = None
        self.frame_angle = np.zeros(1)  # the angle of the frame that follows the web [rad]
        self.kernel_data = None
        #: what the audit's passes cost (record.profile; over the rebuilds, not checkpointed)
        self.profile = Profile(AUDIT_CLOCK, AUDIT_TALLY)

    def build(self, state, rows: int | None = None):
        """The candidate list at the state's positions (and the pairs left out), and the
        step loop's view of it (:attr:`kernel_data`, with room for ``rows`` history rows a
        call)."""
        pos = state.node_pos
        bound = held_nodes(self.model, state)
        bound[self.model.hub.tied_idx] = True
        rigid = bound[self.elem_nodes[:, 0]] & bound[self.elem_nodes[:, 1]]
        active = np.where(rigid, RIGID, 1).astype(np.int8)
        pairs = candidate_pairs(pos, self.elem_nodes, active, self.skin)
        # a pair that enters the list touching is left out; one left out stays out until
        # it is a skin apart (stacked layers drift and part slowly)
        # (codes ascend: the broad phase lists pairs in code order; merges, not hashes)
        fresh = self._codes is None
        self._codes, self.pairs, self.pair_codes, self.pair_dist, self.ignored = sift_pairs(
            pairs, self.elem_nodes, pos, np.zeros(0, np.int64) if fresh else self._codes,
            fresh, self.ignored, self.base_skin, self.touch)
        theta = float(self.frame_angle[0])
        c, s = math.cos(theta), math.sin(theta)
        ref = np.column_stack([c * pos[:, 0] + s * pos[:, 1],
                               -s * pos[:, 0] + c * pos[:, 1], pos[:, 2]])
        # each pair's certificate: its distance now, less the round-off of computing it
        level = self.pair_dist - ROUND * float(np.max(np.abs(pos), initial=0.0))
        self._rows = rows or self._rows
        self._make(active, ref, np.array(state.coil.front, np.int64), level,
                   np.zeros(len(self.elem_nodes)))
        self._built_at = int(state.step[0])
        self.rebuilds += 1

    def _make(self, active, ref, fronts, level, cum0):
        old = self.kernel_data
        pos0 = old.pos0 if old is not None else np.zeros((len(ref), 3))
        motion = old.motion if old is not None else no_motion(len(ref), len(self.elem_nodes))
        motion.cum0[:] = cum0  # (the certificates' sums start again with a new list)
        motion.cum[:] = cum0
        self.kernel_data = AuditKernel(
            self.elem_nodes, self.pairs, self.ignored, active, ref, fronts, pos0,
            self.frame_angle,            level, motion,
            self.skin, np.array([self.count], np.int64), np.zeros(LOG_ROOM),
            np.zeros(LOG_ROOM, np.int64), np.zeros(LOG_ROOM, np.int64),
            np.zeros(LOG_ROOM, np.int64), np.zeros(1, np.int64), np.zeros(self._rows),
            np.zeros(1), self.profile.clock, self.profile.tally)

    # -- the feature's hooks (record.feature) --

    def prepare(self, state, rows: int) -> None:
        """The list at the run's first state, or the one a checkpoint's memory held."""
        self._rows = rows
        self.profile.start()
        k = self.kernel_data
        if self._restored is not None:
            self._make(*self._restored)
            self._restored = None
        elif k is None:
            self.build(state, rows)
        elif k.row_count.shape[0] < rows:  # (built before, with room for fewer rows)
            self._make(k.active, k.ref, k.fronts, k.level, k.motion.cum0)

    def kernel(self, hooks: dict):
        return self.kernel_data

    def trial(self, kernel, hooks: dict):
        return copied(kernel)

    def columns(self, kernel, rec, nrec: int) -> dict:
        return named(kernel.row_count[:nrec, None].astype(float), AUDIT)

    def service(self, state) -> None:
        """After a call of the step loop: its log into :attr:`log`, and a rebuild if the
        list went stale."""
        k = self.kernel_data
        n = int(k.n_log[0])
        if n:
            self.log["time"].extend(k.log_time[:n].tolist())
            self.log["element_a"].extend(k.log_a[:n].tolist())
            self.log["element_b"].extend(k.log_b[:n].tolist())
            self.log["direction"].extend(k.log_sign[:n].tolist())
            k.n_log[0] = 0
        self.count = int(k.count[0])
        moved = k.moved[0] > REBUILD * self.skin
        if moved or not np.array_equal(k.fronts, state.coil.front):
            if moved:
                self.adapt(int(state.step[0]))
            self.build(state)

    def adapt(self, step: int) -> None:
        """The skin for the next list, from how long this one lasted (a rebuild after
        ``step - last build`` steps): wider for a web that used it up quickly, back towards
        the starting skin for one that did not. Every skin gives the same crossings: the
        skin sets only how many pairs each step looks at and how often the list is built."""
        steps = step - self._built_at
        active = max(1, int(np.count_nonzero(self.kernel_data.active)))
        if (steps < SOON and self.skin < self.growth * self.base_skin
                and len(self.pairs) < PAIRS_MAX * active):
            self.skin = min(SKIN_STEP * self.skin, self.growth * self.base_skin)
        elif steps > LATE and self.skin > self.base_skin:
            self.skin = max(self.skin / SKIN_STEP, self.base_skin)

    take = service

    def write(self, h5) -> None:
        write_table(h5, self)
        self.profile.write(h5.require_group("crossings").require_group("profile"), "audit")
        log.info("crossings: %d (broad phase built %d times)", self.count, self.rebuilds)

    def step(self, pos0, state, t0: float, dt: float):
        """The crossings of the step that took the nodes from ``pos0`` to the state's
        positions (starting at ``t0`` [s]), as the step loop tests them; then a rebuild if
        the list went stale (scripted motions: tests)."""
        self.kernel_data.pos0[:] = pos0
        self.kernel_data.motion.theta[0] = self.frame_angle[0]
        # (fresh, clean and threads given, as a one-thread step loop gives them: one
        # compile for both)
        audit_step(self.kernel_data, state.node_pos, t0, dt,
                   np.asarray(state.coil.front, np.int64), False, False, None)
        self.service(state)

    def table(self) -> dict:
        """The log as arrays (name -> (K,) array)."""
        return {"time": np.asarray(self.log["time"], np.float64),
                "element_a": np.asarray(self.log["element_a"], np.int64),
                "element_b": np.asarray(self.log["element_b"], np.int64),
                "direction": np.asarray(self.log["direction"], np.int64)}

    def memory(self) -> dict:
        """The count, the log, and the list as the step loop holds it (its pairs, those
        left out, the positions it was built at, its fronts, each pair's certificate), so
        that a restart tests the same pairs as the run would have, and rebuilds where it
        would have."""
        k = self.kernel_data
        out = {"count": np.array([self.count], np.int64), **self.table(),
               "ignored": self.ignored.copy(), "rebuilds": np.array([self.rebuilds]),
               "frame": self.frame_angle, "skin": np.array([self.skin]),
               "built_at": np.array([self._built_at])}
        if k is not None:
            out.update(pairs=self.pairs, pair_codes=self.pair_codes, pair_dist=self.pair_dist,
                       codes=self._codes, active=k.active, ref=k.ref, fronts=k.fronts,
                       level=k.level, cum0=k.motion.cum0)
        return {name: np.array(v, copy=True) for name, v in out.items()}

    def restore(self, memory: dict) -> None:
        self.count = int(memory["count"][0])
        for k in self.log:
            self.log[k] = list(np.asarray(memory[k]).tolist())
        self.ignored = np.asarray(memory["ignored"], np.int64)
        self.rebuilds = int(np.asarray(memory.get("rebuilds", [0])).ravel()[0])
        self.frame_angle[:] = np.asarray(memory.get("frame", [0.0]), np.float64).ravel()[:1]
        self.skin = float(np.asarray(memory.get("skin", [self.skin])).ravel()[0])
        self._built_at = int(np.asarray(memory.get("built_at", [0])).ravel()[0])
        if "pairs" not in memory:  # (a checkpoint of the audit before its list was kept)
            return
        self.pairs = np.asarray(memory["pairs"], np.int64).reshape(-1, 2)
        self.pair_codes = np.asarray(memory["pair_codes"], np.int64)
        self.pair_dist = np.asarray(memory["pair_dist"], np.float64)
        self._codes = np.asarray(memory["codes"], np.int64)
        self._restored = (np.asarray(memory["active"], np.int8),
                          np.asarray(memory["ref"], np.float64).reshape(-1, 3),
                          np.asarray(memory["fronts"], np.int64),
                          np.asarray(memory["level"], np.float64),
                          np.asarray(memory["cum0"], np.float64))


#: units and meaning of the /crossings table's columns
TABLE_UNITS = {"time": ("s", "time of the crossing"),
               "element_a": ("1", "the first element (index into /mesh/elements)"),
               "element_b": ("1", "the second element"),
               "direction": ("1", "sign of the signed volume of the two elements' ends "
                                  "after the crossing (+1 / -1)")}


def write_table(h5, audit: CrossingAudit):
    """The audit's /crossings group: the log's columns and the attributes ``count``,
    ``skin`` [m] (the starting skin), ``skin_last`` [m] (the skin of the last list: it
    adapts to the web's speed), ``touch`` [m], ``rebuilds``."""
    if "crossings" in h5:
        del h5["crossings"]
    g = h5.create_group("crossings")
    for name, arr in audit.table().items():
        ds = g.create_dataset(name, data=arr)
        ds.attrs["units"], ds.attrs["description"] = TABLE_UNITS[name]
    g.attrs["count"] = audit.count
    g.attrs["skin"] = audit.base_skin
    g.attrs["skin_last"] = audit.skin
    g.attrs["touch"] = audit.touch
    g.attrs["rebuilds"] = audit.rebuilds
    g.attrs["units"] = "skin, skin_last, touch: m"
