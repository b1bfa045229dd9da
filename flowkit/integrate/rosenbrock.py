"""ROS34PW2: an L-stable linearly implicit (Rosenbrock-W) method for stiff stretches of a field.

Rang & Angermann's ROS34PW2 (BIT 45, 2005): 4 stages, order 3 with an embedded order-2
solution, L-stable (R(∞) = 0), a W-method (order 3 kept with an inexact Jacobian).  A step solves
four 3x3 linear systems with the same matrix W = I − hγJ:

    W k_i = h f(y0 + Σ_j α_ij k_j) + h J Σ_j γ_ij k_j,   y1 = y0 + Σ b_i k_i,
    err = Σ (b_i − b̂_i) k_i   (RMS norm over x, y, z with atol + rtol |y|, as the kernel).

J is the exact velocity gradient of the trilinear polynomial of the cell the step starts in
(``stiffness.cell_jacobian``; projected, (I − ûûᵀ) J / |u|, for the arc-length parameter).
The dependent parameter (arc length in time mode, time in arc-length mode) is the 4th ODE
component, linearised with its exact gradient (the 4x4 W is block triangular, so still one
3x3 inverse per step).  Dense output: cubic Hermite of (y0, f0, y1, f1), order 3 like the method.

The driver reuses the numba kernel's pieces (cell location ``_relocate``, the move onto the next
cell ``_onto_next_cell``/``_through_face``, the cell's exit ``_exit_time``, right-hand side
``_fc``, dense evaluation and event roots ``_dense``/``_root``, the reject rule ``_retry``, vertex
output ``_put``) and its option arrays (``trace.Setup``); it is always cell-aware, and its
termination follows the kernel's rules and reason codes.  The coefficients are the registry
entry's (``methods.RosenbrockMethod``): any number of stages, the error exponent from its
orders.  Its step loop mirrors the kernel's, because the kernel's loop has no hook for
another step formula (docs/precision.md, "What the two loops share").

Per line it also records the stiffness it met: ``stiff_steps`` (accepted steps with
h ρ(J) > 3.25, steps an explicit DP5 step of that size would be unstable for; ρ bounded by the
row-sum norm) and ``stiff`` (the Hairer–Wanner flag: 15 such steps in a row).
"""

from __future__ import annotations

import math

import numpy as np

from ..fields import Field
from ..fields.bricks import NO_BRICKS
from ..jit import inline, kernel
from ..lines import Lines
from ..threads import run_ranges
from . import kernel as K
from .kernel import _dense, _fc, _norm3, _put, _relocate, _root
from .methods import get_method
from .options import TraceOptions
from .schema import I_NACC, I_NREJ, I_REASON, I_STATUS, ROS_INT_STATE
from .stiffness import (
    HLAMBDA_STIFF,
    STIFF_BIT,
    cell_jacobian,
    spectral_radius_bound,
    stiff_update,
)
from .trace import trace

NAME = "ros34pw2"
_M = get_method(NAME)
GAMMA, ALPHA, GAMMAS, B, BHAT = _M.gamma, _M.alpha, _M.gammas, _M.b, _M.bhat
_Q = 3  # Hermite dense output degree
_OVERFLOW = 3  # line status: its output buffer filled; rerun with a larger one
# a line's int row (schema.py): the kernel's leading columns, then its stiffness
NI = ROS_INT_STATE.size
I_STIFF, I_NSTIFF = ROS_INT_STATE["I_STIFF"], ROS_INT_STATE["I_NSTIFF"]


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


# The step and its events are functions of their own, inlined by LLVM (jit.inline): numba types
# and lowers them apart from the line loop, and the second compile process (parallel_compile)
# compiles them during a default trace, so a first Rosenbrock trace compiles a loop of half the
# size.
@inline
def _step(y, hs, param, cf, coef, alpha, gam, b, bhat, fo, k, kk, J, g, u, W, Wi, yt, rhs, y1):
    """One step of the coefficients' method from y over hs, in the cell (cf, coef): the stage
    increments into kk, y1, f(y1) into k[ns] and the Jacobian at y into J; the error norm, and
    whether everything came out finite."""
    ns = b.size
    gamma = gam[0, 0]
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
                    acc += alpha[st, m] * kk[m, a]
                yt[a] = y[a] + acc
            _fc(yt[0], yt[1], yt[2], param, cf, coef, k, st)
        for a in range(4):  # h f(Y_i) + h J Σ γ_ij k_j (J extended by g as its 4th row)
            acc = 0.0
            for m in range(st):
                if a < 3:
                    acc += gam[st, m] * (J[a, 0] * kk[m, 0] + J[a, 1] * kk[m, 1] + J[a, 2] * kk[m, 2])
                else:
                    acc += gam[st, m] * (g[0] * kk[m, 0] + g[1] * kk[m, 1] + g[2] * kk[m, 2])
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
                acc += b[m] * kk[m, a]
                ea += (b[m] - bhat[m]) * kk[m, a]
            y1[a] = y[a] + acc
            if a < 3:
                sc = fo[K.O_ATOL + a] + fo[K.O_RTOL + a] * max(abs(y[a]), abs(y1[a]))
                err += (ea / sc) ** 2
        err = math.sqrt(err / 3.0)
        finite = math.isfinite(err)
    if finite:  # f(y1): the next step's f0 and the Hermite end slope
        _fc(y1[0], y1[1], y1[2], param, cf, coef, k, np.int64(ns))
        finite = math.isfinite(k[ns, 0] + k[ns, 1] + k[ns, 2] + k[ns, 3])
    return err, finite


@inline
def _event(y, y1, k, hs, ns, cf, lim_dep, d, qd, q):
    """The first event of an accepted step from y to y1 on its Hermite dense output (into qd):
    leaving the cell, the dependent limit.  (EV_NONE, 1.0, -1, 0.0), or the event, its θ, and
    for a face its axis and coordinate."""
    need_face = False
    for a in range(3):
        if y1[a] < cf[a] or y1[a] > cf[3 + a]:
            need_face = True
    need_dep = abs(y1[3]) >= lim_dep
    ev = K.EV_NONE
    th = 1.0
    ev_axis = -1
    ev_face = 0.0
    if need_face or need_dep:
        for a in range(4):
            dl = (y1[a] - y[a]) / hs
            qd[a, 0] = k[0, a]
            qd[a, 1] = 3.0 * dl - 2.0 * k[0, a] - k[ns, a]
            qd[a, 2] = -2.0 * dl + k[0, a] + k[ns, a]
    # (one inlined root finder for the three faces and the dependent limit: each copy
    # costs compile time)
    for a in range(4):
        if a < 3:
            up = y1[a] > cf[3 + a]
            if not (up or y1[a] < cf[a]):
                continue
            target, sgn = (cf[3 + a], 1.0) if up else (cf[a], -1.0)
        elif need_dep:
            target, sgn = d * lim_dep, d
        else:
            continue
        tha = _root(qd, a, q, y[a], hs, target, sgn, 1.0)
        if ev == K.EV_NONE or tha < th:
            th = tha
            ev = K.EV_FACE if a < 3 else K.EV_DEPLIM
            if a < 3:
                ev_axis = a
                ev_face = target
    return ev, th, ev_axis, ev_face


# without NRT (no reference counting of the arrays handed to the helpers; nothing allocated
# here: the scratch arrays come from _range)
@kernel(nogil=True)
def _lines(start, stop, seeds, dirs, gx, gy, gz, period, inv, vec, bk, alpha, gam, b, bhat, kexp,
           fo, io, si, out_p, out_par, out_n, k, kk, coef, cf, ci, y, yt, y1, J, W, Wi, g, u, rhs, qd):
    """Trace the lines start..stop-1 one after the other into out_*[l]; their counts and
    stiffness into si[l] (``ROS_INT_STATE``).  ``gam`` is Γ with its diagonal γ; ``kexp`` the
    controller's q + 1.  One function with the loop over the lines inside, without the GIL, so
    that threads run ranges side by side (``threads.run_ranges``): a line function called from a
    range function was compiled, and optimised again inside its caller, twice.  k: f at the
    stages (row 0: f(y0); row ns: f(y1)), kk: the stage increments, qd: the step's Hermite
    dense coefficients, the rest the cell and the linear algebra's."""
    Bcap = out_p.shape[1]
    param = io[K.P_PARAM]
    max_steps = io[K.P_MAXSTEPS]
    safety, facmin, facmax = fo[K.O_SAFETY], fo[K.O_FACMIN], fo[K.O_FACMAX]
    hmin, hmax, cellfac, stag = fo[K.O_HMIN], fo[K.O_HMAX], fo[K.O_CELLFAC], fo[K.O_STAG]
    q = np.int64(_Q)  # the helpers' arguments typed (jit.helper): a literal compiles a copy
    lim_ind = fo[K.O_MAXTIME] if param == 0 else fo[K.O_MAXLEN]
    lim_dep = fo[K.O_MAXLEN] if param == 0 else fo[K.O_MAXTIME]
    r_ind = K.R_MAXTIME if param == 0 else K.R_MAXLEN
    r_dep = K.R_MAXLEN if param == 0 else K.R_MAXTIME
    ns = b.size
    for l in range(start, stop):
        d = dirs[l]
        out_n[l] = 0
        for a in range(3):
            ci[a] = -1
        for i in range(ns):
            for a in range(4):
                kk[i, a] = 0.0
        px, py, pz = seeds[l, 0], seeds[l, 1], seeds[l, 2]
        inside = math.isfinite(px) and math.isfinite(py) and math.isfinite(pz)
        for a in range(3):
            c = gx if a == 0 else (gy if a == 1 else gz)
            if period[a] == 0.0 and not (c[0] <= seeds[l, a] <= c[c.size - 1]):
                inside = False
        sp = np.nan
        if inside:
            _relocate(gx, gy, gz, period, inv, vec, bk, px, py, pz, ci, cf, coef)
            sp = _fc(px, py, pz, param, cf, coef, k, np.int64(0))
        si[l, I_STATUS] = K.DONE
        if not (inside and math.isfinite(sp)):
            si[l, I_REASON] = K.R_SEED
            continue
        y[0], y[1], y[2], y[3] = px, py, pz, 0.0
        tau = 0.0
        n_acc = 0
        n_rej = 0
        last_rej = False
        stiff = np.int64(0)
        n_stiff = 0
        h = fo[K.O_H0]
        if h <= 0.0:  # a tenth of the time to cross the cell at the seed's speed
            wmin = min(1.0 / cf[6], 1.0 / cf[7], 1.0 / cf[8])
            h = 0.1 * wmin / sp if (param == 0 and sp > 0.0) else 0.1 * wmin
        h = d * min(h, hmax)
        _put(out_p, out_par, out_n, l, px, py, pz, 0.0, 0.0)

        reason = -1
        while True:
            if out_n[l] >= Bcap:
                si[l, I_STATUS] = _OVERFLOW  # traced again with room for more vertices
                break
            speed = k[0, 3] if param == 0 else 1.0 / k[0, 3]
            if not (speed >= stag) or speed == 0.0:
                reason = K.R_STAG
                break
            if n_acc + n_rej >= max_steps:
                reason = K.R_MAXSTEPS
                break
            # on a face moving outwards: next cell, or out of the domain
            reason = K._onto_next_cell(d, y, k, param, gx, gy, gz, period, vec, bk, ci, cf, coef)
            if reason >= 0:
                break
            hs = h
            t_exit, _ = K._exit_time(d, y, k, cf)
            cap = cellfac * t_exit
            if cap > 0.0 and abs(hs) > cap:
                hs = d * cap
            hit_lim = False
            rem = lim_ind - abs(tau)
            if abs(hs) >= rem:
                hs = d * rem
                hit_lim = True

            err, finite = _step(y, hs, param, cf, coef, alpha, gam, b, bhat, fo, k, kk, J, g, u, W, Wi,
                                yt, rhs, y1)
            if not finite or err > 1.0:  # NaN data met (a stage, or f(y1)), or an error too large
                n_rej += 1
                last_rej = True
                h, reason = K._retry(hs, err, not finite, hmin, safety, facmin, 1.0 / kexp)
                if reason >= 0:
                    break
                continue
            fac = facmax if err == 0.0 else min(facmax, max(facmin, safety * err ** (-1.0 / kexp)))
            if last_rej:
                fac = min(fac, 1.0)
            hnext = hs * fac
            if fac >= 1.0 and abs(h) > abs(hnext):
                hnext = h  # the step was cut by the cell cap or a limit, not by its error
            last_rej = False
            hlam = abs(hs) * spectral_radius_bound(J)
            stiff = stiff_update(stiff, hlam)
            if hlam > HLAMBDA_STIFF:
                n_stiff += 1

            ev, th, ev_axis, ev_face = _event(y, y1, k, hs, ns, cf, lim_dep, d, qd, q)
            n_acc += 1
            if ev == K.EV_NONE:
                for a in range(4):
                    y[a] = y1[a]
                    k[0, a] = k[ns, a]
                tau = d * lim_ind if hit_lim else tau + hs
            else:
                for a in range(4):
                    y[a] = _dense(qd, a, q, y[a], hs, th)
                if ev == K.EV_DEPLIM:
                    y[3] = d * lim_dep
                tau = tau + th * hs
                hit_lim = False
                if ev == K.EV_FACE:
                    y[ev_axis] = ev_face
                    # typed: numba's SSA form gives ev_axis its literal -1 on one path
                    res = K._through_face(np.int64(ev_axis), ev_face == cf[3 + ev_axis], y, param, gx,
                                          gy, gz, period, vec, bk, ci, cf, coef, k)
                    if res == 1:
                        reason = K.R_OUT
                    elif res == 2:
                        reason = K.R_NAN
                else:
                    reason = r_dep
            if hit_lim:
                reason = r_ind
            h = d * min(abs(hnext), hmax)
            if th * hs != 0.0:
                t_out = tau if param == 0 else y[3]
                s_out = y[3] if param == 0 else tau
                if out_n[l] >= Bcap:
                    si[l, I_STATUS] = _OVERFLOW
                    break
                _put(out_p, out_par, out_n, l, y[0], y[1], y[2], t_out, s_out)
            if reason >= 0:
                break
        if si[l, I_STATUS] == _OVERFLOW:
            continue
        si[l, I_REASON] = reason
        si[l, I_NACC] = n_acc
        si[l, I_NREJ] = n_rej
        si[l, I_STIFF] = stiff
        si[l, I_NSTIFF] = n_stiff


def _range(start, stop, *args):
    """``_lines`` with scratch arrays of its own (one set per range)."""
    ns = args[11].size  # b
    _lines(start, stop, *args, np.empty((ns + 1, 4)), np.empty((ns, 4)), np.empty((8, 3)),
           np.empty(9), np.empty(4, np.int64), np.empty(4), np.empty(3), np.empty(4),
           np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty(3), np.empty(3),
           np.empty(4), np.empty((4, K.QMAX)))


def _advance(seeds, dirs, gx, gy, gz, period, inv, vec, alpha, gam, b, bhat, kexp, fo, io,
             si, out_p, out_par, out_n):
    """Every line, on numba's thread count of Python threads: a prange loop around the line loop
    compiled it twice (its index is int64 where numba types the loop, uint64 where it lowers
    it) and built a parallel gufunc, seconds of compilation on every fresh machine."""
    run_ranges(_range, seeds.shape[0], seeds, dirs, gx, gy, gz, period, inv, vec, NO_BRICKS,
               alpha, gam, b, bhat, kexp, fo, io, si, out_p, out_par, out_n)


def run_tasks(method, setup, seeds, dirs, max_steps):
    """Trace the half-lines (``seeds`` (n, 3), ``dirs`` ±1) by the RosenbrockMethod ``method``
    with the options of ``setup`` (``trace.Setup``); returns (points, t, s, owner, columns) with vertices grouped by task in
    order, as the explicit kernel's passes do, and per-task line_data columns."""
    n = seeds.shape[0]
    arrays = [np.ascontiguousarray(x, np.float64) for x in
              (method.alpha, method.gammas + method.gamma * np.eye(method.b.size), method.b,
               method.bhat)]
    kexp = np.int64(min(method.order, method.err_order) + 1)
    si = np.zeros((n, NI), np.int64)
    cap = int(min(max_steps + 2, 1024))
    todo = np.arange(n)
    pts_of = [np.zeros((0, 3))] * n
    par_of = [np.zeros((0, 2))] * n
    while todo.size:
        out_p = np.empty((todo.size, cap, 3))
        out_par = np.empty((todo.size, cap, 2))
        out_n = np.zeros(todo.size, np.int64)
        ssi = np.zeros((todo.size, NI), np.int64)
        _advance(seeds[todo], dirs[todo], *setup.grid, setup.vec, *arrays, kexp,
                 setup.fo, setup.io, ssi, out_p, out_par, out_n)
        done = ssi[:, I_STATUS] != _OVERFLOW
        for j in np.flatnonzero(done):
            pts_of[todo[j]] = out_p[j, :out_n[j]]
            par_of[todo[j]] = out_par[j, :out_n[j]]
        si[todo[done]] = ssi[done]
        todo = todo[~done]
        cap = min(4 * cap, max_steps + 2)  # a line has at most max_steps + 1 vertices
    counts = np.array([p.shape[0] for p in pts_of], np.int64)
    pts = np.concatenate(pts_of) if n else np.zeros((0, 3))
    par = np.concatenate(par_of) if n else np.zeros((0, 2))
    owner = np.repeat(np.arange(n), counts)
    cols = {"reason": si[:, I_REASON].astype(np.int8),
            "n_accepted": si[:, I_NACC].astype(np.int32),
            "n_rejected": si[:, I_NREJ].astype(np.int32),
            "n_crossing": np.zeros(len(si), np.int32),  # (it ends every step on a face)
            "stiff": ((si[:, I_STIFF] & STIFF_BIT) != 0).astype(np.int8),
            "stiff_steps": si[:, I_NSTIFF].astype(np.int32)}
    return pts, par[:, 0].copy(), par[:, 1].copy(), owner, cols


def trace_rosenbrock(field: Field, seeds, options: TraceOptions | None = None, **kw) -> Lines:
    """``flowkit.trace(..., method="ros34pw2")``: streamlines by ROS34PW2 (cell-aware, exact
    cell Jacobian), vertices at the accepted steps.  line_data adds ``stiff`` (int8,
    Hairer–Wanner flag) and ``stiff_steps`` (int32)."""
    kw["method"] = NAME
    return trace(field, seeds, options, **kw)
