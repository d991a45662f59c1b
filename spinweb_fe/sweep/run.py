"""Parameter sweeps: many runs of one base case, executed with Dask, one summary table.

A sweep file (TOML, see docs/sweep.md)::

    title = "hub radius and spin"
    base = "../paper_free_web.toml"   # relative to the sweep file
    mode = "fe"                       # fe | analytic
    model = "consistent"              # analytic only: printed | consistent
    [set]                             # applied to every run
    time.end = 0.5
    [grid]                            # cartesian product of the lists
    hub.radius = [4.0, 6.3]
    initial.omega = [12.566, 25.133]
    [[runs]]                          # and/or explicit override tables
    name = "slow"                     # optional directory label
    initial.omega = 6.283

Every run's case is built (base + [set] + its [[runs]] entry + its grid point) and
validated before anything runs: an invalid sweep raises :class:`InputError`. Each run is
one Dask task (:func:`run_one`) writing ``DIR/runs/<index>_<slug>/`` and returning its
metrics (:func:`history_metrics`); a failing run is recorded with its error in
``status``, not raised. :mod:`spinweb_fe.sweep_report` writes ``summary.csv``,
``summary.h5`` and ``summary.png``.
"""

from __future__ import annotations

import contextlib
import copy
import difflib
import itertools
import logging
import math
import os
import re
import time
import tomllib
import traceback
from dataclasses import dataclass
from pathlib import Path


from spinweb_fe.case.load import validate
from spinweb_fe.case.text import base_path, read_toml
from spinweb_fe.record import metrics as metric_reg
from spinweb_fe.record import verdict
from spinweb_fe.errors import InputError, RunError
from spinweb_fe.run.estimate import case_elements
from spinweb_fe.sweep.draws import member_values
from spinweb_fe.sweep.draws import parse as parse_draws
from spinweb_fe.sweep.limits import check_runs, count_runs

log = logging.getLogger(__name__)

MODES = ("fe", "analytic")
MODELS = ("consistent", "printed")
TOP_KEYS = ("title", "base", "mode", "model", "set", "grid", "runs", "members", "seed", "random")
#: the summary's columns after the swept keys: (name, units, description); the metrics are
#: the registry's (record/metrics.py), then the verdict's and the run's own
METRICS = (
    *((m.column, m.unit, m.measures) for m in metric_reg.METRICS.values()),
    ("recoiled", "1", "1 if the verdict's re-coil criterion fails (a tip fell back toward the "
                      "hub by more than verdict.recoil of its arm)"),
    ("passed", "1", "1 if the run's verdict passes (every required criterion that applies), "
                    "else 0"),
    ("severity", "1", "the verdict's worst criterion against its limit (above 1: failed)"),
    ("wall_time_s", "s", "wall-clock time of the run (task)"),
)
#: metrics drawn in summary.png, with their axis labels
PLOTTED = {m.column: m.plot for m in metric_reg.METRICS.values() if m.plot}


@dataclass(frozen=True)
class Run:
    """One run of a sweep: ``values`` of the swept keys, all ``overrides``, the case dict."""

    index: int
    name: str
    values: dict
    overrides: dict
    raw: dict
    label: str = ""  # the name of its [[runs]] entry, if given
    member: int = -1  # its Monte-Carlo member (-1: the sweep has none)
    elements: float = 0.0  # about its cable elements (FE; run.estimate.case_elements)


@dataclass(frozen=True)
class Sweep:
    """A validated sweep file."""

    source: Path
    title: str
    base: Path
    mode: str
    model: str
    keys: tuple
    runs: tuple
    text: str
    grid: tuple = ()  # the [grid] keys (the first of ``keys``)
    members: int = 0  # Monte-Carlo members per grid point and [[runs]] entry (0: none)
    seed: int = 0
    draws: tuple = ()  # sweep.draws.Draw of each [random] key (the last of ``keys``)


def flatten(table: dict, prefix: str = "") -> dict:
    """Nested TOML tables -> dotted keys: ``{'hub': {'radius': 1}} -> {'hub.radius': 1}``."""
    out = {}
    for k, v in table.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, key + "."))
        else:
            out[key] = v
    return out


def apply(raw: dict, overrides: dict, src, where) -> dict:
    """A deep copy of the case dict ``raw`` with dotted ``overrides`` set; a number among
    the parts indexes a list (``stowage.brake_force_table.1.1``: the second point's
    force)."""
    raw = copy.deepcopy(raw)
    for dotted, value in overrides.items():
        node = raw
        parts = dotted.split(".")
        for p in parts[:-1]:
            if isinstance(node, list):
                node = _item(node, p, src, f"{where}.{dotted}")
                continue
            node = node.setdefault(p, {})
            if not isinstance(node, (dict, list)):
                raise InputError(src, f"{where}.{dotted}", f"'{p}' is not a table of the case")
        if isinstance(node, list):
            _item(node, parts[-1], src, f"{where}.{dotted}")
            node[int(parts[-1])] = value
        else:
            node[parts[-1]] = value
    return raw


def _item(node: list, part: str, src, key):
    """``node[int(part)]``, or InputError when ``part`` is no index of it."""
    if not part.isdigit() or int(part) >= len(node):
        raise InputError(src, key, f"'{part}' is not an index of a list of {len(node)}")
    return node[int(part)]


def _clean(text: str, width: int = 48) -> str:
    return re.sub(r"[^A-Za-z0-9.=+_-]+", "-", text)[:width].strip("-_") or "run"


def _slug(values: dict) -> str:
    """Directory label of a run: ``radius=2_omega=12.57`` (last part of each key)."""
    return _clean("_".join(f"{k.split('.')[-1]}={v:.4g}" if isinstance(v, float)
                           else f"{k.split('.')[-1]}={v}" for k, v in values.items()) or "base")


def _read_toml(path: Path, what: str) -> dict:
    return read_toml(path, what)


def _scalar(src, key, v):
    if isinstance(v, (dict, list)):
        raise InputError(src, key, f"expected a single value, got {v!r}")
    return v


def load_sweep(path, mode=None, sets=(), only=(), force=False) -> Sweep:
    """Read a sweep file, build and validate every run.

    Parameters
    ----------
    path : str or Path
    mode : {'fe', 'analytic'}, optional
        Overrides the file's ``mode``.
    sets : iterable of str
        ``key=value`` overrides (TOML values) added to ``[set]``.
    only : iterable of str
        Keep only these runs (their names or indices; each run keeps its own draws).
    force : bool
        Accept more runs than the machine can keep track of (sweep.limits.check_runs).

    Raises
    ------
    InputError
        Unknown keys, a missing base case, empty grid lists, a key both in [grid] and
        [[runs]] (or in ``sets`` and one of them), or any run whose case does not validate
        (named by index and key).
    """
    from spinweb_fe.case.load import parse_set

    src = Path(path)
    doc = _read_toml(src, "sweep file")
    for key in doc:
        if key not in TOP_KEYS:
            near = difflib.get_close_matches(key, TOP_KEYS, n=1, cutoff=0.5)
            hint = f" (did you mean '{near[0]}'?)" if near else f" (valid: {', '.join(TOP_KEYS)})"
            raise InputError(src, key, "unknown key" + hint)
    base = base_path(src, doc, "sweep")
    mode = mode or doc.get("mode", "fe")
    if mode not in MODES:
        raise InputError(src, "mode", f"unknown mode '{mode}' (valid: {', '.join(MODES)})")
    model = doc.get("model", "consistent")
    if model not in MODELS:
        raise InputError(src, "model", f"unknown model '{model}' (valid: {', '.join(MODELS)})")
    for name in ("set", "grid"):
        if not isinstance(doc.get(name, {}), dict):
            raise InputError(src, name, f"must be a table [{name}]")
    common = {k: _scalar(src, f"set.{k}", v) for k, v in flatten(doc.get("set", {})).items()}
    given = []  # the --set keys, which the grid and the runs must not set as well
    for arg in sets or ():
        parts, value = parse_set(arg)
        common[".".join(parts)] = value
        given.append(".".join(parts))
    grid = flatten(doc.get("grid", {}))
    for k, v in grid.items():
        if not isinstance(v, list) or not v:
            raise InputError(src, f"grid.{k}", "must be a non-empty list of values")
        for x in v:
            _scalar(src, f"grid.{k}", x)
    entries = doc.get("runs", [{}])
    if not isinstance(entries, list) or not all(isinstance(e, dict) for e in entries):
        raise InputError(src, "runs", "must be an array of tables [[runs]]")
    entries = [flatten(e) for e in entries] or [{}]
    run_keys = list(dict.fromkeys(k for e in entries for k in e if k != "name"))
    for k in run_keys:
        if k in grid:
            raise InputError(src, f"grid.{k}", "also set in [[runs]]: give it in one place")
    for k in given:
        if k in grid or k in run_keys:
            where = f"[grid] ({src.name}: grid.{k})" if k in grid else f"[[runs]] ({src.name})"
            raise InputError("--set", k, f"is also set by the sweep's {where}, which would "
                             "override it: give it in one place")
    members, seed, draws = parse_draws(src, doc)
    for d in draws:
        if d.key in grid or d.key in run_keys or d.key in common:
            raise InputError(src, f"random.{d.key}", "also set in [set], [grid] or [[runs]]: "
                             "give it in one place")
    keys = tuple(list(grid) + run_keys + [d.key for d in draws])
    check_runs(count_runs(len(entries), [len(v) for v in grid.values()], members), src,
               force)  # before anything is built
    base_raw = _read_toml(base, "base case")
    points = [dict(zip(grid, combo)) for combo in itertools.product(*grid.values())]
    combos = [(i, e, g, m) for i, e in enumerate(entries) for g in points
              for m in (range(members) if members else [-1])]
    width = max(3, len(str(len(combos) - 1)))
    mwidth = len(str(max(members - 1, 0)))
    runs = []
    wanted = {str(x) for x in only or ()}
    for index, (i_entry, entry, point, member) in enumerate(combos):
        own = {k: _scalar(src, f"runs[{i_entry}].{k}", v)
               for k, v in entry.items() if k != "name"}
        drawn = member_values(draws, seed, member) if member >= 0 else {}
        overrides = {**common, **own, **point, **drawn}
        where = f"run {index}" + (f" (member {member}: "
                                  + ", ".join(f"{k} = {v!r}" for k, v in drawn.items()) + ")"
                                  if member >= 0 else "")
        raw = apply(base_raw, overrides, src, where)
        try:
            case = validate(raw, str(base))
            resolved = flatten(case.to_dict())
        except InputError as exc:
            raise InputError(src, f"{where}: {exc.key}" if exc.key else where,
                             exc.reason) from None
        values = {k: resolved.get(k, overrides.get(k)) for k in keys}
        label = entry.get("name")
        fixed = {k: v for k, v in values.items() if k not in drawn}
        slug = _slug(fixed) if label is None else _clean(
            "_".join([str(label)] + ([_slug(point)] if point else [])))
        if member >= 0:
            slug = _clean(("" if slug == "base" else slug + "_") + f"m{member:0{mwidth}d}")
        name = f"{index:0{width}d}_{slug}"
        if wanted and name not in wanted and str(index) not in wanted:
            continue
        runs.append(Run(index, name, values, overrides, raw,
                        "" if label is None else str(label), member,
                        case_elements(case) if mode == "fe" else 0.0))
    if wanted and not runs:
        raise InputError("--only", "", f"no run of {src.name} is named {', '.join(sorted(wanted))} "
                         "(see --dry-run for the names)")
    return Sweep(src, str(doc.get("title", "")), base, mode, model, keys, tuple(runs),
                 src.read_text(encoding="utf-8"), tuple(grid), members, seed, draws)


def history_metrics(h: dict, crits, reach, hub_radius: float,
                    fraction: float = verdict.DEFAULTS["deployed_fraction"],
                    ea_fail: float | None = None) -> dict:
    """The summary's metric columns of one run (record.metrics.compute of its ``/history``
    and criteria, by column name; docs/sweep.md)."""
    return metric_reg.columns(metric_reg.compute(h, crits, reach, hub_radius, fraction,
                                                 ea_fail))


def fe_metrics(path) -> tuple:
    """(:func:`history_metrics`, the verdict's criteria) of an FE ``results.h5``, read in one
    opening (the deployed reach from ``/mesh``, the deployed share from the case's
    [verdict], the criteria from ``/verdict``, which the driver writes).

    Raises
    ------
    RunError
        The file has no verdict (the run could not be judged).
    """
    import h5py

    from spinweb_fe.io.mesh import read_mesh_group

    with h5py.File(path, "r") as h5:
        mesh = read_mesh_group(h5["mesh"])
        case = tomllib.loads(str(h5.attrs.get("case", "")))
        keys = ("time", "tip_position", "hub_position", "hub_axis", "hub_torque", "hub_omega",
                "max_tension", "brake_tension")
        h = {k: h5["history"][k][()] for k in keys if k in h5["history"]}
        crits = verdict.read_group(h5)
    if crits is None:
        raise RunError(f"{path} has no verdict (the run could not be judged: see run.log)")
    frac = verdict.limits_of(case.get("verdict"))["deployed_fraction"]
    return history_metrics(h, crits, verdict.reach_of(mesh), mesh.hub_radius, frac), crits


def run_one(task: dict) -> dict:
    """Run one case of a sweep (a Dask task) and return its metrics, wall time and status.

    ``task``: ``raw`` (case dict), ``source`` (base case path), ``mode``, ``model`` and
    ``out_dir``. Never raises: an error becomes ``status`` (one line); the traceback and
    the run's log go to ``out_dir/run.log``.
    """
    t0 = time.perf_counter()
    out = Path(task["out_dir"])
    with member_log(out) as spin_log:
        try:
            case = validate(task["raw"], task["source"])
            if task["mode"] == "fe":
                from spinweb_fe.run.driver import run_case

                run_case(case, out, progress=False)
                metrics, crits = fe_metrics(out / "results.h5")
            else:
                from spinweb_fe.analytic import solve as analytic

                res = analytic.solve_case(case, model=task["model"])
                analytic.write(out / "analytic.h5", case, res, rtol=1e-10, atol=1e-10)
                p = res.params  # a model that stopped (its validity) fails 'completed'
                crits = analytic.judge(case, res)
                metrics = history_metrics(res.history, crits, p.r0 + p.H, p.r0,
                                          verdict.limits_of(case.verdict)["deployed_fraction"])
            recoil = next(c for c in crits if c.name == "recoil")
            metrics.update(recoiled=float(recoil.passed is False),
                           passed=float(verdict.passed(crits)), severity=verdict.severity(crits),
                           failed=",".join(verdict.failed_names(crits)))
            status = "ok"
        except Exception as exc:  # recorded, not fatal: the sweep goes on
            spin_log.error("run failed:\n%s", traceback.format_exc())
            metrics = {name: math.nan for name, _, _ in METRICS}
            metrics["failed"] = "run failed"
            status = one_line(exc)
    return {**metrics, "wall_time_s": time.perf_counter() - t0, "status": status}


def one_line(exc) -> str:
    """An error as a run's status: its type and first line."""
    return f"{type(exc).__name__}: {exc}".splitlines()[0] or type(exc).__name__


@contextlib.contextmanager
def member_log(out: Path):
    """The log of one run on a worker: ``out/run.log`` gets the package's log lines (INFO
    and up) while the block runs, and nothing goes to the worker's own log; the kernels'
    compile helper is off (the workers share the cores already). Yields the package's
    logger."""
    os.environ["SPINWEB_COMPILE_HELPER"] = "0"
    out.mkdir(parents=True, exist_ok=True)
    spin_log = logging.getLogger("spinweb_fe")  # the package: every module logs under it
    handler = logging.FileHandler(out / "run.log", mode="w")
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
    saved = spin_log.propagate, spin_log.level
    spin_log.addHandler(handler)
    spin_log.propagate, spin_log.level = False, logging.INFO
    try:
        yield spin_log
    finally:
        spin_log.removeHandler(handler)
        handler.close()
        spin_log.propagate, spin_log.level = saved
