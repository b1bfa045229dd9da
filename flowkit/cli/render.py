"""``flowkit render lines.h5 [--style style.toml] -o out.png --size 1920x1080 [camera options]``

Without ``--style``: lines with a black halo, coloured by speed when the file has it.  The
picture carries the style's legend (colour bars with names, units and ticks; ``--no-legend``,
``--legend CORNER``) and annotations (``--title``, ``--text``, ``--time``, ``--scale-bar``).

``--frames N`` animates the style's shapes and colour patterns (one period over N frames, so it
loops): ``-o out.png`` writes out_0000.png..., ``-o out.gif`` an animated GIF, ``-o out.mp4`` an
MP4 (optional imageio + imageio-ffmpeg).
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys

import numpy as np

from ..render.camera import VIEWS
from ..render.style.model import PLACEMENTS
from . import CLIError


def _size(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"(\d+)[xX](\d+)", text)
    if not m or int(m[1]) < 1 or int(m[2]) < 1:
        raise CLIError(f"--size {text!r}: expected WIDTHxHEIGHT, e.g. 1920x1080")
    return int(m[1]), int(m[2])


def _vec3(name: str, text: str | None):
    if text is None:
        return None
    parts = text.split(",")
    try:
        vals = tuple(float(p) for p in parts)
    except ValueError:
        vals = ()
    if len(vals) != 3:
        raise CLIError(f"--{name} {text!r}: expected three numbers x,y,z")
    return vals


def register(subparsers) -> None:
    p = subparsers.add_parser("render", help="render a lines file to PNG with a line style",
                              description=__doc__)
    p.add_argument("lines", help="lines HDF5 file (flowkit trace output)")
    p.add_argument("--style", help="TOML style file (see examples/styles/); default: a halo "
                   "style coloured by speed when the file has it")
    p.add_argument("-o", "--output", required=True, help="PNG to write (atomically)")
    p.add_argument("--size", default="1920x1080", help="WIDTHxHEIGHT in pixels (default 1920x1080)")
    p.add_argument("--supersample", type=int, help="render k times larger and average (print)")
    p.add_argument("--context", choices=["egl", "standalone"], default="egl",
                   help="OpenGL context: headless EGL (default) or the platform default")
    p.add_argument("--strips", choices=["vertex", "geometry"], default="vertex",
                   help="shader stage that builds the line strips: vertex (default, faster on "
                   "software rasterizers) or a lines_adjacency geometry shader; same picture")
    anim = p.add_argument_group("animation (moves shapes and colour patterns along the lines)")
    anim.add_argument("--frames", type=int, help="render N frames, the patterns advancing one "
                      "period in all: -o out.png writes out_0000.png..., .gif / .mp4 one file")
    anim.add_argument("--fps", type=float, default=12.0, help="frames per second (GIF/MP4)")
    over = p.add_argument_group("legend and annotations (override the style's [legend] and "
                                "[annotations])")
    over.add_argument("--no-legend", action="store_true", help="draw no legend")
    over.add_argument("--legend", choices=PLACEMENTS, help="where the legend goes (default auto: "
                      "the corner where it covers the fewest lines; outside: in margins added "
                      "to the picture, with the title and text)")
    over.add_argument("--title", help="a title (top or bottom centre, where it covers fewer "
                      "lines)")
    over.add_argument("--text", help="free text (in the corner where it covers the fewest lines)")
    over.add_argument("--time", action=argparse.BooleanOptionalAction, default=None,
                      help="the snapshot's time (t = 2000 s) when the lines file knows it")
    over.add_argument("--scale-bar", action="store_true", help="a scale bar in world units")
    cam = p.add_argument_group("camera (over the style file's [camera]; a direction given here, "
                               "--view or an angle, replaces the style's whole direction)")
    cam.add_argument("--view", choices=VIEWS, help="named view: +x looks along +x, ..., iso "
                     "(default: the style's camera, else along the domain's thinnest axis)")
    cam.add_argument("--azimuth", type=float, help="degrees about the up axis")
    cam.add_argument("--elevation", type=float, help="degrees above the horizontal plane")
    cam.add_argument("--distance", type=float, help="eye distance from the target (default: fit)")
    cam.add_argument("--zoom", type=float, help="magnification of the fitted view")
    cam.add_argument("--fov", type=float, help="vertical field of view in degrees")
    cam.add_argument("--projection", choices=["perspective", "orthographic"])
    cam.add_argument("--target", help="x,y,z looked at (default: centre of the lines' bounds)")
    cam.add_argument("--up", help="x,y,z up direction (default: chosen so that the domain's "
                     "longest axis lies along the image's long side)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..io.atomic import check_output
    from ..io.lines_h5 import read_lines
    from ..render import LineRenderer, create_context, default_context, load_style, save_png
    from ..render.renderer import check_picture
    from ..render.style.toml import camera_from_dict

    size = _size(args.size)
    check_output(args.output)  # before any work (numbered frames go beside it)
    if args.style is not None:
        style = load_style(args.style)
    else:
        from ..io.lines_h5 import lines_attributes
        from ..render.renderer import default_style

        names = [a for a in ("speed",) if a in lines_attributes(args.lines)]
        style = default_style(names)
    style = _overlays(args, style)
    over = {k: getattr(args, k) for k in ("azimuth", "elevation", "distance", "zoom", "fov",
                                          "projection", "view") if getattr(args, k) is not None}
    for k in ("target", "up"):
        v = _vec3(k, getattr(args, k))
        if v is not None:
            over[k] = list(v)
    # the same validation as the style file's [camera] table, naming the option
    checked = camera_from_dict("command line camera option", over)
    camera = style.camera.over(**{k: getattr(checked, k) for k in over})
    if args.supersample is not None:
        style = dataclasses.replace(style, supersample=args.supersample)
    ctx = default_context() if args.context == "egl" else create_context(args.context)
    if args.time:
        from ..io.lines_h5 import read_metadata

        if "snapshot_time" not in read_metadata(args.lines):
            print(f"flowkit render: {args.lines}: --time: the lines file holds no snapshot time "
                  "(its field had none); no time drawn", file=sys.stderr)
    if args.frames is not None:
        return _animate(args, style, size, camera, ctx)
    lines = drawable(read_lines(args.lines, attributes=style.attributes()), args.lines)
    with LineRenderer(lines, ctx, strips=args.strips) as r:
        image = r.render(style, size, camera)
        check_picture(image, r.resolve(style, camera, size),
                      r.scene_scale(style, camera, size).per_pixel)
        image = r.overlay(image, style, camera)
        used = r.camera_report(style, camera, size)
    path = save_png(image, args.output)
    print(f"wrote {path} ({size[0]}x{size[1]}, {used})")
    return 0


def drawable(lines, path):
    """``lines``, or a CLIError when none has two vertices (nothing to draw)."""
    from ..integrate.trace import check_result
    from ..io.lines_h5 import lines_attributes, read_lines

    n = int((lines.n_vertices >= 2).sum())
    reasons = np.zeros(0, np.int8)
    if not n and "reason" in lines_attributes(path):  # (only to say why)
        reasons = read_lines(path, attributes=["reason"]).line_data["reason"]
    try:
        check_result(len(lines), n, reasons)
    except ValueError as e:
        raise CLIError(f"{path}: nothing to draw: {e}") from None
    if not len(lines):
        raise CLIError(f"{path}: nothing to draw: the file holds no line")
    return lines


def _overlays(args, style):
    """The style's [legend] and [annotations] with the command line's changes."""
    lg, an = style.legend, style.annotations
    if args.no_legend:
        lg = dataclasses.replace(lg, show=False)
    if args.legend is not None:
        lg = dataclasses.replace(lg, placement=args.legend)
    changes = {k: getattr(args, k) for k in ("title", "text", "time") if getattr(args, k) is not None}
    if args.scale_bar:
        changes["scale_bar"] = True
    return dataclasses.replace(style, legend=lg, annotations=dataclasses.replace(an, **changes))


def _animate(args, style, size, camera, ctx) -> int:
    from tqdm import tqdm

    from ..io.lines_h5 import read_lines
    from ..render import LineRenderer
    from ..render.animate import FORMATS, render_frames, write_animation

    n = args.frames
    if n < 1:
        raise CLIError(f"--frames {n}: expected an integer >= 1")
    if not args.fps > 0:
        raise CLIError(f"--fps {args.fps}: expected a number > 0")
    if not args.output.lower().endswith(FORMATS):
        raise CLIError(f"-o {args.output!r}: with --frames, write {', '.join(FORMATS)} "
                       "(.png: numbered files)")
    if not style.animated:
        raise CLIError(f"--frames with {args.style or 'the default style'}: the style has no "
                       "band 'shape' or 'pattern' to move along the lines")
    lines = drawable(read_lines(args.lines, attributes=style.attributes()), args.lines)
    with LineRenderer(lines, ctx, strips=args.strips) as r, tqdm(total=n, unit="frame", desc="render") as bar:
        paths = write_animation(render_frames(r, style, n, size, camera, True), args.output, n,
                                args.fps, progress=bar.update)
    where = paths[0] if len(paths) == 1 else f"{paths[0]} ... {paths[-1].name}"
    print(f"wrote {where} ({n} frames, {size[0]}x{size[1]})")
    return 0
