"""The field inside one cell: its trilinear polynomial, evaluated as the step loop's right-hand side.

``kernel._gather`` writes a cell's 8 corner values as the coefficients of its trilinear
polynomial (``coef``) and ``cf`` holds the cell's faces and inverse widths; the explicit and the
Rosenbrock steppers evaluate the field through ``_fc``.
"""

from __future__ import annotations

import math

from ..jit import inline

NORM_TINY, NORM_HUGE = 1e-150, 1e150  # _norm3 rescales a norm outside (squares over/underflow)


@inline
def _norm3(u, v, w):
    """|(u, v, w)|: the plain formula, rescaled by the largest component only where the squares
    would overflow or underflow (so normal speeds stay bit-identical to the OpenCL kernel's)."""
    sp = math.sqrt(u * u + v * v + w * w)
    if not (sp > NORM_TINY and sp < NORM_HUGE):
        m = max(abs(u), abs(v), abs(w))
        if m > 0.0 and m < math.inf:
            a, b, c = u / m, v / m, w / m
            sp = m * math.sqrt(a * a + b * b + c * c)
    return sp


@inline
def _fc(px, py, pz, param, cf, coef, k, row):
    """Right-hand side from the current cell's polynomial into k[row, 0:4]; returns |v|."""
    tx = (px - cf[0]) * cf[6]
    ty = (py - cf[1]) * cf[7]
    tz = (pz - cf[2]) * cf[8]
    u = coef[0, 0] + tx * (coef[1, 0] + ty * (coef[4, 0] + tz * coef[7, 0]) + tz * coef[5, 0]) \
        + ty * (coef[2, 0] + tz * coef[6, 0]) + tz * coef[3, 0]
    v = coef[0, 1] + tx * (coef[1, 1] + ty * (coef[4, 1] + tz * coef[7, 1]) + tz * coef[5, 1]) \
        + ty * (coef[2, 1] + tz * coef[6, 1]) + tz * coef[3, 1]
    w = coef[0, 2] + tx * (coef[1, 2] + ty * (coef[4, 2] + tz * coef[7, 2]) + tz * coef[5, 2]) \
        + ty * (coef[2, 2] + tz * coef[6, 2]) + tz * coef[3, 2]
    sp = _norm3(u, v, w)
    if param == 0:
        k[row, 0] = u
        k[row, 1] = v
        k[row, 2] = w
        k[row, 3] = sp
    else:
        r = 1.0 / sp
        k[row, 0] = u * r
        k[row, 1] = v * r
        k[row, 2] = w * r
        k[row, 3] = r
    return sp
