"""The field between two snapshots: the evaluator the step loop uses for pathlines.

The velocity between snapshots at times t0 < t1 is interpolated linearly in time,
``v(x, t) = (1 - a) v0(x) + a v1(x)`` with ``a = (t - t0) / (t1 - t0)``, and trilinearly in space
(``fields.interp``).  Each stage looks its cell up again: the two snapshots' corners are not
gathered into one cell polynomial, because the blend changes with every stage's time.

Read brick by brick (``bk`` not empty, ``fields/bricks.py``), ``v0`` and ``v1`` are the two
snapshots' pools, one table for both: a brick is resident in both or in neither, in the same
slot.  A cell with a corner in a brick that is not resident puts the brick's number in ci[3]
(the step loop suspends the line, which waits for it) and gives no value.
"""

from __future__ import annotations

import math

import numpy as np

from ..fields.bricks import B_NODES, B_SIZE, axis_bricks, missing_brick, slot_of
from ..fields.interp import corner, finite_or_nan, locate_axis, trilinear_vector
from ..jit import helper, inline, kernel


@inline
def _axis(c, period, inv, x):
    """Cell and local coordinate of x on one axis; beyond a bounded end the end cell's
    polynomial is extended (local coordinate outside [0, 1]) so stages just outside stay smooth."""
    n = c.size
    # one inlined locate_axis, not one per branch (each copy costs compilation); period is
    # 0.0 on a bounded axis
    xc = x if period > 0.0 else min(max(x, c[0]), c[n - 1])
    i, t = locate_axis(c, period, inv, xc)
    if xc != x:
        t = (x - c[i]) / (c[i + 1] - c[i])
    return i, t


@helper
def _trilinear_bricks(vec, bk, i, j, k, tx, ty, tz):
    """``interp.trilinear_vector`` of cell (i, j, k) with its corners read from their bricks'
    slots (all resident), in the same order with the same weights: the same value.  Called,
    not inlined: compiled once for both snapshots."""
    # each axis' two nodes as (brick, index in it)
    bx0, i0, bx1, i1 = axis_bricks(bk[B_SIZE], bk[B_NODES], i)
    by0, j0, by1, j1 = axis_bricks(bk[B_SIZE + 1], bk[B_NODES + 1], j)
    bz0, k0, bz1, k1 = axis_bricks(bk[B_SIZE + 2], bk[B_NODES + 2], k)
    size = bk[B_SIZE]
    out0 = 0.0
    out1 = 0.0
    out2 = 0.0
    for c in range(8):
        ii, jj, kk, w = corner(c, i0, j0, k0, i1, j1, k1, tx, ty, tz)
        if w != 0.0:
            r = slot_of(bk, bx1 if c & 1 else bx0, by1 if c & 2 else by0,
                        bz1 if c & 4 else bz0) * size + ii
            out0 += w * vec[r, jj, kk, 0]
            out1 += w * vec[r, jj, kk, 1]
            out2 += w * vec[r, jj, kk, 2]
    return finite_or_nan(out0, out1, out2)


@kernel()
def velocity(x, y, z, t, gx, gy, gz, period, inv, v0, v1, bk, t0, t1, k, row, ci):
    """(1 - a) v0 + a v1 at (x, y, z) into k[row, 0:3] and the speed into k[row, 3];
    False for NaN data or a NaN position (k[row] untouched), or a brick that is not resident
    (its number into ci[3])."""
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        return False
    i, tx = _axis(gx, period[0], inv[0], x)
    j, ty = _axis(gy, period[1], inv[1], y)
    m, tz = _axis(gz, period[2], inv[2], z)
    if bk.size == 0:
        u0, w0, s0, bad0 = trilinear_vector(v0, i, j, m, tx, ty, tz)
        u1, w1, s1, bad1 = trilinear_vector(v1, i, j, m, tx, ty, tz)
    else:
        missing = missing_brick(bk, i, j, m)
        if missing >= 0:
            ci[3] = missing
            return False
        u0, w0, s0, bad0 = _trilinear_bricks(v0, bk, i, j, m, tx, ty, tz)
        u1, w1, s1, bad1 = _trilinear_bricks(v1, bk, i, j, m, tx, ty, tz)
    a = (t - t0) / (t1 - t0)
    if bad0 or bad1:
        return False
    u = (1.0 - a) * u0 + a * u1
    v = (1.0 - a) * w0 + a * w1
    w = (1.0 - a) * s0 + a * s1
    k[row, 0] = u
    k[row, 1] = v
    k[row, 2] = w
    k[row, 3] = math.sqrt(u * u + v * v + w * w)
    return True


@inline
def stage(p, t, gx, gy, gz, period, inv, v0, v1, bk, tp, k, row, ci):
    """A stage's velocity at the point p and time t into k[row] (v0 at tp[0], v1 at tp[1]); NaN
    data or a missing brick leaves a NaN in it (the step's end is then not finite: it is tried
    again shorter, or, for the brick, the line waits)."""
    if not velocity(p[0], p[1], p[2], t, gx, gy, gz, period, inv, v0, v1, bk, tp[0], tp[1], k,
                    row, ci):
        k[row, 0] = np.nan
