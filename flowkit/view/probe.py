"""The probe: the vertex under the cursor (a CPU spatial index) and what the file says about it.

Picking casts the ray through the cursor, asks a k-d tree (``scipy.spatial.cKDTree``, built once
in a background thread) for the vertices in a chain of balls along the part of the ray inside
the lines' bounds, front to back, projects those few and keeps the ones within ``radius`` pixels
of the cursor; of the ones nearest the eye (drawn on top) the nearest to the cursor wins, and
balls behind those are not asked.  Cost: the balls and the candidates, not the number of
vertices (benchmarks/bench_viewer.py times it on 2.5M vertices).
"""

from __future__ import annotations

import itertools
import math
import threading
import time

import numpy as np
from scipy.spatial import cKDTree

from ..integrate.reasons import Reason
from ..lines import Lines, finite_rows

MAX_BALLS = 4000  # along one ray; beyond it the balls grow (more candidates, fewer queries)
CHUNK = 32  # balls queried at a time, front to back


class Picker:
    def __init__(self, points: np.ndarray, start: bool = True):
        """``start``: build the index now (in a thread); False: when first asked for (``ready``
        starts the thread, ``tree`` and ``pick`` wait for it), so that lines replaced before
        any pick (a rake being dragged) cost no index and leave the CPU to drawing."""
        self.points = np.asarray(points, np.float64)
        self._index: np.ndarray | None = None  # tree rows -> vertex numbers
        self._tree: cKDTree | None = None
        self.build_time: float | None = None  # s
        self._thread = threading.Thread(target=self._build, daemon=True)
        self._lock = threading.Lock()
        if start:
            self.start()

    def start(self) -> None:
        """Start building the index (once)."""
        with self._lock:
            if self._thread.ident is None:
                self._finite()
                self._thread.start()

    def _finite(self) -> np.ndarray:
        if self._index is None:
            self._index = np.flatnonzero(finite_rows(self.points))
        return self._index

    def _build(self) -> None:
        t0 = time.perf_counter()
        self._tree = cKDTree(self.points[self._index], balanced_tree=False, compact_nodes=False)
        self.build_time = time.perf_counter() - t0

    @property
    def ready(self) -> bool:
        self.start()
        return self._tree is not None

    @property
    def tree(self) -> cKDTree:
        self.start()
        self._thread.join()
        return self._tree

    def pick(self, setup, size: tuple[int, int], x: float, y: float, bounds: np.ndarray,
             radius: float = 8.0) -> int | None:
        """The vertex within ``radius`` pixels of scene pixel (x, y) (y down) that is drawn
        there: of those nearest the eye (within a pick radius in depth), the nearest on screen.
        ``setup``: the camera's (render.camera.CameraSetup) on an image of ``size``; None when
        no vertex is that close."""
        if self._finite().size == 0:
            return None
        w, h = size
        m = setup.proj @ setup.view
        inv = np.linalg.inv(m)
        ndc = np.array([2 * x / w - 1, 1 - 2 * y / h])
        ends = inv @ np.array([[*ndc, -1.0, 1.0], [*ndc, 1.0, 1.0]]).T
        a, b = (ends[:3] / ends[3]).T
        px_a, px_b = setup.px_scale
        bounds = np.asarray(bounds, float)

        def world_radius(p):  # of ``radius`` pixels at points p, (n, 3)
            depth = -(p @ setup.view[2, :3] + setup.view[2, 3])
            return radius * (px_a * np.maximum(depth, 0.0) + px_b)

        # a vertex on the box's surface is picked by rays passing just outside it too
        pad = 1.5 * float(world_radius(bounds[:, 1][None])[0] + world_radius(bounds[:, 0][None])[0])
        t0, t1 = _clip(a, b - a, bounds, pad)
        if t0 is None:
            return None
        # balls along the ray, spaced by the smallest local pick radius r (at most MAX_BALLS:
        # then farther apart), each of radius 1.12 r (> sqrt(1 + 1/4) r) or the spacing: they
        # cover the cylinder of the pick radius about the ray
        seg = (b - a) * (t1 - t0)
        a = a + t0 * (b - a)
        length = float(np.linalg.norm(seg))
        r_min = float(world_radius(np.array([a, a + seg])).min())
        n = int(min(max(np.ceil(length / max(r_min, 1e-300)), 1), MAX_BALLS)) + 1
        centres = a + np.linspace(0.0, 1.0, n)[:, None] * seg
        radii = np.maximum(1.12 * world_radius(centres), length / (n - 1))
        view_z = setup.view[2, :3]
        # front to back, CHUNK balls at a time: once a vertex is within the pick radius, only
        # the balls up to one pick radius deeper can hold the front layer; the rest is skipped
        # (on a dense ray most candidates lie behind the first hit)
        hits, stop = [], math.inf
        for k in range(0, n, CHUNK):
            c = centres[k:k + CHUNK]
            if -(c[0] @ view_z + setup.view[2, 3]) - radii[k] > stop:
                break
            found = self.tree.query_ball_point(c, radii[k:k + CHUNK], return_sorted=False)
            cand = np.fromiter(itertools.chain.from_iterable(found), np.int64)  # repeats: fine
            if cand.size == 0:
                continue
            vert = self._index[cand]
            p = np.c_[self.points[vert], np.ones(vert.size)] @ m.T
            sx = (p[:, 0] / p[:, 3] + 1) / 2 * w
            sy = (1 - p[:, 1] / p[:, 3]) / 2 * h
            d2 = (sx - x) ** 2 + (sy - y) ** 2
            near = (p[:, 3] > 0) & (d2 <= radius ** 2) & (np.abs(p[:, 2]) <= p[:, 3])
            if near.any():
                vert, d2 = vert[near], d2[near]
                depth = -(self.points[vert] @ view_z + setup.view[2, 3])
                hits.append((vert, d2, depth))
                front = float(depth.min())
                stop = min(stop, front + float(world_radius(self.points[vert[np.argmin(depth)]]
                                                            [None])[0]))
        if not hits:
            return None
        vert, d2, depth = (np.concatenate(z) for z in zip(*hits))
        # the front layer (within a pick radius of the nearest depth), then the nearest there
        front = depth <= stop
        return int(vert[front][np.argmin(d2[front])])


def _clip(origin, direction, bounds, pad: float):
    """Parameter interval of the ray inside the box (slabs), or (None, None)."""
    lo, hi = bounds[:, 0] - pad, bounds[:, 1] + pad
    t0, t1 = 0.0, 1.0
    for k in range(3):
        if abs(direction[k]) < 1e-300:
            if not lo[k] <= origin[k] <= hi[k]:
                return None, None
            continue
        u, v = (lo[k] - origin[k]) / direction[k], (hi[k] - origin[k]) / direction[k]
        t0, t1 = max(t0, min(u, v)), min(t1, max(u, v))
    return (t0, t1) if t0 <= t1 else (None, None)


def _number(v) -> str:
    v = np.asarray(v)
    if v.ndim:
        return "(" + ", ".join(_number(x) for x in v) + ")"
    if v.dtype.kind in "iub":
        return str(int(v))
    return f"{float(v):.6g}"


def _reason(code) -> str:
    try:
        return Reason(int(code)).label
    except ValueError:
        return f"code {int(code)}"


def describe(lines: Lines, vertex: int, units: dict[str, str] | None = None) -> list[str]:
    """The probe's read-out for a vertex: position, line and seed, every point and line
    attribute with its units (where the file gives them), why the line stopped."""
    units = units or {}

    def unit(name):
        u = units.get(name, "")
        return f" {u}" if u and u != "1" else ""

    line = int(np.searchsorted(lines.offsets, vertex, side="right") - 1)
    first = int(lines.offsets[line])
    n = int(lines.offsets[line + 1]) - first
    ld = lines.line_data
    seed = int(ld["seed_id"][line]) if "seed_id" in ld else line
    out = [f"position {_number(lines.points[vertex])}{unit('position')}",
           f"seed {seed}, line {line}, vertex {vertex - first + 1} of {n}"]
    for name, values in lines.point_data.items():
        out.append(f"{name} {_number(values[vertex])}{unit(name)}")
    if "reason" in ld:
        direction = lines.attrs.get("direction", "forward")
        if "reason_backward" in ld:
            out.append(f"stopped: forward {_reason(ld['reason'][line])}, "
                       f"backward {_reason(ld['reason_backward'][line])}")
        else:
            out.append(f"stopped ({direction}): {_reason(ld['reason'][line])}")
    for name, values in ld.items():
        if name not in ("seed_id", "reason", "reason_backward"):
            out.append(f"{name} {_number(values[line])}{unit(name)}")
    return out
