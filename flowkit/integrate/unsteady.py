"""The field between two snapshots: the evaluator the step loop uses for pathlines.

The velocity between snapshots at times t0 < t1 is interpolated linearly in time,
``v(x, t) = (1 - a) v0(x) + a v1(x)`` with ``a = (t - t0) / (t1 - t0)``, and trilinearly in space
(``fields.interp``).  Each stage looks its cell up again: the two snapshots' corners are not
gathered into one cell polynomial, because the blend changes with every stage's time.
"""

from __future__ import annotations

import math

import numpy as np

from ..fields.interp import locate_axis, trilinear_vector
from ..jit import inline, kernel


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


@kernel()
def velocity(x, y, z, t, gx, gy, gz, period, inv, v0, v1, t0, t1, k, row):
    """(1 - a) v0 + a v1 at (x, y, z) into k[row, 0:3] and the speed into k[row, 3];
    False for NaN data or a NaN position (k[row] untouched)."""
    if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
        return False
    i, tx = _axis(gx, period[0], inv[0], x)
    j, ty = _axis(gy, period[1], inv[1], y)
    m, tz = _axis(gz, period[2], inv[2], z)
    a = (t - t0) / (t1 - t0)
    u0, w0, s0, bad0 = trilinear_vector(v0, i, j, m, tx, ty, tz)
    u1, w1, s1, bad1 = trilinear_vector(v1, i, j, m, tx, ty, tz)
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
def stage(p, t, gx, gy, gz, period, inv, v0, v1, tp, k, row):
    """A stage's velocity at the point p and time t into k[row] (v0 at tp[0], v1 at tp[1]); NaN
    data leaves a NaN in it (the step's end is then not finite: it is tried again shorter)."""
    if not velocity(p[0], p[1], p[2], t, gx, gy, gz, period, inv, v0, v1, tp[0], tp[1], k, row):
        k[row, 0] = np.nan
