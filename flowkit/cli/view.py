"""``flowkit view lines.h5 --style style.toml``: an interactive window.

Left drag orbits, right (or shift + left) drag pans, the wheel zooms towards the cursor;
hovering a line probes the vertex under the cursor (position, seed, attributes with units, why
the line stopped), a click pins it.  R resets the camera, S saves a screenshot
(flowkit-view-NNN.png), C cycles the colour attribute of the colour-mapped bands, A toggles the
orientation axes, B the outline, P the probe, H the panel, Ctrl+Z / Ctrl+Shift+Z undo and redo
panel edits, Ctrl+S saves the style, Esc quits.  The style file is watched: save it in an editor
and the view follows (an error is shown in the window and the last good style stays).  The
panel edits the style; "save style" writes it back.

``flowkit view --scene scene.toml [--view NAME]`` opens a scene's lines with live seeding: a seed
rake (a line or a plane; the scene's seeds when they are a line: or plane: spec) whose handles a
left drag moves; the lines are traced again with the scene's field and options and redrawn.
+ / - change the seed count, T switches line / plane, G shows the rake, W saves the rake's seed
spec (for --seeds, or a scene's [seeds] spec) to SCENE.seeds beside the scene.

Needs the ``view`` extra (pip install 'flowkit[view]') and a display.
"""

from __future__ import annotations

from . import CLIError
from .render import _size


def register(subparsers) -> None:
    p = subparsers.add_parser("view", help="explore a lines file in a window, live style editing",
                              description=__doc__)
    p.add_argument("lines", nargs="?", help="lines HDF5 file (flowkit trace output)")
    p.add_argument("--style", help="TOML style file, watched for changes (with --scene: "
                   "instead of the view's style)")
    p.add_argument("--scene", help="a scene file: its lines with live seeding from a rake")
    p.add_argument("--view", help="with --scene: the view whose style and camera to use "
                   "(default: the first)")
    p.add_argument("--snapshot", type=int, help="with --scene: the snapshot position (default: "
                   "the first the scene selects)")
    p.add_argument("--rake", help="with --scene: the rake to start from when the scene's seeds "
                   "are not a line or plane: 'line', 'plane' or a line:/plane: spec")
    p.add_argument("--size", default="1280x800", help="window WIDTHxHEIGHT (default 1280x800)")
    p.add_argument("--screenshots", default=".", help="folder for S screenshots (default: here)")
    p.add_argument("--no-vsync", action="store_true", help="do not wait for the display refresh")
    p.set_defaults(func=run)


def run(args) -> int:
    try:
        from ..view.app import Viewer, ViewerError
    except ImportError as e:
        raise CLIError(f"the viewer needs the optional 'view' extra ({e.name} is missing): "
                       "pip install 'flowkit[view]'") from None
    from ..io.lines_h5 import read_lines, read_units

    size = _size(args.size)
    common = {"size": size, "vsync": not args.no_vsync, "screenshot_dir": args.screenshots}
    if args.scene is not None:
        if args.lines is not None:
            raise CLIError("flowkit view: give a lines file or --scene, not both")
        from ..view.seeding import open_scene

        s = open_scene(args.scene, args.view, args.snapshot, args.rake, args.style)
        kw = {**common, "units": s.units, "camera": s.camera, "seeding": s.seeding,
              "title": s.title}
        lines, style = s.lines, s.style_path
    else:
        if args.lines is None or args.style is None:
            raise CLIError("flowkit view: give a lines file and --style STYLE, or --scene SCENE")
        for opt in ("view", "snapshot", "rake"):
            if getattr(args, opt) is not None:
                raise CLIError(f"flowkit view: --{opt} goes with --scene")
        lines, style = read_lines(args.lines), args.style
        kw = {**common, "units": read_units(args.lines)}
    try:
        viewer = Viewer(lines, style, **kw)
    except ViewerError as e:
        raise CLIError(str(e)) from None
    viewer.run()
    return 0
