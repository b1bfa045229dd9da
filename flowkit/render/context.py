"""OpenGL contexts: headless EGL by default, the caller's window context on request."""

from __future__ import annotations

import moderngl

KINDS = ("egl", "standalone", "window")
MIN_GL = 330

_INSTALL_HINT = (
    "flowkit renders with OpenGL 3.3+ through EGL (headless). Install the EGL loader and Mesa "
    "drivers, e.g. on Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri (llvmpipe renders "
    "on the CPU); on an NVIDIA machine the driver's libEGL_nvidia must be visible to libglvnd."
)


class RenderContextError(RuntimeError):
    """No usable OpenGL context; the message says what to install."""


_default: moderngl.Context | None = None


def create_context(kind: str = "egl") -> moderngl.Context:
    """``egl``: headless standalone context (no display needed).  ``standalone``: the platform's
    default standalone context (GLX/WGL/CGL).  ``window``: attach to the OpenGL context that is
    current in the caller's window (made by glfw, pyglet, Qt...)."""
    if kind not in KINDS:
        raise ValueError(f"context kind {kind!r} is not allowed; expected one of {', '.join(KINDS)}")
    try:
        if kind == "egl":
            ctx = moderngl.create_standalone_context(backend="egl", require=MIN_GL)
        elif kind == "standalone":
            ctx = moderngl.create_standalone_context(require=MIN_GL)
        else:
            ctx = moderngl.create_context(require=MIN_GL)
    except Exception as e:  # noqa: BLE001 -- glcontext raises plain Exception with the loader's message
        where = "no current window context" if kind == "window" else f"{kind} context"
        raise RenderContextError(f"could not create an OpenGL {MIN_GL // 100}.{MIN_GL % 100 // 10} "
                                 f"{where}: {e}. {_INSTALL_HINT}") from None
    if ctx.version_code < MIN_GL:
        v = ctx.version_code
        ctx.release()
        raise RenderContextError(f"OpenGL {v // 100}.{v % 100 // 10} found, 3.3 or newer needed. "
                                 f"{_INSTALL_HINT}")
    return ctx


SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast", "swiftshader", "lavapipe")


def is_software(ctx: moderngl.Context) -> bool:
    """Whether ``ctx`` rasterizes on the CPU (Mesa llvmpipe and friends), where 4x MSAA costs
    about 2-3x the frame time and analytic edge smoothing is the cheaper antialiasing."""
    name = str(ctx.info.get("GL_RENDERER", "")).lower()
    return any(s in name for s in SOFTWARE_RENDERERS)


def default_context() -> moderngl.Context:
    """One headless EGL context per process, made on first use."""
    global _default
    if _default is None:
        _default = create_context("egl")
    return _default
