"""Look-at camera from azimuth/elevation/distance about a target, fit to the lines' bounds by
default; perspective or orthographic.  Matrices are float64 numpy, column-vector convention
(clip = P @ V @ [x, y, z, 1]); upload them transposed (GL is column-major)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

FITS = ("bounds", "sphere")
VIEWS = ("+x", "-x", "+y", "-y", "+z", "-z", "iso")
FILL = 0.9  # fitted bounds span this fraction of the image's limiting side (room for widths)
AZIMUTH, ELEVATION = -60.0, 25.0  # a direction given by one angle takes the other from here
TIE = 1.1  # axes whose extents differ by less than this factor are equally thin
_AXES = np.eye(3)
SETUPS_KEPT = 8  # Camera.setup results kept
_SETUPS: dict[tuple, CameraSetup] = {}


@dataclass(frozen=True)
class Camera:
    """``azimuth``/``elevation`` in degrees: the eye sits at
    target + distance * (cos el cos az * e1 + cos el sin az * e2 + sin el * up), where (e1, e2, up)
    is a right-handed frame with e1 the first coordinate axis not parallel to ``up``.  With
    ``up = (0, 0, 1)``: azimuth -90, elevation 0 looks along +y, x to the right, z up.
    ``view``: a named view instead of azimuth/elevation, as ParaView's buttons: "+x" looks along
    +x (from the -x side), ..., "iso" looks along (-1, -1, -1).  No view and no angle: the
    automatic view (``resolve``): along the domain's thinnest axis, its longest other axis along
    the image's long side.  One angle alone takes the other from AZIMUTH, ELEVATION.
    ``up`` None: the coordinate axis (z, then y, then x) that lays the domain's longest axis
    along the image's long side.  ``distance`` (perspective) or the view height (orthographic)
    None: fitted.  ``fit = "bounds"`` (default) fits the bounds' corners as projected on the
    image, to FILL of its limiting side (perspective: looking at the projected box's centre), so
    a thin or tall domain fills the frame; ``"sphere"``
    fits their bounding sphere, the same size from every direction (also the fit of a domain
    seen as a point, e.g. a straight line end on).  With an explicit ``target``
    the fit about the bounds' centre grows as the bounding sphere about the target does.
    ``parallel_scale`` (orthographic): half the view's height in world units, as ParaView's
    parallel scale; None: fitted.  ``zoom`` > 1 magnifies (a fitted distance, or the view
    height).  ``fov`` is the vertical field of view (perspective)."""

    azimuth: float | None = None
    elevation: float | None = None
    distance: float | None = None
    target: tuple[float, float, float] | None = None
    up: tuple[float, float, float] | None = None
    fov: float = 30.0
    projection: str = "perspective"
    zoom: float = 1.0
    view: str | None = None
    fit: str = "bounds"
    parallel_scale: float | None = None

    def __post_init__(self):
        if self.parallel_scale is not None and not (math.isfinite(self.parallel_scale)
                                                    and self.parallel_scale > 0):
            raise ValueError(f"camera parallel_scale = {self.parallel_scale!r} must be a "
                             "positive number")
        if self.fit not in FITS:
            raise ValueError(f"camera fit = {self.fit!r} is not allowed; expected one of "
                             f"{', '.join(FITS)}")
        if self.view is not None and self.view not in VIEWS:
            raise ValueError(f"camera view = {self.view!r} is not allowed; expected one of "
                             f"{', '.join(VIEWS)}")

    @property
    def automatic(self) -> bool:
        """No view direction given: ``resolve`` chooses it from the bounds."""
        return self.view is None and self.azimuth is None and self.elevation is None

    def over(self, **changes) -> Camera:
        """This camera with ``changes`` (keys of a camera given at a higher precedence: command
        line over scene over style).  A direction replaces the whole direction: a view clears
        the angles, an angle the view, so a lower level's named view never wins silently."""
        if "view" in changes:
            changes.setdefault("azimuth", None)
            changes.setdefault("elevation", None)
        elif "azimuth" in changes or "elevation" in changes:
            changes["view"] = None
        return dataclasses.replace(self, **changes)

    def resolve(self, bounds, width: int, height: int, travel=None) -> Camera:
        """The camera with the automatic view made explicit (a named view and, unless given, an
        up); any other camera unchanged.  The automatic view looks along the thinnest axis of
        ``bounds`` (of equally thin ones: the one the lines travel least along, ``travel`` (3,)
        summed |dx|, |dy|, |dz|, when given; else y, x, z: a side view), with the longest other
        axis along the image's long side, pointing right or up (right-handed); the fit then
        fills the frame."""
        if not self.automatic:
            return self
        ext = np.ptp(np.asarray(bounds, float), axis=1)
        ext = np.where(np.isfinite(ext), ext, 0.0)
        axes = [a for a in range(3) if self.up is None or abs(_AXES[a] @ _unit(self.up)) < 0.9]
        thin = [a for a in axes if ext[a] <= TIE * min(ext[axes])]
        order = (1, 0, 2) if travel is None else tuple(np.argsort(np.asarray(travel, float),
                                                                  kind="stable"))
        look = next(a for a in order if a in thin)
        if self.up is not None:  # a given up: across it, the sign that puts +axes to the right
            sign = "+" if np.cross(_AXES[look], _unit(self.up)).sum() >= 0 else "-"
            return dataclasses.replace(self, view=sign + "xyz"[look])
        a, b = (r for r in range(3) if r != look)
        short = a if ext[a] < ext[b] else b
        long_ = a + b - short
        up_axis, right_axis = (short, long_) if width >= height else (long_, short)
        if 2 in (a, b) and max(ext[a], ext[b]) <= TIE * min(ext[a], ext[b]):
            up_axis, right_axis = 2, a + b - 2  # two equal axes: z stays up
        f = np.cross(_AXES[up_axis], _AXES[right_axis])  # right-handed: right = f x up
        return dataclasses.replace(self, view=("+" if f[look] > 0 else "-") + "xyz"[look],
                                   up=tuple(float(v) for v in _AXES[up_axis]))

    def describe(self) -> str:
        """The direction in words, as --explain and the render log report it."""
        if self.automatic:
            return "automatic view"
        up = "" if self.up is None else " up " + ",".join(f"{v:g}" for v in self.up)
        if self.view is not None:
            return f"view {self.view}{up}"
        az = AZIMUTH if self.azimuth is None else self.azimuth
        el = ELEVATION if self.elevation is None else self.elevation
        return f"azimuth {az:g} elevation {el:g}{up}"

    def frame(self, up=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(e1, e2, up) about ``up`` (default: the camera's own, z when it has none)."""
        up = _unit(up if up is not None else self.up if self.up is not None else _AXES[2])
        e1 = _AXES[0]
        for a in _AXES:  # first coordinate axis not (nearly) parallel to up
            if abs(a @ up) < 0.9:
                e1 = a - (a @ up) * up
                break
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(up, e1)
        return e1, e2, up

    def direction(self, up=None) -> np.ndarray:
        """Unit vector from the target to the eye."""
        if self.view == "iso":
            return np.ones(3) / math.sqrt(3.0)
        if self.view is not None:
            return -float(self.view[0] + "1") * _AXES["xyz".index(self.view[1])]
        e1, e2, up = self.frame(up)
        az = math.radians(AZIMUTH if self.azimuth is None else self.azimuth)
        el = math.radians(ELEVATION if self.elevation is None else self.elevation)
        return math.cos(el) * math.cos(az) * e1 + math.cos(el) * math.sin(az) * e2 + math.sin(el) * up

    def choose_up(self, bounds, width: int, height: int) -> np.ndarray:
        """The camera's up, or when it has none the first of z, y, x (not along the view) that
        shows the domain's longest axis more along the image's long side than its short one;
        failing all, the one showing it most so."""
        if self.automatic:
            return self.resolve(bounds, width, height).choose_up(bounds, width, height)
        if self.up is not None:
            return np.asarray(self.up, float)
        ext = np.ptp(np.asarray(bounds, float), axis=1)
        longest = _AXES[int(np.argmax(ext))] * max(float(ext.max()), 1e-30)
        best, best_score = _AXES[2], -math.inf
        for up in (_AXES[2], _AXES[1], _AXES[0]):
            d = self.direction(up)
            if abs(d @ up) > 0.999:  # looking along it: not an up
                continue
            s, u = _screen_axes(d, up)
            horiz, vert = abs(longest @ s), abs(longest @ u)
            along, across = (horiz, vert) if width >= height else (vert, horiz)
            if along >= across and along > 0:
                return up
            score = along - across
            if score > best_score:
                best, best_score = up, score
        return best

    def setup(self, bounds: np.ndarray, width: int, height: int) -> CameraSetup:
        """View and projection for lines with ``bounds`` (3, 2) on a width x height image.
        The last few are kept (a viewer frame asks for the same one several times: scene,
        overlays, picking); their arrays are read-only."""
        b = np.asarray(bounds, float)
        if self.automatic:
            return self.resolve(b, width, height).setup(b, width, height)
        try:
            key = (self, b.tobytes(), b.shape, int(width), int(height))
            hit = _SETUPS.get(key)
        except (TypeError, ValueError):  # a field that is not hashable (a list): not kept
            key = hit = None
        if hit is not None:
            return hit
        out = self._setup(b, width, height)
        if key is not None:
            for a in (out.view, out.proj, out.eye, out.target):
                if isinstance(a, np.ndarray):
                    a.setflags(write=False)
            if len(_SETUPS) >= SETUPS_KEPT:
                del _SETUPS[next(iter(_SETUPS))]
            _SETUPS[key] = out
        return out

    def _setup(self, b: np.ndarray, width: int, height: int) -> CameraSetup:
        corners = np.array(np.meshgrid(*b)).reshape(3, -1).T
        mid = b.mean(axis=1)
        centre = mid if self.target is None else np.asarray(self.target, float)
        radius = max(float(np.max(np.linalg.norm(corners - centre, axis=1))), 1e-9)
        # an explicit target: the fit about the bounds' centre, grown as the sphere about it
        grow = radius / max(float(np.max(np.linalg.norm(corners - mid, axis=1))), 1e-9)
        aspect = width / height
        half_fov = math.radians(self.fov) / 2
        up = self.choose_up(b, width, height)
        d = self.direction(up)
        s, u = _screen_axes(d, up)
        rel = corners - mid
        x, y, z = rel @ s, rel @ u, rel @ d  # corners on the image's axes and towards the eye
        # a domain seen as a point (a straight line end on) has no projected extent to fit
        sphere = self.fit == "sphere" or max(np.ptp(x), np.ptp(y)) < 1e-3 * radius
        persp = self.projection == "perspective"
        if self.distance is not None:
            dist = self.distance
        elif not persp:
            dist = 3.0 * radius
        elif sphere:  # the tighter of the vertical and horizontal half-angles holds the sphere
            dist = radius / math.sin(min(half_fov, math.atan(math.tan(half_fov) * aspect))) / self.zoom
        else:
            dist, (a, b) = _fit_distance(x, y, z, math.tan(half_fov), aspect, radius,
                                         recentre=self.target is None)
            dist *= grow / self.zoom
            if self.target is None:  # looking at the projected box's centre
                centre = centre + a * s + b * u
                radius = max(float(np.max(np.linalg.norm(corners - centre, axis=1))), 1e-9)
        eye = centre + dist * d
        view = look_at(eye, centre, up)
        near = max(dist - 1.01 * radius, dist * 1e-3)
        far = dist + 1.01 * radius
        if persp:
            proj = perspective(2 * half_fov, aspect, near, far)
            # world units per pixel at view depth z (< 0): px_a * (-z) + px_b
            px_a, px_b = 2 * math.tan(half_fov) / height, 0.0
        else:
            if self.parallel_scale is not None:
                half_h = self.parallel_scale / self.zoom
            elif sphere:
                half_h = radius / self.zoom / min(1.0, aspect)
            else:
                half = max(float(np.max(np.abs(x))) / aspect, float(np.max(np.abs(y))), 1e-9)
                half_h = half / FILL * grow / self.zoom
            near = dist - 1.01 * radius  # orthographic: a near plane behind the eye is fine
            proj = orthographic(half_h * aspect, half_h, near, far)
            px_a, px_b = 0.0, 2 * half_h / height
        return CameraSetup(view, proj, eye, (px_a, px_b), centre)


def _centring_shift(xy: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """The sideways shifts (a, b) of eye and target that centre corners at image coordinates
    ``xy`` (2, n) and ``depth`` (n,) in front of the eye: max((x - a) / depth) = -min(...), the
    same for y.  That sum falls as the shift grows; searched on a grid, 256 times finer in each
    of two rounds (1/65536 of the extent)."""
    lo, hi = xy.min(axis=1), xy.max(axis=1)
    for _ in range(2):
        a = np.linspace(lo, hi, 257, axis=1)  # (2, 257)
        p = (xy[:, :, None] - a[:, None, :]) / depth[None, :, None]  # (2, n, 257)
        g = p.max(axis=1) + p.min(axis=1)
        k = np.clip((g > 0).sum(axis=1), 1, 256)  # g falls: the first index with g <= 0
        lo, hi = a[[0, 1], k - 1], a[[0, 1], k]
    return 0.5 * (lo + hi)


def _fit_distance(x, y, z, tan_y, aspect, radius, recentre: bool = True):
    """(eye distance, (a, b)): at that distance the corners (image axes x, y; z towards the eye)
    span FILL of the image's limiting side, with none nearer than 4 % to an edge, seen from the
    bounds' centre shifted by a, b along the image's axes (``recentre``: the shift that centres
    the projected box, which perspective otherwise makes lopsided; else none)."""
    xy = np.stack([x, y])
    scale = np.array([[tan_y * aspect], [tan_y]])

    def extents(dist):
        depth = np.maximum(dist - z, 1e-12 * dist)
        ab = _centring_shift(xy, depth) if recentre else np.zeros(2)
        p = (xy - ab[:, None]) / depth / scale  # -1..1 on the image
        return np.ptp(p, axis=1).max() / 2, np.abs(p).max(), ab

    lo = float(np.max(z)) + 1e-9 * radius
    hi = max(lo, radius) * 4.0 + radius / tan_y
    for _ in range(45):  # the smallest distance with span <= FILL and every corner <= 0.96
        mid = 0.5 * (lo + hi)
        span, edge, _ = extents(mid)
        lo, hi = (mid, hi) if span > FILL or edge > 0.96 else (lo, mid)
    dist = max(hi, radius * 1e-6)
    return dist, tuple(float(v) for v in extents(dist)[2])


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    n = np.linalg.norm(v)
    if not np.isfinite(n) or n == 0:
        raise ValueError(f"camera up = {tuple(v)} must be a non-zero vector")
    return v / n


def _screen_axes(d: np.ndarray, up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(right, up) on the image for an eye direction ``d`` (target -> eye) and ``up``."""
    f = -d
    s = np.cross(f, up)
    if np.linalg.norm(s) < 1e-9:
        s = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 1.0, 0.0])
    s /= np.linalg.norm(s)
    return s, np.cross(s, f)


@dataclass(frozen=True)
class CameraSetup:
    view: np.ndarray
    proj: np.ndarray
    eye: np.ndarray
    px_scale: tuple[float, float]  # world per pixel = px_scale[0] * (-z_view) + px_scale[1]
    target: np.ndarray  # the point looked at (a fitted perspective view: the projection's centre)


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
