"""The linking check of a run (``[audit] crossings = true``, beside the crossing audit): the
linking numbers of the web's cells (:mod:`spinweb_fe.record.linking`) at the run's states,
a feature (record.feature) with its /linking group.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from spinweb_fe.record.feature import Feature
from spinweb_fe.record.linking import Loops, cell_loops, linked_pairs

log = logging.getLogger(__name__)


#: the linking check's columns, one value per check: units, dtype, meaning
COLUMNS = {
    "time": ("s", np.float64, "time of the check"),
    "linked": ("1", np.int64, "cell pairs with a nonzero linking number"),
    "changed": ("1", np.int64, "cell pairs whose linking number changed since the previous "
                               "check (0 at the first)"),
    "worst": ("1", np.float64, "largest distance of a computed linking number from an "
                               "integer"),
    "suspect": ("1", np.int64, "pairs farther than the tolerance from an integer (cells "
                               "that meet: a check caught mid-crossing); they keep their "
                               "previous value"),
}


def _cell_elements(loops: Loops, elem_nodes) -> np.ndarray:
    """(ptr[-1],) int64: the element from each loop node to the next (cells run along
    elements, so each is one)."""
    e = np.asarray(elem_nodes, np.int64)
    n = int(max(e.max(initial=-1), loops.nodes.max(initial=-1))) + 1
    nxt = np.arange(len(loops.nodes)) + 1
    nxt[loops.ptr[1:] - 1] = loops.ptr[:-1]
    a, b = loops.nodes, loops.nodes[nxt]
    key = np.minimum(a, b) * n + np.maximum(a, b)
    ekey = np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1])
    order = np.argsort(ekey, kind="stable")
    return order[np.searchsorted(ekey[order], key)]


def _among(rows, alive):
    """The rows (K, 3) (i, j, Lk) of pairs of cells that are both ``alive`` (L,) bool."""
    return rows[alive[rows[:, 0]] & alive[rows[:, 1]]]


def _values(rows, keys, n):
    """Lk of the pairs ``keys`` (codes i n + j, sorted) in ``rows`` (K, 3), 0 if absent."""
    out = np.zeros(len(keys), np.int64)
    out[np.searchsorted(keys, rows[:, 0] * n + rows[:, 1])] = rows[:, 2]
    return out


class LinkingMonitor(Feature):
    """The linking check of a run (``[audit] crossings = true``, beside the crossing
    audit): the linking numbers of the web's cells, checked at the run's states.

    A check: :func:`linked_pairs` of the cells (:func:`cell_loops`) that have no broken
    element, at the check's positions. A pair farther than ``tol`` from an integer (a
    suspect: its cells meet, a check caught mid-crossing) keeps the value it had; a cell
    that loses an element to rupture is no loop any more and leaves the check, its pairs
    with it (not counted as changes). The first check's links are the reference; each
    check records the :data:`COLUMNS`.

    Which states: the run's first (``state``, when the run does not continue a
    checkpoint's memory), every frame (``output.frame_dt``; the loop gives one at the
    last step) and the last step (the loop's checkpoint event at the end, which it
    calls with or without checkpoint files): a run without frames is checked at its
    start and at its end. A state is checked once.

    Parameters
    ----------
    mesh : meshgen.mesh.Mesh
    state : spinweb_fe.fe.state.State or None
        The run's first state.
    tol : float
        How far from an integer a linking number may be (:func:`linked_pairs`).
    """

    name = "linking"

    def __init__(self, mesh, state=None, tol: float = 1e-6):
        self.loops = cell_loops(mesh)
        self.tol = float(tol)
        self.edge_elem = _cell_elements(self.loops, mesh.elem_nodes)
        self.edge_cell = np.repeat(np.arange(self.loops.n_loops), np.diff(self.loops.ptr))
        self.log = {k: [] for k in COLUMNS}
        self.reference = self.current = np.zeros((0, 3), np.int64)
        self.last_step = -1
        self.alive = np.ones(self.loops.n_loops, bool)  # at the last check
        self.dt, self.end_step = 1.0, None
        self._first = None if state is None else (
            int(state.step[0]), state.node_pos.copy(), _broken(state))

    def start(self, info):
        self.dt, self.end_step = info.dt, info.n_total
        if self._first is not None and not self.log["time"]:
            self.check(*self._first)
        self._first = None

    def frame(self, frame):
        self.check(round(frame.time / self.dt), frame.pos, frame.broken)

    def checkpoint(self, state, memory):
        if self.end_step is not None and int(state.step[0]) >= self.end_step:
            self.check(int(state.step[0]), state.node_pos, _broken(state))

    def check(self, step: int, pos, broken=None) -> None:
        """Check the positions ``pos`` (n, 3) [m] of step ``step`` (time step * dt), with
        the elements ``broken`` (m,) bool (None: none); a step already checked is not."""
        if step == self.last_step:
            return
        n = self.loops.n_loops
        alive = np.ones(n, bool)
        loops = self.loops
        if broken is not None and np.any(broken):
            alive[self.edge_cell[np.asarray(broken)[self.edge_elem]]] = False
            sizes = np.diff(loops.ptr)[alive]
            loops = Loops(np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                          loops.nodes[alive[self.edge_cell]])
        live = np.flatnonzero(alive)
        res = linked_pairs(pos, loops, self.tol)
        prev = _among(self.current, alive)
        suspect = live[res.suspect]
        held = np.isin(prev[:, 0] * n + prev[:, 1], suspect[:, 0] * n + suspect[:, 1])
        now = np.vstack([np.column_stack([live[res.links[:, :2]], res.links[:, 2]]),
                         prev[held]]).astype(np.int64)
        now = now[np.lexsort((now[:, 1], now[:, 0]))]
        keys = np.union1d(prev[:, 0] * n + prev[:, 1], now[:, 0] * n + now[:, 1])
        changed = int(np.count_nonzero(_values(prev, keys, n) != _values(now, keys, n)))
        if not self.log["time"]:
            self.reference, changed = now, 0
        for k, v in (("time", step * self.dt), ("linked", len(now)), ("changed", changed),
                     ("worst", res.worst), ("suspect", len(suspect))):
            self.log[k].append(v)
        self.current, self.last_step, self.alive = now, int(step), alive

    def table(self) -> dict:
        """The checks as arrays (name -> (C,) array, the :data:`COLUMNS`)."""
        return {k: np.asarray(v, COLUMNS[k][1]) for k, v in self.log.items()}

    def summary(self) -> dict:
        """``changed_total``, ``first_change_time`` [s] (NaN: none), ``net_changed`` (pairs
        whose Lk at the last check differs from the first's), ``linked`` (at the last)."""
        table = self.table()
        t, changed = table["time"], table["changed"]
        n = self.loops.n_loops
        ref = _among(self.reference, self.alive)
        keys = np.union1d(ref[:, 0] * n + ref[:, 1],
                          self.current[:, 0] * n + self.current[:, 1])
        net = _values(ref, keys, n) != _values(self.current, keys, n)
        return {"changed_total": int(changed.sum()), "net_changed": int(np.count_nonzero(net)),
                "first_change_time": float(t[changed > 0][0]) if np.any(changed) else math.nan,
                "linked": len(self.current)}

    def write(self, h5) -> None:
        """Its /linking group (:func:`write_group`), and a line in the run log."""
        write_group(h5, self)
        s = self.summary()
        log.info("linking: %d cell pairs linked at the end, %d changes of a linking number%s",
                 s["linked"], s["changed_total"], "" if not s["changed_total"] else
                 f" (the first at t = {s['first_change_time']:.6g} s)")

    def memory(self) -> dict:
        return {**self.table(), "reference": self.reference, "current": self.current,
                "last_step": np.array([self.last_step], np.int64), "alive": self.alive}

    def restore(self, memory: dict) -> None:
        for k in self.log:
            self.log[k] = np.asarray(memory[k]).tolist()
        self.reference = np.asarray(memory["reference"], np.int64).reshape(-1, 3)
        self.current = np.asarray(memory["current"], np.int64).reshape(-1, 3)
        self.last_step = int(memory["last_step"][0])
        self.alive = np.asarray(memory["alive"], bool)
        self._first = None


def _broken(state):
    """The state's broken elements (m,) bool, or None without rupture."""
    broken = state.strength.broken
    return broken.copy() if len(broken) else None


def write_group(h5, monitor: LinkingMonitor):
    """The /linking group: the :data:`COLUMNS` with their units, ``links`` (K, 3) (i, j,
    Lk) at the last check and ``reference`` at the first (cells: /linking/cells, ptr and
    nodes), attributes ``loops``, ``dropped``, ``tol``, ``changed_total``,
    ``net_changed``, ``first_change_time`` [s] (NaN: no change)."""
    if "linking" in h5:
        del h5["linking"]
    g = h5.create_group("linking")
    for name, arr in monitor.table().items():
        ds = g.create_dataset(name, data=arr)
        ds.attrs["units"], ds.attrs["description"] = COLUMNS[name][0], COLUMNS[name][2]
    for name, rows, what in (("links", monitor.current, "at the last check"),
                             ("reference", monitor.reference, "at the first check")):
        ds = g.create_dataset(name, data=rows.reshape(-1, 3))
        ds.attrs["units"] = "1"
        ds.attrs["description"] = f"(i, j, Lk) of the linked cell pairs {what}"
    cells = g.create_group("cells")
    cells.create_dataset("ptr", data=monitor.loops.ptr)
    cells.create_dataset("nodes", data=monitor.loops.nodes)
    cells.attrs["description"] = "cell i: nodes[ptr[i]:ptr[i+1]] (indices into /mesh/points)"
    summary = monitor.summary()
    g.attrs["loops"] = monitor.loops.n_loops
    g.attrs["dropped"] = int(np.count_nonzero(~monitor.alive))
    g.attrs["tol"] = monitor.tol
    for k in ("changed_total", "net_changed", "first_change_time"):
        g.attrs[k] = summary[k]
    g.attrs["units"] = "first_change_time: s"
