"""The curl of a field's vectors: at the nodes, and trilinearly at any points.

At a node, each derivative is np.gradient's: second order on the node coordinates, one-sided at
bounded ends, wrapped on periodic axes (:func:`gradient`); where that stencil meets non-finite
data, the first all-finite one-sided stencil of :func:`fallback_stencils`, so that only the
non-finite nodes themselves get a NaN curl.  The numba kernel applies per-node tables made by
:func:`axis_table` with np.gradient's own formulas and order of operations, so its values are
np.gradient's, bit for bit (tests/test_integrate_attributes.py).  :func:`vorticity_at` computes
the node curl only at the corners of the cells the points lie in, then samples it as the field
is sampled: its cost follows the points, not the grid (the whole grid's curl at 193^3 nodes
took about a second).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..jit import inline, prefetch
from ..threads import run_ranges
from . import interp
from .bricks import by_bricks, cell_nodes, read_whole, zeroed

# -- the derivative along one axis, as np.gradient forms it --------------------------------


def gradient(f: np.ndarray, c: np.ndarray, period: float, axis: int) -> np.ndarray:
    """np.gradient along ``axis`` on the node coordinates ``c``: second order, one-sided at
    bounded ends, wrapped on a periodic axis (NaN wherever its stencil meets NaN)."""
    n = c.size
    if period > 0 and n >= 3:
        # wrap: neighbours across the period join the stencil
        lo_i, hi_i = _seam(c, period)
        lo_c = c[lo_i] - period
        hi_c = c[hi_i] + period
        ext_c = np.concatenate([[lo_c], c, [hi_c]])
        ext_f = np.concatenate([np.take(f, [lo_i], axis), f, np.take(f, [hi_i], axis)], axis=axis)
        return np.take(np.gradient(ext_f, ext_c, axis=axis, edge_order=2), np.arange(1, n + 1), axis)
    return np.gradient(f, c, axis=axis, edge_order=2 if n >= 3 else 1)


# nodes a node's derivative may read on either side of it: a one-sided fallback stencil 2, one
# more across a seam whose last node repeats the first
CURL_REACH = 3

# a node's derivative: WEIGHTS  w0 f[i0] + w1 f[i1] + w2 f[i2]  (in that order), or
# QUOTIENT  (f[i1] - f[i0]) / w0  (np.gradient's form on uniform spacing and for two nodes)
WEIGHTS, QUOTIENT = 0, 1


def axis_table(c: np.ndarray, period: float = 0.0):
    """How :func:`gradient` forms the derivative at each node of an axis: (mode (n,) int8,
    nodes (n, 3) int64, w (n, 3)), np.gradient's formulas and coefficients for these
    coordinates (its uniform-spacing test included) on :func:`gradient`'s periodic extension."""
    n = c.size
    if period > 0 and n >= 3:
        lo, hi = _seam(c, period)
        ext = np.concatenate([[lo], np.arange(n), [hi]])
        mode, nodes, w = _np_gradient_table(np.concatenate([[c[lo] - period], c, [c[hi] + period]]), 2)
        return mode[1:n + 1], ext[nodes[1:n + 1]], w[1:n + 1]
    return _np_gradient_table(c, 2 if n >= 3 else 1)


def _np_gradient_table(c: np.ndarray, edge_order: int):
    n = c.size
    mode = np.full(n, WEIGHTS, np.int8)
    nodes = np.zeros((n, 3), np.int64)
    w = np.zeros((n, 3))
    dx = np.diff(c)
    uniform = bool((dx == dx[0]).all())
    i = np.arange(1, n - 1)
    if uniform:
        h = dx[0]
        mode[1:-1] = QUOTIENT
        nodes[1:-1, 0], nodes[1:-1, 1] = i - 1, i + 1
        w[1:-1, 0] = 2.0 * h
    else:
        dx1, dx2 = dx[0:-1], dx[1:]
        nodes[1:-1] = np.stack([i - 1, i, i + 1], axis=1)
        w[1:-1, 0] = -(dx2) / (dx1 * (dx1 + dx2))
        w[1:-1, 1] = (dx2 - dx1) / (dx1 * dx2)
        w[1:-1, 2] = dx1 / (dx2 * (dx1 + dx2))
    if edge_order == 1:
        mode[0] = mode[n - 1] = QUOTIENT
        nodes[0, :2] = 0, 1
        nodes[n - 1, :2] = n - 2, n - 1
        w[0, 0] = dx[0]
        w[n - 1, 0] = dx[-1]
        return mode, nodes, w
    nodes[0] = 0, 1, 2
    nodes[n - 1] = n - 3, n - 2, n - 1
    if uniform:
        w[0] = -1.5 / h, 2.0 / h, -0.5 / h
        w[n - 1] = 0.5 / h, -2.0 / h, 1.5 / h
    else:
        dx1, dx2 = dx[0], dx[1]
        w[0] = (-(2.0 * dx1 + dx2) / (dx1 * (dx1 + dx2)), (dx1 + dx2) / (dx1 * dx2),
                -dx1 / (dx2 * (dx1 + dx2)))
        dx1, dx2 = dx[-2], dx[-1]
        w[n - 1] = ((dx2) / (dx1 * (dx1 + dx2)), -(dx2 + dx1) / (dx1 * dx2),
                    (2.0 * dx2 + dx1) / (dx2 * (dx1 + dx2)))
    return mode, nodes, w


def fallback_stencils(c: np.ndarray, period: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The one-sided differences tried, in order, at a node whose standard stencil (:func:
    `gradient`) meets non-finite data: 3-point forward, 3-point backward (second order on the
    node coordinates), 2-point forward, 2-point backward.  Returns (nodes (n, 4, 3) int32, -1
    unused or unavailable; weights (n, 4, 3)) for the node coordinates ``c``.  On a periodic
    axis (``period`` > 0) the stencils wrap across the seam with :func:`gradient`'s neighbours
    (a last node that repeats the first is skipped); on a bounded one they stay inside.  The
    OpenCL kernel applies the same table (opencl/vertex.py)."""
    n = c.size
    if period > 0 and n >= 3:
        lo, hi = _seam(c, period)  # two neighbours beyond each end (gradient's wrap takes one)
        ext = np.r_[lo - 1, lo, np.arange(n), hi, hi + 1]
        ext_c = np.r_[c[[lo - 1, lo]] - period, c, c[[hi, hi + 1]] + period]
        nodes, w = _one_sided(ext_c)
        nodes, w = nodes[2:n + 2], w[2:n + 2]
        return np.where(nodes >= 0, ext[np.maximum(nodes, 0)], -1).astype(np.int32), w
    return _one_sided(c)


def _one_sided(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = c.size
    nodes = np.full((n, 4, 3), -1, np.int32)
    w = np.zeros((n, 4, 3))
    i = np.arange(n)
    # 3-point forward at i from i, i+1, i+2 (derivative of the quadratic through them)
    f3 = i[: max(n - 2, 0)]
    h1, h2 = c[f3 + 1] - c[f3], c[f3 + 2] - c[f3 + 1]
    nodes[f3, 0] = np.stack([f3, f3 + 1, f3 + 2], axis=1)
    w[f3, 0] = np.stack([-(2 * h1 + h2) / (h1 * (h1 + h2)), (h1 + h2) / (h1 * h2),
                         -h1 / (h2 * (h1 + h2))], axis=1)
    # 3-point backward at i from i, i-1, i-2
    b3 = i[2:]
    h1, h2 = c[b3] - c[b3 - 1], c[b3 - 1] - c[b3 - 2]
    nodes[b3, 1] = np.stack([b3, b3 - 1, b3 - 2], axis=1)
    w[b3, 1] = np.stack([(2 * h1 + h2) / (h1 * (h1 + h2)), -(h1 + h2) / (h1 * h2),
                         h1 / (h2 * (h1 + h2))], axis=1)
    f2 = i[: max(n - 1, 0)]
    h = c[f2 + 1] - c[f2]
    nodes[f2, 2, :2] = np.stack([f2, f2 + 1], axis=1)
    w[f2, 2, :2] = np.stack([-1.0 / h, 1.0 / h], axis=1)
    b2 = i[1:]
    h = c[b2] - c[b2 - 1]
    nodes[b2, 3, :2] = np.stack([b2, b2 - 1], axis=1)
    w[b2, 3, :2] = np.stack([1.0 / h, -1.0 / h], axis=1)
    return nodes, w


def _seam(c: np.ndarray, period: float) -> tuple[int, int]:
    """The nodes beside the seam of a periodic axis: (the one below node 0, the one above the
    last), skipping a last node that repeats the first."""
    n = c.size
    return (n - 1, 0) if c[0] + period - c[-1] > 0 else (n - 2, 1)


def _tables(grid):
    """The three axes' tables, one row per node of each axis (x rows, then y, then z)."""
    parts = [axis_table(grid.axes[a], float(grid.period[a])) for a in range(3)]
    fb = [fallback_stencils(grid.axes[a], float(grid.period[a])) for a in range(3)]
    cat = [np.ascontiguousarray(np.concatenate([p[m] for p in parts])) for m in range(3)]
    fbn = np.ascontiguousarray(np.concatenate([p[0] for p in fb]).astype(np.int64))
    fbw = np.ascontiguousarray(np.concatenate([p[1] for p in fb]))
    off = np.array([0, grid.axes[0].size, grid.axes[0].size + grid.axes[1].size], np.int64)
    return (*cat, fbn, fbw, off)


# -- the node curl, compiled ------------------------------------------------------------


@inline
def _at(vec, axis, i, j, k, m, comp):
    """vec at node (i, j, k) with its index along ``axis`` replaced by m, as float64 (a
    float32 field's curl is then its float64 copy's)."""
    if axis == 0:
        return np.float64(vec[m, j, k, comp])
    if axis == 1:
        return np.float64(vec[i, m, k, comp])
    return np.float64(vec[i, j, m, comp])


@inline
def _derivative(vec, comp, axis, i, j, k, mode, nodes, w, fbn, fbw, off):
    """d vec[..., comp] / dx_axis at node (i, j, k), as :func:`gradient` and its fallbacks."""
    r = off[axis] + (i if axis == 0 else (j if axis == 1 else k))
    f0 = _at(vec, axis, i, j, k, nodes[r, 0], comp)
    f1 = _at(vec, axis, i, j, k, nodes[r, 1], comp)
    if mode[r] == QUOTIENT:
        if np.isfinite(f0) and np.isfinite(f1):
            return (f1 - f0) / w[r, 0]
    else:
        f2 = _at(vec, axis, i, j, k, nodes[r, 2], comp)
        if np.isfinite(f0) and np.isfinite(f1) and np.isfinite(f2):
            return w[r, 0] * f0 + w[r, 1] * f1 + w[r, 2] * f2
    # the stencil meets non-finite data: the first one-sided stencil whose values are finite
    for cand in range(4):
        if fbn[r, cand, 0] < 0:
            continue
        acc = 0.0  # (summed from 0.0: a -0.0 first product gives +0.0, not -0.0)
        ok = True
        for slot in range(3):
            q = fbn[r, cand, slot]
            v = _at(vec, axis, i, j, k, q, comp) if q >= 0 else 0.0
            ok = ok and np.isfinite(v)
            acc += fbw[r, cand, slot] * v
        if ok:
            return acc
    return np.nan


AHEAD_NODES = 16  # how far ahead the node curl prefetches neighbours


@njit(cache=True, nogil=True)
def _curl_range(start, stop, ids, vec, mode, nodes, w, fbn, fbw, off, out):
    """The curl at nodes ids[start:stop] (flat node indices; ids empty: the nodes start..stop
    themselves) into the rows start..stop of out (n, 3)."""
    ny, nz = vec.shape[1], vec.shape[2]
    x, y, z = np.int64(0), np.int64(1), np.int64(2)  # typed: a literal compiles a copy per value
    for n in range(start, stop):
        if ids.size and n + AHEAD_NODES < stop:  # a marked node further on: its x and y
            p = ids[n + AHEAD_NODES] * 3          # neighbours (hints: off the array is harmless)
            for dn in (-ny * nz * 3, ny * nz * 3, -nz * 3, nz * 3):
                prefetch(vec, p + dn)
        q = ids[n] if ids.size else n
        i, j, k = q // (ny * nz), (q // nz) % ny, q % nz
        out[n, 0] = (_derivative(vec, z, y, i, j, k, mode, nodes, w, fbn, fbw, off)
                     - _derivative(vec, y, z, i, j, k, mode, nodes, w, fbn, fbw, off))
        out[n, 1] = (_derivative(vec, x, z, i, j, k, mode, nodes, w, fbn, fbw, off)
                     - _derivative(vec, z, x, i, j, k, mode, nodes, w, fbn, fbw, off))
        out[n, 2] = (_derivative(vec, y, x, i, j, k, mode, nodes, w, fbn, fbw, off)
                     - _derivative(vec, x, y, i, j, k, mode, nodes, w, fbn, fbw, off))


@njit(cache=True, nogil=True)
def _mark_range(start, stop, gx, gy, gz, period, inv, pts, mark):
    """mark[i, j, k] = 1 at the 8 corners of the cell of every point start..stop (the cell the
    samplers locate; threads may write the same 1 to the same byte)."""
    nx, ny, nz = mark.shape
    i = j = k = np.int64(-1)  # the last point's cell
    for n in range(start, stop):
        i, j, k, _, _, _, ok = interp.locate_near(gx, gy, gz, period, inv, pts[n, 0], pts[n, 1],
                                                  pts[n, 2], i, j, k)
        if ok:
            i1, j1, k1 = interp.upper(i, nx), interp.upper(j, ny), interp.upper(k, nz)
            for c in range(8):
                mark[i1 if c & 1 else i, j1 if c & 2 else j, k1 if c & 4 else k] = 1


@njit(cache=True, nogil=True)
def _rank(words, ids, base, first, stop):
    """The marked nodes' flat indices into ids, in order, and base[b] = how many are marked
    before node 8b (``words``: the marks, 8 bytes of 0 or 1 to a word, all of them in words
    first..stop-1); returns their count.
    Node q's row among them is then ``_row``: a word of unmarked nodes costs one test.  base is
    written only at words with a mark, the only ones ``_row`` reads: zeroed by the allocator, a
    grid-sized base then takes memory where the points are, not a byte per node."""
    count = 0
    for b in range(first, stop):
        wd = words[b]
        if wd:
            base[b] = count
            for byte in range(8):
                if (wd >> np.uint64(8 * byte)) & np.uint64(1):
                    ids[count] = 8 * b + byte
                    count += 1
    return count


@inline
def _row(words, base, q):
    """The row of marked node q in ``_rank``'s order: the marks before it in its word, summed
    by one multiply (bytes of 0 or 1 add up to at most 8, so no byte carries)."""
    b = q >> 3
    below = words[b] & ((np.uint64(1) << np.uint64(8 * (q & 7))) - np.uint64(1))
    return base[b] + np.int64((below * np.uint64(0x0101010101010101)) >> np.uint64(56))


@inline
def _corner_nodes(shape, i, j, k):
    """The flat index of cell (i, j, k)'s first corner and the offsets of its upper corners
    along x and y (node 0 after the last on a wrapped axis)."""
    ny, nz = shape[1], shape[2]
    di = ny * nz if i + 1 < shape[0] else -i * ny * nz
    dj = nz if j + 1 < ny else -j * nz
    return (i * ny + j) * nz + k, di, dj


@inline
def _prefetch_counts(words, base, shape, i, j, k):
    q, di, dj = _corner_nodes(shape, i, j, k)
    for c in (q, q + di, q + dj, q + di + dj):
        prefetch(words, c >> 3)
        prefetch(base, c >> 3)


@njit(cache=True, nogil=True)
def _sample_rows(start, stop, gx, gy, gz, period, inv, shape, words, base, rows, pts, out):
    """``interp.sample_vectors`` of a node field held only at the marked nodes, as ``rows``
    (``_rank``'s order): the same sums, so the same values, NaN outside or where a corner that
    counts is NaN.  A point is located 2 AHEAD points before it is sampled (its cell's counts
    prefetched then), its corners' rows found and prefetched AHEAD points before; cells, local
    coordinates and rows wait in a ring of 2 AHEAD slots."""
    nx, ny, nz = shape[0], shape[1], shape[2]
    A, R = interp.AHEAD, 2 * interp.AHEAD
    cell, loc = np.empty((R, 4), np.int64), np.empty((R, 3))
    corner_rows = np.empty((R, 8), np.int64)
    i = j = k = np.int64(-1)  # the last point located: the next one's first guess
    for m in range(start, stop + R):
        n, r, rp = m - R, (m - start) % R, (m - A - start) % R
        ok = cell[r, 3] != 0
        ci, cj, ck = cell[r, 0], cell[r, 1], cell[r, 2]
        tx, ty, tz = loc[r, 0], loc[r, 1], loc[r, 2]
        if start <= m - A < stop and cell[rp, 3] != 0:  # point m - A: its counts are in
            pi, pj, pk = cell[rp, 0], cell[rp, 1], cell[rp, 2]
            i1, j1, k1 = interp.upper(pi, nx), interp.upper(pj, ny), interp.upper(pk, nz)
            for c in range(8):
                ii, jj, kk, _ = interp.corner(c, pi, pj, pk, i1, j1, k1, 0.0, 0.0, 0.0)
                q = _row(words, base, (ii * ny + jj) * nz + kk)
                corner_rows[rp, c] = q
                prefetch(rows, 3 * q)
        if m < stop:
            i, j, k, sx, sy, sz, okm = interp.locate_near(gx, gy, gz, period, inv, pts[m, 0],
                                                          pts[m, 1], pts[m, 2], i, j, k)
            cell[r, 0], cell[r, 1], cell[r, 2], cell[r, 3] = i, j, k, okm
            loc[r, 0], loc[r, 1], loc[r, 2] = sx, sy, sz
            if okm:
                _prefetch_counts(words, base, shape, i, j, k)
        if n < start:
            continue
        o0 = o1 = o2 = np.nan
        if ok:
            i1, j1, k1 = interp.upper(ci, nx), interp.upper(cj, ny), interp.upper(ck, nz)
            o0 = o1 = o2 = 0.0
            for c in range(8):
                _, _, _, w = interp.corner(c, ci, cj, ck, i1, j1, k1, tx, ty, tz)
                if w != 0.0:
                    q = corner_rows[r, c]
                    o0 += w * rows[q, 0]
                    o1 += w * rows[q, 1]
                    o2 += w * rows[q, 2]
            o0, o1, o2, _ = interp.finite_or_nan(o0, o1, o2)
        out[n, 0], out[n, 1], out[n, 2] = o0, o1, o2


def curl(field) -> np.ndarray:
    """Curl of the node vector field at every node, (nx, ny, nz, 3)."""
    vec = field.vector
    out = np.empty((int(np.prod(vec.shape[:3])), 3))
    run_ranges(_curl_range, out.shape[0], np.empty(0, np.int64), vec, *_tables(field.grid), out)
    return out.reshape(vec.shape)


def vorticity_at(field, points) -> np.ndarray:
    """The curl at ``points`` (N, 3): the node curl at the corners of their cells only, sampled
    trilinearly as the field is (NaN outside or in a cell whose corners that count are NaN).

    Its memory follows the points, not the grid: a byte per node marks the corners and a word
    per 8 nodes counts them (a marked node's rank among all of them is its row), zeroed pages
    of their own (numpy advises huge pages for a large array: a mark would take 2 MiB) touched
    only where the points are, counted only over the x planes the points span; the curl is
    kept at the marked nodes only.  (A grid-sized curl array, even written only at those nodes,
    cost a page fault for every 4 KiB page they touched: a third of the time.)  A large field
    not in memory is read near the points only (``bricks.by_bricks``)."""
    pts = np.ascontiguousarray(points, dtype=np.float64)
    if not read_whole(field):
        got = by_bricks(field, pts, lambda f, p: {"w": vorticity_at(f, p)}, halo=CURL_REACH)
        return got.get("w", np.empty((0, 3)))
    g = field.grid
    vec = field.vector
    shape = np.array(vec.shape[:3], np.int64)
    n_nodes = int(np.prod(shape))
    words = zeroed((n_nodes + 7) // 8, np.uint64)  # the marks, padded to whole words
    mark = words.view(np.uint8)[:n_nodes].reshape(vec.shape[:3])
    run_ranges(_mark_range, pts.shape[0], *g.kernel_args(), pts, mark)
    ids = np.empty(min(n_nodes, 8 * pts.shape[0]), np.int64)
    base = zeroed(words.size, np.int64)
    # the x planes the marks lie on (a cell's upper corners one further, or plane 0 on a wrapped
    # axis): the words to count
    i = cell_nodes(g, pts)[:, 0] if pts.shape[0] else np.zeros(1, np.int64)
    lo, hi = max(int(i.min()) - 1, 0), min(int(i.max()) + 2, int(shape[0]))
    if g.periodic[0] and hi >= shape[0] - 1:
        lo = 0
    plane = int(shape[1] * shape[2])
    ids = ids[:_rank(words, ids, base, lo * plane // 8, min(-(-hi * plane // 8), words.size))]
    rows = np.empty((ids.size, 3))
    if ids.size:
        run_ranges(_curl_range, ids.size, ids, vec, *_tables(g), rows)
    out = np.empty((pts.shape[0], 3))
    run_ranges(_sample_rows, pts.shape[0], *g.kernel_args(), shape, words, base, rows, pts, out)
    return out
