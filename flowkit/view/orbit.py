"""Mouse camera control on the renderer's Camera (azimuth/elevation/distance about a target).

A style's camera may leave the distance, target, up, the orthographic view height, or the
direction (a named view) to be fitted to the lines' bounds.  A fit depends on the direction (the
projected bounds differ from every side), so the viewer fits once (``pinned``: everything made
explicit, the same view) and orbiting, zooming and panning then change only what they are asked
to: the scale stays while the view turns, as in ParaView."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..render.camera import Camera

DEG_PER_PIXEL = 0.4
ZOOM_STEP = 0.9  # distance factor per scroll step (towards the target)
MAX_ELEVATION = 89.0


def is_pinned(cam: Camera) -> bool:
    return (cam.target is not None and cam.distance is not None and cam.up is not None
            and cam.view is None
            and (cam.projection != "orthographic" or cam.parallel_scale is not None))


def pinned(cam: Camera, bounds: np.ndarray, size: tuple[int, int]) -> Camera:
    """``cam`` with explicit target, distance, up, azimuth/elevation (for a named view) and,
    orthographic, parallel scale, giving the same view of ``bounds`` on a ``size`` image."""
    if is_pinned(cam):
        return cam
    w, h = size
    s = cam.setup(bounds, w, h)
    up = cam.choose_up(bounds, w, h)
    centre = s.target  # a fitted perspective view looks at its projection's centre
    dist = float(np.linalg.norm(s.eye - centre))
    e1, e2, u = cam.frame(up)
    d = (s.eye - centre) / dist
    kw = {"target": tuple(float(v) for v in centre), "distance": dist,
          "up": tuple(float(v) for v in up), "view": None,
          "azimuth": math.degrees(math.atan2(d @ e2, d @ e1)),
          "elevation": math.degrees(math.asin(min(max(d @ u, -1.0), 1.0)))}
    if cam.projection == "orthographic":  # the fitted half height, before the zoom
        kw["parallel_scale"] = s.px_scale[1] * h / 2 * cam.zoom
    return dataclasses.replace(cam, **kw)


def orbit(cam: Camera, dx: float, dy: float) -> Camera:
    """Drag right turns the scene right (the eye left); drag up tilts the eye up.  On a
    ``pinned`` camera (else the fit, and so the scale, follows the direction)."""
    az = (cam.azimuth - DEG_PER_PIXEL * dx + 180.0) % 360.0 - 180.0
    el = min(max(cam.elevation + DEG_PER_PIXEL * dy, -MAX_ELEVATION), MAX_ELEVATION)
    return dataclasses.replace(cam, azimuth=az, elevation=el)


def zoom(cam: Camera, steps: float, bounds: np.ndarray, size: tuple[int, int]) -> Camera:
    """Scroll up (steps > 0) moves closer (perspective) or magnifies (orthographic)."""
    f = ZOOM_STEP ** steps
    cam = pinned(cam, bounds, size)
    if cam.projection == "orthographic":
        return dataclasses.replace(cam, zoom=cam.zoom / f)
    return dataclasses.replace(cam, distance=cam.distance * f)


def pan(cam: Camera, dx: float, dy: float, bounds: np.ndarray, size: tuple[int, int]) -> Camera:
    """Move the target so the scene follows the mouse (pixels, y down)."""
    cam = pinned(cam, bounds, size)
    s = cam.setup(bounds, *size)
    px = s.px_scale[0] * cam.distance + s.px_scale[1]  # world size of a pixel at the target
    right, up = s.view[0, :3], s.view[1, :3]
    new = np.asarray(cam.target, float) - px * dx * right + px * dy * up
    if not all(math.isfinite(v) for v in new):
        return cam
    return dataclasses.replace(cam, target=tuple(float(v) for v in new))


def zoom_at(cam: Camera, steps: float, bounds: np.ndarray, size: tuple[int, int], x: float,
            y: float) -> Camera:
    """Zoom like ``zoom`` about the point under scene pixel (x, y) (y down) instead of the image
    centre: the camera is scaled about that point (on the target's depth plane), so it stays
    under the cursor."""
    f = ZOOM_STEP ** steps
    cam = pinned(cam, bounds, size)
    s = cam.setup(bounds, *size)
    w, h = size
    px = s.px_scale[0] * cam.distance + s.px_scale[1]
    old = np.asarray(cam.target, float)
    p = old + px * ((x - w / 2) * s.view[0, :3] - (y - h / 2) * s.view[1, :3])
    new = p + f * (old - p)
    if not all(math.isfinite(v) for v in new):
        return cam
    target = tuple(float(v) for v in new)
    if cam.projection == "orthographic":
        return dataclasses.replace(cam, target=target, zoom=cam.zoom / f)
    return dataclasses.replace(cam, target=target, distance=cam.distance * f)
