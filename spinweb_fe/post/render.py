"""Pictures and animations of a result file: top view of the web, lines coloured by tension.

:func:`render` reads the ``/frames`` of a ``results.h5`` and writes one frame as PNG or all
frames as GIF / MP4. The web is drawn as lines coloured by the element tension [N] (cell
data, one fixed colour range over the frames drawn, with a colour bar), the hub as a grey
disc of radius r0 with four spokes turned by the hub angle of that frame (``/history
hub_angle`` interpolated at the frame time), the corner / tip masses as black points and
the simulated time in the title. The motion is in the x-y plane: the view looks down the
spin axis (+z towards the viewer, counter-clockwise positive), in parallel projection.

Renderers: pyvista off-screen (VTK; EGL / OSMesa / X), or matplotlib (``LineCollection``)
when VTK cannot open an off-screen context. Encoders: PNG and GIF through Pillow (a fixed
256-colour palette for GIF, so the colours do not flicker between frames), MP4 through
imageio with imageio-ffmpeg (H.264, yuv420p): :mod:`spinweb_fe.encoders`. See
docs/render.md.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import math
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spinweb_fe.io.media import CMAP, WRITERS
from spinweb_fe.errors import InputError, RunError

log = logging.getLogger(__name__)

BACKGROUND = "white"
HUB_FACE = (0.82, 0.82, 0.82)
SUFFIXES = (".png", ".gif", ".mp4")
RENDERERS = ("auto", "pyvista", "matplotlib")
MARGIN = 1.12  # view half-width / largest node radius


@dataclass(frozen=True)
class Scene:
    """What a picture needs from a result file (all arrays float64 unless said).

    Attributes
    ----------
    time : (F,) [s]
        Frame times.
    position : (F, N, 3) [m]
        Node positions of each frame.
    tension : (F, E) [N]
        Element tensions of each frame (0 = slack).
    elements : (E, 2) int64
        Element connectivity.
    tips : (k,) int64
        Corner / tip mass nodes.
    hub_radius : float [m]
        r0; 0 draws no hub.
    hub_angle : (F,) [rad]
        Hub rotation at each frame time (counter-clockwise positive).
    title : str
        The case title.
    """

    time: np.ndarray
    position: np.ndarray
    tension: np.ndarray
    elements: np.ndarray
    tips: np.ndarray
    hub_radius: float
    hub_angle: np.ndarray
    title: str

    @property
    def n_frames(self) -> int:
        return len(self.time)


def _case_table(h5) -> dict:
    text = h5.attrs.get("case", "")
    if isinstance(text, bytes):
        text = text.decode("utf-8")
    try:
        return tomllib.loads(str(text)) if text else {}
    except tomllib.TOMLDecodeError:
        return {}


def load_scene(path) -> Scene:
    """Read the frames, mesh and hub of a ``results.h5``.

    Raises
    ------
    InputError
        Missing or unreadable file, no ``/mesh``, no frames.
    """
    from spinweb_fe.io.h5 import open_h5

    path = Path(path)
    with open_h5(path) as h5:
        if "mesh" not in h5:
            raise InputError(path, "mesh", "no /mesh group (an FE results.h5 is needed; "
                             "an analytic.h5 has no web to draw)")
        frames = h5.get("frames")
        if frames is None or "time" not in frames or frames["time"].shape[0] == 0:
            raise InputError(path, "frames", "no frames in this file (run with "
                             "output.frame_dt > 0)")
        mesh = h5["mesh"]
        times = frames["time"][()]
        n = min(len(times), frames["position"].shape[0], frames["tension"].shape[0])
        times = times[:n]
        position = frames["position"][:n]
        tension = frames["tension"][:n]
        elements = mesh["elements"][()].astype(np.int64)
        sets = mesh.get("node_sets", {})
        tips = sets["tips"][()].astype(np.int64) if "tips" in sets else np.zeros(0, np.int64)
        case = _case_table(h5)
        r0 = case.get("hub", {}).get("radius", mesh.attrs.get("hub_radius", 0.0))
        hist = h5.get("history", {})
        if "time" in hist and "hub_angle" in hist and hist["time"].shape[0] > 0:
            hub_angle = np.interp(times, hist["time"][()], hist["hub_angle"][()])
        else:
            hub_angle = np.zeros(n)
    return Scene(times, position, tension, elements, tips, float(r0), hub_angle,
                 str(case.get("title", "")))


def pick_frame(scene: Scene, frame=None, time=None) -> int:
    """Index of the frame to draw: ``frame`` (negative counts from the end), the frame
    nearest to ``time`` [s], or the last frame."""
    n = scene.n_frames
    if frame is not None:
        if not -n <= frame < n:
            raise InputError("--frame", "", f"frame {frame} is out of range (0 .. {n - 1})")
        return frame % n
    if time is not None:
        t = scene.time
        tol = 0.5 * (float(np.max(np.diff(t))) if n > 1 else 0.0) + 1e-12
        if not t[0] - tol <= time <= t[-1] + tol:
            raise InputError("--time", "", f"{time} s is outside the frames "
                             f"({t[0]:g} .. {t[-1]:g} s)")
        return int(np.argmin(np.abs(t - time)))
    return n - 1


def hub_geometry(radius: float, angle: float, n_rim: int = 120):
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


def view_radius(scene: Scene, frames) -> float:
    """Half-width [m] of a view that holds the web of all ``frames`` and the hub."""
    xy = scene.position[list(frames), :, :2]
    r = float(np.max(np.hypot(xy[..., 0], xy[..., 1]))) if xy.size else 0.0
    return MARGIN * max(r, scene.hub_radius, 1e-9)


def tension_range(scene: Scene, frames) -> tuple[float, float]:
    """Colour range (0, largest tension of ``frames``) [N] (0, 1 if all slack)."""
    tmax = float(np.max(scene.tension[list(frames)])) if scene.tension.size else 0.0
    return 0.0, tmax if tmax > 0 else 1.0


def _title(scene, k, width=120):
    """Case title (cut to ``width`` characters) over the time of frame ``k``."""
    title = scene.title if len(scene.title) <= width else scene.title[:width - 3] + "..."
    head = f"{title}\n" if title else ""
    return f"{head}t = {scene.time[k]:.3f} s   (frame {k} of {scene.n_frames - 1})"


class PyvistaCanvas:
    """Off-screen VTK picture of one scene; :meth:`draw` updates the actors in place."""

    name = "pyvista"

    def __init__(self, scene: Scene, size, clim, radius):
        import pyvista as pv

        pv.OFF_SCREEN = True
        self.scene = scene
        self.pv = pv
        s = scene
        lines = np.column_stack([np.full(len(s.elements), 2), s.elements]).ravel()
        self.web = pv.PolyData(np.array(s.position[0], dtype=float), lines=lines)
        self.web.cell_data["tension"] = np.asarray(s.tension[0], dtype=float)
        self.plotter = p = pv.Plotter(off_screen=True, window_size=list(size))
        p.set_background(BACKGROUND)
        eps = 1e-3 * radius
        if s.hub_radius > 0:
            disc = pv.Disc(center=(0, 0, -eps), inner=0.0, outer=s.hub_radius, c_res=120)
            p.add_mesh(disc, color=HUB_FACE, lighting=False)
            rim, _ = hub_geometry(s.hub_radius, 0.0)
            p.add_mesh(pv.lines_from_points(np.column_stack([rim, np.zeros(len(rim))])),
                       color="black", line_width=2, lighting=False)
            self.spokes = pv.PolyData(np.zeros((8, 3)),
                                      lines=np.array([[2, 2 * i, 2 * i + 1] for i in range(4)]))
            p.add_mesh(self.spokes, color="black", line_width=3, lighting=False)
        else:
            self.spokes = None
        self.font = max(6, round(11 * min(size) / 900))  # text scales with the picture
        p.add_mesh(self.web, scalars="tension", cmap=CMAP, clim=list(clim), line_width=2,
                   lighting=False, scalar_bar_args={
                       "title": "tension [N]", "color": "black", "vertical": True,
                       "position_x": 0.83, "position_y": 0.1, "height": 0.72, "width": 0.05,
                       "fmt": "%.3g", "n_labels": 6, "title_font_size": 2 * self.font,
                       "label_font_size": round(1.7 * self.font)})
        self.tips = None
        if len(s.tips):
            self.tips = pv.PolyData(np.array(s.position[0][s.tips], dtype=float))
            p.add_mesh(self.tips, color="black", point_size=10,
                       render_points_as_spheres=True)
        p.view_xy()
        p.enable_parallel_projection()
        w, h = size
        aspect = w / h
        # the colour bar takes the right 20 % of the window and the title the top 12 %:
        # fit the disc of radius `radius` into what is left, centred there
        scale = radius * max(1.0 / (0.8 * aspect), 1.0 / 0.86)
        fx, fy = 0.2 * scale * aspect, 0.1 * scale
        cam = p.camera
        cam.focal_point = (fx, fy, 0.0)
        cam.position = (fx, fy, 10.0 * radius)
        cam.up = (0.0, 1.0, 0.0)
        cam.parallel_scale = scale
        self.size = size

    def draw(self, k: int) -> np.ndarray:
        """Frame ``k`` as an (H, W, 3) uint8 image."""
        s = self.scene
        self.web.points = np.array(s.position[k], dtype=float)
        self.web.cell_data["tension"] = np.asarray(s.tension[k], dtype=float)
        if self.spokes is not None:
            _, spokes = hub_geometry(s.hub_radius, float(s.hub_angle[k]))
            pts = np.zeros((8, 3))
            pts[:, :2] = spokes.reshape(8, 2)
            self.spokes.points = pts
        if self.tips is not None:
            self.tips.points = np.array(s.position[k][s.tips], dtype=float)
        self.plotter.add_text(_title(s, k, self.size[0] // self.font), position="upper_edge",
                              font_size=self.font, color="black", name="title")
        self.plotter.renderer.ResetCameraClippingRange()
        self.plotter.render()
        return np.asarray(self.plotter.screenshot(return_img=True))[..., :3]

    def describe(self) -> str:
        return f"pyvista {self.pv.__version__} ({self.plotter.ren_win.GetClassName()})"

    def close(self):
        self.plotter.close()


class MatplotlibCanvas:
    """The same picture with matplotlib (Agg): no OpenGL needed."""

    name = "matplotlib"

    def __init__(self, scene: Scene, size, clim, radius):
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.collections import LineCollection
        from matplotlib.colors import Normalize

        self.scene = s = scene
        self.plt = plt
        dpi = 100
        self.fig, ax = plt.subplots(figsize=(size[0] / dpi, size[1] / dpi), dpi=dpi,
                                    layout="constrained")
        self.ax = ax
        self.web = LineCollection(self._segments(0), cmap=CMAP, norm=Normalize(*clim),
                                  linewidths=1.2, zorder=2)
        self.web.set_array(np.asarray(s.tension[0], dtype=float))
        ax.add_collection(self.web)
        self.spokes = None
        if s.hub_radius > 0:
            ax.add_patch(plt.Circle((0, 0), s.hub_radius, facecolor=HUB_FACE,
                                    edgecolor="black", lw=1.5, zorder=1))
            self.spokes = LineCollection([], colors="black", linewidths=2.0, zorder=1.5)
            ax.add_collection(self.spokes)
        self.tips = ax.scatter([], [], s=18, c="black", zorder=3)
        self.fig.colorbar(self.web, ax=ax, label="tension [N]", shrink=0.8)
        ax.set_xlim(-radius, radius)
        ax.set_ylim(-radius, radius)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        self.size = size

    def _segments(self, k):
        return self.scene.position[k][self.scene.elements][:, :, :2]

    def draw(self, k: int) -> np.ndarray:
        """Frame ``k`` as an (H, W, 3) uint8 image."""
        s = self.scene
        self.web.set_segments(self._segments(k))
        self.web.set_array(np.asarray(s.tension[k], dtype=float))
        if self.spokes is not None:
            self.spokes.set_segments(hub_geometry(s.hub_radius, float(s.hub_angle[k]))[1])
        self.tips.set_offsets(s.position[k][s.tips, :2] if len(s.tips) else np.zeros((0, 2)))
        self.ax.set_title(_title(s, k), fontsize=10)
        self.fig.canvas.draw()
        return np.asarray(self.fig.canvas.buffer_rgba())[..., :3].copy()

    def describe(self) -> str:
        import matplotlib

        return f"matplotlib {matplotlib.__version__} (Agg)"

    def close(self):
        self.plt.close(self.fig)


CANVASES = {"pyvista": PyvistaCanvas, "matplotlib": MatplotlibCanvas}


_PROBE = """
import pyvista as pv
pv.OFF_SCREEN = True
with pv.vtk_verbosity("off"):
    p = pv.Plotter(off_screen=True, window_size=(32, 32))
    p.add_mesh(pv.Line())
    p.screenshot(return_img=True)
    print(p.ren_win.GetClassName())
    p.close()
"""


def probe_pyvista(timeout: float = 120.0) -> tuple[bool, str]:
    """Render a tiny picture with pyvista in a child process.

    VTK without a usable OpenGL back end (EGL, OSMesa or X) can crash the process
    (segmentation fault) instead of raising, so the test runs in a child.

    Returns
    -------
    (bool, str)
        Whether it worked, and the render window class or the reason it did not.
    """
    try:
        r = subprocess.run([sys.executable, "-c", _PROBE], capture_output=True, text=True,
                           timeout=timeout)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return False, f"test render did not finish: {exc}"
    if r.returncode != 0:
        last = (r.stderr.strip().splitlines() or [""])[-1]
        return False, f"test render exited with code {r.returncode} {last}".strip()
    return True, r.stdout.strip()


@functools.lru_cache(maxsize=1)
def pyvista_works() -> tuple[bool, str]:
    """:func:`probe_pyvista`, once per process."""
    return probe_pyvista()


def _open_canvas(renderer, scene, size, clim, radius, first):
    """The canvas and the image of frame ``first``; 'auto' falls back to matplotlib."""
    if renderer not in RENDERERS:
        raise InputError("--renderer", "", f"unknown renderer '{renderer}' "
                         f"(valid: {', '.join(RENDERERS)})")
    if renderer == "auto":
        ok, why = pyvista_works()
        if not ok:
            log.warning("pyvista cannot render off-screen (%s); using matplotlib", why)
            renderer = "matplotlib"
    if renderer in ("auto", "pyvista"):
        canvas = None
        try:
            canvas = PyvistaCanvas(scene, size, clim, radius)
            return canvas, canvas.draw(first)
        except Exception as exc:  # no OpenGL context (or no VTK): fall back
            if canvas is not None:
                with contextlib.suppress(Exception):
                    canvas.close()
            if renderer == "pyvista":
                raise RunError(f"pyvista cannot render off-screen: {exc}") from None
            log.warning("pyvista cannot render off-screen (%s); using matplotlib",
                        str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
    canvas = MatplotlibCanvas(scene, size, clim, radius)
    return canvas, canvas.draw(first)


def render(result, out, frame=None, time=None, fps=10.0, size=(900, 900),
           renderer="auto") -> dict:
    """Draw a result file into a PNG (one frame) or a GIF / MP4 (all frames).

    Parameters
    ----------
    result : str or Path
        ``results.h5`` of an FE run with frames.
    out : str or Path
        ``.png``, ``.gif`` or ``.mp4``; the suffix chooses the writer.
    frame : int, optional
        PNG: frame index (negative counts from the end). Default: the last frame.
    time : float, optional [s]
        PNG: draw the frame nearest to this time.
    fps : float
        Animation frames per second.
    size : (int, int)
        Picture width and height [pixels].
    renderer : {'auto', 'pyvista', 'matplotlib'}
        'auto' uses pyvista and falls back to matplotlib if VTK cannot render off-screen.

    Returns
    -------
    dict
        ``path``, ``renderer`` (name and version), ``frames`` (number drawn).
    """
    out = Path(out)
    suffix = out.suffix.lower()
    if suffix not in WRITERS:
        raise InputError(out, "", f"unknown picture type '{out.suffix}' "
                         f"(valid: {', '.join(SUFFIXES)})")
    if suffix != ".png" and (frame is not None or time is not None):
        raise InputError("--frame/--time", "", "select the frame of a .png; an animation "
                         "draws every frame")
    if not (fps > 0 and math.isfinite(fps)):
        raise InputError("--fps", "", f"must be > 0, got {fps}")
    w, h = (int(v) for v in size)
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise InputError("--size", "", f"{w}x{h} pixels: each side must be 16 .. 8192")
    scene = load_scene(result)
    frames = [pick_frame(scene, frame, time)] if suffix == ".png" else list(range(scene.n_frames))
    out.parent.mkdir(parents=True, exist_ok=True)
    writer = WRITERS[suffix](out, fps)
    quiet = _vtk_quiet() if renderer != "matplotlib" else contextlib.nullcontext()
    with quiet:
        clim, radius = tension_range(scene, frames), view_radius(scene, frames)
        canvas, img = _open_canvas(renderer, scene, (w, h), clim, radius, frames[0])
        try:
            writer.append(img)
            for k in frames[1:]:
                writer.append(canvas.draw(k))
            what = canvas.describe()
        finally:
            canvas.close()
    writer.close()
    log.info("wrote %s: %d frame(s), renderer %s", out, len(frames), what)
    return {"path": out, "renderer": what, "frames": len(frames)}


def _vtk_quiet():
    """Silence VTK's console warnings (e.g. 'bad X server connection' before EGL is used)."""
    try:
        import pyvista as pv

        return pv.vtk_verbosity("off")
    except Exception:  # no pyvista: the matplotlib fallback will be used
        return contextlib.nullcontext()
