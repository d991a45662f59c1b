"""The plot of a ``spinweb modes --sweep``: the lowest frequencies against the swept value,
and the same as multiples of the spin rate, coloured by how much of each mode's stiffness
is cable stretch (EA) rather than tension (which scales with omega^2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

MARKERS = {"out_of_plane": "o", "in_plane": "^"}


def plot_sweep(path, name: str, unit: str, points, title: str = "") -> Path:
    """Write the two-panel sweep plot (PNG).

    Parameters
    ----------
    path : str or Path
    name, unit : str
        The swept parameter ('omega' or 'tip_mass') and its unit.
    points : list of spinweb_fe.run.modal.SweepPoint
    title : str
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_f, ax_r) = plt.subplots(1, 2, figsize=(11, 4.6))
    norm = matplotlib.colors.Normalize(0.0, 1.0)
    cmap = matplotlib.colormaps["viridis"]
    sc = None
    for kind, marker in MARKERS.items():
        x, f, r, share = [], [], [], []
        for p in points:
            if p.modes is None:
                continue
            sel = p.modes.kind == kind
            x += [p.value] * int(sel.sum())
            f += list(p.modes.frequency[sel])
            r += list(p.modes.ratio[sel])
            share += list(np.nan_to_num(p.modes.material_share[sel]))
        if not x:
            continue
        label = kind.replace("_", "-")
        ax_f.scatter(x, f, c=share, cmap=cmap, norm=norm, marker=marker, s=28,
                     edgecolors="k", linewidths=0.3, label=label)
        sc = ax_r.scatter(x, r, c=share, cmap=cmap, norm=norm, marker=marker, s=28,
                          edgecolors="k", linewidths=0.3, label=label)
    done = [p for p in points if p.modes is not None]
    if name == "omega" and done:
        xs = np.array([p.value for p in done])
        ax_f.plot(xs, np.abs(xs), "k--", lw=0.8, label="omega_k = omega")
    for p in points:
        if p.modes is None:
            for ax in (ax_f, ax_r):
                ax.axvline(p.value, color="r", lw=0.6, alpha=0.5)
    ax_f.set_ylabel("omega_k [rad/s]")
    ax_r.set_ylabel("omega_k / omega [-]")
    for ax in (ax_f, ax_r):
        ax.set_xlabel(f"{name} [{unit}]")
        ax.grid(alpha=0.3)
    ax_f.legend(fontsize=8, loc="upper left")
    if sc is not None:
        fig.colorbar(sc, ax=ax_r, label="material share of the modal stiffness")
    fig.suptitle(title or f"lowest modes against {name} (o out-of-plane, ^ in-plane; "
                          "red lines: no steady state)", fontsize=10)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
