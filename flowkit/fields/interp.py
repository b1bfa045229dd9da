"""Trilinear interpolation on uniform/rectilinear grids, as numba functions.

The scalar functions (``locate_axis``, ``locate``, ``trilinear_vector``, ``trilinear_scalar``) are
meant to be called from other numba kernels; ``sample`` (``sample_vectors``, ``sample_scalars``) is
the vectorised entry point, called from Python.  Grid arguments are ``Grid.kernel_args()``:
``(x, y, z, period[3], inv_spacing[3])`` with ``inv_spacing`` all zero for rectilinear grids.

Status codes of a sample: INSIDE, OUTSIDE (never extrapolated), NAN_CELL (a corner is NaN).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ..jit import inline, prefetch
from ..threads import run_ranges

INSIDE = 0
OUTSIDE = 1
NAN_CELL = 2


@inline
def locate_axis(c, period, inv, x):
    """Cell index i and local coordinate t in [0, 1] of x on one axis; i = -1 when outside.

    For a periodic axis the cell with index n-1 (when it exists) is the wrap cell whose upper
    node is node 0; callers take the upper node as (i + 1) % n.
    """
    n = c.size
    c0 = c[0]
    if period > 0.0:
        x = c0 + (x - c0) % period
        if x > c[n - 1]:
            # wrap cell, or rounding of x0 + L when the period equals the span
            w = c0 + period - c[n - 1]
            if w <= 0.0:
                return n - 2, 1.0
            t = (x - c[n - 1]) / w
            return n - 1, min(t, 1.0)
    elif not (x >= c0 and x <= c[n - 1]):  # also false for NaN
        return -1, 0.0
    if inv > 0.0:
        i = int((x - c0) * inv)
        if i > n - 2:
            i = n - 2
        elif i < 0:
            i = 0
        # rounding of (x - c0) * inv may land one cell off; fix with the true coordinates
        if x < c[i]:
            i -= 1
        elif x > c[i + 1] and i < n - 2:
            i += 1
    else:
        # bisection for the first node above x (np.searchsorted's side="right", NaN last), by
        # hand: numba's generic searchsorted costs a second of compilation on a fresh machine
        lo, hi = 0, n
        while lo < hi:
            mid = (lo + hi) >> 1
            if x < c[mid]:
                hi = mid
            else:
                lo = mid + 1
        i = lo - 1
        if i > n - 2:
            i = n - 2
        elif i < 0:
            i = 0
    t = (x - c[i]) / (c[i + 1] - c[i])
    return i, min(max(t, 0.0), 1.0)


@inline
def guess_cell(c, period, inv, x):
    """Cell index of x on a uniform axis by one multiply (clamped; -1 for a non-uniform axis):
    only to choose what to prefetch, so an index one off near a face does no harm."""
    if inv <= 0.0 or not (abs(x) < 1e300):
        return -1
    n = c.size
    r = (x - c[0]) * inv
    if period > 0.0:
        r = r % (n if c[0] + period - c[n - 1] > 0.0 else n - 1)
    return min(max(int(r), 0), n - 2)


@inline
def prefetch_cell(a, nc, gx, gy, gz, period, inv, px, py, pz, last):
    """Prefetch the corners of the cell holding (px, py, pz) on a uniform grid from ``a``, nc
    values per node (C order: the field's vectors, nc = 3, or a scalar, nc = 1), unless it is
    ``last`` (flat index of the cell's first corner, returned): the cache lines a later read
    of that cell touches, fetched while other work runs instead of in its dependent chain."""
    i = guess_cell(gx, period[0], inv[0], px)
    j = guess_cell(gy, period[1], inv[1], py)
    k = guess_cell(gz, period[2], inv[2], pz)
    if i < 0 or j < 0 or k < 0:
        return last
    base = ((i * gy.size + j) * gz.size + k) * nc
    if base != last:
        prefetch_corners(a, nc, gx.size, gy.size, gz.size, i, j, k)
    return base


@inline
def prefetch_corners(a, nc, nx, ny, nz, i, j, k):
    """Prefetch the corners of cell (i, j, k) (node 0 after the last on a wrapped axis) from
    ``a``, nc values per node; no integer division: the tracing kernel runs this every stage."""
    base = ((i * ny + j) * nz + k) * nc
    di = (ny * nz * nc) if i + 1 < nx else -i * ny * nz * nc
    dj = (nz * nc) if j + 1 < ny else -j * nz * nc
    dk = 2 * nc - 1 if k + 1 < nz else nc - 1 - nc * k  # last value of the (k + 1) corner
    for b in (base, base + di, base + dj, base + di + dj):
        prefetch(a, b)
        prefetch(a, b + dk)


@inline
def locate_axis_near(c, period, inv, x, hint):
    """``locate_axis``, on a bounded non-uniform axis trying the cell ``hint`` and its two
    neighbours before the bisection (a line's next vertex is mostly in its last one's cell or
    beside it): the same cell, since a cell whose nodes bracket x is the one the bisection
    finds.  (Apart from locate_axis, which the tracing kernel compiles, to keep it small.)"""
    if period == 0.0 and inv <= 0.0 and hint >= 0:
        for i in (hint, hint + 1, hint - 1):
            if 0 <= i < c.size - 1 and c[i] <= x < c[i + 1]:
                return i, min(max((x - c[i]) / (c[i + 1] - c[i]), 0.0), 1.0)
    return locate_axis(c, period, inv, x)


@inline
def locate(gx, gy, gz, period, inv, px, py, pz):
    """(i, j, k, tx, ty, tz, inside) of a point."""
    none = np.int64(-1)
    return locate_near(gx, gy, gz, period, inv, px, py, pz, none, none, none)


@inline
def locate_near(gx, gy, gz, period, inv, px, py, pz, hi, hj, hk):
    """``locate``, trying the cell (hi, hj, hk) and its neighbours first on non-uniform axes
    (``locate_axis_near``): the samplers pass the last point's, as a line's vertices come."""
    i, tx = locate_axis_near(gx, period[0], inv[0], px, hi)
    j, ty = locate_axis_near(gy, period[1], inv[1], py, hj)
    k, tz = locate_axis_near(gz, period[2], inv[2], pz, hk)
    ok = i >= 0 and j >= 0 and k >= 0
    return i, j, k, tx, ty, tz, ok


@inline
def trilinear_vector(vec, i, j, k, tx, ty, tz):
    """Trilinear vector at local coords of cell (i, j, k); returns (u, v, w, has_nan)."""
    nx, ny, nz = vec.shape[0], vec.shape[1], vec.shape[2]
    i1, j1, k1 = upper(i, nx), upper(j, ny), upper(k, nz)
    out0 = 0.0
    out1 = 0.0
    out2 = 0.0
    for c in range(8):
        ii, jj, kk, w = corner(c, i, j, k, i1, j1, k1, tx, ty, tz)
        if w != 0.0:  # on a face, edge or node the corners off it do not count, NaN or not
            out0 += w * vec[ii, jj, kk, 0]
            out1 += w * vec[ii, jj, kk, 1]
            out2 += w * vec[ii, jj, kk, 2]
    return finite_or_nan(out0, out1, out2)


@inline
def upper(i, n):
    """The upper node of cell i on an axis of n nodes: i + 1, or node 0 for a periodic axis's
    wrap cell (i = n - 1).  Not (i + 1) % n: Python's modulo is an integer division and a sign
    fix, a quarter of a sample's time."""
    return i + 1 if i + 1 < n else i + 1 - n


@inline
def corner(c, i, j, k, i1, j1, k1, tx, ty, tz):
    """Corner c (bit 0: x, 1: y, 2: z upper) of the cell (i, j, k) whose upper nodes are i1, j1,
    k1: its node and its trilinear weight at the local coordinates."""
    ii = i1 if c & 1 else i
    jj = j1 if c & 2 else j
    kk = k1 if c & 4 else k
    w = (tx if c & 1 else 1.0 - tx) * (ty if c & 2 else 1.0 - ty) * (tz if c & 4 else 1.0 - tz)
    return ii, jj, kk, w


@inline
def finite_or_nan(out0, out1, out2):
    """(u, v, w, has_nan): a NaN corner that counts poisons the sum; say so."""
    if not (np.isfinite(out0) and np.isfinite(out1) and np.isfinite(out2)):
        return np.nan, np.nan, np.nan, True
    return out0, out1, out2, False


@inline
def trilinear_scalar(arr, i, j, k, tx, ty, tz):
    """Trilinear scalar at local coords of cell (i, j, k); returns (value, has_nan)."""
    nx, ny, nz = arr.shape[0], arr.shape[1], arr.shape[2]
    i1, j1, k1 = upper(i, nx), upper(j, ny), upper(k, nz)
    out = 0.0
    for c in range(8):
        ii, jj, kk, w = corner(c, i, j, k, i1, j1, k1, tx, ty, tz)
        if w != 0.0:
            out += w * arr[ii, jj, kk]
    if not np.isfinite(out):
        return np.nan, True
    return out, False


# How many points ahead the samplers prefetch a point's cell: its corners' memory latency then
# overlaps the points between (in a prototype, 8 ran 2.1-2.3x faster than none on ABC 193^3 and
# 385^3; 4 and 16 gained less)
AHEAD = 8


# The vectorised sampler: a nogil loop over a range of points, run on ranges by Python threads
# (threads.py, as the tracing kernel is) instead of a prange loop, whose parallel
# gufunc cost seconds of compilation on every fresh machine.  One kernel samples a vector, a
# scalar or both (the attributes speed and T: each point located once), so one compiles.
@njit(cache=True, nogil=True)
def _sample_range(start, stop, gx, gy, gz, period, inv, vec, arr, pts, out, out_s, status):
    with_vec, with_arr = vec.shape[0] > 0, arr.shape[0] > 0
    one, three = np.int64(1), np.int64(3)
    # the scalar as nodes of one value, so that prefetch_corners compiles for 4-D arrays only
    arr4 = arr.reshape((arr.shape[0], arr.shape[1], arr.shape[2], 1))
    # each point is located AHEAD points before it is sampled, its cell's corners prefetched
    # then: cells and local coordinates wait in a ring of AHEAD slots
    cell, loc = np.empty((AHEAD, 4), np.int64), np.empty((AHEAD, 3))
    i = j = k = np.int64(-1)  # the last point located: the next one's first guess
    nx, ny, nz = gx.size, gy.size, gz.size
    for m in range(start, stop + AHEAD):
        n, r = m - AHEAD, (m - start) % AHEAD  # point n leaves the slot point m takes
        ci, cj, ck, ok = cell[r, 0], cell[r, 1], cell[r, 2], cell[r, 3] != 0
        sx, sy, sz = loc[r, 0], loc[r, 1], loc[r, 2]
        if m < stop:  # locate point m into the slot, and ask for its cell
            i, j, k, tx, ty, tz, okm = locate_near(gx, gy, gz, period, inv, pts[m, 0],
                                                   pts[m, 1], pts[m, 2], i, j, k)
            cell[r, 0], cell[r, 1], cell[r, 2], cell[r, 3] = i, j, k, okm
            loc[r, 0], loc[r, 1], loc[r, 2] = tx, ty, tz
            if okm and with_vec:
                prefetch_corners(vec, three, nx, ny, nz, i, j, k)
            if okm and with_arr:
                prefetch_corners(arr4, one, nx, ny, nz, i, j, k)
        if n < start:
            continue
        if not ok:
            if with_vec:
                out[n, 0] = np.nan
                out[n, 1] = np.nan
                out[n, 2] = np.nan
            if with_arr:
                out_s[n] = np.nan
            status[n] = OUTSIDE
            continue
        bad = False
        if with_vec:
            u, v, w, bad = trilinear_vector(vec, ci, cj, ck, sx, sy, sz)
            out[n, 0] = u
            out[n, 1] = v
            out[n, 2] = w
        if with_arr:
            val, bad_s = trilinear_scalar(arr, ci, cj, ck, sx, sy, sz)
            out_s[n] = val
            bad = bad or bad_s
        status[n] = NAN_CELL if bad else INSIDE


# "not sampled": empty arrays of the kernel's argument types, of the type of the array that is
# sampled (one signature for every use on a field of one type)
_NO_VEC = {np.dtype(t): np.zeros((0, 1, 1, 3), t) for t in (np.float32, np.float64)}
_NO_ARR = {np.dtype(t): np.zeros((0, 1, 1), t) for t in (np.float32, np.float64)}
_NO_OUT, _NO_OUT_S = np.zeros((0, 3)), np.zeros(0)


def sample(gx, gy, gz, period, inv, vec, arr, pts, out, out_s, status):
    """Trilinear vectors of ``vec`` (nx, ny, nz, 3) into ``out`` (n, 3) and values of ``arr``
    (nx, ny, nz) into ``out_s`` (n,) at ``pts`` (n, 3), each point located once, and
    ``status`` (n,) int8: INSIDE, OUTSIDE (NaN) or NAN_CELL (a NaN corner counts, for either:
    that one NaN)."""
    run_ranges(_sample_range, pts.shape[0], gx, gy, gz, period, inv, vec, arr, pts, out, out_s,
               status)


def sample_vectors(gx, gy, gz, period, inv, vec, pts, out, status):
    """``sample`` of a vector alone."""
    sample(gx, gy, gz, period, inv, vec, _NO_ARR[vec.dtype], pts, out, _NO_OUT_S, status)


def sample_scalars(gx, gy, gz, period, inv, arr, pts, out, status):
    """``sample`` of a scalar alone."""
    sample(gx, gy, gz, period, inv, _NO_VEC[arr.dtype], arr, pts, _NO_OUT, out, status)
