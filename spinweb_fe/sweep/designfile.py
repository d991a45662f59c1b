"""Design files (``spinweb design``): reading and validating one, and the case of a point
(docs/design.md, "The design file").

A design file (TOML; keys in TOP_KEYS): ``base`` (the case, relative to the design file),
``law`` (optional control.law), ``minimise`` (record.metrics.OBJECTIVES), ``require``
(criteria of record.criteria that must pass; default the registry's required ones),
``[search]`` (``"control.M0" = [low, high]``; a table's entry by index, e.g.
``"stowage.brake_force_table.1.1"``), ``[set]`` (fixed keys), ``[tie]``
(``"control.omega0" = "initial.omega"`` or ``{key = ..., factor = f}``), ``[bounds]``
(upper limits, record.metrics.BOUNDS), ``[fe]`` (overrides of the FE runs only),
``[chart]`` (one key and its values), and for a robust design ``members``, ``seed``,
``[random]`` (as in sweeps, sweep.draws) and ``pass_rate`` (the share of Monte-Carlo
members that must pass, judged by the lower end of its 95 % interval).
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spinweb_fe.errors import InputError
from spinweb_fe.fe.control import LAWS
from spinweb_fe.record import criteria as criteria_reg
from spinweb_fe.record.metrics import BOUNDS, OBJECTIVES
from spinweb_fe.case.text import base_path, show
from spinweb_fe.sweep.run import _read_toml, apply, flatten

TOP_KEYS = ("title", "base", "law", "minimise", "require", "candidates", "refine",
            "refine_step", "scan", "rtol", "maxiter", "search", "set", "tie", "bounds", "fe",
            "chart", "members", "seed", "random", "pass_rate")
@dataclass(frozen=True)
class Design:
    """A validated design file (see the module's doc); ``search``: key -> (low, high)."""

    source: Path
    text: str
    title: str
    base: Path
    base_raw: dict
    law: str | None
    search: dict
    sets: dict
    ties: dict              # key -> (source key, factor)
    fe_sets: dict
    bounds: dict            # name -> upper limit (strength: 1.0)
    minimise: str | None
    require: tuple | None   # None: every criterion
    candidates: int = 2
    refine: int = 4
    refine_step: float = 0.05
    scan: int = 17
    rtol: float = 1e-3
    maxiter: int = 12
    chart_key: str | None = None
    chart_values: tuple = ()
    chart_fe: tuple = ()
    chart_factor: float = 1.25
    members: int = 0        # Monte-Carlo members per verified candidate (0: nominal only)
    seed: int = 0
    draws: tuple = ()       # sweep.draws.Draw of each [random] key
    pass_rate: float | None = None  # the share that must pass (its 95 % interval's low end)

    @property
    def keys(self) -> tuple:
        return tuple(self.search)

    def is_log(self, key) -> bool:
        """Searched on a log scale: a positive range of a decade or more."""
        lo, hi = self.search[key]
        return lo > 0 and hi / lo >= 10.0

    def to_unit(self, values: dict) -> np.ndarray:
        """Searched values -> [0, 1] per key (log or linear)."""
        out = []
        for k in self.keys:
            lo, hi = self.search[k]
            x = values[k]
            out.append(math.log(x / lo) / math.log(hi / lo) if self.is_log(k)
                       else (x - lo) / (hi - lo))
        return np.array(out)

    def from_unit(self, u) -> dict:
        out = {}
        for k, v in zip(self.keys, np.clip(np.atleast_1d(u), 0.0, 1.0)):
            lo, hi = self.search[k]
            out[k] = float(lo * (hi / lo) ** v if self.is_log(k) else lo + v * (hi - lo))
        return out

    def unit_tol(self, key) -> float:
        """The bisection's resolution in unit coordinates: rtol of the value (log keys) or
        of the range."""
        lo, hi = self.search[key]
        return math.log1p(self.rtol) / math.log(hi / lo) if self.is_log(key) else self.rtol


def _num(src, key, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(src, key, f"must be a finite number, got {show(v)}")
    return float(v)


def _ties(src, table) -> dict:
    """[tie]: ``key = "other.key"`` or ``key = {key = "other.key", factor = f}``."""
    out = {}

    def walk(node, prefix):
        for k, v in node.items():
            dotted = prefix + k
            if isinstance(v, dict) and "key" not in v:
                walk(v, dotted + ".")
            elif isinstance(v, str):
                out[dotted] = (v, 1.0)
            elif isinstance(v, dict) and isinstance(v["key"], str) and set(v) <= {"key",
                                                                                  "factor"}:
                out[dotted] = (v["key"], _num(src, f"tie.{dotted}.factor", v.get("factor", 1.0)))
            else:
                raise InputError(src, f"tie.{dotted}", "must be a key name or "
                                 "{key = \"table.key\", factor = number}")
    walk(table, "")
    return out


def _options(src, doc):
    def integer(name, default, lo, hi):
        v = doc.get(name, default)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            raise InputError(src, name, f"must be an integer in [{lo}, {hi}], got {v!r}")
        return v

    def real(name, default, lo, hi):
        v = _num(src, name, doc.get(name, default))
        if not lo < v < hi:
            raise InputError(src, name, f"must be in ({lo:g}, {hi:g}), got {v!r}")
        return v
    return dict(candidates=integer("candidates", 2, 1, 3), refine=integer("refine", 4, 0, 10),
                refine_step=real("refine_step", 0.05, 0.0, 1.0), scan=integer("scan", 17, 3, 400),
                rtol=real("rtol", 1e-3, 0.0, 0.5), maxiter=integer("maxiter", 12, 1, 1000))


def _choice(src, key, v, valid, what):
    """``v`` if it is one of ``valid``, else InputError naming the nearest."""
    if isinstance(v, str) and v in valid:
        return v
    near = difflib.get_close_matches(str(v), list(valid), n=1, cutoff=0.5)
    raise InputError(src, key, f"unknown {what} {show(v)}" + (
        f" (did you mean '{near[0]}'?)" if near else f" (valid: {', '.join(valid)})"))


def _search(src, table, law):
    """[search]: key -> (low, high); a control key must be one of the law's."""
    out = {}
    for k, v in flatten(table).items():
        if not (isinstance(v, list) and len(v) == 2):
            raise InputError(src, f"search.{k}", f"must be [low, high], got {v!r}")
        lo, hi = _num(src, f"search.{k}", v[0]), _num(src, f"search.{k}", v[1])
        if not lo < hi:
            raise InputError(src, f"search.{k}", f"must be [low, high] with low < high, got {v!r}")
        have = [p.name for p in LAWS[law].keys]
        if k.startswith("control.") and k[8:] not in have:
            raise InputError(src, f"search.{k}", f"law {law!r} has no key {k[8:]!r} (its "
                             f"keys: {', '.join(have) or 'none'})")
        out[k] = (lo, hi)
    if not out:
        raise InputError(src, "search", "missing: a design searches at least one key, "
                         "e.g. [search] \"control.M0\" = [1e4, 1e7]")
    return out


def _bounds(src, table):
    out = {}
    for k, v in table.items():
        _choice(src, f"bounds.{k}", k, BOUNDS, "bound")
        if k == "strength":
            if not isinstance(v, bool):
                raise InputError(src, "bounds.strength", f"must be true or false, got {v!r}")
            out.update({k: 1.0} if v else {})
        elif _num(src, f"bounds.{k}", v) > 0:
            out[k] = float(v)
        else:
            raise InputError(src, f"bounds.{k}", f"must be > 0 ({BOUNDS[k][0]}), got {v!r}")
    return out


def load_design(path, chart: bool = False) -> Design:
    """Read and validate a design file (the cases at the corners of the search, and at
    every chart value, are built and validated too).

    Raises
    ------
    InputError
        Unknown keys, no searched key, a search range not [low, high] with low < high, a
        control key the law does not have, no [bounds] or no objective (a design; a
        ``chart`` needs neither), an unknown objective, bound or criterion, no [chart]
        table (``chart``), or a case that does not validate.
    """
    src = Path(path)
    doc = _read_toml(src, "design file")
    for key in doc:
        _choice(src, key, key, TOP_KEYS, "key")
    base = base_path(src, doc, "design")
    base_raw = _read_toml(base, "base case")
    for name in ("search", "set", "tie", "bounds", "fe", "chart"):
        if not isinstance(doc.get(name, {}), dict):
            raise InputError(src, name, f"must be a table [{name}]")
    law = doc.get("law")
    _choice(src, "law", law if law is not None else base_raw.get("control", {}).get(
        "law", "free"), LAWS, "control law")
    search = _search(src, doc.get("search", {}), law or base_raw.get("control", {}).get(
        "law", "free"))
    sets, ties, fe_sets = (flatten(doc.get("set", {})), _ties(src, doc.get("tie", {})),
                           flatten(doc.get("fe", {})))
    for k in [*ties, *fe_sets, *search]:  # [fe] may override [set] for the FE runs
        if (k in search) + (k in sets) + (k in ties) > 1 or k in fe_sets and (
                k in search or k in ties):
            where = "tie" if k in ties else "fe" if k in fe_sets else "set"
            raise InputError(src, f"{where}.{k}", "given in more than one of [search], [set], "
                             "[tie] (or searched or tied and in [fe]): give it in one place")
    bounds = _bounds(src, doc.get("bounds", {}))
    minimise = doc.get("minimise")
    if minimise is not None:
        _choice(src, "minimise", minimise, OBJECTIVES, "objective")
    if minimise == "parameter" and len(search) != 1:
        raise InputError(src, "minimise", "'parameter' needs exactly one searched key")
    if not chart and minimise is None:
        raise InputError(src, "minimise", f"missing: the objective (valid: {', '.join(OBJECTIVES)})")
    if not chart and not bounds:
        raise InputError(src, "bounds", "missing: a design needs at least one bound in "
                         f"[bounds] (valid: {', '.join(BOUNDS)})")
    require = doc.get("require")
    if require is not None:
        if not isinstance(require, list) or not require:
            raise InputError(src, "require", "must be a non-empty list of criteria")
        require = tuple(_choice(src, "require", c, criteria_reg.CRITERIA, "criterion")
                        for c in require)
    members, seed, draws, pass_rate = _robust(src, doc, search, sets, ties)
    d = Design(src, src.read_text(encoding="utf-8"), str(doc.get("title", "")), base, base_raw,
               law, search, sets, ties, fe_sets, bounds, minimise, require, **_options(src, doc),
               members=members, seed=seed, draws=draws, pass_rate=pass_rate)
    if not chart:  # a chart checks its cases with its values (sweep.chart.load_chart)
        check_cases(d)
    return d


def _robust(src, doc, search, sets, ties):
    """(members, seed, draws, pass_rate) of a robust design: ``[random]`` and ``members``
    as in a Monte-Carlo sweep (sweep.draws), ``pass_rate`` in (0, 1] (needs members)."""
    from spinweb_fe.sweep.draws import parse

    members, seed, draws = parse(src, doc)
    for dr in draws:
        if dr.key in search or dr.key in sets or dr.key in ties:
            raise InputError(src, f"random.{dr.key}", "also searched, set or tied: a drawn "
                             "key perturbs what the design sets, give it in one place")
    rate = doc.get("pass_rate")
    if rate is not None:
        rate = _num(src, "pass_rate", rate)
        if not 0.0 < rate <= 1.0:
            raise InputError(src, "pass_rate", f"must be in (0, 1], got {rate!r}")
        if not members:
            raise InputError(src, "pass_rate", "needs members and [random]: the rate is "
                             "judged on Monte-Carlo members in FE")
    return members, seed, draws, rate


def _lookup(raw, dotted):
    node = raw
    for p in dotted.split("."):
        if isinstance(node, list) and p.isdigit() and int(p) < len(node):
            node = node[int(p)]
        elif isinstance(node, dict) and p in node:
            node = node[p]
        else:
            return None
    return node


def case_raw(d: Design, values: dict, extra: dict | None = None, fe: bool = False) -> dict:
    """The case dict of a point: base, [set], law, the searched (and chart) ``values``,
    [fe] for an FE run, then the [tie] keys."""
    over = {**d.sets, **({"control.law": d.law} if d.law else {}), **values, **(extra or {})}
    if fe:
        over.update(d.fe_sets)
    raw = apply(d.base_raw, over, d.source, "design")
    if d.law:  # the base's keys of another law go
        keep = {"law", *(p.name for p in LAWS[d.law].keys)}
        raw["control"] = {k: v for k, v in raw["control"].items() if k in keep}
    ties = {}
    for k, (other, factor) in d.ties.items():
        v = _lookup(raw, other)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(d.source, f"tie.{k}", f"{other} is not a number of the case "
                             f"(got {v!r})")
        ties[k] = factor * float(v)
    return apply(raw, ties, d.source, "tie")


def build_case(d: Design, values: dict, extra=None, fe=False):
    from spinweb_fe.case.load import validate

    try:
        return validate(case_raw(d, values, extra, fe), str(d.base))
    except InputError as exc:
        if exc.source == str(d.source):
            raise
        raise InputError(d.source, exc.key, exc.reason) from None


def _fe_startable(d: Design, case):
    """What the FE refuses at its start (the solver's check, case.scene.prepare), here before
    the search: a prescribed rate's start at another initial rate."""
    from spinweb_fe.case.scene import control_from_case

    control = control_from_case(case)
    if control.law.prescribes_rate:
        w_law = control.law.rate(control.params, 0.0)[0]
        if abs(w_law - case.initial.omega) > 1e-12 * max(1.0, abs(w_law)):
            raise InputError(d.source, "set.initial.omega", f"the FE starts {control.law.name} "
                             f"from its own rate at t = 0 ({w_law:g} rad/s): set initial.omega "
                             "to it")


def check_cases(d: Design):
    """Build and validate the cases at the search's corners (and chart values)."""
    corners = [{k: v[i] for k, v in d.search.items()} for i in (0, 1)]
    extras = [{d.chart_key: v} for v in d.chart_values] or [None]
    for values in corners:
        for extra in extras:
            case = build_case(d, values, extra)
            _fe_startable(d, build_case(d, values, extra, fe=True))
            if "strength" in d.bounds and case.cable.failure_strain is None:
                raise InputError(d.source, "bounds.strength", "needs cable.failure_strain "
                                 "in the case (base or [set])")
            if "brake_force" in d.bounds and case.stowage.payout not in ("rate", "brake"):
                raise InputError(d.source, "bounds.brake_force", "the case has no payout "
                                 "device (stowage.payout = 'rate' or 'brake')")


