"""The Rosenbrock-W stepper of the step loop: ROS34PW2 and any method of its kind, for stiff stretches.

Rang & Angermann's ROS34PW2 (BIT 45, 2005): 4 stages, order 3 with an embedded order-2
solution, L-stable (R(∞) = 0), a W-method (order 3 kept with an inexact Jacobian).  A step solves
its stages' 3x3 linear systems with the same matrix W = I − hγJ:

    W k_i = h f(y0 + Σ_j α_ij k_j) + h J Σ_j γ_ij k_j,   y1 = y0 + Σ b_i k_i,
    err = Σ (b_i − b̂_i) k_i   (RMS norm over x, y, z with atol + rtol |y|, as the explicit step).

J is the exact velocity gradient of the trilinear polynomial of the cell the step starts in
(``stiffness.cell_jacobian``; projected, (I − ûûᵀ) J / |u|, for the arc-length parameter).
The dependent parameter (arc length in time mode, time in arc-length mode) is the 4th ODE
component, linearised with its exact gradient (the 4x4 W is block triangular, so still one
3x3 inverse per step).  Dense output: cubic Hermite of (y0, f0, y1, f1), order 3 like the method.

The step loop (``kernel._advance_lines``, its ``ros`` argument) runs this stepper cell-aware,
ending every step on a face, with the explicit stepper's controller (its β = 0 form, an
I-controller with the exponent 1 / (min(order, err_order) + 1)), events, limits and reasons.
Per line it counts the accepted steps with h ρ(J) above ``stiffness.HLAMBDA_STIFF`` (steps an
explicit DP5 step of that size would be unstable for; ρ bounded by the row-sum norm).
"""

from __future__ import annotations

import math

import numpy as np

from ..jit import inline
from .cell import _fc, _norm3
from .schema import O_ATOL, O_RTOL
from .stiffness import cell_jacobian

DENSE_DEGREE = 3  # the cubic Hermite dense output


def table(method) -> np.ndarray:
    """A RosenbrockMethod's coefficients as the step loop takes them, one array (arrays inside
    a tuple cannot be handed on without NRT): row i < s holds α_i (s columns), Γ_i with its
    diagonal γ (s), b_i and b̂_i; row s holds the controller's exponent base min(order,
    err_order) + 1."""
    s = method.b.size
    R = np.zeros((s + 1, 2 * s + 2))
    R[:s, :s] = method.alpha
    R[:s, s:2 * s] = method.gammas + method.gamma * np.eye(s)
    R[:s, 2 * s], R[:s, 2 * s + 1] = method.b, method.bhat
    R[s, 0] = min(method.order, method.err_order) + 1
    return R


@inline
def _rhs_jac(px, py, pz, param, coef, cf, J, g, u):
    """Jacobian of the right-hand side at p (time or arc-length form) into J (3x3) and the
    gradient of the dependent parameter's rate into g; u holds the raw velocity."""
    cell_jacobian(coef, cf, px, py, pz, J)
    tx = (px - cf[0]) * cf[6]
    ty = (py - cf[1]) * cf[7]
    tz = (pz - cf[2]) * cf[8]
    for c in range(3):
        u[c] = coef[0, c] + tx * (coef[1, c] + ty * (coef[4, c] + tz * coef[7, c]) + tz * coef[5, c]) \
            + ty * (coef[2, c] + tz * coef[6, c]) + tz * coef[3, c]
    sp = _norm3(u[0], u[1], u[2])
    # g = ∇|u| = Jᵀ û
    for j in range(3):
        g[j] = (J[0, j] * u[0] + J[1, j] * u[1] + J[2, j] * u[2]) / sp
    if param == 1:  # f = û: ∂f = (J − û gᵀ) / |u|; dt/ds = 1/|u|: gradient −g / |u|²
        for i in range(3):
            for j in range(3):
                J[i, j] = (J[i, j] - u[i] / sp * g[j]) / sp
        for j in range(3):
            g[j] = -g[j] / (sp * sp)


@inline
def _inv3(M, Mi):
    """Inverse of a 3x3 matrix by cofactors; False when singular or not finite."""
    c00 = M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1]
    c01 = M[1, 2] * M[2, 0] - M[1, 0] * M[2, 2]
    c02 = M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]
    det = M[0, 0] * c00 + M[0, 1] * c01 + M[0, 2] * c02
    if det == 0.0 or not math.isfinite(det):
        return False
    r = 1.0 / det
    Mi[0, 0] = c00 * r
    Mi[1, 0] = c01 * r
    Mi[2, 0] = c02 * r
    Mi[0, 1] = (M[0, 2] * M[2, 1] - M[0, 1] * M[2, 2]) * r
    Mi[1, 1] = (M[0, 0] * M[2, 2] - M[0, 2] * M[2, 0]) * r
    Mi[2, 1] = (M[0, 1] * M[2, 0] - M[0, 0] * M[2, 1]) * r
    Mi[0, 2] = (M[0, 1] * M[1, 2] - M[0, 2] * M[1, 1]) * r
    Mi[1, 2] = (M[0, 2] * M[1, 0] - M[0, 0] * M[1, 2]) * r
    Mi[2, 2] = (M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]) * r
    return True


@inline
def step(y, hs, param, cf, coef, R, fo, k, kk, J, g, u, W, Wi, yt, rhs, y1):
    """One step of the table R's method (``table``) from y over hs, in the cell (cf, coef): the
    stage increments into kk, y1 (position and dependent parameter), f(y1) into k[s] and the
    Jacobian at y into J; the error norm, and whether everything came out finite."""
    ns = R.shape[0] - 1
    gamma = R[0, ns]
    _rhs_jac(y[0], y[1], y[2], param, coef, cf, J, g, u)
    for i in range(3):
        for j in range(3):
            W[i, j] = (1.0 if i == j else 0.0) - hs * gamma * J[i, j]
    finite = _inv3(W, Wi)
    for st in range(ns):
        if not finite:
            break
        if st > 0:
            for a in range(3):
                acc = 0.0
                for m in range(st):
                    acc += R[st, m] * kk[m, a]
                yt[a] = y[a] + acc
            _fc(yt[0], yt[1], yt[2], param, cf, coef, k, st)
        for a in range(4):  # h f(Y_i) + h J Σ γ_ij k_j (J extended by g as its 4th row)
            acc = 0.0
            for m in range(st):
                if a < 3:
                    acc += R[st, ns + m] * (J[a, 0] * kk[m, 0] + J[a, 1] * kk[m, 1]
                                            + J[a, 2] * kk[m, 2])
                else:
                    acc += R[st, ns + m] * (g[0] * kk[m, 0] + g[1] * kk[m, 1] + g[2] * kk[m, 2])
            rhs[a] = hs * (k[st, a] + acc)
        for a in range(3):
            kk[st, a] = Wi[a, 0] * rhs[0] + Wi[a, 1] * rhs[1] + Wi[a, 2] * rhs[2]
        kk[st, 3] = rhs[3] + hs * gamma * (g[0] * kk[st, 0] + g[1] * kk[st, 1] + g[2] * kk[st, 2])
        for a in range(4):
            if not math.isfinite(kk[st, a]):
                finite = False
    err = 0.0
    if finite:
        for a in range(4):
            acc = 0.0
            ea = 0.0
            for m in range(ns):
                acc += R[m, 2 * ns] * kk[m, a]
                ea += (R[m, 2 * ns] - R[m, 2 * ns + 1]) * kk[m, a]
            y1[a] = y[a] + acc
            if a < 3:
                sc = fo[O_ATOL + a] + fo[O_RTOL + a] * max(abs(y[a]), abs(y1[a]))
                err += (ea / sc) ** 2
        err = math.sqrt(err / 3.0)
        finite = math.isfinite(err)
    if finite:  # f(y1): the next step's f0 and the Hermite end slope
        _fc(y1[0], y1[1], y1[2], param, cf, coef, k, np.int64(ns))
        finite = math.isfinite(k[ns, 0] + k[ns, 1] + k[ns, 2] + k[ns, 3])
    return err, finite


@inline
def hermite(y, y1, k, hs, ns, qd):
    """The step's cubic Hermite dense output (from y, f(y) = k[0], y1, f(y1) = k[ns]) as
    coefficients qd[a, 0:3] of θ, in the explicit stepper's form (``kernel._dense``)."""
    for a in range(4):
        dl = (y1[a] - y[a]) / hs
        qd[a, 0] = k[0, a]
        qd[a, 1] = 3.0 * dl - 2.0 * k[0, a] - k[ns, a]
        qd[a, 2] = -2.0 * dl + k[0, a] + k[ns, a]


@inline
def initial_step(cf, sp, param):
    """A tenth of the time to cross the cell at the seed's speed (of its width, arc length)."""
    wmin = min(1.0 / cf[6], 1.0 / cf[7], 1.0 / cf[8])
    return 0.1 * wmin / sp if (param == 0 and sp > 0.0) else 0.1 * wmin
