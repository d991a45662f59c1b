"""The verdict panels (``spinweb plot --panels verdict``): what each criterion of a run's
verdict (record/verdict.py) was judged from, over time, with its limit (dashed) and the
time it first failed (a vertical line), each panel's title passing (green) or failing (red).

Panels, those the run has (no empty panel): the tips' distance from the hub axis per reach
with the deployed line (``deployed_fraction``); how far each tip fell back toward the hub
per arm length (re-coil); the slack share at every frame; the strength utilisation; the
arms' angle phi with the swing window; the payout devices' line tension and speed; the
energy and angular-momentum audits. Curves per arm are drawn as their spread (the band from
the least to the largest arm, their mean as the line).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from spinweb_fe.io.h5 import read_result
from spinweb_fe.post.axes import save_figure, spread
from spinweb_fe.post.judged import history_checked, judged
from spinweb_fe.record import verdict
from spinweb_fe.record.energy import energy_balance, energy_reference

#: colours of a criterion that passed, failed, does not apply; failed but not required
STATUS_COLOUR = {True: "tab:green", False: "tab:red", None: "0.35", "optional": "tab:orange"}
LIMIT_STYLE = {"color": "0.2", "ls": "--", "lw": 1.0}


def load_judged(path):
    """:class:`spinweb_fe.post.judged.Judged` of a result file (InputError: no rows)."""
    path = Path(path)
    return read_result(path, lambda h5: judged(h5, history_checked(path, h5)))


def panel_names(j) -> list:
    """The panels a judged run has data for, in order."""
    h = j.history
    names = ["reach", "fallback"]
    if j.slack is not None:
        names.append("slack_share")
    if "utilisation" in h:
        names.append("utilisation")
    if (c := j.criterion("swing")) is not None and c.passed is not None:
        names.append("phi")
    if "brake_tension" in h:
        names += ["device_tension", "device_speed"]
    if "kinetic_energy" in h and "angular_momentum" in h:
        names.append("audits")
    return names


def _mark(ax, crit, colour):
    """The time ``crit`` first failed, as a vertical line."""
    if crit is not None and crit.passed is False and math.isfinite(crit.time):
        ax.axvline(crit.time, color=colour, ls=":", lw=1.2)


def _limit(ax, y, text):
    ax.axhline(y, **LIMIT_STYLE)
    ax.annotate(text, (0.01, y), xycoords=("axes fraction", "data"), fontsize=7,
                va="bottom", color="0.2")


def _tip_radius(j):
    t = np.asarray(j.history["time"], float)
    return t, verdict.tip_radius(j.history, j.hub_radius)


def _deployed(ax, j, colour, label, first):
    t, radius = _tip_radius(j)
    frac = j.limits["deployed_fraction"]
    spread(ax, t, radius / j.reach, color=colour, label=label)
    if first:
        _limit(ax, frac, f"deployed line {frac:g} of the reach")
    t_dep = verdict.deploy_time(t, radius, j.reach, frac)
    if math.isfinite(t_dep):
        ax.axvline(t_dep, color=colour, ls="-.", lw=0.8)
        ax.annotate(f" out for good from {t_dep:.3g} s", (t_dep, 0.02),
                    xycoords=("data", "axes fraction"), fontsize=7, color=colour)
    ax.set_ylabel("tip distance from axis / reach")


def _recoil(ax, j, colour, label, first):
    t, radius = _tip_radius(j)
    back = (np.maximum.accumulate(radius, axis=0) - radius) / (j.reach - j.hub_radius)
    spread(ax, t, back, color=colour, label=label)
    if first:
        _limit(ax, j.limits["recoil"], f"re-coil limit {j.limits['recoil']:g}")
    ax.set_ylabel("fall-back toward hub / arm length")


def _slack(ax, j, colour, label, first):
    ts, share = j.slack
    ax.plot(ts, share, ".-", color=colour, ms=3, lw=1.0, label=label)
    if first:
        _limit(ax, j.limits["slack_share"], f"at most {j.limits['slack_share']:g} at the end")
    ax.set_ylabel("slack share of the elements")
    ax.set_ylim(-0.03, 1.03)


def _overstrain(ax, j, colour, label, first):
    t = j.history["time"]
    ax.plot(t, j.history["utilisation"], color=colour, lw=1.0, label=label)
    if first:
        _limit(ax, 1.0, "failure strain")
    ax.set_ylabel("strength utilisation")


def _swing(ax, j, colour, label, first):
    """phi over the run, the window judged shaded, the limit about the window's mid."""
    t, radius = _tip_radius(j)
    phi = np.asarray(j.history["arm_angle"], float).reshape(len(t), -1)
    spread(ax, t, phi, color=colour, label=label)
    t_dep = verdict.deploy_time(t, radius, j.reach, j.limits["deployed_fraction"])
    if not math.isfinite(t_dep):
        return
    i_dep = int(np.searchsorted(t, t_dep))
    i0 = i_dep + (len(t) - i_dep) // 2
    after = np.unwrap(phi[i0:], axis=0).mean(axis=1)
    mid = 0.5 * (after.max() + after.min())
    ax.axvspan(t[i0], t[-1], color=colour, alpha=0.08)
    lim = j.limits["swing"]
    for y in (mid - lim, mid + lim):
        ax.plot([t[i0], t[-1]], [y, y], **LIMIT_STYLE)
    if first:
        ax.annotate(f"+-{lim:g} rad", (t[i0], mid + lim), fontsize=7, va="bottom", color="0.2")
    ax.set_ylabel("arm angle phi [rad]")


def _device_tension(ax, j, colour, label, first):
    t = j.history["time"]
    spread(ax, t, np.asarray(j.history["brake_tension"]) / 1e3, color=colour, label=label)
    cable, stow = j.case.get("cable", {}), j.case.get("stowage", {})
    if first and cable.get("failure_strain") and cable.get("area"):
        _limit(ax, cable["failure_strain"] * cable["youngs_modulus"] * cable["area"] / 1e3,
               "the line breaks (failure strain)")
    force = stow.get("brake_force")
    if first and stow.get("payout") == "brake" and isinstance(force, (int, float)):
        ax.axhline(force / 1e3, color="0.45", ls=":", lw=1.0)
    ax.set_ylabel("device: line tension at D [kN]")


def _device_speed(ax, j, colour, label, first):
    t = j.history["time"]
    spread(ax, t, j.history["payout_speed"], color=colour, label=label)
    stow = j.case.get("stowage", {})
    rate = stow.get("payout_rate")
    if first and stow.get("payout") == "rate" and isinstance(rate, (int, float)):
        _limit(ax, rate, f"reel's rate {rate:g} m/s")
    ax.set_ylabel("device: payout speed [m/s]")


def audit_series(j) -> tuple:
    """((T,) energy-balance error, (T,) angular-momentum error) of a judged run's rows, each
    relative to its audit's scale as the verdict measures them (their largest values are the
    energy and momentum criteria's)."""
    h, floors = j.history, j.floors
    b0, s0 = energy_reference(h)
    scale = max(s0, float(np.max(np.abs(h["torque_work"]))), floors["energy_floor"])
    energy = np.abs(energy_balance(h) - b0) / scale
    terms = verdict.case_terms(j.case) if j.case else {"prescribed": False}
    K = np.asarray(h["angular_momentum"], float)
    imp = verdict.torque_impulse(h, terms["prescribed"])
    if "hub_axis" in h:  # the z part of each row's impulse (record.verdict.momentum_error)
        az = np.asarray(h["hub_axis"])[:, 2]
        imp = np.concatenate([[0.0], np.cumsum(np.diff(imp) * 0.5 * (az[1:] + az[:-1]))])
    m_scale = max(float(np.max(np.abs(K))), floors["momentum_floor"], 1e-300)
    return energy, np.abs(K - K[0] - imp) / m_scale


def _audits(ax, j, colour, label, first):
    t = j.history["time"]
    energy, momentum = audit_series(j)
    tiny = 1e-16  # round-off: the log axis shows it at this floor
    ax.semilogy(t, np.maximum(energy, tiny), color=colour, lw=1.0,
                label=None if label is None else f"{label}: energy")
    ax.semilogy(t, np.maximum(momentum, tiny), color=colour, lw=1.0, ls=(0, (4, 2)),
                label=None if label is None else f"{label}: momentum (dashed)")
    if first:
        _limit(ax, j.limits["energy"], f"energy {j.limits['energy']:g}")
        ax.axhline(j.limits["momentum"], color="0.2", ls=(0, (1, 3)), lw=1.0)
        ax.annotate(f"momentum {j.limits['momentum']:g} (dotted)", (0.99, j.limits["momentum"]),
                    xycoords=("axes fraction", "data"), fontsize=7, va="top", ha="right",
                    color="0.2")
    ax.set_ylabel("balance error / scale")


#: panel -> (how it is drawn, the criteria its title judges: record/criteria.py's names)
PANELS = {"reach": (_deployed, ("deployed",)), "fallback": (_recoil, ("recoil",)),
          "slack_share": (_slack, ("slack",)), "utilisation": (_overstrain, ("overstrain",)),
          "phi": (_swing, ("swing",)), "device_tension": (_device_tension, ()),
          "device_speed": (_device_speed, ()), "audits": (_audits, ("energy", "momentum"))}
DRAW = {name: draw for name, (draw, _) in PANELS.items()}
SHOWS = {name: shows for name, (_, shows) in PANELS.items()}
HEADINGS = {"device_tension": "device: line tension", "device_speed": "device: payout speed"}


def criterion_text(c) -> str:
    """'deployed: pass 0.979 (limit 0.8)' or '... FAIL ..., first at t = 2 s'."""
    word = {True: "pass", False: "FAIL", None: "n/a"}[c.passed]
    if c.passed is False and not getattr(c, "required", True):
        word = "fail (not required)"
    if c.passed is None:
        return f"{c.name}: n/a"
    text = f"{c.name}: {word} {c.value:.3g} (limit {c.limit:.3g})"
    if c.passed is False and math.isfinite(c.time):
        text += f", first at t = {c.time:.3g} s"
    return text


def _title(ax, name, j, single):
    """The panel's title: its criteria with value, limit and the time they first failed (one
    file), coloured by the worst."""
    crits = [c for n in SHOWS[name] if (c := j.criterion(n)) is not None]
    if not single or not crits:
        ax.set_title(HEADINGS.get(name, " / ".join(SHOWS[name]) or name), fontsize=9)
        return
    failed = [c for c in crits if c.passed is False]
    worst = False if any(getattr(c, "required", True) for c in failed) else (
        "optional" if failed else True if any(c.passed for c in crits) else None)
    ax.set_title("\n".join(criterion_text(c) for c in crits), fontsize=8.5,
                 color=STATUS_COLOUR[worst])


def verdict_figure(files, out, labels=None, title=None):
    """The verdict panels of result files (``results.h5`` / ``analytic.h5``) -> ``out``: the
    panels of :func:`panel_names` (those of any file), one colour per file; with one file
    each panel's title says its criteria, and the figure's the case's title and the
    verdict."""
    runs = [load_judged(f) for f in files]
    names = [n for n in DRAW if any(n in panel_names(j) for j in runs)]
    return save_figure(draw(runs, names, labels or [_label(f) for f in files], title), out)


def _label(path) -> str:
    path = Path(path)
    return path.parent.name or path.stem


def draw(runs, names, labels, title=None):
    """The panels ``names`` of the judged ``runs`` (one colour each, ``labels``); returns the
    matplotlib Figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = max(1, -(-len(names) // 2))
    fig, axes = plt.subplots(rows, 2, figsize=(11, 2.9 * rows + 0.9), sharex=True,
                             squeeze=False)
    single = len(runs) == 1
    for k, (j, label) in enumerate(zip(runs, labels)):
        ok = verdict.passed(j.criteria)
        tag = label if single else f"{label}: {'deploys' if ok else 'fails'}"
        for ax, name in zip(axes.flat, names):
            if name not in panel_names(j):
                continue
            colour = f"C{k % 10}"
            DRAW[name](ax, j, colour, tag, k == 0)
            for crit in SHOWS[name]:
                c = j.criterion(crit)
                mark = STATUS_COLOUR[False if getattr(c, "required", True) else "optional"]
                _mark(ax, c, mark if single else colour)
    for ax, name in zip(axes.flat, names):
        _title(ax, name, runs[0], single)
        ax.grid(alpha=0.3)
        if name == "audits":
            ax.legend(fontsize=7, loc="lower right")
    for ax in axes.flat[len(names):]:
        ax.remove()  # an odd panel count: no empty axes
    for ax in axes[-1]:
        ax.set_xlabel("t [s]")
    if len(names) % 2 and rows > 1:  # the panel above the removed one shows the times
        axes[-2, 1].tick_params(labelbottom=True)
        axes[-2, 1].set_xlabel("t [s]")
    axes.flat[0].legend(fontsize=7, loc="lower right")
    top = title or " | ".join(dict.fromkeys(j.title for j in runs if j.title))
    lines = ([top] if top else []) + ([verdict.report(runs[0].criteria)[0]] if single else [])
    colour = STATUS_COLOUR[verdict.passed(runs[0].criteria)] if single else "black"
    fig.suptitle("\n".join(lines), fontsize=10, color=colour)
    fig.tight_layout()
    return fig
