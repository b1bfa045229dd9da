"""``flowkit view lines.h5 --style style.toml``: an interactive window.

Left drag orbits, right (or shift + left) drag pans, the wheel zooms towards the cursor;
hovering a line probes the vertex under the cursor (position, seed, attributes with units, why
the line stopped), a click pins it.  R resets the camera, S saves a screenshot
(flowkit-view-NNN.png), C cycles the colour attribute of the colour-mapped bands, A toggles the
orientation axes, B the outline, P the probe, H the panel, Ctrl+Z / Ctrl+Shift+Z undo and redo
panel edits, Ctrl+S saves the style, Esc quits.  The style file is watched: save it in an editor
and the view follows (an error is shown in the window and the last good style stays).  The
panel edits the style; "save style" writes it back.  Needs the ``view`` extra
(pip install 'flowkit[view]') and a display.
"""

from __future__ import annotations

from . import CLIError
from .render import _size


def register(subparsers) -> None:
    p = subparsers.add_parser("view", help="explore a lines file in a window, live style editing",
                              description=__doc__)
    p.add_argument("lines", help="lines HDF5 file (flowkit trace output)")
    p.add_argument("--style", required=True, help="TOML style file, watched for changes")
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
    lines = read_lines(args.lines)
    try:
        viewer = Viewer(lines, args.style, size=size, vsync=not args.no_vsync,
                        screenshot_dir=args.screenshots, units=read_units(args.lines))
    except ViewerError as e:
        raise CLIError(str(e)) from None
    viewer.run()
    return 0
