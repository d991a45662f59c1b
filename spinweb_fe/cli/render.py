"""``spinweb render RESULT.h5 -o FILE.png|FILE.gif|FILE.mp4``: the web seen from above (or
obliquely, from 30 degrees above its plane), lines coloured by tension, hub turned by its
angle, tip masses as points (docs/render.md)."""

from __future__ import annotations

import argparse

from spinweb_fe.errors import InputError


def _size(text):
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise InputError("--size", "", f"expected WIDTHxHEIGHT in pixels, e.g. 900x900, "
                         f"got '{text}'") from None
    return w, h


def add_parser(sub):
    p = sub.add_parser("render", help="picture (PNG) or animation (GIF, MP4) of a result",
                       description=__doc__,
                       formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    p.add_argument("result", help="results.h5 of an FE run (with frames)")
    p.add_argument("-o", "--output", required=True, metavar="FILE",
                   help=".png (one frame), .gif or .mp4 (all frames)")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--frame", type=int, default=None, metavar="K",
                       help="PNG: frame index, negative from the end; without --frame and --time "
                            "the last frame")
    which.add_argument("--time", type=float, default=None, metavar="T",
                       help="PNG: the frame nearest to T [s]")
    p.add_argument("--fps", type=float, default=10.0, help="animation frames per second")
    p.add_argument("--size", default="900x900", metavar="WxH", help="picture size [pixels]")
    p.add_argument("--renderer", choices=("auto", "pyvista", "matplotlib"), default="auto",
                   help="auto: pyvista off-screen, matplotlib if VTK cannot render")
    p.add_argument("--view", choices=("top", "oblique"), default="top",
                   help="top: down the spin axis; oblique: from 30 degrees above the x-y "
                        "plane, from -y (the out-of-plane shape shows)")
    p.add_argument("--z-scale", type=float, default=1.0, metavar="S",
                   help="oblique view: draw the out-of-plane coordinate z times S (> 0; "
                        "said in the title when not 1)")
    return p


def run(args) -> int:
    from spinweb_fe.post.render import render

    render(args.result, args.output, frame=args.frame, time=args.time, fps=args.fps,
           size=_size(args.size), renderer=args.renderer, view=args.view,
           z_scale=args.z_scale)
    return 0
