"""Render the paper web's mesh states to docs/img/*.png (plan view, coloured by arm).

    .venv/bin/python -m studies.render_mesh [--matplotlib]

    .venv/bin/python -m studies.render_mesh --ties axes --suffix _axes   # the 4-node ties

Uses pyvista off-screen; falls back to matplotlib when no OpenGL context is available
(or with ``--matplotlib``). Writes mesh_flat.png (deployed), mesh_star.png (star fold
before coiling) and mesh_folded.png (star fold coiled trailing on the hub: the initial
state of cases/paper_free_web.toml), with the case's hub ties (default ``frame``: the
whole boundary of the cut-out is tied, black dots).
"""

from __future__ import annotations

import argparse
import dataclasses
import logging
from pathlib import Path

import numpy as np

from meshgen.fold import star_fold
from spinweb_fe.case import load
from spinweb_fe.case.scene import build_mesh

ROOT = Path(__file__).resolve().parents[1]
log = logging.getLogger("render_mesh")


def _element_arm(mesh):
    """(m,) arm of each element (-1: cross / gathered at the ties)."""
    a = mesh.node_arm[mesh.elem_nodes]
    return np.where(a[:, 0] == a[:, 1], a[:, 0], np.maximum(a[:, 0], a[:, 1]))


def render_pyvista(mesh, pos, path, title):
    """Plan view of the line mesh at ``pos`` (n,3) [m] with pyvista, hub rim in black."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    cells = np.column_stack([np.full(mesh.n_elems, 2), mesh.elem_nodes]).ravel()
    grid = pv.PolyData(np.asarray(pos, float), lines=cells)
    grid.cell_data["arm"] = _element_arm(mesh)
    p = pv.Plotter(off_screen=True, window_size=(900, 900))
    p.set_background("white")
    p.add_mesh(grid, scalars="arm", cmap="tab10", clim=(-1, 8), line_width=2,
               show_scalar_bar=False)
    if mesh.hub_radius > 0:
        rim = pv.Circle(radius=mesh.hub_radius, resolution=180)
        p.add_mesh(rim.extract_feature_edges(), color="black", line_width=3)
    tips = pos[mesh.node_sets["tips"]]
    p.add_points(np.asarray(tips, float), color="red", point_size=14,
                 render_points_as_spheres=True)
    tied = pos[mesh.node_sets["hub_tied"]]
    p.add_points(np.asarray(tied, float), color="black", point_size=12,
                 render_points_as_spheres=True)
    p.add_text(title, font_size=12, color="black")
    p.view_xy()
    p.enable_parallel_projection()
    p.screenshot(str(path))
    p.close()


def render_matplotlib(mesh, pos, path, title):
    """The same plan view with matplotlib."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection

    fig, ax = plt.subplots(figsize=(7, 7), dpi=130)
    segs = pos[mesh.elem_nodes][:, :, :2]
    colours = plt.get_cmap("tab10")((_element_arm(mesh) + 1) % 10)
    ax.add_collection(LineCollection(segs, colors=colours, linewidths=0.8))
    if mesh.hub_radius > 0:
        ax.add_patch(plt.Circle((0, 0), mesh.hub_radius, fill=False, color="k", lw=1.5))
    ax.plot(*pos[mesh.node_sets["tips"], :2].T, "ro", ms=5, label="tips (corner masses)")
    ax.plot(*pos[mesh.node_sets["hub_tied"], :2].T, "ks", ms=5, label="hub-tied nodes")
    ax.set_aspect("equal")
    ax.autoscale()
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title)
    ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default=str(ROOT / "cases" / "paper_free_web.toml"))
    ap.add_argument("--matplotlib", action="store_true", help="skip pyvista")
    ap.add_argument("--ties", choices=("frame", "axes"), default=None,
                    help="override fold.ties (default: the case's, i.e. frame)")
    ap.add_argument("--suffix", default="", help="appended to the file names")
    args = ap.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    case = load(args.case)
    if args.ties is not None:
        case = dataclasses.replace(case, fold=dataclasses.replace(case.fold, ties=args.ties))
    ties = case.fold.ties
    folded = build_mesh(case)
    star = star_fold(folded)
    out = ROOT / "docs" / "img"
    out.mkdir(exist_ok=True)
    w = case.web
    jobs = [(f"mesh_flat{args.suffix}.png", folded.node_ref,
             f"flat (deployed) web, S = {w.side:g} m, t = {w.mesh_width:g} m, ties: {ties}"),
            (f"mesh_star{args.suffix}.png", star.node_pos,
             f"star fold before coiling (arms radial), ties: {ties}"),
            (f"mesh_folded{args.suffix}.png", folded.node_pos,
             f"star fold coiled {case.fold.wrap} on the hub, ties: {ties}")]
    renderer = render_matplotlib if args.matplotlib else render_pyvista
    for name, pos, title in jobs:
        try:
            renderer(folded, pos, out / name, title)
        except Exception as exc:  # no OpenGL context: fall back
            log.warning("pyvista failed (%s); using matplotlib", exc)
            renderer = render_matplotlib
            renderer(folded, pos, out / name, title)
        log.info("wrote %s (%s)", out / name, renderer.__name__)


if __name__ == "__main__":
    main()
