"""The paper's four-panel figure: arm length L, arm angle phi, omega_centre, omega_tip."""

from __future__ import annotations

from pathlib import Path

from spinweb_fe.errors import InputError
from spinweb_fe.io.folder import check_writable
from spinweb_fe.io.h5 import history_of, read_result

PANELS = (("arm_length", "L [m]"), ("arm_angle", "phi [rad]"),
          ("hub_omega", "omega_centre [rad/s]"), ("tip_omega", "omega_tip [rad/s]"))


def load_for_plot(path):
    """(history dict, label) of a result file; the label is its folder (and model)."""
    path = Path(path)

    def read(h5):
        if "history" not in h5:
            raise InputError(path, "history", "no /history group in this file")
        return history_of(h5), h5.attrs.get("model", "")

    h, label = read_result(path, read)
    if not h:
        raise InputError(path, "history", "no rows yet (the run stopped before its first "
                         "rows were written)")
    name = path.parent.name or path.stem
    label = f"{name} ({label})" if label else name
    return h, label


def plot_histories(curves, out, title=None, arm=0, t_max=None):
    """Overlay histories on the four panels and save ``out``.

    Parameters
    ----------
    curves : list of (history dict, label, matplotlib style or None)
    out : path
    title : str or None
    arm : int
        Which arm's L, phi and omega_tip to draw (all arms move alike in symmetric runs).
    t_max : float or None [s]
        Draw up to this time (default: everything).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(10, 7), sharex=True)
    for h, label, style in curves:
        t = h["time"]
        sel = t <= (t_max if t_max else t[-1]) + 1e-12
        for ax, (key, ylab) in zip(axes.flat, PANELS):
            if key not in h:
                continue
            y = h[key]
            if y.ndim == 2:
                y = y[:, min(arm, y.shape[1] - 1)]
            ax.plot(t[sel], y[sel], *([style] if style else []), label=label, lw=1.2)
            ax.set_ylabel(ylab)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    if title:
        fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return Path(out)


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


def four_panel(files, out, labels=None, arm=0, title=None):
    """The four panels of several result files (``results.h5`` / ``analytic.h5``) -> ``out``.

    Raises
    ------
    InputError
        An unknown figure suffix, an unwritable folder, an unreadable file, a file without
        history rows, or an ``arm`` that some file does not have.
    """
    check_figure_path(out)
    curves = []
    for i, f in enumerate(files):
        h, label = load_for_plot(f)
        n_arms = h["arm_length"].shape[1] if "arm_length" in h and h["arm_length"].ndim == 2 \
            else 1
        if not 0 <= arm < n_arms:
            raise InputError("--arm", "", f"arm {arm} does not exist: {f} has {n_arms} "
                             f"arm{'s' if n_arms > 1 else ''} (0 to {n_arms - 1})")
        curves.append((h, labels[i] if labels else label, None))
    return plot_histories(curves, out, title=title, arm=arm)
