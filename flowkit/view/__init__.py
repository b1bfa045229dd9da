"""Interactive viewer: a window (glfw) drawing lines with LineRenderer, a Dear ImGui panel of the
style's parameters, and a watched style file (``flowkit view lines.h5 --style style.toml``).

Needs the optional ``view`` extra (glfw, imgui-bundle) and a display; imported lazily so the rest
of flowkit never needs either.
"""

from __future__ import annotations

import os

# numba's parallel loops (the renderer's level of detail) run on OpenMP threads that by default
# spin for a while after each loop; in the viewer they then take the cores from the software
# rasterizer (llvmpipe) and from the trace's threads drawing and tracing right after (on 2 cores a
# re-trace and redraw took ~25 % longer).  Read when libgomp loads, i.e. at the first parallel
# loop of the process; a value already set is kept.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")


def __getattr__(name):
    if name == "Viewer":
        from .app import Viewer

        return Viewer
    raise AttributeError(name)


__all__ = ["Viewer"]
