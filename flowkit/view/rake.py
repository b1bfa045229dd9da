"""The seed rake of live seeding: a line (its two ends) or a plane (a corner and the corners at
the ends of its two edges, as ParaView's plane widget), with its seed count, and the seed spec
it stands for.

A rake is the arguments of a ``line:`` or ``plane:`` spec (``integrate.seeds.parse_rake_spec``);
its seeds are that spec parsed (``seeds``), so the viewer traces exactly the points that
``flowkit trace --seeds SPEC`` and a scene's ``[seeds] spec`` give.  Handles are moved to
coordinates rounded to ``decimals`` (a ten-thousandth of the domain's diagonal, see
``decimals_for``): the saved spec then reads ``line:1.25,0.6,1.0:...``, not seventeen digits, and
still parses back to the same floats.

``drag_point`` moves a point parallel to the screen by a mouse drag, ``project`` gives handles'
scene pixels, ``rake_image`` draws the rake as an overlay.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from PIL import Image, ImageDraw

from ..integrate.seeds import SeedError, line_spec, parse_rake_spec, parse_seed_spec, plane_spec

HANDLES = {"line": ("start", "end", "middle"), "plane": ("origin", "u", "v", "centre")}
GRAB_PX = 10.0  # a press within this many pixels of a handle grabs it
RAKE_COLOR = (255, 200, 40)
ACTIVE_COLOR = (90, 220, 255)


def _tup(p) -> tuple[float, float, float]:
    return tuple(float(x) for x in np.asarray(p, float).reshape(3))


def decimals_for(bounds) -> int:
    """Decimals that resolve a ten-thousandth of the diagonal of ``bounds`` (3, 2)."""
    diag = float(np.linalg.norm(np.diff(np.asarray(bounds, float), axis=1)))
    return max(0, 4 - math.floor(math.log10(diag))) if diag > 0 else 6


@dataclass(frozen=True)
class Rake:
    """``kind`` "line": ``a`` the start, ``b`` the end, ``counts`` (n,); "plane": ``a`` the
    origin corner, ``b`` and ``c`` the edge vectors u and v, ``counts`` (nu, nv)."""

    kind: str
    a: tuple
    b: tuple
    c: tuple | None
    counts: tuple

    @classmethod
    def from_spec(cls, spec: str) -> Rake:
        """The rake of a ``line:`` or ``plane:`` spec; SeedError for any other spec."""
        parsed = parse_rake_spec(spec)
        if parsed is None:
            raise SeedError(f"seed spec '{spec}': a rake is a line:x0,y0,z0:x1,y1,z1:n or "
                            "plane:ox,oy,oz:ux,uy,uz:vx,vy,vz:nu,nv spec")
        kind, args = parsed
        if kind == "line":
            return cls("line", _tup(args[0]), _tup(args[1]), None, (int(args[2]),))
        return cls("plane", _tup(args[0]), _tup(args[1]), _tup(args[2]), (int(args[3]),
                                                                         int(args[4])))

    @classmethod
    def default(cls, bounds, kind: str = "line") -> Rake:
        """A rake across the middle of ``bounds``: a line of 32 seeds along the longest axis,
        or an 8 x 8 plane on the two longest axes, from 10 % to 90 % of them."""
        b = np.asarray(bounds, float)
        lo, hi = b[:, 0] + 0.1 * np.ptp(b, axis=1), b[:, 0] + 0.9 * np.ptp(b, axis=1)
        mid = b.mean(axis=1)
        order = np.argsort(-np.ptp(b, axis=1), kind="stable")
        k = decimals_for(b)
        start = mid.copy()
        start[order[0]] = lo[order[0]]
        if kind == "line":
            end = start.copy()
            end[order[0]] = hi[order[0]]
            return cls("line", _round(start, k), _round(end, k), None, (32,))
        start[order[1]] = lo[order[1]]
        u, v = np.zeros(3), np.zeros(3)
        u[order[0]], v[order[1]] = hi[order[0]] - lo[order[0]], hi[order[1]] - lo[order[1]]
        return cls("plane", _round(start, k), _round(u, k), _round(v, k), (8, 8))

    # -- what it gives ---------------------------------------------------------------------
    def spec(self) -> str:
        """The seed spec (``flowkit trace --seeds``, a scene's ``[seeds] spec``)."""
        if self.kind == "line":
            return line_spec(self.a, self.b, self.counts[0])
        return plane_spec(self.a, self.b, self.c, *self.counts)

    def seeds(self) -> np.ndarray:
        """The seed points: the spec parsed, as the CLI and scenes parse it."""
        return parse_seed_spec(self.spec())

    @property
    def n_seeds(self) -> int:
        return math.prod(self.counts)

    def handles(self) -> dict[str, np.ndarray]:
        """Handle name -> world position."""
        a, b = np.array(self.a), np.array(self.b)
        if self.kind == "line":
            return {"start": a, "end": b, "middle": (a + b) / 2}
        c = np.array(self.c)
        return {"origin": a, "u": a + b, "v": a + c, "centre": a + (b + c) / 2}

    def outline(self) -> np.ndarray:
        """The rake's shape as a closed or open polyline of world points."""
        h = self.handles()
        if self.kind == "line":
            return np.array([h["start"], h["end"]])
        a, b, c = np.array(self.a), np.array(self.b), np.array(self.c)
        return np.array([a, a + b, a + b + c, a + c, a])

    # -- edits -------------------------------------------------------------------------------
    def moved(self, handle: str, to, bounds=None, decimals: int = 6) -> Rake:
        """The rake with ``handle`` at world point ``to``: an end or a corner moves alone (a
        plane's origin keeps the other two corners where they are), "middle"/"centre"
        translates the rake.  Points are kept inside ``bounds`` and rounded to ``decimals``;
        a move that would make the plane flat is refused (the rake is returned unchanged)."""
        if handle not in HANDLES[self.kind]:
            raise ValueError(f"rake handle {handle!r}: a {self.kind} rake has "
                             f"{', '.join(HANDLES[self.kind])}")
        to = np.asarray(to, float)
        h = self.handles()
        lo = hi = None
        if bounds is not None:
            lo, hi = np.asarray(bounds, float).T
        if handle in ("middle", "centre"):
            delta = to - h[handle]
            if lo is not None:  # every handle stays inside: the translation is limited
                pts = np.array(list(h.values()))
                delta = np.clip(delta, lo - pts.min(axis=0), hi - pts.max(axis=0))
            new = {"a": _round(np.array(self.a) + delta, decimals)}
            if self.kind == "line":  # its end is a point too (a plane's u, v are edges)
                new["b"] = _round(np.array(self.b) + delta, decimals)
            return dataclasses.replace(self, **new)
        if lo is not None:
            to = np.clip(to, lo, hi)
        p = _round(to, decimals)
        if self.kind == "line":
            return dataclasses.replace(self, **{"a" if handle == "start" else "b": p})
        a = np.array(self.a)
        if handle == "origin":
            new = {"a": p, "b": _round(h["u"] - p, decimals), "c": _round(h["v"] - p, decimals)}
        else:
            new = {"b" if handle == "u" else "c": _round(np.array(p) - a, decimals)}
        rake = dataclasses.replace(self, **new)
        try:
            rake.seeds()
        except SeedError:  # u and v parallel or zero
            return self
        return rake

    def with_counts(self, *counts: int) -> Rake:
        """The rake with seed counts ``counts`` (n, or nu, nv), each at least 1."""
        if len(counts) != len(self.counts):
            raise ValueError(f"a {self.kind} rake has {len(self.counts)} seed count(s), "
                             f"got {counts}")
        return dataclasses.replace(self, counts=tuple(max(1, int(n)) for n in counts))

    def more(self, step: int = 1) -> Rake:
        """One seed more per edge (``step`` < 0: fewer): the + and - keys."""
        return self.with_counts(*(n + step for n in self.counts))

    def as_kind(self, kind: str, decimals: int = 6) -> Rake:
        """The rake as a line (a plane's u edge, all its seeds) or as a plane (the line as its
        u edge, v across it as long, square-ish counts of about the line's seeds)."""
        if kind == self.kind:
            return self
        if kind == "line":
            end = _round(np.array(self.a) + np.array(self.b), decimals)
            return Rake("line", self.a, end, None, (self.n_seeds,))
        u = np.array(self.b) - np.array(self.a)
        axis = np.eye(3)[int(np.argmin(np.abs(u)))]  # the world axis most across the line
        v = axis - (axis @ u) / max(u @ u, 1e-300) * u
        v *= np.linalg.norm(u) / max(np.linalg.norm(v), 1e-300)
        side = max(1, round(math.sqrt(self.n_seeds)))
        return Rake("plane", self.a, _round(u, decimals), _round(v, decimals), (side, side))


def _round(p, decimals: int) -> tuple[float, float, float]:
    return tuple(round(float(x), decimals) + 0.0 for x in p)  # + 0.0: no "-0.0" in specs


# -- screen ---------------------------------------------------------------------------------
def project(setup, size, pts) -> tuple[np.ndarray, np.ndarray]:
    """Scene pixels (n, 2) (y down) of world points (n, 3), and whether each is in front of
    the eye."""
    w, h = size
    pts = np.atleast_2d(np.asarray(pts, float))
    clip = (setup.proj @ setup.view @ np.c_[pts, np.ones(len(pts))].T).T
    front = clip[:, 3] > 1e-12
    wc = np.where(front, clip[:, 3], 1.0)
    xy = np.c_[(clip[:, 0] / wc + 1) / 2 * w, (1 - clip[:, 1] / wc) / 2 * h]
    return xy, front


def drag_point(setup, p, dx: float, dy: float) -> np.ndarray:
    """World point ``p`` moved by a drag of (dx, dy) pixels (y down) in the plane through it
    parallel to the screen: it stays under the mouse."""
    p = np.asarray(p, float)
    depth = -(p @ setup.view[2, :3] + setup.view[2, 3])
    px = setup.px_scale[0] * max(depth, 0.0) + setup.px_scale[1]
    return p + px * (dx * setup.view[0, :3] - dy * setup.view[1, :3])


def handle_at(rake: Rake, setup, size, x: float, y: float, radius: float = GRAB_PX) -> str | None:
    """The handle within ``radius`` pixels of scene pixel (x, y), the nearest; None if none."""
    h = rake.handles()
    xy, front = project(setup, size, np.array(list(h.values())))
    d = np.hypot(xy[:, 0] - x, xy[:, 1] - y)
    d[~front] = np.inf
    i = int(np.argmin(d))
    return list(h)[i] if d[i] <= radius else None


def rake_image(rake: Rake, setup, size, active: str | None = None, scale: float = 1.0):
    """The rake drawn for the overlay: its outline, its seeds as dots, its handles as rings
    (``active``, the one grabbed or under the cursor, filled); (RGBA image, (x, y) of its top
    left in scene pixels), or None when the rake is behind the eye."""
    k = 2  # drawn at twice the size, reduced: smooth edges
    handles = rake.handles()
    shape, f1 = project(setup, size, rake.outline())
    hxy, f2 = project(setup, size, np.array(list(handles.values())))
    if not (f1.all() and f2.all()):
        return None
    seeds = rake.seeds()
    sxy, f3 = project(setup, size, seeds) if len(seeds) <= 20000 else (np.zeros((0, 2)), [])
    sxy = sxy[np.asarray(f3, bool)] if len(sxy) else sxy
    r = 6.0 * scale
    pad = r + 4 * scale
    allxy = np.r_[shape, hxy]
    x0, y0 = np.floor(allxy.min(axis=0) - pad)
    x1, y1 = np.ceil(allxy.max(axis=0) + pad)
    w, h = size
    x0, y0 = max(x0, -pad), max(y0, -pad)  # nothing drawn far outside the scene
    x1, y1 = min(x1, w + pad), min(y1, h + pad)
    if x1 <= x0 or y1 <= y0:
        return None
    img = Image.new("RGBa", (int(x1 - x0) * k, int(y1 - y0) * k), (0, 0, 0, 0))
    d = ImageDraw.Draw(img)

    def at(p):
        return ((p[0] - x0) * k, (p[1] - y0) * k)

    pts = [at(p) for p in shape]
    for width, color in ((4, (0, 0, 0)), (2, RAKE_COLOR)):
        d.line(pts, fill=(*color, 255), width=int(width * scale * k), joint="curve")
    dot = 1.6 * scale * k
    for p in sxy:
        cx, cy = at(p)
        d.ellipse([cx - dot, cy - dot, cx + dot, cy + dot], fill=(*RAKE_COLOR, 255),
                  outline=(0, 0, 0, 255))
    for name, p in zip(handles, hxy):
        cx, cy = at(p)
        rr = r * k * (0.75 if name in ("middle", "centre") else 1.0)
        color = ACTIVE_COLOR if name == active else RAKE_COLOR
        d.ellipse([cx - rr, cy - rr, cx + rr, cy + rr], fill=(*color, 255) if name == active
                  else (0, 0, 0, 160), outline=(*color, 255), width=int(2 * scale * k))
    image = np.asarray(img.reduce(k).convert("RGBA"))
    return image, (int(x0), int(y0))
