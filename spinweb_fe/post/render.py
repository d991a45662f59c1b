"""Pictures and animations of a result file: the web seen from above or obliquely, lines
coloured by tension.

:func:`render` reads the ``/frames`` of a ``results.h5`` and writes one frame as PNG or all
frames as GIF / MP4. The web is drawn as lines coloured by the element tension [N] (cell
data, one fixed colour range over the frames drawn, with a colour bar), the hub as a grey
disc of radius r0 with four spokes turned by the hub angle of that frame (``/history
hub_angle`` interpolated at the frame time), the corner / tip masses as black points and
the simulated time in the title. The default view looks down the spin axis (+z towards the
viewer, counter-clockwise positive), in parallel projection; the oblique view
(:mod:`spinweb_fe.post.view`) looks from 30 degrees above the x-y plane, with the hub in
its own plane (``/history hub_position`` and ``hub_quaternion`` when the file has them) and
the out-of-plane coordinate optionally exaggerated for display.

Renderers (:mod:`spinweb_fe.post.canvas`): pyvista off-screen (VTK; EGL / OSMesa / X), or
matplotlib (``LineCollection``) when VTK cannot open an off-screen context. Encoders: PNG
and GIF through Pillow (a fixed 256-colour palette for GIF, so the colours do not flicker
between frames), MP4 through imageio with imageio-ffmpeg (H.264, yuv420p):
:mod:`spinweb_fe.io.media`. See docs/render.md.
"""

from __future__ import annotations

import contextlib
import logging
import math
import subprocess
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spinweb_fe.io.media import CMAP, WRITERS  # noqa: F401  (CMAP: the colour map)
from spinweb_fe.errors import InputError, RunError
from spinweb_fe.post.canvas import (BACKGROUND, CANVASES, HUB_FACE,  # noqa: F401
                                    MatplotlibCanvas,
                                    PyvistaCanvas, hub_geometry, hub_geometry_3d)
from spinweb_fe.post.view import MARGIN, View, screen_box

log = logging.getLogger(__name__)

SUFFIXES = (".png", ".gif", ".mp4")
RENDERERS = ("auto", "pyvista", "matplotlib")


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
    hub_centre : (F, 3) [m]
        The hub centre at each frame time (``/history hub_position``; else the origin).
    hub_rotation : (F, 3, 3)
        The hub's attitude, hub frame -> inertial, at each frame time (``/history
        hub_quaternion``; else the turn by ``hub_angle`` about +z).
    """

    time: np.ndarray
    position: np.ndarray
    tension: np.ndarray
    elements: np.ndarray
    tips: np.ndarray
    hub_radius: float
    hub_angle: np.ndarray
    title: str
    hub_centre: np.ndarray = None
    hub_rotation: np.ndarray = None

    def __post_init__(self):
        n = len(self.time)
        if self.hub_centre is None:
            object.__setattr__(self, "hub_centre", np.zeros((n, 3)))
        if self.hub_rotation is None:
            object.__setattr__(self, "hub_rotation", turn_about_z(self.hub_angle))

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


def turn_about_z(angle) -> np.ndarray:
    """(F, 3, 3) rotations by ``angle`` (F,) [rad] about +z."""
    a = np.asarray(angle, dtype=float)
    c, s, z, o = np.cos(a), np.sin(a), np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1),
                     np.stack([z, z, o], -1)], -2)


def quaternion_rotation(q) -> np.ndarray:
    """(F, 3, 3) rotation matrices of unit quaternions ``q`` (F, 4) = (w, x, y, z)."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)],
        -2)


def interp_quaternion(times, t, q) -> np.ndarray:
    """Unit quaternions at ``times`` from rows (``t``, ``q`` (T, 4)): each component linear
    in time between neighbouring rows (after a sign flip that keeps them on one side),
    normalised."""
    q = np.array(q, dtype=float)
    flip = np.cumprod(np.where(np.sum(q[1:] * q[:-1], axis=1) < 0, -1.0, 1.0))
    q[1:] *= flip[:, None]
    out = np.column_stack([np.interp(times, t, q[:, j]) for j in range(4)])
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)


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
        rows = "time" in hist and hist["time"].shape[0] > 0
        if rows and "hub_angle" in hist:
            hub_angle = np.interp(times, hist["time"][()], hist["hub_angle"][()])
        else:
            hub_angle = np.zeros(n)
        centre = rotation = None
        if rows and "hub_quaternion" in hist and "hub_position" in hist:
            th = hist["time"][()]
            pos = hist["hub_position"][()]
            centre = np.column_stack([np.interp(times, th, pos[:, j]) for j in range(3)])
            rotation = quaternion_rotation(interp_quaternion(times, th,
                                                             hist["hub_quaternion"][()]))
    return Scene(times, position, tension, elements, tips, float(r0), hub_angle,
                 str(case.get("title", "")), centre, rotation)


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


def view_radius(scene: Scene, frames) -> float:
    """Half-width [m] of a top view that holds the web of all ``frames`` and the hub."""
    xy = scene.position[list(frames), :, :2]
    r = float(np.max(np.hypot(xy[..., 0], xy[..., 1]))) if xy.size else 0.0
    return MARGIN * max(r, scene.hub_radius, 1e-9)


def oblique_box(scene: Scene, frames, view: View):
    """(centre (2,), half-size (2,)) [m]: the picture box of the oblique ``view`` that holds
    the web and the hub rim of all ``frames`` (display coordinates, with the margin), and the
    largest distance [m] of a displayed point from the origin (the depth scale)."""
    pts = [view.display(scene.position[list(frames)]).reshape(-1, 3)]
    if scene.hub_radius > 0:
        pts += [hub_geometry_3d(scene, k, view, n_rim=24)[1] for k in frames]
    pts = np.vstack(pts)
    centre, half = screen_box(view, pts)
    return (centre, half), MARGIN * max(float(np.max(np.linalg.norm(pts, axis=1))),
                                        scene.hub_radius, 1e-9)


def tension_range(scene: Scene, frames) -> tuple[float, float]:
    """Colour range (0, largest tension of ``frames``) [N] (0, 1 if all slack)."""
    tmax = float(np.max(scene.tension[list(frames)])) if scene.tension.size else 0.0
    return 0.0, tmax if tmax > 0 else 1.0


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


class _Probe:
    """The test render of :func:`probe_pyvista` in a child process, started at once; its
    answer is taken by :meth:`result`."""

    def __init__(self, timeout: float = 120.0):
        self.timeout, self.proc, self.error = timeout, None, ""
        try:
            self.proc = subprocess.Popen([sys.executable, "-c", _PROBE], text=True,
                                         stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                         stderr=subprocess.PIPE)
        except OSError as exc:
            self.error = f"test render did not finish: {exc}"

    def result(self) -> tuple[bool, str]:
        if self.proc is None:
            return False, self.error
        try:
            out, err = self.proc.communicate(timeout=self.timeout)
        except subprocess.TimeoutExpired as exc:
            self.stop()
            return False, f"test render did not finish: {exc}"
        if self.proc.returncode != 0:
            last = (err.strip().splitlines() or [""])[-1]
            return False, f"test render exited with code {self.proc.returncode} {last}".strip()
        return True, out.strip()

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.communicate()


def probe_pyvista(timeout: float = 120.0) -> tuple[bool, str]:
    """Render a tiny picture with pyvista in a child process.

    VTK without a usable OpenGL back end (EGL, OSMesa or X) can crash the process
    (segmentation fault) instead of raising, so the test runs in a child.

    Returns
    -------
    (bool, str)
        Whether it worked, and the render window class or the reason it did not.
    """
    return _Probe(timeout).result()


_answer: list = []  # pyvista_works's answer, once per process
_pending: list = []  # a test render started by start_probe, not yet asked


def start_probe() -> None:
    """Start :func:`pyvista_works`'s test render now, so that it runs on another core while
    this process reads the result file and imports pyvista (a second on a cold start);
    nothing if it has answered or started already."""
    if not _answer and not _pending:
        _pending.append(_Probe())


def pyvista_works() -> tuple[bool, str]:
    """:func:`probe_pyvista`, once per process (the test render :func:`start_probe` started,
    if it did)."""
    if not _answer:
        probe = _pending.pop() if _pending else _Probe()
        _answer.append(probe.result())
    return _answer[0]


def _drop_probe() -> None:
    """Stop a test render that no one asked (the picture failed before, or needed none)."""
    while _pending:
        _pending.pop().stop()


def _open_canvas(renderer, scene, size, clim, radius, first, view=None, box=None):
    """The canvas and the image of frame ``first``; 'auto' falls back to matplotlib."""
    if renderer not in RENDERERS:
        raise InputError("--renderer", "", f"unknown renderer '{renderer}' "
                         f"(valid: {', '.join(RENDERERS)})")
    if renderer == "auto":
        with contextlib.suppress(Exception):  # VTK's libraries load while the test renders
            import pyvista.plotting  # noqa: F401
        ok, why = pyvista_works()
        if not ok:
            log.warning("pyvista cannot render off-screen (%s); using matplotlib", why)
            renderer = "matplotlib"
    if renderer in ("auto", "pyvista"):
        canvas = None
        try:
            canvas = PyvistaCanvas(scene, size, clim, radius, view, box)
            return canvas, canvas.draw(first)
        except Exception as exc:  # no OpenGL context (or no VTK): fall back
            if canvas is not None:
                with contextlib.suppress(Exception):
                    canvas.close()
            if renderer == "pyvista":
                raise RunError(f"pyvista cannot render off-screen: {exc}") from None
            log.warning("pyvista cannot render off-screen (%s); using matplotlib",
                        str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
    canvas = MatplotlibCanvas(scene, size, clim, radius, view, box)
    return canvas, canvas.draw(first)


def render(result, out, frame=None, time=None, fps=10.0, size=(900, 900),
           renderer="auto", view="top", z_scale=1.0) -> dict:
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
    view : {'top', 'oblique'}
        Looking down the spin axis, or from 30 degrees above the x-y plane
        (:mod:`spinweb_fe.post.view`).
    z_scale : float > 0
        Oblique view: the out-of-plane coordinate times this, for display (1: true shape).

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
    camera = View(view, z_scale)
    w, h = (int(v) for v in size)
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise InputError("--size", "", f"{w}x{h} pixels: each side must be 16 .. 8192")
    if renderer == "auto":
        start_probe()
    try:
        return _draw(result, out, suffix, frame, time, fps, (w, h), renderer, camera)
    finally:
        _drop_probe()


def _draw(result, out, suffix, frame, time, fps, size, renderer, camera) -> dict:
    """:func:`render` after its checks."""
    scene = load_scene(result)
    frames = [pick_frame(scene, frame, time)] if suffix == ".png" else list(range(scene.n_frames))
    out.parent.mkdir(parents=True, exist_ok=True)
    writer = WRITERS[suffix](out, fps)
    quiet = _vtk_quiet() if renderer != "matplotlib" else contextlib.nullcontext()
    with quiet:
        clim, box = tension_range(scene, frames), None
        if camera.oblique:
            box, radius = oblique_box(scene, frames, camera)
        else:
            radius = view_radius(scene, frames)
        canvas, img = _open_canvas(renderer, scene, size, clim, radius, frames[0], camera,
                                   box)
        from spinweb_fe.run.progress import Stage, enabled

        try:
            writer.append(img)
            with Stage(f"render {out.name}", len(frames), enabled() and len(frames) > 1,
                       unit="frame") as bar:
                bar.update()
                for k in frames[1:]:
                    writer.append(canvas.draw(k))
                    bar.update()
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
