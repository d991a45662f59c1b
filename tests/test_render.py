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
