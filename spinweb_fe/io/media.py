"""Picture and animation writers of :mod:`spinweb_fe.render`, chosen by file suffix.

Each writer takes ``(path, fps)``, then ``append(img)`` with (H, W, 3) uint8 pictures and
``close()``. PNG and GIF through Pillow (a GIF uses one fixed 256-colour palette, the
colour map and greys, so colours do not flicker between frames); MP4 through imageio with
imageio-ffmpeg, whose absence raises :class:`RunError` before anything is drawn.
"""

from __future__ import annotations

import numpy as np

from spinweb_fe.errors import RunError

CMAP = "turbo"


def _gif_palette():
    """A 'P' image holding the fixed GIF palette: the colour map, greys, black, white."""
    import matplotlib
    from PIL import Image

    cmap = matplotlib.colormaps[CMAP]
    cols = (np.asarray(cmap(np.linspace(0, 1, 192)))[:, :3] * 255).round()
    greys = np.repeat(np.linspace(0, 255, 64).round()[:, None], 3, axis=1)
    pal = np.vstack([cols, greys]).astype(np.uint8)
    img = Image.new("P", (1, 1))
    img.putpalette(pal.ravel().tolist())
    return img


class PngWriter:
    """One picture, written by Pillow at :meth:`close`."""

    def __init__(self, out, fps):
        self.out, self.image = out, None

    def append(self, img):
        self.image = img

    def close(self):
        from PIL import Image

        Image.fromarray(self.image).save(self.out)


class GifWriter:
    """Looping GIF of every appended picture, ``fps`` per second, fixed palette."""

    def __init__(self, out, fps):
        self.out, self.frames = out, []
        self.duration = max(20, int(round(1000.0 / fps)))  # ms; browsers clamp < 20 ms
        self.palette = _gif_palette()

    def append(self, img):
        from PIL import Image

        self.frames.append(Image.fromarray(img).quantize(palette=self.palette,
                                                         dither=Image.Dither.NONE))

    def close(self):
        first, *rest = self.frames
        first.save(self.out, save_all=True, append_images=rest, duration=self.duration,
                   loop=0, optimize=False)


class Mp4Writer:
    """H.264 MP4 (yuv420p) through imageio-ffmpeg, ``fps`` per second."""

    def __init__(self, out, fps):
        try:
            import imageio.v2 as imageio
            import imageio_ffmpeg

            imageio_ffmpeg.get_ffmpeg_exe()
        except Exception as exc:  # ImportError, or no ffmpeg binary
            raise RunError(f"cannot write {out}: MP4 needs imageio and imageio-ffmpeg "
                           f"(pip install imageio imageio-ffmpeg): {exc}; "
                           "write a .gif instead") from None
        self.writer = imageio.get_writer(out, format="FFMPEG", mode="I", fps=fps,
                                         codec="libx264", pixelformat="yuv420p",
                                         macro_block_size=1, quality=7)

    def append(self, img):
        h, w = img.shape[:2]  # yuv420p needs even sizes: repeat the last row / column
        img = np.pad(img, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge")
        self.writer.append_data(img)

    def close(self):
        self.writer.close()


#: picture writers by file suffix
WRITERS = {".png": PngWriter, ".gif": GifWriter, ".mp4": Mp4Writer}
