"""Helpers of the figures: a per-arm quantity as the spread across the arms, tick labels
that do not overlap."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def save_figure(fig, out, dpi=110) -> Path:
    """Save a matplotlib Figure as ``out`` (its folder made) and close it; returns the path."""
    import matplotlib.pyplot as plt

    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return Path(out)


def spread(ax, t, y, style=None, color=None, label=None, lw=1.2):
    """Draw ``y`` against ``t``: a (T,) column (or one arm) as a line, a (T, n) one as the
    spread across the n arms, the band from the least to the largest arm (translucent)
    under the arms' mean (the line, in ``style`` / ``color``). Returns the line."""
    y = np.asarray(y, dtype=float)
    y = y.reshape(len(t), -1)
    n = y.shape[1]
    if n == 1:
        line, = ax.plot(t, y[:, 0], *([style] if style else []), lw=lw, label=label,
                        **({"color": color} if color else {}))
        return line
    mean = y.mean(axis=1)
    line, = ax.plot(t, mean, *([style] if style else []), lw=lw,
                    label=None if label is None else f"{label}: mean of {n} arms, band "
                    "min-max", **({"color": color} if color else {}))
    ax.fill_between(t, y.min(axis=1), y.max(axis=1), color=line.get_color(), alpha=0.25,
                    lw=0)
    return line


def untangle_ticks(fig, ax, rotation=0.0):
    """Label the x ticks of ``ax`` so that no two labels overlap: at ``rotation`` degrees
    (right-aligned when slanted), every k-th label kept, k the least that leaves room (the
    labels' boxes apart when level; when slanted, their spacing along the axis at least a
    line's height over sin(rotation)). The ticks are fixed where they were drawn. Returns
    k."""
    fig.canvas.draw()
    lo, hi = sorted(ax.get_xlim())
    ticks = [(lb.get_position()[0], lb.get_text()) for lb in ax.get_xticklabels()
             if lb.get_text() and lo <= lb.get_position()[0] <= hi]
    if len(ticks) < 2:
        return 1
    style = {"rotation": rotation, "ha": "right"} if rotation else {}
    where = [p for p, _ in ticks]
    ax.set_xticks(where, [t for _, t in ticks], **style)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    labels = ax.get_xticklabels()
    boxes = [lb.get_window_extent(renderer) for lb in labels]
    x = [ax.transData.transform((p, 0.0))[0] for p in where]
    height = 1.2 * labels[0].get_fontsize() * fig.dpi / 72.0
    sin = abs(np.sin(np.radians(rotation)))

    def fits(k):
        keep = list(range(0, len(ticks), k))
        pairs = list(zip(keep, keep[1:]))
        if rotation:  # parallel slanted lines of text: their distance across the slant
            return all(abs(x[b] - x[a]) * sin >= height for a, b in pairs)
        return all(boxes[a].x1 + 3.0 <= boxes[b].x0 for a, b in pairs)

    k = next(k for k in range(1, len(ticks) + 1) if fits(k))
    ax.set_xticks(where, [t if i % k == 0 else "" for i, (_, t) in enumerate(ticks)], **style)
    return k
