"""Mouse camera control on the renderer's Camera (azimuth/elevation/distance about a target).

The style's camera may leave distance and target to be fitted to the lines' bounds; the first
zoom or pan pins them to the fitted values so the view does not jump."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..render.camera import Camera

DEG_PER_PIXEL = 0.4
ZOOM_STEP = 0.9  # distance factor per scroll step (towards the target)
MAX_ELEVATION = 89.0


def _radius(bounds: np.ndarray, centre: np.ndarray) -> float:
    corners = np.array(np.meshgrid(*bounds)).reshape(3, -1).T
    return max(float(np.max(np.linalg.norm(corners - centre, axis=1))), 1e-9)


def pinned(cam: Camera, bounds: np.ndarray, size: tuple[int, int]) -> Camera:
    """``cam`` with explicit target and distance giving the same view."""
    if cam.target is not None and cam.distance is not None:
        return cam
    centre = np.asarray(bounds, float).mean(axis=1) if cam.target is None else np.asarray(cam.target)
    eye = cam.setup(bounds, *size).eye
    return dataclasses.replace(cam, target=tuple(float(v) for v in centre),
                               distance=float(np.linalg.norm(eye - centre)))


def orbit(cam: Camera, dx: float, dy: float) -> Camera:
    """Drag right turns the scene right (the eye left); drag up tilts the eye up."""
    az = (cam.azimuth - DEG_PER_PIXEL * dx + 180.0) % 360.0 - 180.0
    el = min(max(cam.elevation + DEG_PER_PIXEL * dy, -MAX_ELEVATION), MAX_ELEVATION)
    return dataclasses.replace(cam, azimuth=az, elevation=el)


def zoom(cam: Camera, steps: float, bounds: np.ndarray, size: tuple[int, int]) -> Camera:
    """Scroll up (steps > 0) moves closer (perspective) or magnifies (orthographic)."""
    f = ZOOM_STEP ** steps
    if cam.projection == "orthographic":
        return dataclasses.replace(cam, zoom=cam.zoom / f)
    cam = pinned(cam, bounds, size)
    return dataclasses.replace(cam, distance=cam.distance * f)


def pan(cam: Camera, dx: float, dy: float, bounds: np.ndarray, size: tuple[int, int]) -> Camera:
    """Move the target so the scene follows the mouse (pixels, y down)."""
    cam = pinned(cam, bounds, size)
    s = cam.setup(bounds, *size)
    px = s.px_scale[0] * cam.distance + s.px_scale[1]  # world size of a pixel at the target
    right, up = s.view[0, :3], s.view[1, :3]
    old = np.asarray(cam.target, float)
    new = old - px * dx * right + px * dy * up
    z = cam.zoom
    if cam.projection == "orthographic":  # its view height follows the radius about the target
        z *= _radius(bounds, new) / _radius(bounds, old)
    if not all(math.isfinite(v) for v in new):
        return cam
    return dataclasses.replace(cam, target=tuple(float(v) for v in new), zoom=z)


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
    if cam.projection == "orthographic":  # the view height follows the radius about the target
        z = cam.zoom / f * _radius(bounds, new) / _radius(bounds, old)
        return dataclasses.replace(cam, target=target, zoom=z)
    return dataclasses.replace(cam, target=target, distance=cam.distance * f)
