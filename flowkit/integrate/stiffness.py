"""Stiffness: the exact Jacobian of a cell's trilinear polynomial, and Hairer & Wanner's test.

A streamline ODE is stiff where the velocity gradient has an eigenvalue λ with Re λ << 0 whose
mode has already decayed: an explicit method's step is then held at |hλ| ≈ 3.3 (DP5's
stability boundary on the negative axis) by stability, not by accuracy.

*Detection* (Hairer & Wanner, Solving ODEs II, IV.2; the ``dopri5`` code's test): the last two
DP5 stages are both evaluated at c = 1, at ``y_s`` (stage 6) and at ``y1`` (stage 7, FSAL), so

    |hλ| ≈ h ‖k7 − k6‖ / ‖y1 − y_s‖

estimates the dominant eigenvalue along the stage difference at no extra cost.  A line is
flagged stiff after ``STIFF_STEPS`` (15) consecutive accepted steps with hλ > ``HLAMBDA_STIFF``
(3.25); ``NONSTIFF_RESET`` (6) steps below it reset the count.  ``stiff_update`` keeps the counts
and the (sticky) flag in one int, made for the kernel's reserved state column ``I_STIFF``.

*Jacobian*: within a cell the interpolant is u(t) = c0 + c1 tx + c2 ty + c3 tz + c4 tx ty
+ c5 tx tz + c6 ty tz + c7 tx ty tz with t = (x − lo) / width (the kernel's ``coef``/``cf``
layout), so ∂u/∂x = (c1 + c4 ty + c5 tz + c7 ty tz) / wx, and likewise for y and z: exact and
cheap; the Rosenbrock driver (``rosenbrock.py``) uses it.
"""

from __future__ import annotations

import math

from numba import njit

HLAMBDA_STIFF = 3.25  # DP5's stability interval on the negative real axis is about 3.3
STIFF_STEPS = 15
NONSTIFF_RESET = 6
# the state: the stiff count in bits 0-7, the non-stiff count in bits 8-15, the flag in bit 16
# (named: the OpenCL template renders them)
STIFF_COUNT_BITS = 8
STIFF_COUNT_MAX = (1 << STIFF_COUNT_BITS) - 1
STIFF_BIT = 1 << (2 * STIFF_COUNT_BITS)


@njit(cache=True)
def cell_jacobian(coef, cf, px, py, pz, J):
    """J[i, j] = ∂u_i/∂x_j of the cell polynomial (``coef`` (8, 3), ``cf`` faces and inverse
    widths as in the kernel) at (px, py, pz); valid beyond the faces too (the extension)."""
    tx = (px - cf[0]) * cf[6]
    ty = (py - cf[1]) * cf[7]
    tz = (pz - cf[2]) * cf[8]
    for c in range(3):
        J[c, 0] = (coef[1, c] + ty * coef[4, c] + tz * coef[5, c] + ty * tz * coef[7, c]) * cf[6]
        J[c, 1] = (coef[2, c] + tx * coef[4, c] + tz * coef[6, c] + tx * tz * coef[7, c]) * cf[7]
        J[c, 2] = (coef[3, c] + tx * coef[5, c] + ty * coef[6, c] + tx * ty * coef[7, c]) * cf[8]


@njit(cache=True)
def stage_hlambda(h, k, last, stage, ys, y1):
    """|hλ| from two evaluations at the step's end: h ‖k[last] − k[stage]‖ / ‖y1 − ys‖ over the
    position (``k`` rows are stages; ``last`` is f(y1)'s row, ``stage`` the method's stiffness
    stage, at c = 1, evaluated at ``ys``; DP5: 6 and 5).  0 when the two points coincide (no
    information)."""
    num = 0.0
    den = 0.0
    for a in range(3):
        num += (k[last, a] - k[stage, a]) ** 2
        den += (y1[a] - ys[a]) ** 2
    return hlambda(h, num, den)


@njit(cache=True)
def hlambda(h, num, den):
    """|hλ| = h sqrt(num / den) from the squared norms of the stage difference (num) and of
    the points' difference (den); the lock-step sums them itself (lanes.py)."""
    if den <= 0.0 or not math.isfinite(num):
        return 0.0
    return abs(h) * math.sqrt(num / den)


@njit(cache=True)
def stiff_update(state, hlam):
    """The stiffness state after one accepted step with estimate ``hlam``."""
    flag = state & STIFF_BIT
    n_stiff = state & STIFF_COUNT_MAX
    n_non = (state >> STIFF_COUNT_BITS) & STIFF_COUNT_MAX
    if hlam > HLAMBDA_STIFF:
        n_non = 0
        n_stiff = min(n_stiff + 1, STIFF_COUNT_MAX)
        if n_stiff >= STIFF_STEPS:
            flag = STIFF_BIT
    else:
        n_non = min(n_non + 1, STIFF_COUNT_MAX)
        if n_non >= NONSTIFF_RESET:
            n_stiff = 0
    return flag | (n_non << STIFF_COUNT_BITS) | n_stiff


@njit(cache=True)
def is_stiff(state):
    """True once the line has met STIFF_STEPS consecutive stiff steps."""
    return (state & STIFF_BIT) != 0


@njit(cache=True)
def spectral_radius_bound(J):
    """max_i Σ_j |J[i, j]| (≥ the spectral radius): a cheap a-priori stiffness scale 1/time."""
    r = 0.0
    for i in range(3):
        r = max(r, abs(J[i, 0]) + abs(J[i, 1]) + abs(J[i, 2]))
    return r
