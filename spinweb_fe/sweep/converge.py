"""Mesh convergence of a case: the same case at three or more mesh widths, run on Dask as
sweeps are, and its quantities of interest on each (docs/converge.md).

The mesh: a web's ``web.mesh_width`` t (the grid must fit the side, N = S/t an integer of
the base grid's parity, so that the fold keeps its central cross or its lack of one) with
the cable area following it at the web's areal density; tethers' ``tethers.elements``
(the mesh size H / elements). The time step follows the mesh through the CFL number (a
``time.dt`` cap is scaled with the width). Frames are off.

The quantities of each grid are named and read by :mod:`spinweb_fe.sweep.quantities` (on
the worker, from the grid's ``results.h5``).
"""

from __future__ import annotations

import copy
import logging
import math
import time
import tomllib
import traceback
from dataclasses import dataclass
from pathlib import Path

from spinweb_fe.case.load import apply_overrides, validate
from spinweb_fe.errors import InputError
from spinweb_fe.sweep.quantities import default_quantities, parse_quantity, quantities_of

log = logging.getLogger(__name__)

#: the key each scene refines
MESH_KEY = {"web": "web.mesh_width", "tethers": "tethers.elements"}
#: the least refinement ratio between neighbouring grids, and the default
MIN_RATIO, RATIO = 1.1, 2.0
#: the share of time.end that --quick runs
QUICK_SHARE = 0.1


@dataclass(frozen=True)
class Member:
    """One grid: ``h`` its mesh size [m], ``value`` of the refined key, its case dict."""

    index: int
    name: str
    h: float
    value: float
    raw: dict


@dataclass(frozen=True)
class Plan:
    """A validated convergence study of one case."""

    source: Path
    scene: str
    key: str
    members: tuple  # coarsest first
    quantities: tuple
    end: float
    times: tuple
    title: str = ""


def _read_raw(path: Path, sets) -> dict:
    with open(path, "rb") as fh:
        return apply_overrides(tomllib.load(fh), sets)


def _set(raw: dict, dotted: str, value):
    node = raw
    parts = dotted.split(".")
    for p in parts[:-1]:
        node = node.setdefault(p, {})
    if value is None:
        node.pop(parts[-1], None)
    else:
        node[parts[-1]] = value


def _ladder(n0: int, ratio: float, levels: int, parity: bool) -> list:
    """Integer counts n0 < n1 < ... near n0 ratio^k (of n0's parity when ``parity``)."""
    out = [n0]
    for k in range(1, levels):
        target = n0 * ratio ** k
        n = 2 * round(target / 2) if parity and n0 % 2 == 0 else round(target)
        if parity and n0 % 2 == 1 and n % 2 == 0:
            n += 1 if target > n else -1
        out.append(max(n, out[-1] + (2 if parity else 1)))
    return out


def _counts(case, src, widths, ratio, levels) -> tuple:
    """(counts, sizes [m]) of the grids, coarsest first: N = S / t for a web, elements for
    tethers; InputError for fewer than three, a ratio below MIN_RATIO or a width that does
    not fit the side."""
    if case.scene == "web":
        size, n0, what = case.web.side, case.web.side / case.web.mesh_width, "the side"
    else:
        size, n0, what = case.tethers.length, float(case.tethers.elements), "the tether"
    if abs(n0 - round(n0)) > 1e-9 * n0:
        raise InputError(src, MESH_KEY[case.scene], f"the side {size:g} m is not a whole "
                         f"number of mesh widths (side / width = {n0:.9g})")
    if widths:
        counts = []
        for w in widths:
            n = size / w if w > 0 else 0.0
            if not (abs(n - round(n)) <= 1e-9 * n and round(n) >= 2):
                raise InputError("--widths", "", f"{w:g} m does not fit {what} "
                                 f"({size:g} m) a whole number of times")
            counts.append(round(n))
        counts = sorted(set(counts))
    else:
        if not ratio >= MIN_RATIO:
            raise InputError("--ratio", "", f"{ratio:g} is below {MIN_RATIO}: neighbouring "
                             "grids would differ by less than the noise of the runs")
        counts = _ladder(round(n0), ratio, levels, case.scene == "web")
    if len(counts) < 3:
        raise InputError("--widths" if widths else "--levels", "", f"{len(counts)} "
                         "mesh widths: a grid study needs at least three (an order needs "
                         "three values)")
    for a, b in zip(counts, counts[1:]):
        if b / a < MIN_RATIO:
            raise InputError("--widths" if widths else "--ratio", "", f"the widths "
                             f"{size / a:g} and {size / b:g} m differ by a ratio {b / a:.3g}"
                             f", below {MIN_RATIO}")
    return counts, [size / n for n in counts]


def plan(path, sets=(), widths=None, ratio=RATIO, levels=3, quick=False, end=None,
         times=None, quantities=None) -> Plan:
    """Read and check a study: the case, its grids (each validated) and quantities.

    Parameters
    ----------
    path : str or Path
        The case file.
    sets : iterable of str
        ``key=value`` overrides of the case.
    widths : sequence of float [m], optional
        The mesh widths (tethers: element lengths); default the case's width refined
        ``levels - 1`` times by ``ratio``.
    quick : bool
        Run the first QUICK_SHARE of time.end (``end`` overrides).
    times : sequence of float [s], optional
        Times of the default hub-rate and arm-length quantities (default: a quarter, half,
        three quarters and the whole window).
    quantities : sequence of str, optional
        Quantity names (module docstring); default :func:`default_quantities`.

    Raises
    ------
    InputError
        A case that cannot be refined, fewer than three widths, a ratio below 1.1, a width
        that does not fit, an unknown quantity, or a grid whose case does not validate.
    """
    from spinweb_fe.case import load as load_case

    src = Path(path)
    case = load_case(src, sets)
    if case.scene not in MESH_KEY:
        raise InputError(src, case.scene, "this scene has no mesh width to refine")
    raw0 = _read_raw(src, sets)
    if case.scene == "tethers" and "elements" not in raw0.get("tethers", {}):
        raise InputError(src, "tethers.elements", "not given: converge refines the tethers' "
                         "element count, and the case must state the one it starts from")
    counts, hs = _counts(case, src, widths, ratio, levels)
    end = float(end) if end is not None else case.time.end * (QUICK_SHARE if quick else 1.0)
    if not 0 < end <= case.time.end:
        raise InputError("--end", "", f"{end:g} s is not within the case's run "
                         f"(0, {case.time.end:g}] s")
    times = tuple(float(t) for t in times) if times else tuple(end * f for f in
                                                               (0.25, 0.5, 0.75, 1.0))
    for t in times:
        if not 0 <= t <= end:
            raise InputError("--times", "", f"{t:g} s is outside the window [0, {end:g}] s")
    names = tuple(quantities) if quantities else default_quantities(case, times)
    for q in names:
        parse_quantity(q)
    members = []
    cutout = hole(case)
    h0 = (case.web.mesh_width if case.scene == "web"  # the width a time.dt cap was set for
          else case.tethers.length / case.tethers.elements)
    for k, (n, h) in enumerate(sorted(zip(counts, hs), key=lambda x: -x[1])):
        raw = copy.deepcopy(raw0)
        value = h if case.scene == "web" else int(n)
        _set(raw, MESH_KEY[case.scene], value)
        if case.scene == "web" and case.web.areal_density is None:
            _set(raw, "web.areal_density", areal_density(case))
            _set(raw, "cable.area", None)
        if cutout is not None:
            _set(raw, "web.hub_cutout", cutout)
            _check_cutout(src, case.web.side, h, cutout)
        _set(raw, "time.end", end)
        _set(raw, "output.frame_dt", 0.0)
        if case.time.dt is not None:
            _set(raw, "time.dt", case.time.dt * h / h0)
        name = f"{k}_{MESH_KEY[case.scene].split('.')[1]}={value:.6g}"
        try:
            validate(raw, str(src))
        except InputError as exc:
            raise InputError(src, f"grid {name}: {exc.key}", exc.reason) from None
        members.append(Member(k, name, h, value, raw))
    return Plan(src, case.scene, MESH_KEY[case.scene], tuple(members), names, end, times,
                case.title)


def hole(case) -> float | None:
    """[m] the square web's hub cut-out, pinned for every grid at the base grid's (by
    default the smallest grid line outside the hub follows the mesh: 7.5 m at t = 2.5 and
    1.25 m, 6.875 m at 0.625 m, and the root region and frame with it); None for other
    topologies and tethers."""
    from meshgen.build import quadquad_cutout
    from meshgen.checks import MeshValueError

    if case.scene != "web" or case.web.topology != "quadquad":
        return None
    w = case.web
    try:
        return quadquad_cutout(w.side, w.mesh_width, case.hub.radius, w.hub_cutout)
    except MeshValueError as exc:
        raise InputError(case.source, "web.hub_cutout", exc.reason) from None


def _check_cutout(src, side, h, cutout):
    """A warning when a grid has no line at the pinned cut-out (its hole is larger)."""
    from meshgen.checks import MeshValueError
    from meshgen.flat import effective_cutout

    try:
        got = effective_cutout(side, h, cutout)
    except MeshValueError as exc:
        raise InputError(src, "web.hub_cutout", f"grid of width {h:g} m: {exc.reason}") from None
    if abs(got - cutout) > 1e-9 * side:
        log.warning("%s: the grid of width %.6g m has no mesh line at the hub cut-out "
                    "%.6g m: its hole is %.6g m (the geometry changes with the mesh; widths "
                    "that divide the cut-out keep it)", src, h, cutout, got)


def areal_density(case) -> float:
    """[kg/m^2] the areal density of a web given by its cable area (kept as the mesh is
    refined, so that the web's mass stays)."""
    from meshgen.registry import area_from_areal_density

    w = case.web
    return case.cable.area / area_from_areal_density(w.topology, 1.0, w.mesh_width,
                                                     case.cable.density)


def run_member(task: dict) -> dict:
    """Run one grid (a Dask task): the case on one thread, then its quantities. Never
    raises: an error becomes ``status``, its traceback goes to ``out_dir/run.log``."""
    from spinweb_fe.sweep.run import member_log, one_line

    t0 = time.perf_counter()
    out = Path(task["out_dir"])
    row = {"values": {q: math.nan for q in task["quantities"]}, "passed": {}, "info": {}}
    with member_log(out) as spin_log:
        try:
            from spinweb_fe.run.driver import run_case

            run_case(validate(task["raw"], task["source"]), out, progress=False, threads=1)
            row["values"], row["passed"], row["info"] = quantities_of(out / "results.h5",
                                                                      task["quantities"])
            row["status"] = "ok"
        except Exception as exc:  # recorded, not fatal: the other grids go on
            spin_log.error("run failed:\n%s", traceback.format_exc())
            row["status"] = one_line(exc)
    row["wall_time_s"] = time.perf_counter() - t0
    return row


def execute(p: Plan, out_dir, scheduler=None, workers=2, progress=True) -> list:
    """Run every grid of ``p`` on Dask (the finest first); one row per member, in member
    order: ``values`` {quantity: value}, ``passed`` {criterion: bool or None}, ``info``
    (dt [s], steps, elements), ``status``, ``wall_time_s``."""
    from dask.distributed import as_completed

    from spinweb_fe.sweep.cluster import dask_client
    from spinweb_fe.sweep.run import one_line

    out_dir = Path(out_dir).resolve()
    rows = [None] * len(p.members)
    with dask_client(scheduler, workers) as client:
        futures = {}
        for m in sorted(p.members, key=lambda m: m.h):
            task = {"raw": m.raw, "source": str(p.source), "quantities": list(p.quantities),
                    "out_dir": str(out_dir / "runs" / m.name)}
            fut = client.submit(run_member, task, pure=False,
                                key=f"spinweb-converge-{m.name}-{id(task)}")
            futures[fut] = m.index
        for done, fut in enumerate(as_completed(futures), start=1):
            i = futures[fut]
            try:
                rows[i] = fut.result()
            except Exception as exc:  # the worker died or the task was lost
                rows[i] = {"values": {q: math.nan for q in p.quantities}, "passed": {},
                           "info": {}, "status": one_line(exc), "wall_time_s": math.nan}
            if progress:
                log.info("[%d/%d] %s: %s (%.1f s)", done, len(rows), p.members[i].name,
                         rows[i]["status"], rows[i]["wall_time_s"])
    return rows
