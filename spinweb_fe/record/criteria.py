"""The registry of verdict criteria and their limits: the one place where a criterion is
defined (name, what it measures, its value's unit, the ``[verdict]`` key of its limit and
that key's default, where it applies, whether a design requires it by default).

Read by the judge (:mod:`spinweb_fe.record.verdict`, which the FE driver and the analytical
model both call), the case schema (the ``[verdict]`` table), ``spinweb info`` (its
``--criteria`` listing and the verdict lines), sweeps and design (the criteria a design
may require). docs/design.md's table of criteria is :func:`markdown` of this registry
(tests/test_criteria.py holds them equal).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Limit:
    """A key of the case's ``[verdict]`` table: its schema (kind, default, check as in
    :class:`spinweb_fe.case.schema.Field`), SI unit and what it sets."""

    key: str
    kind: str
    default: Any
    check: Any
    unit: str
    doc: str


@dataclass(frozen=True)
class CriterionDef:
    """A verdict criterion: ``measures`` what it judges, ``passes`` when, the ``unit`` of its
    value, the ``limit`` key of ``[verdict]`` that sets its threshold (None: a fixed one,
    stated in ``passes``), where it ``applies``, and whether a design ``required`` it when
    its file does not say (every criterion that applies to the run must then pass)."""

    name: str
    measures: str
    passes: str
    unit: str
    limit: str | None
    applies: str
    required: bool = True
    fails: str = ""   # how a failure reads for a designer (design's "why no design")


CRITERIA = {c.name: c for c in (
    CriterionDef("completed", "the run reached its end time",
                 "the run reached `time.end` (analytical: the model did not stop, e.g. where "
                 "an arm swings over its held coil); value: the share of the run done",
                 "1", None, "all",
                 fails="the analytical model leaves its validity (an arm swings over its held coil)"),
    CriterionDef("deployed", "every arm at its deployed length, and staying there",
                 "every tip is at least `deployed_fraction` of its deployed distance from "
                 "the hub axis from some time on, to the end (by `deploy_by` [s] if given)",
                 "1", "deployed_fraction", "all",
                 fails="the arms are not out for good"),
    CriterionDef("recoil", "no tip fell back toward the hub (re-coil)",
                 "no tip falls back toward the hub from its farthest by more than `recoil` "
                 "of its arm's deployed length", "1", "recoil", "all",
                 fails="a tip falls back toward the hub (re-coil)"),
    CriterionDef("slack", "share of the cable elements without tension at the end",
                 "at most `slack_share` of the cable elements carry no tension at the end "
                 "(not required by default: it says where the run ended, a web still in its "
                 "second stage or a tether still on its reel, more than whether it deploys)",
                 "1", "slack_share", "FE", required=False,
                 fails="the web stays gathered (slack)"),
    CriterionDef("overstrain", "no element beyond its failure strain",
                 "the utilisation (strain / `cable.failure_strain`) stays at most 1 "
                 "(docs/strength.md)", "1", None,
                 "FE, and analytical tethers, with a failure strain",
                 fails="a cable strains beyond its failure strain"),
    CriterionDef("swing", "in-plane swing of the arms after deployment",
                 "half the range of every arm's phi over the second half of the time after "
                 "deployment is at most `swing`", "rad", "swing", "deployed runs",
                 fails="the arms keep swinging"),
    CriterionDef("flatness", "out-of-plane distance of the web at the end",
                 "the web's largest distance from the hub plane at the end is at most "
                 "`flatness` of the deployed arm length", "1", "flatness",
                 "FE runs that can leave the plane",
                 fails="the web leaves its plane"),
    CriterionDef("energy", "energy balance of the run",
                 "the energy balance closes within `energy` of the run's energy scale "
                 "(docs/results.md)", "1", "energy", "all",
                 fails="the energy audit fails"),
    CriterionDef("momentum", "angular momentum balance about the spin axis",
                 "K - K0 - the control torque's impulse about the spin axis stays within "
                 "`momentum` of max abs(K)", "1", "momentum", "all but the gravity gradient",
                 fails="the momentum audit fails"),
    CriterionDef("tangled", "cable elements that passed through each other (the crossing "
                 "audit)", "at most `crossings` crossings of cable elements", "1", "crossings",
                 "FE with audit.crossings",
                 fails="cables cross"),
)}

#: the ``[verdict]`` table: every limit a criterion names, and the keys that qualify them
LIMITS = {lim.key: lim for lim in (
    Limit("deployed_fraction", "float", 0.8, "frac", "", "deployed: every tip at least this "
          "share of its deployed distance from the hub axis, and staying there to the end"),
    Limit("deploy_by", "float", None, "pos", "s", "deployed: by this time (default: any time "
          "before the end)"),
    Limit("recoil", "float", 0.5, "pos", "", "re-coil: a tip falling back toward the hub "
          "from its farthest by more than this share of its arm's deployed length"),
    Limit("slack_share", "float", 0.75, "frac", "", "slack: at most this share of the cable "
          "elements without tension at the end"),
    Limit("swing", "float", 0.3, "pos", "rad", "swing: the largest in-plane swing of an arm "
          "after deployment (half the range of phi)"),
    Limit("flatness", "float", 0.05, "pos", "", "flatness: the web's largest distance from "
          "the hub plane at the end, per deployed arm length"),
    Limit("energy", "float", 0.02, "pos", "", "energy audit: the balance closed within this "
          "share of the energy scale"),
    Limit("momentum", "float", 0.01, "pos", "", "momentum audit: K - K0 - torque impulse "
          "within this share of max |K|"),
    Limit("crossings", "int", 0, "nonneg", "", "tangled: more crossings of cable elements "
          "than this (needs audit.crossings)"),
    Limit("require", "names", None, tuple(CRITERIA), "", "the criteria the run's overall "
          "verdict asks to pass (default: every one that applies); a design writes its own"),
)}

#: the thresholds' defaults (``require`` aside: the overall verdict's criteria)
DEFAULTS = {k: lim.default for k, lim in LIMITS.items() if k != "require"}
#: the criteria with a limit that every run of a scene has (not those of some runs only: the
#: out-of-plane flatness, the crossing audit): a convergence study's default margins
GENERAL = tuple(c.name for c in CRITERIA.values() if c.limit and c.applies in (
    "all", "FE", "deployed runs", "all but the gravity gradient"))
#: the criteria a design requires when its file names none
REQUIRED = tuple(name for name, c in CRITERIA.items() if c.required)


def required(names=None) -> tuple:
    """The criteria an overall verdict or a design asks to pass: ``names`` (validated
    elsewhere) or the registry's :data:`REQUIRED`."""
    return tuple(names) if names else REQUIRED


def markdown() -> str:
    """The table of criteria of docs/design.md."""
    rows = ["| criterion | measures | passes when | unit | limit (`[verdict]` key) | default "
            "| applies to | required by default |", "|---|---|---|---|---|---|---|---|"]
    for c in CRITERIA.values():
        lim = LIMITS.get(c.limit) if c.limit else None
        default = "-" if lim is None or lim.default is None else f"{lim.default:g}"
        rows.append(f"| `{c.name}` | {c.measures} | {c.passes} | {c.unit} | "
                    f"{'`' + c.limit + '`' if c.limit else '-'} | {default} | {c.applies} | "
                    f"{'yes' if c.required else 'no'} |")
    return "\n".join(rows)


def listing() -> list:
    """Lines of ``spinweb info --criteria``: each criterion and limit key with its unit and
    default."""
    out = ["verdict criteria (record/criteria.py):"]
    for c in CRITERIA.values():
        lim = LIMITS.get(c.limit) if c.limit else None
        where = (f"limit verdict.{c.limit} = {lim.default:g}" if lim and lim.default is not None
                 else "fixed limit")
        out.append(f"  {c.name:<11} [{c.unit}] {c.measures}; {where}; applies to {c.applies}"
                   f"{'' if c.required else '; not required by default'}")
    return out
