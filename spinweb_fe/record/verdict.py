"""Verdicts: does a run deploy? Each criterion of the registry
(:mod:`spinweb_fe.record.criteria`: what it measures, its ``[verdict]`` limit and default,
where it applies) judged from a run's history (FE or analytical: the same columns), with
the time and arm where it first failed; written into a result file as root attributes and
a ``/verdict`` group, read back by ``spinweb info``, the sweeps and ``spinweb design``
(docs/design.md). A criterion that does not apply to a run is reported as such, never
passed; the overall verdict asks the required ones (``[verdict] require``) to pass.

Distances, not the arm-length measure of record.arms, say whether an arm is out: a quad
web's cells shear, its corners breathe radially about the flat web's place, and an arm
still wound on the hub is short.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from spinweb_fe.record import criteria as criteria_mod
from spinweb_fe.record.energy import balance_error

#: the criteria and the [verdict] table's defaults: the registry (record/criteria.py)
CRITERIA, DEFAULTS = criteria_mod.CRITERIA, criteria_mod.DEFAULTS


@dataclass(frozen=True)
class Criterion:
    """One criterion's judgement: ``passed`` None where it does not apply (``detail``
    says why); ``time`` [s] and ``arm`` where it first failed (NaN, -1 otherwise);
    ``required``: the overall verdict asks it to pass (``[verdict] require``)."""

    name: str
    passed: bool | None
    value: float = math.nan
    limit: float = math.nan
    units: str = "1"
    time: float = math.nan
    arm: int = -1
    detail: str = ""
    required: bool = True

    def line(self) -> str:
        """One line for ``spinweb info``."""
        mark = {True: "pass", False: "FAIL", None: "n/a "}[self.passed]
        if self.passed is False and not self.required:
            mark = "fail"  # not asked for by the overall verdict
        text = f"  {mark}  {self.name:<10} "
        if self.passed is None:
            return text + self.detail
        text += f"{self.value:.4g} (limit {self.limit:.4g}{'' if self.units == '1' else ' ' + self.units})"
        if self.passed is False and math.isfinite(self.time):
            text += f", first at t = {self.time:.4g} s" + (f", arm {self.arm}" if self.arm >= 0
                                                          else "")
        return text + (f": {self.detail}" if self.detail else "")


def limits_of(table) -> dict:
    """The thresholds of a case's [verdict] table (a dict or its dataclass; None: the
    defaults)."""
    if table is None:
        return dict(DEFAULTS)
    given = table if isinstance(table, dict) else vars(table)
    return {k: (given.get(k) if given.get(k) is not None else v) for k, v in DEFAULTS.items()}


def _first(mask, t):
    """(index, time) of the first True in ``mask`` (-1, NaN: none)."""
    if not np.any(mask):
        return -1, math.nan
    i = int(np.argmax(mask))
    return i, float(t[i])


def reach_of(mesh) -> np.ndarray:
    """(n_arms,) [m] each tip's distance from the hub axis in the mesh's flat (deployed)
    reference state."""
    tips = np.asarray(mesh.node_sets["tips"])
    return np.hypot(mesh.node_ref[tips, 0], mesh.node_ref[tips, 1])


def tip_radius(h, hub_radius: float) -> np.ndarray:
    """(T, n_arms) [m] each tip's distance from the hub axis: from ``tip_position`` (FE;
    about the hub centre and axis where the history has them), else from the arm length L
    and angle phi at the rim (analytical: sqrt(r0^2 + L^2 + 2 r0 L cos phi) pivoting, the
    tangent's sqrt(r0^2 + L^2) wrapped)."""
    if "tip_position" in h:
        p = np.asarray(h["tip_position"], dtype=float)
        if "hub_position" in h:
            p = p - np.asarray(h["hub_position"])[:, None, :]
        if "hub_axis" in h:
            a = np.asarray(h["hub_axis"])[:, None, :]
            p = p - np.sum(p * a, axis=2, keepdims=True) * a
            return np.sqrt(np.sum(p * p, axis=2))
        return np.hypot(p[..., 0], p[..., 1])
    t = np.asarray(h["time"])
    L = np.asarray(h["arm_length"], dtype=float).reshape(len(t), -1)
    phi = np.asarray(h["arm_angle"], dtype=float).reshape(len(t), -1)
    c = np.cos(np.minimum(np.abs(phi), 0.5 * math.pi))
    return np.sqrt(hub_radius ** 2 + L * L + 2.0 * hub_radius * L * c)


def _deployment(t, radius, reach, lim):
    """(index of full deployment or -1, criterion): every tip at least deployed_fraction
    of its deployed distance from the hub axis, from then on to the end; the value is the
    least share at the end."""
    frac = lim["deployed_fraction"]
    ratio = radius / reach
    short, i_dep = _for_good(ratio, frac)
    by = lim["deploy_by"]
    first, t_first = _first(~short, t)
    if i_dep >= len(t):
        k = int(np.argmin(ratio[-1]))
        if first < 0:
            return -1, Criterion("deployed", False, float(ratio[-1, k]), frac,
                                 time=float(t[-1]), arm=k, detail="never fully deployed")
        return -1, Criterion("deployed", False, float(ratio[-1, k]), frac, time=float(t[-1]),
                             arm=k, detail=f"out at t = {t_first:.4g} s, short at the end")
    t_dep = float(t[i_dep])
    if by is not None and t_dep > by:
        k = int(np.argmin(ratio[min(np.searchsorted(t, by), len(t) - 1)]))
        return i_dep, Criterion("deployed", False, t_dep, by, "s", time=float(by), arm=k,
                                detail=f"deployed at t = {t_dep:.4g} s, after deploy_by")
    detail = f"out for good from t = {t_dep:.4g} s" + (
        f" (first out at {t_first:.4g} s)" if t_first < t_dep else "") + (
        f" (deploy_by {by:g} s)" if by is not None else "")
    return i_dep, Criterion("deployed", True, float(ratio[-1].min()), frac, detail=detail)


def _for_good(ratio, fraction):
    """((T,) rows in which some tip is short of ``fraction`` of its reach, the first row
    from which none is to the end: the row after the last short one; T if the last is)."""
    short = ~np.all(ratio >= fraction, axis=1)
    return short, len(short) - int(np.argmax(short[::-1])) if short.any() else 0


def deploy_time(t, radius, reach, fraction) -> float:
    """[s] first time from which every tip stays at least ``fraction`` of its deployed
    distance from the hub axis to the end (NaN: not deployed at the end)."""
    i = _for_good(radius / reach, fraction)[1]
    return float(t[i]) if i < len(t) else math.nan


def _recoil(t, radius, full, lim):
    """How far each tip fell back toward the hub from its farthest so far, per deployed arm
    length: an arm that winds back on the hub (or folds back on itself) brings its tip in;
    a deployed web's corners breathe radially, its folded arms unfold with dips of up to
    0.38 of the arm length (docs/design.md), far less than a re-coil."""
    back = np.maximum.accumulate(radius, axis=0) - radius
    share = back / full
    worst = float(share.max())
    over = share > lim["recoil"]
    if not over.any():
        return Criterion("recoil", True, worst, lim["recoil"],
                         detail=f"a tip fell back at most {float(back.max()):.3g} m")
    i, when = _first(np.any(over, axis=1), t)
    k = int(np.argmax(share[i]))
    kw = int(np.argmax(back.max(axis=0)))
    return Criterion("recoil", False, worst, lim["recoil"], time=when, arm=k,
                     detail=f"arm {kw}'s tip fell back {float(back[:, kw].max()):.3g} m "
                            "toward the hub")


def _swing(t, phi, i_dep, lim):
    """Half the range of each arm's phi over the second half of the time after deployment
    (the residual swing, not the arrival)."""
    if i_dep < 0:
        return Criterion("swing", None, detail="not deployed: no swing after deployment")
    i0 = i_dep + (len(t) - i_dep) // 2
    if i0 >= len(t) - 1:
        return Criterion("swing", None, detail="deployed in the last rows: no time after it")
    after = np.unwrap(phi[i0:], axis=0)
    mid = 0.5 * (after.max(axis=0) + after.min(axis=0))
    amp = 0.5 * (after.max(axis=0) - after.min(axis=0))
    worst = float(amp.max())
    window = f"over t = {t[i0]:.4g} .. {t[-1]:.4g} s"
    if worst <= lim["swing"]:
        return Criterion("swing", True, worst, lim["swing"], "rad", detail=window)
    out = np.abs(after - mid) > lim["swing"]
    j, when = _first(np.any(out, axis=1), t[i0:])
    return Criterion("swing", False, worst, lim["swing"], "rad", time=when,
                     arm=int(np.argmax(np.abs(after[j] - mid))), detail=window)


def _flatness(t, h, full, lim):
    z = np.asarray(h["out_of_plane_max"]).reshape(len(t)) / float(full.max())
    end = float(z[-1])
    if end <= lim["flatness"]:
        return Criterion("flatness", True, end, lim["flatness"],
                         detail=f"largest on the way {z.max():.3g}")
    i = len(z) - 1 - int(np.argmax((z <= lim["flatness"])[::-1])) if np.any(
        z <= lim["flatness"]) else -1
    return Criterion("flatness", False, end, lim["flatness"], time=float(t[min(i + 1, len(t) - 1)]),
                     detail="out of the plane at the end (first above the limit for good)")


def slack_share(pos, elem_nodes, rest_len, broken=None) -> float:
    """Share of the cable elements (not broken) whose length at ``pos`` is not above their
    rest length: they carry no tension (a tension-only cable)."""
    d = pos[elem_nodes[:, 1]] - pos[elem_nodes[:, 0]]
    slack = np.sqrt(np.einsum("ij,ij->i", d, d)) <= rest_len
    keep = np.ones(len(rest_len), bool) if broken is None or not len(broken) else ~broken
    return float(np.count_nonzero(slack & keep)) / max(int(np.count_nonzero(keep)), 1)


def torque_impulse(h, prescribed: bool = False) -> np.ndarray:
    """(T,) [N m s] the control torque's angular impulse about the hub axis since the first
    row, from the history's rows (sampled every history_dt, while the torque acts every
    step). A torque law affine in the hub rate (free, constant, the feedback law: M = a +
    b omega, the fit of the rows checked to 1e-9) integrates exactly as a t + b theta (the
    hub angle); a prescribed rate's torque (a reaction that changes from step to step) as
    the row's torque work over its mean rate, or the trapezoid where the rate is near 0."""
    t = np.asarray(h["time"], dtype=float)
    M = np.asarray(h["hub_torque"], dtype=float)
    w = np.asarray(h["hub_omega"], dtype=float)
    if not prescribed:
        A = np.column_stack([np.ones_like(w), w])
        (a, b), *_ = np.linalg.lstsq(A, M, rcond=None)
        if np.max(np.abs(A @ np.array([a, b]) - M)) <= 1e-9 * max(np.max(np.abs(M)), 1e-300):
            th = np.asarray(h["hub_angle"], dtype=float)
            return a * (t - t[0]) + b * (th - th[0])
        d_imp = 0.5 * (M[1:] + M[:-1]) * np.diff(t)
    else:
        wm = 0.5 * (w[1:] + w[:-1])
        by_work = np.abs(wm) > 1e-6 * max(float(np.max(np.abs(w))), 1e-300)
        d_imp = np.where(by_work, np.diff(np.asarray(h["torque_work"], dtype=float))
                         / np.where(by_work, wm, 1.0), 0.5 * (M[1:] + M[:-1]) * np.diff(t))
    return np.concatenate([[0.0], np.cumsum(d_imp)])


def momentum_error(h, prescribed: bool = False, floor: float = 0.0) -> float:
    """Largest |K - K0 - torque impulse| over the rows (:func:`torque_impulse`; a free
    hub's torque acts about its axis: its +z part counts), relative to max |K| (or
    ``floor``, record.energy.momentum_floor, if larger: a scene at rest)."""
    K = np.asarray(h["angular_momentum"], dtype=float)
    imp = torque_impulse(h, prescribed)
    if "hub_axis" in h:  # the z part of each row's impulse
        axis_z = np.asarray(h["hub_axis"])[:, 2]
        imp = np.concatenate([[0.0], np.cumsum(np.diff(imp) * 0.5 * (axis_z[1:] + axis_z[:-1]))])
    scale = max(float(np.max(np.abs(K))), floor, 1e-300)
    return float(np.max(np.abs(K - K[0] - imp))) / scale


def floors_of(attrs) -> dict:
    """:func:`judge`'s energy and momentum floors from a result file's root attributes
    (``energy_floor``, ``momentum_floor``; 0 in files written before them)."""
    return {name: float(attrs.get(name, 0.0)) for name in ("energy_floor", "momentum_floor")}


def case_terms(case: dict) -> dict:
    """:func:`judge`'s keyword arguments that a case decides, from its resolved dict
    (Case.to_dict(), or a result file's ``case`` attribute): the [verdict] thresholds and
    required criteria, the failure strain, the gravity gradient, whether the law prescribes
    the hub rate, the end time."""
    from spinweb_fe.fe.control import LAWS

    table = case.get("verdict") or {}
    return {"limits": limits_of(table),
            "require": criteria_mod.required(table.get("require")),
            "failure_strain": case.get("cable", {}).get("failure_strain"),
            "gravity": bool(case.get("environment", {}).get("gravity_gradient")),
            "prescribed": LAWS[case.get("control", {}).get("law", "free")].prescribes_rate,
            "t_end": case.get("time", {}).get("end")}


def judge(h: dict, reach, hub_radius: float, limits=None, *, status: str = "completed",
          slack_share: float | None = None, failure_strain: float | None = None,
          out_of_plane: bool = False, gravity: bool = False, prescribed: bool = False,
          t_end: float | None = None, require=None, energy_floor: float = 0.0,
          momentum_floor: float = 0.0) -> list:
    """The criteria of one run (see the module's doc).

    Parameters
    ----------
    h : dict
        The run's ``/history`` (time, arm_length, arm_angle, hub_torque,
        angular_momentum, the energy terms; optional utilisation, max_strain_arm,
        out_of_plane_max, hub_axis).
    reach : (n_arms,) [m]
        Each deployed tip's distance from the hub axis (FE: the flat mesh's; analytical:
        r0 + H).
    hub_radius : float [m]
        r0: a wrap angle of the arm winds r0 per radian on the hub.
    limits : dict
        :func:`limits_of` of the case's [verdict] table (None: the defaults).
    status : str
        'completed', or why the run stopped.
    slack_share : float or None
        FE: share of the elements without tension at the end (None: not known).
    failure_strain : float or None
        The case's cable.failure_strain (None: no strength check).
    out_of_plane : bool
        The run can leave the plane (the flatness criterion applies).
    gravity : bool
        The gravity gradient acts (its torque is not recorded: no momentum audit).
    prescribed : bool
        The control law prescribes the hub rate (its torque is a reaction).
    t_end : float or None [s]
        The run's end time: a run that stopped early has completed t[-1] / t_end of it.
    require : sequence of str or None
        The criteria the overall verdict asks to pass (default: record.criteria.REQUIRED).
    energy_floor, momentum_floor : float [J], [N m s]
        The least scales of the energy and momentum audits (record.energy.energy_floor;
        :func:`floors_of` a result file): a scene at rest is judged against them.
    """
    lim = limits_of(limits)
    t = np.asarray(h["time"], dtype=float)
    phi = np.asarray(h["arm_angle"], dtype=float).reshape(len(t), -1)
    reach = np.broadcast_to(np.asarray(reach, dtype=float), (phi.shape[1],)).copy()
    full = reach - hub_radius  # the arm's deployed length from the rim
    done = 1.0 if status == "completed" else (
        min(float(t[-1]) / t_end, 1.0 - 1e-12) if t_end else 0.0)
    out = [Criterion("completed", status == "completed", done,
                     1.0, time=math.nan if status == "completed" else float(t[-1]),
                     detail="" if status == "completed" else status)]
    radius = tip_radius(h, hub_radius)
    i_dep, dep = _deployment(t, radius, reach, lim)
    out += [dep, _recoil(t, radius, full, lim)]
    if slack_share is None:
        out.append(Criterion("slack", None, detail="no final tensions (analytical model: "
                             "a rigid arm)"))
    else:
        out.append(Criterion("slack", slack_share <= lim["slack_share"], slack_share,
                             lim["slack_share"], time=math.nan if slack_share <= lim[
                                 "slack_share"] else float(t[-1])))
    if failure_strain is None or "utilisation" not in h:
        out.append(Criterion("overstrain", None, detail="no cable.failure_strain"))
    else:
        u = np.asarray(h["utilisation"])
        i, when = _first(u > 1.0, t)
        arm_of = int(np.asarray(h["max_strain_arm"])[i]) if i >= 0 and "max_strain_arm" in h \
            else -1
        out.append(Criterion("overstrain", i < 0, float(u.max()), 1.0, time=when, arm=arm_of,
                             detail="utilisation: strain / failure strain"))
    out.append(_swing(t, phi, i_dep, lim))
    if out_of_plane and "out_of_plane_max" in h:
        out.append(_flatness(t, h, full, lim))
    else:
        out.append(Criterion("flatness", None, detail="the run stays in its plane"))
    err = balance_error(h, floor=energy_floor)
    out.append(Criterion("energy", err <= lim["energy"], err, lim["energy"],
                         time=math.nan if err <= lim["energy"] else float(t[-1])))
    if gravity:
        out.append(Criterion("momentum", None, detail="the gravity gradient's torque is not "
                             "recorded"))
    else:
        m = momentum_error(h, prescribed, momentum_floor)
        out.append(Criterion("momentum", m <= lim["momentum"], m, lim["momentum"],
                             time=math.nan if m <= lim["momentum"] else float(t[-1])))
    out.append(_tangled(t, h, lim))
    need = set(criteria_mod.required(require))
    return [dataclasses.replace(c, required=c.name in need) for c in out]


def _tangled(t, h, lim) -> Criterion:
    """Tangled: more crossings of cable elements than the limit (the crossing audit's
    running count, history ``crossings``); not judged without the audit."""
    if "crossings" not in h:
        return Criterion("tangled", None, detail="no crossing audit (audit.crossings)")
    n = np.asarray(h["crossings"], dtype=float)
    i, when = _first(n > lim["crossings"], t)
    return Criterion("tangled", i < 0, float(n[-1]), float(lim["crossings"]), time=when,
                     detail="crossings of cable elements")


def passed(criteria) -> bool:
    """Every required criterion that applies passed."""
    return all(c.passed is not False for c in criteria if c.required)


def severity(criteria) -> float:
    """The worst criterion against its limit, as a number (above 1: failed): value / limit
    for a quantity that must stay below its limit, limit / value for the deployed share
    (a deployment time against deploy_by: time / limit), infinity for a run that did not
    complete. Ranks the members of a Monte-Carlo sweep (the worst is the largest)."""
    worst = 0.0
    for c in criteria:
        if c.passed is None or not c.required:
            continue
        if c.name == "completed":
            r = 0.0 if c.passed else math.inf
        elif c.name == "deployed" and c.units != "s":
            r = c.limit / max(c.value, 1e-300) if math.isfinite(c.value) else math.inf
        else:
            r = c.value / c.limit if c.limit > 0 else (0.0 if c.value <= 0 else math.inf)
        worst = max(worst, r if math.isfinite(r) or r > 0 else 0.0)
    return worst


def failed_names(criteria) -> list:
    """The required criteria that failed."""
    return [c.name for c in criteria if c.passed is False and c.required]


def write_group(h5, criteria):
    """Root attributes ``verdict`` ('pass' / 'fail') and ``verdict_failed`` (names), and a
    ``/verdict`` group with one subgroup per criterion (attributes passed: 1, 0 or -1 for
    does not apply; value, limit, units, time [s], arm, detail)."""
    if "verdict" in h5:
        del h5["verdict"]
    g = h5.create_group("verdict")
    g.attrs["description"] = "does the run deploy? (docs/design.md)"
    for c in criteria:
        s = g.create_group(c.name)
        s.attrs["passed"] = -1 if c.passed is None else int(c.passed)
        s.attrs["value"] = c.value
        s.attrs["limit"] = c.limit
        s.attrs["units"] = c.units
        s.attrs["time"] = c.time
        s.attrs["time_units"] = "s"
        s.attrs["arm"] = c.arm
        s.attrs["detail"] = c.detail
        s.attrs["description"] = CRITERIA[c.name].measures
        s.attrs["required"] = int(c.required)
    h5.attrs["verdict"] = "pass" if passed(criteria) else "fail"
    h5.attrs["verdict_failed"] = ",".join(failed_names(criteria))


def read_group(h5) -> list | None:
    """The criteria a result file holds (None: it has no /verdict group)."""
    g = h5.get("verdict")
    if g is None:
        return None
    out = []
    for name in CRITERIA:
        if name not in g:
            continue
        a = g[name].attrs
        p = int(a["passed"])
        out.append(Criterion(name, None if p < 0 else bool(p), float(a["value"]),
                             float(a["limit"]), str(a["units"]), float(a["time"]),
                             int(a["arm"]), str(a["detail"]), bool(a.get("required", 1))))
    return out


def report(criteria) -> list:
    """Lines of a verdict: the overall one, then one per criterion."""
    bad = failed_names(criteria)
    skip = [c.name for c in criteria if not c.required]
    head = ("verdict: deploys (every required criterion that applies passed)" if not bad
            else f"verdict: FAILS ({', '.join(bad)})") + (
        f"; not required: {', '.join(skip)}" if skip else "")
    return [head] + [c.line() for c in criteria]
