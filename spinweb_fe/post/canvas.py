"""The two renderers of ``spinweb render``: one picture of a :class:`~spinweb_fe.post.render.Scene`
per frame, through pyvista off-screen (VTK) or matplotlib (Agg), in the top or the oblique
view (:mod:`spinweb_fe.post.view`).

Each canvas is made once for a scene, a picture size, a colour range and a framing (the
top view's half-width ``radius`` [m], or the oblique view's picture box), and
:meth:`draw` returns frame k as an (H, W, 3) uint8 image. Layout: the colour bar takes the
right 20 % of the picture and the title the top; the web is fitted into what is left.
"""

from __future__ import annotations

import math

import numpy as np

from spinweb_fe.io.media import CMAP
from spinweb_fe.post.view import View

BACKGROUND = "white"
HUB_FACE = (0.82, 0.82, 0.82)
N_RIM = 120  # points on the hub's rim


def hub_geometry(radius: float, angle: float, n_rim: int = N_RIM):
    """Hub outline in the x-y plane.

    Returns
    -------
    rim : (n_rim + 1, 2) [m]
        Closed circle of radius ``radius``.
    spokes : (4, 2, 2) [m]
        Four spokes from the centre to the rim, the first at ``angle`` [rad].
    """
    a = np.linspace(0.0, 2.0 * math.pi, n_rim + 1)
    rim = radius * np.column_stack([np.cos(a), np.sin(a)])
    b = angle + 0.5 * math.pi * np.arange(4)
    ends = radius * np.column_stack([np.cos(b), np.sin(b)])
    spokes = np.stack([np.zeros_like(ends), ends], axis=1)
    return rim, spokes


def hub_geometry_3d(scene, k: int, view: View, n_rim: int = N_RIM):
    """The hub of frame ``k`` in its own plane, display coordinates (z times the view's
    z_scale): centre (3,), rim (n_rim + 1, 3) and spokes (4, 2, 3) [m]; the first spoke
    along the hub frame's x axis."""
    rim2, spokes2 = hub_geometry(scene.hub_radius, 0.0, n_rim)
    R, c = scene.hub_rotation[k], scene.hub_centre[k]
    rim = c + np.column_stack([rim2, np.zeros(len(rim2))]) @ R.T
    sp = np.concatenate([spokes2, np.zeros((4, 2, 1))], axis=2) @ R.T + c
    return view.display(c), view.display(rim), view.display(sp)


def frame_title(scene, k, width=120, view=None):
    """Case title (cut to ``width`` characters) over the time of frame ``k`` (and, in the
    oblique view, a line naming it and its z scale)."""
    title = scene.title if len(scene.title) <= width else scene.title[:width - 3] + "..."
    head = f"{title}\n" if title else ""
    text = f"{head}t = {scene.time[k]:.3f} s   (frame {k} of {scene.n_frames - 1})"
    caption = view.caption() if view is not None else ""
    return f"{text}\n{caption}" if caption else text


def _fan(n_rim: int) -> np.ndarray:
    """VTK faces of a disc: triangles from point 0 (the centre) to rim points 1 .. n_rim."""
    i = np.arange(1, n_rim + 1)
    return np.column_stack([np.full(n_rim, 3), np.zeros(n_rim, int), i,
                            np.where(i == n_rim, 1, i + 1)]).ravel()


class PyvistaCanvas:
    """Off-screen VTK picture of one scene; :meth:`draw` updates the actors in place."""

    name = "pyvista"

    def __init__(self, scene, size, clim, radius, view=None, box=None):
        import pyvista as pv

        pv.OFF_SCREEN = True
        self.scene = scene
        self.pv = pv
        self.view = view = view if view is not None else View()
        s = scene
        lines = np.column_stack([np.full(len(s.elements), 2), s.elements]).ravel()
        self.web = pv.PolyData(view.display(s.position[0]), lines=lines)
        self.web.cell_data["tension"] = np.asarray(s.tension[0], dtype=float)
        self.plotter = p = pv.Plotter(off_screen=True, window_size=list(size))
        p.set_background(BACKGROUND)
        eps = 1e-3 * radius
        self.spokes = self.disc = self.rim = None
        if s.hub_radius > 0 and not view.oblique:
            disc = pv.Disc(center=(0, 0, -eps), inner=0.0, outer=s.hub_radius, c_res=120)
            p.add_mesh(disc, color=HUB_FACE, lighting=False)
            rim, _ = hub_geometry(s.hub_radius, 0.0)
            p.add_mesh(pv.lines_from_points(np.column_stack([rim, np.zeros(len(rim))])),
                       color="black", line_width=2, lighting=False)
        if s.hub_radius > 0:
            self.spokes = pv.PolyData(np.zeros((8, 3)),
                                      lines=np.array([[2, 2 * i, 2 * i + 1] for i in range(4)]))
            p.add_mesh(self.spokes, color="black", line_width=3, lighting=False)
        if s.hub_radius > 0 and view.oblique:  # the hub in its own (moving) plane
            self.eps = eps
            self.disc = pv.PolyData(np.zeros((N_RIM + 1, 3)), faces=_fan(N_RIM))
            p.add_mesh(self.disc, color=HUB_FACE, lighting=False)
            self.rim = pv.PolyData(np.zeros((N_RIM + 1, 3)), lines=np.concatenate(
                [[N_RIM + 1], np.arange(N_RIM + 1)]))
            p.add_mesh(self.rim, color="black", line_width=2, lighting=False)
        self.font = max(6, round(11 * min(size) / 900))  # text scales with the picture
        p.add_mesh(self.web, scalars="tension", cmap=CMAP, clim=list(clim), line_width=2,
                   lighting=False, scalar_bar_args={
                       "title": "tension [N]", "color": "black", "vertical": True,
                       "position_x": 0.83, "position_y": 0.1, "height": 0.72, "width": 0.05,
                       "fmt": "%.3g", "n_labels": 6, "title_font_size": 2 * self.font,
                       "label_font_size": round(1.7 * self.font)})
        self.tips = None
        if len(s.tips):
            self.tips = pv.PolyData(view.display(s.position[0][s.tips]))
            p.add_mesh(self.tips, color="black", point_size=10,
                       render_points_as_spheres=True)
        w, h = size
        aspect = w / h
        cam = p.camera
        if not view.oblique:
            p.view_xy()
            p.enable_parallel_projection()
            # the colour bar takes the right 20 % of the window and the title the top 12 %:
            # fit the disc of radius `radius` into what is left, centred there
            scale = radius * max(1.0 / (0.8 * aspect), 1.0 / 0.86)
            fx, fy = 0.2 * scale * aspect, 0.1 * scale
            cam.focal_point = (fx, fy, 0.0)
            cam.position = (fx, fy, 10.0 * radius)
            cam.up = (0.0, 1.0, 0.0)
        else:
            p.enable_parallel_projection()
            centre, half = box
            # the same layout, for the picture box (centre, half) of the oblique view;
            # the title has a third line here, so it takes 16 % of the height
            scale = max(half[0] / (0.8 * aspect), half[1] / 0.82)
            fu, fv = centre[0] + 0.2 * scale * aspect, centre[1] + 0.14 * scale
            focal = fu * view.right + fv * view.up
            cam.focal_point = tuple(focal)
            cam.position = tuple(focal + 10.0 * radius * view.toward_camera)
            cam.up = tuple(view.up)
        cam.parallel_scale = scale
        self.size = size

    def draw(self, k: int) -> np.ndarray:
        """Frame ``k`` as an (H, W, 3) uint8 image."""
        s, view = self.scene, self.view
        self.web.points = view.display(s.position[k])
        self.web.cell_data["tension"] = np.asarray(s.tension[k], dtype=float)
        if self.spokes is not None and not view.oblique:
            _, spokes = hub_geometry(s.hub_radius, float(s.hub_angle[k]))
            pts = np.zeros((8, 3))
            pts[:, :2] = spokes.reshape(8, 2)
            self.spokes.points = pts
        elif self.spokes is not None:
            centre, rim, spokes = hub_geometry_3d(s, k, view)
            normal = s.hub_rotation[k][:, 2] / np.array([1.0, 1.0, view.z_scale])
            normal /= np.linalg.norm(normal)  # of the disc scaled by z_scale
            # the disc a little behind the web's plane, so that the cables lie on top of it
            below = -self.eps * normal if normal @ view.toward_camera >= 0 else self.eps * normal
            self.disc.points = np.vstack([centre, rim[:-1]]) + below
            self.rim.points = rim
            self.spokes.points = spokes.reshape(8, 3)
        if self.tips is not None:
            self.tips.points = view.display(s.position[k][s.tips])
        self.plotter.add_text(frame_title(s, k, self.size[0] // self.font, view),
                              position="upper_edge", font_size=self.font, color="black",
                              name="title")
        self.plotter.renderer.ResetCameraClippingRange()
        self.plotter.render()
        return np.asarray(self.plotter.screenshot(return_img=True))[..., :3]

    def describe(self) -> str:
        return f"pyvista {self.pv.__version__} ({self.plotter.ren_win.GetClassName()})"

    def close(self):
        self.plotter.close()


class MatplotlibCanvas:
    """The same picture with matplotlib (Agg): no OpenGL needed. In the oblique view the
    web is projected by :meth:`View.screen` and drawn over the hub (no hidden lines)."""

    name = "matplotlib"

    def __init__(self, scene, size, clim, radius, view=None, box=None):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.collections import LineCollection
        from matplotlib.colors import Normalize

        self.scene = s = scene
        self.view = view = view if view is not None else View()
        self.plt = plt
        dpi = 100
        self.fig, ax = plt.subplots(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi,
                                    layout="constrained")
        self.ax = ax
        self.web = LineCollection(self._segments(0), cmap=CMAP, norm=Normalize(*clim),
                                  linewidths=1.2, zorder=2)
        self.web.set_array(np.asarray(s.tension[0], dtype=float))
        ax.add_collection(self.web)
        self.spokes = self.disc = None
        if s.hub_radius > 0:
            if view.oblique:
                self.disc = plt.Polygon(np.zeros((N_RIM, 2)), closed=True, facecolor=HUB_FACE,
                                        edgecolor="black", lw=1.5, zorder=1)
                ax.add_patch(self.disc)
            else:
                ax.add_patch(plt.Circle((0, 0), s.hub_radius, facecolor=HUB_FACE,
                                        edgecolor="black", lw=1.5, zorder=1))
            self.spokes = LineCollection([], colors="black", linewidths=2.0, zorder=1.5)
            ax.add_collection(self.spokes)
        self.tips = ax.scatter([], [], s=18, c="black", zorder=3)
        self.fig.colorbar(self.web, ax=ax, label="tension [N]", shrink=0.8)
        if view.oblique:
            centre, half = box
            ax.set_xlim(centre[0] - half[0], centre[0] + half[0])
            ax.set_ylim(centre[1] - half[1], centre[1] + half[1])
        else:
            ax.set_xlim(-radius, radius)
            ax.set_ylim(-radius, radius)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel(view.vertical_label())
        self.size = size

    def _segments(self, k):
        s, view = self.scene, self.view
        if not view.oblique:
            return s.position[k][s.elements][:, :, :2]
        return view.screen(view.display(s.position[k][s.elements]))

    def draw(self, k: int) -> np.ndarray:
        """Frame ``k`` as an (H, W, 3) uint8 image."""
        s, view = self.scene, self.view
        self.web.set_segments(self._segments(k))
        self.web.set_array(np.asarray(s.tension[k], dtype=float))
        if self.spokes is not None and not view.oblique:
            self.spokes.set_segments(hub_geometry(s.hub_radius, float(s.hub_angle[k]))[1])
        elif self.spokes is not None:
            _, rim, spokes = hub_geometry_3d(s, k, view)
            self.disc.set_xy(view.screen(rim[:-1]))
            self.spokes.set_segments(view.screen(spokes))
        if not len(s.tips):
            tips = np.zeros((0, 2))
        elif view.oblique:
            tips = view.screen(view.display(s.position[k][s.tips]))
        else:
            tips = s.position[k][s.tips, :2]
        self.tips.set_offsets(tips)
        self.ax.set_title(frame_title(s, k, view=view), fontsize=10)
        self.fig.canvas.draw()
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    def describe(self) -> str:
        import matplotlib

        return f"matplotlib {matplotlib.__version__} (Agg)"

    def close(self):
        self.plt.close(self.fig)


CANVASES = {"pyvista": PyvistaCanvas, "matplotlib": MatplotlibCanvas}
