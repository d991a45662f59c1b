"""The recorder protocol: what the event loop tells the things that record a run.

The loop (:func:`spinweb_fe.run.loop.simulate`) calls, at event boundaries only:

- ``start(info)`` once, with a :class:`RunInfo`;
- ``rows(rows)`` with each chunk of history rows (name -> (T,) or (T, n_arms) arrays);
- ``frame(frame)`` every ``frame_dt`` and at the end, with a :class:`Frame`;
- ``checkpoint(state, memory)`` every ``checkpoint_dt``, at the end and when stopped:
  ``memory`` holds every recorder's :meth:`Recorder.memory` by name (and the arm measure's);
- ``end(status)`` once, when the loop leaves ('completed' or 'interrupted by ...').

A recorder that carries something from row to row (the energy audit's reference, say)
returns it from ``memory()`` as a dict of arrays and takes it back in ``restore()``; a run
continued from a checkpoint restores it by the recorder's ``name``. Every hook defaults to
doing nothing.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class RunInfo(NamedTuple):
    """What a recorder learns at the start of a run."""

    model: object       # spinweb_fe.fe.model.Model
    dt: float           # [s]
    n_total: int        # the end step
    step0: int          # the first step of this call (a restart: the checkpoint's)
    threads: int


class Frame(NamedTuple):
    """One frame: time t_n [s], positions x_n (n,3) [m], velocities (n,3) [m/s] (the
    half-step v_{n-1/2}), element tensions (m,) [N], and with rupture on the broken
    elements (m,) bool (None otherwise)."""

    time: float
    pos: np.ndarray
    vel: np.ndarray
    tension: np.ndarray
    broken: np.ndarray | None = None


class Recorder:
    """Base recorder: every hook a no-op. ``name`` keys its memory in a checkpoint."""

    name = ""

    def start(self, info: RunInfo) -> None:
        pass

    def rows(self, rows: dict) -> None:
        pass

    def frame(self, frame: Frame) -> None:
        pass

    def checkpoint(self, state, memory: dict) -> None:
        pass

    def end(self, status: str) -> None:
        pass

    def memory(self) -> dict:
        return {}

    def restore(self, memory: dict) -> None:
        pass
