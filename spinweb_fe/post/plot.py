"""The paper's four-panel figure (arm length L, arm angle phi, omega_centre, omega_tip: every
arm, as the spread across the arms, or one arm), the out-of-plane panels (the web's distance
from the hub plane, the tips' heights, the hub's tilt and nutation, its transverse rate)
and, through :mod:`spinweb_fe.post.verdict_plot`, the verdict panels."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from spinweb_fe.errors import InputError
from spinweb_fe.io.folder import check_writable
from spinweb_fe.io.h5 import read_result
from spinweb_fe.post.axes import save_figure, spread
from spinweb_fe.post.judged import history_checked

PANELS = (("arm_length", "L [m]"), ("arm_angle", "phi [rad]"),
          ("hub_omega", "omega_centre [rad/s]"), ("tip_omega", "omega_tip [rad/s]"))
#: the out-of-plane panels: derived column -> axis label
OOP_PANELS = (("web_rms_max", "web from hub plane: RMS, max [m]"),
              ("tip_height", "tip height above hub plane [m]"),
              ("hub_tilt", "hub axis from +z, from L [rad]"),
              ("hub_transverse_rate", "hub transverse rate [rad/s]"))
PANEL_SETS = ("arms", "out_of_plane", "verdict")


def out_of_plane_columns(h) -> dict:
    """The out-of-plane panels' curves of a history with the vector columns: the web's RMS
    and largest distance from the hub plane (T, 2), each tip's height above it (T, n), the
    hub axis' angle from +z and from the angular momentum (T, 2), the hub's rate about
    axes in its plane (T,)."""
    axis, centre = h["hub_axis"], h["hub_position"]
    height = np.einsum("tkd,td->tk", h["tip_position"] - centre[:, None, :], axis)
    L = h["angular_momentum_vector"]
    norm = np.linalg.norm(L, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):  # no L (at rest): no angle (NaN)
        from_l = np.arccos(np.clip(np.einsum("td,td->t", axis, L) / norm, -1.0, 1.0))
    from_l[norm <= 1e-12 * max(norm.max(), 1e-300)] = np.nan
    tilt = np.arccos(np.clip(axis[:, 2], -1.0, 1.0))
    w = h["hub_angular_velocity"]
    transverse = np.linalg.norm(w - np.einsum("td,td->t", w, axis)[:, None] * axis, axis=1)
    return {"web_rms_max": np.column_stack([h["out_of_plane_rms"], h["out_of_plane_max"]]),
            "tip_height": height, "hub_tilt": np.column_stack([tilt, from_l]),
            "hub_transverse_rate": transverse}


def load_for_plot(path):
    """(history dict, label) of a result file; the label is its folder (and model)."""
    path = Path(path)
    h, label = read_result(path, lambda h5: (history_checked(path, h5),
                                             h5.attrs.get("model", "")))
    name = path.parent.name or path.stem
    label = f"{name} ({label})" if label else name
    return h, label


def _oop_panels(axes, t, cols, label, style, color):
    """One file's curves on the out-of-plane panels, all in the file's ``color`` (unless
    ``style`` gives one): the first of each pair solid, the second dashed; every tip on the
    tip panel."""
    for ax, (key, ylab) in zip(axes.flat, OOP_PANELS):
        y = cols[key]
        y = y if y.ndim == 2 else y[:, None]
        for j in range(y.shape[1]):
            first = j == 0
            ls = "-" if first or key == "tip_height" else "--"
            ax.plot(t, y[:, j], *([style] if style else []), ls=ls, lw=1.0 if first else 0.8,
                    label=label if first else None, **({} if style else {"color": color}))
        ax.set_ylabel(ylab)


def plot_histories(curves, out, title=None, arm=None, t_max=None, panels="arms"):
    """:func:`history_figure` saved as ``out``; returns its path."""
    return save_figure(history_figure(curves, title, arm, t_max, panels), out)


def history_figure(curves, title=None, arm=None, t_max=None, panels="arms"):
    """Overlay histories on the four panels (``panels`` 'arms', or 'out_of_plane':
    :data:`OOP_PANELS`); returns the matplotlib Figure.

    Parameters
    ----------
    curves : list of (history dict, label, matplotlib style or None)
    title : str or None
    arm : int or None
        Which arm's L, phi and omega_tip to draw; None: every arm, as their spread (the
        band from the least to the largest, the mean as the line: :func:`spread`).
    t_max : float or None [s]
        Draw up to this time (default: everything).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    for index, (h, label, style) in enumerate(curves):
        t = h["time"]
        sel = t <= (t_max if t_max else t[-1]) + 1e-12
        if panels == "out_of_plane":
            _oop_panels(axes, t[sel], {k: v[sel] for k, v in out_of_plane_columns(h).items()},
                        label, style, f"C{index % 10}")
            continue
        for ax, (key, ylab) in zip(axes.flat, PANELS):
            if key not in h:
                continue
            y = h[key]
            if y.ndim == 2 and arm is not None:
                y = y[:, min(arm, y.shape[1] - 1)]
            spread(ax, t[sel], y[sel], style, None if style else f"C{index % 10}", label)
            ax.set_ylabel(ylab)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def check_figure_path(out) -> Path:
    """Raise InputError unless ``out`` has a suffix matplotlib writes and a writable folder."""
    from matplotlib.figure import Figure

    out = Path(out)
    kinds = sorted(Figure().canvas.get_supported_filetypes())
    if out.suffix.lower().lstrip(".") not in kinds:
        raise InputError("-o", "", f"'{out.name}': unknown figure type '{out.suffix}' (valid: "
                         + ", ".join(f".{k}" for k in kinds) + ")")
    check_writable(out.parent)
    return out


def four_panel(files, out, labels=None, arm=None, title=None, panels="arms"):
    """The panels of several result files (``results.h5`` / ``analytic.h5``) -> ``out``:
    'arms' (every arm's spread, or ``arm``), 'out_of_plane', or 'verdict'
    (:func:`spinweb_fe.post.verdict_plot.verdict_panels`). The title defaults to the
    cases' titles.

    Raises
    ------
    InputError
        An unknown figure suffix or panel set, an unwritable folder, an unreadable file, a
        file without history rows (or, for the out-of-plane panels, without the vector
        columns), or an ``arm`` that some file does not have.
    """
    if panels not in PANEL_SETS:
        raise InputError("--panels", "", f"unknown panel set '{panels}' (valid: "
                         f"{', '.join(PANEL_SETS)})")
    check_figure_path(out)
    if panels == "verdict":
        from spinweb_fe.post.verdict_plot import verdict_figure

        return verdict_figure(files, out, labels=labels, title=title)
    curves = []
    for i, f in enumerate(files):
        h, label = load_for_plot(f)
        if panels == "out_of_plane" and "hub_axis" not in h:
            raise InputError(f, "history", "no out-of-plane histories (a fixed-axis run that "
                             "starts in the plane stays there exactly; give it a "
                             "[perturbation] or hub.motion = 'free')")
        n_arms = h["arm_length"].shape[1] if "arm_length" in h and h["arm_length"].ndim == 2 \
            else 1
        if arm is not None and not 0 <= arm < n_arms:
            raise InputError("--arm", "", f"arm {arm} does not exist: {f} has {n_arms} "
                             f"arm{'s' if n_arms > 1 else ''} (0 to {n_arms - 1})")
        curves.append((h, labels[i] if labels else label, None))
    return plot_histories(curves, out, title=title or cases_title(files), arm=arm,
                          panels=panels)


def cases_title(files) -> str | None:
    """The titles of the cases of result files, each once, joined by ' | ' (None: none)."""
    import tomllib

    def title(h5):
        return str(tomllib.loads(str(h5.attrs.get("case", ""))).get("title", "") or "")

    titles = []
    for f in files:
        t = read_result(f, title)
        if t and t not in titles:
            titles.append(t)
    return " | ".join(titles) or None
