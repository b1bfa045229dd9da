"""Interactive viewer: a window (glfw) drawing lines with LineRenderer, a Dear ImGui panel of the
style's parameters, and a watched style file (``flowkit view lines.h5 --style style.toml``).

Needs the optional ``view`` extra (glfw, imgui-bundle) and a display; imported lazily so the rest
of flowkit never needs either.
"""

from __future__ import annotations


def __getattr__(name):
    if name == "Viewer":
        from .app import Viewer

        return Viewer
    raise AttributeError(name)


__all__ = ["Viewer"]
