"""Unstructured mesh data onto a grid, by cell location: each grid node is found in the mesh
element that contains it and interpolated with that element's shape functions (``mesh.py``).

A node in no element (inside an obstacle, or outside the mesh) is NaN, so walls stay walls:
a line traced through the grid ends where its cell meets a NaN node.

How nodes are found: the grid's x planes are the buckets.  Each element's bounding box gives
the range of grid nodes it can hold on each axis; an element is listed under every x plane its
box spans, and each plane's nodes are tested only against that plane's elements, inside the
box's y and z ranges, by inverting the element's map (Newton's method; one step for a
tetrahedron).  A node held by two elements (on a shared face, to rounding) takes the first
element in mesh order.  Planes are shared among threads (``threads.run_ranges``), each node
written by one thread only.

The grid: given (``shape`` / ``spacing`` / a Grid), or chosen from the mesh (:func:`auto_grid`):
the spacing of its fine cells (the 10th percentile of the cells' sizes) over the mesh's bounds,
coarsened to stay under ``AUTO_MAX_NODES``.
"""

from __future__ import annotations

import math
import threading

import numpy as np

from ..jit import inline, kernel
from ..threads import run_ranges
from .grid import Grid
from .mesh import Elements, Mesh, MeshError, centre, elements, map_point, n_nodes, shape
from .stored import Source

INSIDE_TOL = 1e-7  # parametric tolerance: nodes on a face, to rounding, are inside
NEWTON_STEPS = 30
NEWTON_TOL = 1e-13
AUTO_MAX_NODES = 4_000_000  # an automatic grid's node count at most (the memory cap)
AUTO_PERCENTILE = 10


def parse_resample(spec):
    """``resample=`` as given: None, a Grid, (nx, ny, nz), "NX,NY,NZ", "spacing:DX" or "auto"
    -> None, a Grid, ("shape", (nx, ny, nz)), ("spacing", dx) or ("auto", None)."""
    if spec is None or isinstance(spec, Grid):
        return spec
    if isinstance(spec, str):
        text = spec.strip()
        if text == "auto":
            return ("auto", None)
        if text.startswith("spacing:"):
            try:
                dx = float(text.split(":", 1)[1])
            except ValueError:
                dx = math.nan
            if not (dx > 0 and math.isfinite(dx)):
                raise ValueError(f"resample {spec!r}: spacing:DX needs a positive number")
            return ("spacing", dx)
        parts = text.split(",")
    else:
        parts = list(spec) if np.ndim(spec) == 1 else [spec]
    try:
        shape_ = tuple(int(p) for p in parts)
    except (TypeError, ValueError):
        shape_ = ()
    if len(shape_) != 3 or min(shape_) < 2:
        raise ValueError(f"resample {spec!r}: expected NX,NY,NZ (3 integers >= 2), "
                         "spacing:DX or auto")
    return ("shape", shape_)


def auto_grid(mesh: Mesh, bounds, spec) -> tuple[Grid, str]:
    """The grid for ``spec`` (parse_resample's answer) over ``bounds`` (3, 2), and how it was
    chosen."""
    lo, hi = bounds[:, 0], bounds[:, 1]
    span = hi - lo
    kind, value = spec
    if kind == "shape":
        return Grid.regular(lo, span / (np.array(value) - 1), value), "as asked"
    if kind == "spacing":
        h, why = value, f"spacing {value:g} as asked"
    else:
        h = float(np.percentile(mesh.cell_sizes(), AUTO_PERCENTILE))
        why = f"spacing {h:.4g}: the {AUTO_PERCENTILE}th percentile of the cells' sizes"

    def dims(h):
        return np.maximum(np.round(span / h).astype(np.int64), 1) + 1

    if kind == "auto":
        h0 = h
        while np.prod(dims(h)) > AUTO_MAX_NODES:
            h *= 1.02
        if h > h0:
            why += (f", coarsened to {h:.4g} to stay under {AUTO_MAX_NODES:,} nodes "
                    "(resample=NX,NY,NZ or spacing:DX to choose)")
    n = dims(h)
    return Grid.regular(lo, span / (n - 1), n), why


def locate(el: Elements, grid: Grid) -> tuple[np.ndarray, np.ndarray]:
    """(element holding each grid node, -1 for none; its parametric coordinates (r, s, t)),
    shaped (nx, ny, nz) and (nx, ny, nz, 3)."""
    lo, hi = el.lo, el.hi
    pad = 1e-9 * max(float(np.max(np.abs(el.points))), 1e-300)
    rng = np.empty((el.kind.size, 6), np.int64)
    for a, c in enumerate(grid.axes):
        rng[:, 2 * a] = np.searchsorted(c, lo[:, a] - pad, "left")
        rng[:, 2 * a + 1] = np.searchsorted(c, hi[:, a] + pad, "right") - 1
    # each x plane's elements, in element order (a bucket per plane)
    nx = grid.shape[0]
    width = np.maximum(rng[:, 1] - rng[:, 0] + 1, 0)
    width[(rng[:, 3] < rng[:, 2]) | (rng[:, 5] < rng[:, 4])] = 0
    count = np.zeros(nx + 1, np.int64)
    _plane_counts(rng, width, count)
    ptr = np.concatenate([[0], np.cumsum(count[:nx])])
    lists = np.empty(int(ptr[-1]), np.int64)
    _plane_fill(rng, width, ptr.copy(), lists)
    owner = np.full(grid.shape, -1, np.int64)
    rst = np.full(grid.shape + (3,), np.nan)
    run_ranges(_locate, nx, ptr, lists, rng, grid.x, grid.y, grid.z, el.conn, el.kind,
               el.affine.view(np.int8), el.points, owner, rst)
    return owner, rst


class Location:
    """The grid's nodes located in a mesh's cells, done once, when the first array is read:
    opening a mesh costs its metadata, so ``flowkit info`` splits and locates nothing.  Then
    the mesh is split into elements (its cells checked: a bad cell is a ``MeshError`` naming
    the file and the cell), each node is found in its element, and the note at
    ``notes[0]`` (the Field's list, set by the reader) is rewritten with how many nodes lie in
    no cell."""

    def __init__(self, mesh: Mesh, grid: Grid, why: str, data: str, where: str):
        self.mesh, self.grid, self.why, self.data, self.where = mesh, grid, why, data, where
        self.notes: list = []
        self.el = self.owner = self.rst = None
        self._lock = threading.Lock()

    def __getstate__(self):  # (a Field travels to workers: the lock stays behind)
        return {k: v for k, v in self.__dict__.items() if k != "_lock"}

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def located(self) -> tuple[Elements, np.ndarray, np.ndarray]:
        """(elements, owner, parametric coordinates): see ``locate``."""
        with self._lock:
            if self.el is None:
                try:
                    el = elements(self.mesh)
                except MeshError as e:
                    raise MeshError(f"{self.where}: {e}") from None
                self.owner, self.rst = locate(el, self.grid)
                self.el = el
                if self.notes:
                    self.notes[0] = self.note()
        return self.el, self.owner, self.rst

    def note(self) -> str:
        """The grid, why, the method, and the nodes in no cell (once located)."""
        mesh, el, grid = self.mesh, self.el, self.grid
        counts = ", ".join(f"{n} {k}" for k, n in mesh.counts().items())
        split = (f" (polyhedra split into {el.n_tets} tetrahedra about face and cell centroids)"
                 if el is not None and el.n_tets else "")
        how = ("each node interpolated by the shape functions of the cell containing it"
               if self.data == "point" else "each node taking the value of the cell containing "
               "it (cell data, constant per cell)")
        n = int(np.prod(grid.shape))
        if el is None:
            found = ("not located yet: cells are split and checked, and nodes found in them, "
                     "when an array is first read (flowkit info --stats); nodes in no cell "
                     "(obstacles, outside the mesh) will be NaN")
        else:
            found = (f"{int((self.owner < 0).sum())} of {n} nodes lie in no cell (obstacles, "
                     "outside the mesh): NaN")
        return (f"resampled from {mesh.n_cells} cells ({counts}){split} onto a "
                f"{' x '.join(map(str, grid.shape))} {grid.kind} grid ({self.why}): {how}; "
                f"{found}")


class Resampled(Source):
    """One mesh array at the grid nodes ``location`` finds, computed a box (a slab of x planes)
    at a time when the Field first reads it (so ``flowkit info`` and a trace that needs only the
    vector pay for nothing else).  Point data (n_mesh_points[, 3]) is interpolated by each
    node's element's shape functions; cell data (n_cells[, 3]) is each node's cell's value.
    NaN in no cell."""

    def __init__(self, location: Location, values, data="point"):
        self.location, self.data = location, data
        self.values, self.extended = np.asarray(values), data == "cell"

    def fill_box(self, out, box):
        el, owner, rst = self.location.located()
        if not self.extended:  # (the centroids' values, once, when first read)
            self.values, self.extended = el.extend(self.values), True
        owner = np.ascontiguousarray(owner[box])
        if self.data == "cell":
            v = self.values[el.cell[np.maximum(owner, 0)]]
            v[owner < 0] = np.nan
        else:
            pv = np.ascontiguousarray(self.values.reshape(self.values.shape[0], -1))
            v = np.empty(owner.shape + (pv.shape[1],))
            run_ranges(_interpolate, owner.shape[0], owner, np.ascontiguousarray(rst[box]),
                       el.conn, el.kind, pv, v)
        out[...] = v.reshape(out.shape)


# -- compiled ----------------------------------------------------------------------------------
@kernel()
def _plane_counts(rng, width, count):
    for e in range(width.size):
        for i in range(rng[e, 0], rng[e, 0] + width[e]):
            count[i] += 1


@kernel()
def _plane_fill(rng, width, at, lists):
    for e in range(width.size):
        for i in range(rng[e, 0], rng[e, 0] + width[e]):
            lists[at[i]] = e
            at[i] += 1


@inline
def _solve(j00, j01, j02, j10, j11, j12, j20, j21, j22, fx, fy, fz):
    """J d = f by Cramer's rule; ok False where J is singular."""
    c0 = j11 * j22 - j12 * j21
    c1 = j10 * j22 - j12 * j20
    c2 = j10 * j21 - j11 * j20
    det = j00 * c0 - j01 * c1 + j02 * c2
    if det == 0.0 or not math.isfinite(det):
        return 0.0, 0.0, 0.0, False
    d0 = (fx * c0 - j01 * (fy * j22 - j12 * fz) + j02 * (fy * j21 - j11 * fz)) / det
    d1 = (j00 * (fy * j22 - j12 * fz) - fx * c1 + j02 * (j10 * fz - fy * j20)) / det
    d2 = (j00 * (j11 * fz - fy * j21) - j01 * (j10 * fz - fy * j20) + fx * c2) / det
    return d0, d1, d2, True


@inline
def _invert(e, k, lin, conn, pts, x, y, z):
    """Parametric (r, s, t) of (x, y, z) in element e of kind k, and whether it lies inside.
    An affine element (``lin``) is x = p0 + J (r, s, t), J's columns its edges from node 0 to
    the nodes at r = 1, s = 1 and t = 1: one solve.  Any other by Newton's method."""
    p0 = conn[e, 0]
    ok = False
    if lin:
        a, b, c = conn[e, 1], conn[e, 3 if k == 12 else 2], conn[e, 4 if k == 12 else 3]
        r, s, t, ok = _solve(
            pts[a, 0] - pts[p0, 0], pts[b, 0] - pts[p0, 0], pts[c, 0] - pts[p0, 0],
            pts[a, 1] - pts[p0, 1], pts[b, 1] - pts[p0, 1], pts[c, 1] - pts[p0, 1],
            pts[a, 2] - pts[p0, 2], pts[b, 2] - pts[p0, 2], pts[c, 2] - pts[p0, 2],
            x - pts[p0, 0], y - pts[p0, 1], z - pts[p0, 2])
    else:
        r, s, t = centre(k)
        for _ in range(NEWTON_STEPS):
            px, py, pz, j00, j01, j02, j10, j11, j12, j20, j21, j22 = map_point(k, e, conn, pts,
                                                                                r, s, t)
            fx, fy, fz = px - x, py - y, pz - z
            d0, d1, d2, solved = _solve(j00, j01, j02, j10, j11, j12, j20, j21, j22, fx, fy, fz)
            if not solved:
                break
            r -= d0
            s -= d1
            t -= d2
            if max(abs(d0), abs(d1), abs(d2)) < NEWTON_TOL:
                ok = True
                break
            if max(abs(r), abs(s), abs(t)) > 1e3:  # far outside: no need to converge
                break
    if not ok:
        return r, s, t, False
    lo, hi = -INSIDE_TOL, 1.0 + INSIDE_TOL
    if k == 10:
        inside = r >= lo and s >= lo and t >= lo and r + s + t <= hi
    elif k == 13:
        inside = r >= lo and s >= lo and r + s <= hi and lo <= t <= hi
    else:
        inside = lo <= r <= hi and lo <= s <= hi and lo <= t <= hi
    return r, s, t, inside


# nogil: planes shared among threads (threads.run_ranges); each node is written by one thread
@kernel(nogil=True)
def _locate(start, stop, ptr, lists, rng, gx, gy, gz, conn, kind, lin, pts, owner, rst):
    for i in range(start, stop):
        x = gx[i]
        for q in range(ptr[i], ptr[i + 1]):
            e = lists[q]
            k = kind[e]
            for j in range(rng[e, 2], rng[e, 3] + 1):
                y = gy[j]
                for m in range(rng[e, 4], rng[e, 5] + 1):
                    if owner[i, j, m] >= 0:
                        continue
                    r, s, t, inside = _invert(e, k, lin[e], conn, pts, x, y, gz[m])
                    if inside:
                        owner[i, j, m] = e
                        rst[i, j, m, 0] = r
                        rst[i, j, m, 1] = s
                        rst[i, j, m, 2] = t


@kernel(nogil=True)
def _interpolate(start, stop, owner, rst, conn, kind, v, out):
    nc = v.shape[1]
    for i in range(start, stop):
        for j in range(owner.shape[1]):
            for m in range(owner.shape[2]):
                e = owner[i, j, m]
                for c in range(nc):
                    out[i, j, m, c] = np.nan if e < 0 else 0.0
                if e < 0:
                    continue
                k = kind[e]
                for a in range(n_nodes(k)):
                    n, _, _, _ = shape(k, a, rst[i, j, m, 0], rst[i, j, m, 1], rst[i, j, m, 2])
                    p = conn[e, a]
                    for c in range(nc):
                        out[i, j, m, c] += n * v[p, c]
