"""What a result file's verdict was judged from, read back for the plots and ``spinweb
info``: the criteria (the ``/verdict`` group, or judged here from the history for a file
written before verdicts), each tip's reach and the hub radius, the case and its
thresholds, and the slack share at every frame."""

from __future__ import annotations

import tomllib
from typing import NamedTuple

import numpy as np

from spinweb_fe.errors import InputError
from spinweb_fe.io.h5 import history_of
from spinweb_fe.io.mesh import read_mesh_group
from spinweb_fe.record import verdict


class Judged(NamedTuple):
    """One result file's verdict and what it was judged from."""

    history: dict        # /history: name -> array
    criteria: list       # record.verdict.Criterion, in the report's order
    reach: np.ndarray    # (n_arms,) [m] each tip's deployed distance from the hub axis
    hub_radius: float    # [m]
    case: dict           # the resolved case (the file's ``case`` attribute), {} if none
    slack: tuple | None  # ((F,) frame times [s], (F,) slack share) or None: no frames
    floors: dict         # the energy and momentum audits' floors (record.verdict.floors_of)

    @property
    def limits(self) -> dict:
        """The [verdict] thresholds the file was judged by."""
        return verdict.limits_of(self.case.get("verdict"))

    @property
    def title(self) -> str:
        """The case's title ('' if it has none)."""
        return str(self.case.get("title", "") or "")

    def criterion(self, name):
        """The criterion ``name`` (None: the file has none of that name)."""
        return next((c for c in self.criteria if c.name == name), None)


def history_checked(path, h5) -> dict:
    """The history of an open result file (InputError: none, or no rows yet)."""
    if "history" not in h5:
        raise InputError(path, "history", "no /history group in this file")
    h = history_of(h5)
    if not h:
        raise InputError(path, "history", "no rows yet (the run stopped before its first "
                         "rows were written)")
    return h


def reach_of_file(h5) -> tuple:
    """((n_arms,) reach [m], hub radius [m]) of an open FE (``/mesh``) or analytical result
    file (root attributes ``hub_radius``, ``arm_length_H``, ``arms``)."""
    if "mesh" in h5:
        mesh = read_mesh_group(h5["mesh"])
        return verdict.reach_of(mesh), float(mesh.hub_radius)
    r0 = float(h5.attrs["hub_radius"])
    return np.full(int(h5.attrs["arms"]), r0 + float(h5.attrs["arm_length_H"])), r0


def case_of(h5) -> dict:
    """The resolved case a result file stores ({} if none)."""
    return tomllib.loads(str(h5.attrs.get("case", "")))


def judge_file(h5, h) -> list:
    """record.verdict.judge of an open FE or analytical result file without a /verdict
    (its slack is then unknown)."""
    reach, r0 = reach_of_file(h5)
    status = str(h5.attrs.get("status", "completed"))
    if h5.attrs.get("stopped"):
        status = f"stopped: {h5.attrs['stopped']}"
    terms = verdict.case_terms(case_of(h5))
    if "mesh" not in h5:  # the analytical model: no failure strain, no gravity gradient
        terms.update(failure_strain=None, gravity=False)
    return verdict.judge(h, reach, r0, status=status, out_of_plane="out_of_plane_max" in h,
                         **terms, **verdict.floors_of(h5.attrs))


def criteria_of(h5, h) -> list:
    """The verdict a result file holds, or judged from its history (:func:`judge_file`)."""
    crits = verdict.read_group(h5)
    return judge_file(h5, h) if crits is None else crits


def slack_of_frames(h5) -> tuple | None:
    """((F,) frame times [s], (F,) share of the elements without tension) of an FE file's
    frames, as the verdict measures it at the end (record.verdict.slack_share: length not
    above the rest length; broken elements left out); None without frames."""
    if "frames" not in h5 or "mesh" not in h5 or h5["frames/time"].shape[0] == 0:
        return None
    elems = h5["mesh/elements"][()]
    rest = h5["mesh/rest_length"][()]
    pos = h5["frames/position"]
    broken = h5["frames/broken"] if "broken" in h5["frames"] else None
    share = np.array([verdict.slack_share(pos[k], elems, rest,
                                          None if broken is None else broken[k].astype(bool))
                      for k in range(pos.shape[0])])
    return h5["frames/time"][()], share


def judged(h5, h) -> Judged:
    """:class:`Judged` of an open result file and its history."""
    reach, r0 = reach_of_file(h5)
    return Judged(h, criteria_of(h5, h), reach, r0, case_of(h5), slack_of_frames(h5),
                  verdict.floors_of(h5.attrs))
