"""Look-at camera from azimuth/elevation/distance about a target, fit to the lines' bounds by
default; perspective or orthographic.  Matrices are float64 numpy, column-vector convention
(clip = P @ V @ [x, y, z, 1]); upload them transposed (GL is column-major)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Camera:
    """``azimuth``/``elevation`` in degrees: the eye sits at
    target + distance * (cos el cos az * e1 + cos el sin az * e2 + sin el * up), where (e1, e2, up)
    is a right-handed frame with e1 the first coordinate axis not parallel to ``up``.  With
    ``up = (0, 0, 1)``: azimuth -90, elevation 0 looks along +y, x to the right, z up.
    ``distance``/``target`` None: fit the bounds (whole bounding sphere in view).  ``zoom`` > 1
    magnifies.  ``fov`` is the vertical field of view (perspective)."""

    azimuth: float = -60.0
    elevation: float = 25.0
    distance: float | None = None
    target: tuple[float, float, float] | None = None
    up: tuple[float, float, float] = (0.0, 0.0, 1.0)
    fov: float = 30.0
    projection: str = "perspective"
    zoom: float = 1.0

    def frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        up = np.asarray(self.up, float)
        n = np.linalg.norm(up)
        if not np.isfinite(n) or n == 0:
            raise ValueError(f"camera up = {self.up} must be a non-zero vector")
        up = up / n
        axes = np.eye(3)
        e1 = axes[0]
        for a in axes:  # first coordinate axis not (nearly) parallel to up
            if abs(a @ up) < 0.9:
                e1 = a - (a @ up) * up
                break
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(up, e1)
        return e1, e2, up

    def setup(self, bounds: np.ndarray, width: int, height: int) -> CameraSetup:
        """View and projection for lines with ``bounds`` (3, 2) on a width x height image."""
        b = np.asarray(bounds, float)
        centre = b.mean(axis=1) if self.target is None else np.asarray(self.target, float)
        radius = max(0.5 * float(np.linalg.norm(b[:, 1] - b[:, 0])), 1e-9)
        if self.target is not None:  # sphere about the target that still holds the bounds
            corners = np.array(np.meshgrid(*b)).reshape(3, -1).T
            radius = max(float(np.max(np.linalg.norm(corners - centre, axis=1))), 1e-9)
        aspect = width / height
        half_fov = math.radians(self.fov) / 2
        # the tighter of the vertical and horizontal half-angles must hold the sphere
        half_min = min(half_fov, math.atan(math.tan(half_fov) * aspect))
        if self.distance is not None:
            dist = self.distance
        elif self.projection == "perspective":
            dist = radius / math.sin(half_min) / self.zoom
        else:
            dist = 3.0 * radius
        e1, e2, up = self.frame()
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        d = math.cos(el) * math.cos(az) * e1 + math.cos(el) * math.sin(az) * e2 + math.sin(el) * up
        eye = centre + dist * d
        view = look_at(eye, centre, up)
        near = max(dist - 1.01 * radius, dist * 1e-3)
        far = dist + 1.01 * radius
        if self.projection == "perspective":
            proj = perspective(2 * half_fov, aspect, near, far)
            # world units per pixel at view depth z (< 0): px_a * (-z) + px_b
            px_a, px_b = 2 * math.tan(half_fov) / height, 0.0
        else:
            half_h = radius / self.zoom / min(1.0, aspect)
            near = dist - 1.01 * radius  # orthographic: a near plane behind the eye is fine
            proj = orthographic(half_h * aspect, half_h, near, far)
            px_a, px_b = 0.0, 2 * half_h / height
        return CameraSetup(view, proj, eye, (px_a, px_b))


@dataclass(frozen=True)
class CameraSetup:
    view: np.ndarray
    proj: np.ndarray
    eye: np.ndarray
    px_scale: tuple[float, float]  # world per pixel = px_scale[0] * (-z_view) + px_scale[1]


def look_at(eye, target, up) -> np.ndarray:
    f = np.asarray(target, float) - eye
    f /= np.linalg.norm(f)
    s = np.cross(f, up)
    if np.linalg.norm(s) < 1e-9:  # looking along up: any perpendicular will do
        s = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 1.0, 0.0])
    s /= np.linalg.norm(s)
    u = np.cross(s, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = s, u, -f
    m[:3, 3] = -m[:3, :3] @ eye
    return m


def perspective(fovy: float, aspect: float, near: float, far: float) -> np.ndarray:
    t = 1.0 / math.tan(fovy / 2)
    m = np.zeros((4, 4))
    m[0, 0], m[1, 1] = t / aspect, t
    m[2, 2], m[2, 3] = (far + near) / (near - far), 2 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def orthographic(half_w: float, half_h: float, near: float, far: float) -> np.ndarray:
    m = np.eye(4)
    m[0, 0], m[1, 1] = 1 / half_w, 1 / half_h
    m[2, 2], m[2, 3] = -2 / (far - near), -(far + near) / (far - near)
    return m
