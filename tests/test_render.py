"""``spinweb render``: pictures and animations are written and show the web (pixel checks)."""

from __future__ import annotations

import logging
import math
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest
from PIL import Image

from spinweb_fe.post import render as rd
from spinweb_fe.cli import main
from spinweb_fe.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
SIZE = (480, 400)


@pytest.fixture(scope="module")
def demo_h5(tmp_path_factory):
    """The demo case for 0.02 s: three frames of the coiled web starting to spin."""
    out = tmp_path_factory.mktemp("render") / "demo"
    rc = main(["run", str(ROOT / "cases" / "demo.toml"), "-o", str(out), "--set", "time.end=0.02",
               "--set", "output.frame_dt=0.01", "--no-progress"])
    assert rc == 0
    return out / "results.h5"


@pytest.fixture(scope="module")
def tether_h5(tmp_path_factory):
    """Four 5 m tethers deploying from 8 pi rad/s for 0.1 s: tensions of tens of kN."""
    out = tmp_path_factory.mktemp("render") / "tethers"
    rc = main(["run", str(ROOT / "cases" / "paper_free_arms.toml"), "-o", str(out),
               "--set", "tethers.length=5.0", "--set", "tethers.elements=10",
               "--set", "time.end=0.1", "--set", "output.frame_dt=0.05", "--no-progress"])
    assert rc == 0
    return out / "results.h5"


def coloured(img):
    """Mask of saturated pixels: web lines (the colour map), not white, grey or black."""
    img = img.astype(int)
    return (img.max(axis=-1) - img.min(axis=-1)) > 30


def assert_picture(img, size=SIZE):
    """Not blank: the right size, contrast, ink and colour-map pixels."""
    assert img.shape[:2] == (size[1], size[0])
    grey = img[..., :3].mean(axis=-1)
    assert grey.std() > 10.0                      # not a flat image
    assert np.mean(grey < 200) > 0.005            # ink: lines, hub, text
    assert np.mean(coloured(img[..., :3])) > 5e-4  # tension-coloured lines present


def test_png_of_the_last_frame(demo_h5, tmp_path, capsys):
    out = tmp_path / "web.png"
    rc = main(["render", str(demo_h5), "-o", str(out), "--size", "480x400"])
    assert rc == 0 and out.is_file()
    assert_picture(np.asarray(Image.open(out).convert("RGB")))
    err = capsys.readouterr().err  # the CLI logs which renderer drew the picture
    assert "1 frame(s), renderer pyvista" in err or "1 frame(s), renderer matplotlib" in err


@pytest.mark.parametrize("renderer", ["pyvista", "matplotlib"])
def test_tension_colours_span_the_colour_map(tether_h5, tmp_path, renderer):
    """Tensions from slack to tens of kN: low and high ends of the colour map both appear."""
    out = tmp_path / f"web_{renderer}.png"
    if renderer == "pyvista":  # environmental: VTK needs an off-screen OpenGL back end
        ok, why = rd.pyvista_works()
        if not ok:
            pytest.skip(f"VTK has no off-screen OpenGL back end here ({why})")
    info = rd.render(tether_h5, out, size=SIZE, renderer=renderer)
    assert info["renderer"].startswith(renderer) and info["frames"] == 1
    img = np.asarray(Image.open(out).convert("RGB")).astype(float)
    assert_picture(img.astype(np.uint8))
    import matplotlib

    cmap = matplotlib.colormaps[rd.CMAP]
    # pixels close to the colour of the highest and the lowest quarter of the tension range
    pix = img[coloured(img.astype(np.uint8))]
    lut = np.asarray(cmap(np.linspace(0, 1, 64)))[:, :3] * 255
    nearest = np.argmin(((pix[:, None, :] - lut[None]) ** 2).sum(-1), axis=1)
    assert np.sum(nearest < 16) > 20 and np.sum(nearest >= 48) > 5


def test_falls_back_to_matplotlib(demo_h5, tmp_path, monkeypatch, caplog):
    def no_opengl(*args, **kwargs):
        raise RuntimeError("no OpenGL context")

    monkeypatch.setattr(rd.PyvistaCanvas, "__init__", no_opengl)
    out = tmp_path / "fallback.png"
    with caplog.at_level(logging.INFO, logger="spinweb_fe"):
        info = rd.render(demo_h5, out, size=SIZE)
    assert info["renderer"].startswith("matplotlib")
    assert "using matplotlib" in caplog.text
    assert_picture(np.asarray(Image.open(out).convert("RGB")))


def test_falls_back_when_the_test_render_crashes(demo_h5, tmp_path, monkeypatch, caplog):
    """VTK without an OpenGL back end segfaults: 'auto' tests it in a child process first."""
    monkeypatch.setattr(rd, "pyvista_works", lambda: (False, "test render exited with code -11"))
    out = tmp_path / "fallback.png"
    with caplog.at_level(logging.INFO, logger="spinweb_fe"):
        info = rd.render(demo_h5, out, size=SIZE)
    assert info["renderer"].startswith("matplotlib") and "code -11" in caplog.text
    assert_picture(np.asarray(Image.open(out).convert("RGB")))


class FakeProbe:
    """Stands in for render._Probe: counts the test renders started and stopped."""

    started: list = []

    def __init__(self, timeout=120.0):
        self.stopped = False
        FakeProbe.started.append(self)

    def result(self):
        return False, "fake test render"

    def stop(self):
        self.stopped = True


def test_the_test_render_starts_early_and_runs_once(demo_h5, tmp_path, monkeypatch):
    """'auto' starts the test render before it reads the file (it runs on another core while
    this process reads and imports pyvista); the answer is the one of that render, asked
    once per process."""
    monkeypatch.setattr(rd, "_Probe", FakeProbe)
    monkeypatch.setattr(rd, "_answer", [])
    monkeypatch.setattr(FakeProbe, "started", [])
    info = rd.render(demo_h5, tmp_path / "a.png", size=SIZE)
    assert info["renderer"].startswith("matplotlib")  # the fake says pyvista cannot render
    rd.render(demo_h5, tmp_path / "b.png", size=SIZE)
    assert len(FakeProbe.started) == 1 and not FakeProbe.started[0].stopped
    assert rd.pyvista_works() == (False, "fake test render") and not rd._pending


def test_a_test_render_no_one_asked_is_stopped(tmp_path, monkeypatch):
    """A picture that fails after the test render started (here: no such file) stops it."""
    monkeypatch.setattr(rd, "_Probe", FakeProbe)
    monkeypatch.setattr(rd, "_answer", [])
    monkeypatch.setattr(FakeProbe, "started", [])
    with pytest.raises(InputError):
        rd.render(tmp_path / "missing.h5", tmp_path / "a.png", size=SIZE)
    assert len(FakeProbe.started) == 1 and FakeProbe.started[0].stopped and not rd._pending


def test_probe_survives_a_crashing_vtk(monkeypatch):
    """An OpenGL back end that is not installed (here OSMesa) crashes VTK in the child only."""
    monkeypatch.setenv("VTK_DEFAULT_OPENGL_WINDOW", "vtkOSMesaRenderWindow")
    ok, why = rd.probe_pyvista()
    if ok:
        pytest.skip(f"OSMesa is available here ({why})")
    assert "code" in why


def test_gif_has_every_frame(demo_h5, tmp_path):
    out = tmp_path / "web.gif"
    assert main(["render", str(demo_h5), "-o", str(out), "--size", "480x400", "--fps", "5"]) == 0
    with h5py.File(demo_h5) as h5:
        n = h5["frames/time"].shape[0]
    im = Image.open(out)
    assert im.n_frames == n == 3
    frames = []
    for k in range(n):
        im.seek(k)
        frames.append(np.asarray(im.convert("RGB")))
        assert_picture(frames[-1])
    assert im.info.get("duration") == 200
    assert any(np.any(a != b) for a, b in zip(frames, frames[1:]))  # time in the title


def test_mp4(demo_h5, tmp_path):
    pytest.importorskip("imageio_ffmpeg")
    import imageio.v2 as imageio

    out = tmp_path / "web.mp4"
    assert main(["render", str(demo_h5), "-o", str(out), "--size", "480x400"]) == 0
    reader = imageio.get_reader(out, format="FFMPEG")
    frames = [np.asarray(f) for f in reader]
    reader.close()
    assert len(frames) == 3
    for f in frames:
        assert_picture(f)


def test_mp4_without_encoder_is_a_one_line_error(demo_h5, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)  # import fails
    out = tmp_path / "web.mp4"
    assert main(["render", str(demo_h5), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "imageio-ffmpeg" in err and ".gif" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_frame_selection_and_hub_angle(demo_h5):
    scene = rd.load_scene(demo_h5)
    assert scene.n_frames == 3 and scene.hub_radius == 1.0
    assert rd.pick_frame(scene) == 2
    assert rd.pick_frame(scene, frame=0) == 0 and rd.pick_frame(scene, frame=-2) == 1
    assert rd.pick_frame(scene, time=0.0112) == 1
    with pytest.raises(InputError):
        rd.pick_frame(scene, frame=3)
    with pytest.raises(InputError):
        rd.pick_frame(scene, time=5.0)
    with h5py.File(demo_h5) as h5:
        t, a = h5["history/time"][()], h5["history/hub_angle"][()]
    np.testing.assert_allclose(scene.hub_angle, np.interp(scene.time, t, a))
    assert scene.hub_angle[-1] > 0  # the ramp has started turning the hub


def test_hub_geometry():
    rim, spokes = rd.hub_geometry(2.0, 0.3)
    np.testing.assert_allclose(np.hypot(*rim.T), 2.0)
    np.testing.assert_allclose(spokes[:, 0], 0.0)
    np.testing.assert_allclose(np.hypot(*spokes[:, 1].T), 2.0)
    np.testing.assert_allclose(np.arctan2(spokes[0, 1, 1], spokes[0, 1, 0]), 0.3)
    assert math.isclose(np.arctan2(spokes[1, 1, 1], spokes[1, 1, 0]), 0.3 + math.pi / 2)


def test_bad_inputs_exit_2(demo_h5, tmp_path, capsys):
    no_frames = tmp_path / "no_frames.h5"
    with h5py.File(no_frames, "w") as h5:
        h5.create_group("mesh")
    cases = [
        ([str(tmp_path / "missing.h5"), "-o", str(tmp_path / "a.png")], "no such file"),
        ([str(no_frames), "-o", str(tmp_path / "a.png")], "no frames"),
        ([str(demo_h5), "-o", str(tmp_path / "a.jpg")], "unknown picture type"),
        ([str(demo_h5), "-o", str(tmp_path / "a.png"), "--size", "big"], "WIDTHxHEIGHT"),
        ([str(demo_h5), "-o", str(tmp_path / "a.gif"), "--frame", "1"], "animation"),
        ([str(demo_h5), "-o", str(tmp_path / "a.png"), "--frame", "7"], "out of range"),
        ([str(demo_h5), "-o", str(tmp_path / "a.gif"), "--fps", "0"], "--fps"),
    ]
    for argv, words in cases:
        assert main(["render", *argv]) == 2, argv
        err = capsys.readouterr().err
        assert words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "a.png").exists()


# --- the oblique view (--view oblique, --z-scale) -------------------------------------------

TILTED = """title = "flat 20 m web tilted by 0.1 rad"
[web]
side = 20.0
mesh_width = 2.0
areal_density = 1.267e-2
[tip_mass]
mass = 1.0
[hub]
radius = 1.0
mass = 10.0
motion = "free"
[fold]
pattern = "flat"
[initial]
omega = 6.283185307179586
[perturbation]
shape = "tilt"
z_amplitude = 1.0
[time]
end = 0.02
[output]
history_dt = 1e-3
frame_dt = 0.01
"""


@pytest.fixture(scope="module")
def tilted_h5(tmp_path_factory):
    """A flat 20 m web on a free hub, turned 0.1 rad about x (tips 1 m out of the plane)."""
    d = tmp_path_factory.mktemp("render") / "tilted"
    d.mkdir()
    (d / "case.toml").write_text(TILTED)
    assert main(["run", str(d / "case.toml"), "-o", str(d / "out"), "--no-progress"]) == 0
    return d / "out" / "results.h5"


@pytest.fixture(scope="module")
def flattened_h5(tilted_h5, tmp_path_factory):
    """The same result with every frame's z set to 0 (hub pose untouched)."""
    import shutil

    out = tmp_path_factory.mktemp("render") / "flattened.h5"
    shutil.copy(tilted_h5, out)
    with h5py.File(out, "r+") as h5:
        pos = h5["frames/position"][()]
        assert np.max(np.abs(pos[..., 2])) > 0.5  # the tilt lifts the tips about 1 m
        pos[..., 2] = 0.0
        h5["frames/position"][...] = pos
    return out


def picture(path, **kw):
    rd.render(path, kw.pop("out"), size=SIZE, **kw)


def png(path):
    return np.asarray(Image.open(path).convert("RGB"))


def skip_without_vtk(renderer):
    if renderer == "pyvista":
        ok, why = rd.pyvista_works()
        if not ok:
            pytest.skip(f"VTK has no off-screen OpenGL back end here ({why})")


def test_view_projection():
    top, obl = rd.View(), rd.View("oblique", 2.0)
    p = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_allclose(top.screen(top.display(p)), [[1.0, 2.0]])
    np.testing.assert_allclose(obl.screen(obl.display(p)),
                               [[1.0, 2.0 * 0.5 + 2.0 * 3.0 * math.sqrt(3) / 2]])
    # the line of sight is 30 degrees below the x-y plane, perpendicular to the picture axes
    assert math.isclose(obl.toward_camera[2], 0.5) and abs(obl.toward_camera @ obl.up) < 1e-15
    assert obl.toward_camera @ obl.right == 0 and obl.up @ obl.right == 0
    assert top.caption() == "" and "30 deg" in rd.View("oblique").caption()
    assert "drawn x 2" in obl.caption() and "drawn" not in rd.View("oblique").caption()


@pytest.mark.parametrize("renderer", ["pyvista", "matplotlib"])
def test_top_view_is_unchanged(demo_h5, tilted_h5, flattened_h5, tmp_path, renderer):
    """The default view is the top view, and it does not see z: a planar web gives the same
    picture as before the option existed, whatever the out-of-plane state."""
    skip_without_vtk(renderer)
    picture(demo_h5, out=tmp_path / "default.png", renderer=renderer)
    picture(demo_h5, out=tmp_path / "top.png", renderer=renderer, view="top", z_scale=1.0)
    assert np.array_equal(png(tmp_path / "default.png"), png(tmp_path / "top.png"))
    picture(tilted_h5, out=tmp_path / "tilted.png", renderer=renderer)
    picture(flattened_h5, out=tmp_path / "flat.png", renderer=renderer)
    a, b = png(tmp_path / "tilted.png"), png(tmp_path / "flat.png")
    assert_picture(a)
    # matplotlib draws x-y only; VTK's depth test may order crossing lines differently
    assert np.mean(np.any(a != b, axis=-1)) <= (0 if renderer == "matplotlib" else 0.002)


@pytest.mark.parametrize("renderer", ["pyvista", "matplotlib"])
def test_oblique_view_shows_the_tilt(tilted_h5, flattened_h5, tmp_path, renderer):
    skip_without_vtk(renderer)
    top, obl = tmp_path / "top.png", tmp_path / "obl.png"
    picture(tilted_h5, out=top, renderer=renderer)
    picture(tilted_h5, out=obl, renderer=renderer, view="oblique")
    picture(flattened_h5, out=tmp_path / "flat.png", renderer=renderer, view="oblique")
    picture(tilted_h5, out=tmp_path / "x5.png", renderer=renderer, view="oblique", z_scale=5)
    a, b, flat, x5 = (png(p) for p in (top, obl, tmp_path / "flat.png", tmp_path / "x5.png"))
    for img in (b, flat, x5):
        assert_picture(img)
    assert np.mean(np.any(a != b, axis=-1)) > 0.02  # not the top view
    # the web's height / width in pixels (coloured pixels left of the colour bar, which
    # starts at 0.82 of the width) is that of its nodes projected to (x, y sin 30 + z cos 30)
    # (z times the z scale): 0.50 for the flat web, 0.58 tilted by 0.1 rad, 0.89 with z x 5
    def aspect(img):
        mask = coloured(img)[:, : int(0.8 * img.shape[1])]
        rows, cols = np.nonzero(mask.any(axis=1))[0], np.nonzero(mask.any(axis=0))[0]
        return (rows[-1] - rows[0]) / (cols[-1] - cols[0])

    def projected(path, view):
        scene = rd.load_scene(path)
        uv = view.screen(view.display(scene.position[-1]))
        return np.ptp(uv[:, 1]) / np.ptp(uv[:, 0])

    obl = rd.View("oblique")
    expect = [projected(tilted_h5, rd.View()), projected(tilted_h5, obl),
              projected(flattened_h5, obl), projected(tilted_h5, rd.View("oblique", 5.0))]
    np.testing.assert_allclose([aspect(img) for img in (a, b, flat, x5)], expect, rtol=0.03)
    assert expect[2] < 0.52 < 0.56 < expect[1] < expect[3]


@pytest.mark.parametrize("renderer", ["pyvista", "matplotlib"])
def test_oblique_tips_are_where_the_projection_puts_them(tilted_h5, renderer):
    """The black tip masses sit at the pixels of (x, y sin 30 + z cos 30): one scale and
    offset fits all four tips to a pixel, and the pixel there is dark."""
    skip_without_vtk(renderer)
    scene = rd.load_scene(tilted_h5)
    k = scene.n_frames - 1
    view = rd.View("oblique")
    box, radius = rd.oblique_box(scene, [k], view)
    canvas = rd.CANVASES[renderer](scene, SIZE, rd.tension_range(scene, [k]), radius, view, box)
    try:
        img = canvas.draw(k)
        tips = scene.position[k][scene.tips]
        uv = view.screen(tips)
        if renderer == "pyvista":
            ren, px = canvas.plotter.renderer, []
            for p in tips:
                ren.SetWorldPoint(*p, 1.0)
                ren.WorldToDisplay()
                px.append(ren.GetDisplayPoint()[:2])
            px = np.array(px)
        else:
            px = canvas.ax.transData.transform(uv)
    finally:
        canvas.close()
    rows = img.shape[0] - np.asarray(px[:, 1])  # display y counts from the bottom
    # the vertical positions on screen follow v = 0.5 y + 0.87 z with the scale of u
    scale = np.polyfit(uv[:, 0], px[:, 0], 1)[0]
    fit = np.polyfit(uv[:, 1], px[:, 1], 1)
    assert math.isclose(fit[0], scale, rel_tol=0.01)
    assert np.max(np.abs(np.polyval(fit, uv[:, 1]) - px[:, 1])) < 1.0
    for r, c in zip(rows.round().astype(int), px[:, 0].round().astype(int)):
        patch = img[max(r - 2, 0):r + 3, max(c - 2, 0):c + 3].astype(int)
        assert patch.sum(axis=-1).min() < 120, (r, c)  # black tip (cables are lighter)


def test_hub_pose_comes_from_the_history(tilted_h5):
    scene = rd.load_scene(tilted_h5)
    with h5py.File(tilted_h5) as h5:
        t, axis = h5["history/time"][()], h5["history/hub_axis"][()]
        centre = h5["history/hub_position"][()]
    for k, tk in enumerate(scene.time):
        j = int(np.argmin(np.abs(t - tk)))
        np.testing.assert_allclose(scene.hub_rotation[k][:, 2], axis[j], atol=1e-12)
        np.testing.assert_allclose(scene.hub_centre[k], centre[j], atol=1e-12)
    np.testing.assert_allclose(np.einsum("kij,kil->kjl", scene.hub_rotation,
                                         scene.hub_rotation), np.broadcast_to(np.eye(3),
                                                                              (3, 3, 3)),
                               atol=1e-12)
    # without the pose datasets: the turn by the hub angle about +z
    demo = rd.Scene(scene.time, scene.position, scene.tension, scene.elements, scene.tips,
                    1.0, np.array([0.0, 0.5, 1.0]), "")
    np.testing.assert_allclose(demo.hub_rotation[1][:, 0], [math.cos(0.5), math.sin(0.5), 0])
    np.testing.assert_allclose(demo.hub_centre, 0.0)


def test_oblique_animation(tilted_h5, tmp_path):
    out = tmp_path / "obl.gif"
    assert main(["render", str(tilted_h5), "-o", str(out), "--size", "480x400", "--view",
                 "oblique", "--z-scale", "3", "--renderer", "matplotlib"]) == 0
    im = Image.open(out)
    assert im.n_frames == 3
    im.seek(2)
    assert_picture(np.asarray(im.convert("RGB")))


def test_bad_view_arguments_exit_2(tilted_h5, tmp_path, capsys):
    png_out = str(tmp_path / "a.png")
    cases = [
        (["--view", "side"], "invalid choice: 'side'"),
        (["--view", "oblique", "--z-scale", "0"], "--z-scale"),
        (["--view", "oblique", "--z-scale", "-2"], "--z-scale"),
        (["--view", "oblique", "--z-scale", "nan"], "finite number > 0"),
        (["--view", "oblique", "--z-scale", "inf"], "finite number > 0"),
        (["--view", "oblique", "--z-scale", "big"], "invalid float value"),
        (["--z-scale", "10"], "--view oblique"),
    ]
    for argv, words in cases:
        assert main(["render", str(tilted_h5), "-o", png_out, *argv]) == 2, argv
        err = capsys.readouterr().err
        assert words in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    with pytest.raises(InputError, match="unknown view 'side'"):
        rd.render(tilted_h5, png_out, view="side")
    assert not (tmp_path / "a.png").exists()
