"""Lines in lock-step: the numba backend's path for fixed-step methods on uniform grids.

``kernel._advance_line`` follows one line at a time, and a line is a chain of dependent work:
the next stage's point needs this stage's velocity, which needs this stage's cell corners, which
on a large field are often cache misses.  Here a thread advances ``W`` lines side by side, one
stage of all of them at a time, and asks the cache for every lane's cell (``_prefetch_cell``)
before it evaluates any lane, so the misses of different lines overlap instead of queueing.

The arithmetic of a step is the scalar kernel's, operation for operation (the same cell choice,
polynomial coefficients, stage sums and step update), so the lines are bit-identical to
``kernel.advance``'s (tests/test_lanes.py).  A lane commits only a step that the scalar kernel
would commit with no special handling: its stages finite, its end inside the domain and short
of the length and time limits, room in the output buffer.  At anything else — a boundary, NaN
data, stagnation, the final clipped step, a full buffer, ``max_steps`` — the lane stops before
that step and ``kernel._advance_line`` finishes the line from the saved state.  Adaptive
methods, cell-aware stepping, resampled output, periodic and non-uniform axes go to the scalar
kernel whole (``eligible``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .kernel import (
    EMIT_STEPS,
    I_LASTREJ,
    I_NACC,
    I_NREJ,
    I_STATUS,
    O_HMAX,
    O_MAXLEN,
    O_MAXTIME,
    O_STAG,
    P_AWARE,
    P_EMIT,
    P_MAXSTEPS,
    P_PARAM,
    P_PASS,
    P_STIFF,
    PASS_FINISH,
    PASS_FULL,
    PASS_SETUP,
    RUNNING,
    S_DEP,
    S_H,
    S_K0,
    S_TAU,
    S_Y,
    _prefetch_cell,
    _put,
)
from .kernel import advance as advance_one_by_one

W = 32  # lines per group: enough cache misses in flight to cover the memory latency
SMAX = 5  # stages of the eligible methods (rk4 and euler with their f(y1) stage)


@njit(cache=True)
def eligible(period, inv, mi, io):
    """True where the lock-step path applies: a fixed-step method of at most SMAX stages, plain
    stepping, a vertex per step, no stiffness test, every axis uniform and bounded."""
    if mi[3] != 0 or mi[0] > SMAX or io[P_AWARE] != 0 or io[P_EMIT] != EMIT_STEPS \
            or io[P_STIFF] >= 0:
        return False
    for a in range(3):
        if period[a] != 0.0 or not (inv[a] > 0.0):
            return False
    return True


@njit(cache=True, inline="always")
def _axis_cell(c, inv, x):
    """Cell of x on a uniform bounded axis, as ``kernel._relocate`` finds it (clamped to the
    end cells)."""
    n = c.size
    # not max/min: a NaN coordinate must become c[0], a valid index (the lane's step then fails)
    xc = x if x >= c[0] else c[0]  # noqa: FURB136
    xc = xc if xc <= c[n - 1] else c[n - 1]  # noqa: FURB136
    i = min(max(int((xc - c[0]) * inv), 0), n - 2)
    if xc < c[i]:  # rounding of (x - c0) * inv may land one cell off
        i -= 1
    elif xc > c[i + 1] and i < n - 2:
        i += 1
    return i


@njit(cache=True, inline="always")
def _component(flat, b, di, dj, c, tx, ty, tz):
    """Component c of the trilinear polynomial of the cell whose first corner starts at
    flat[b]: ``kernel._gather``'s coefficients in ``kernel._fc``'s Horner form."""
    v000 = flat[b + c]
    v100 = flat[b + di + c]
    v010 = flat[b + dj + c]
    v110 = flat[b + di + dj + c]
    v001 = flat[b + 3 + c]
    v101 = flat[b + di + 3 + c]
    v011 = flat[b + dj + 3 + c]
    v111 = flat[b + di + dj + 3 + c]
    a1 = v100 - v000
    a2 = v010 - v000
    a3 = v001 - v000
    a4 = v110 - v100 - v010 + v000
    a5 = v101 - v100 - v001 + v000
    a6 = v011 - v010 - v001 + v000
    a7 = v111 - v110 - v101 - v011 + v100 + v010 + v001 - v000
    return v000 + tx * (a1 + ty * (a4 + tz * a7) + tz * a5) + ty * (a2 + tz * a6) + tz * a3


@njit(cache=True, inline="always")
def _eval(yt, w, param, gx, gy, gz, inv, flat, ny, nz, ci, lo, hi, sc, k, row):
    """Right-hand side of lane w at yt[:, w] into k[row, :, w], as ``kernel._f`` computes it
    with the cell it has cached: kept while the point is inside it (faces included), else
    located again.  False where ``kernel._norm3`` would rescale (tiny or huge speeds)."""
    px, py, pz = yt[0, w], yt[1, w], yt[2, w]
    if not (ci[0, w] >= 0 and lo[0, w] <= px <= hi[0, w] and lo[1, w] <= py <= hi[1, w]
            and lo[2, w] <= pz <= hi[2, w]):
        ci[0, w] = _axis_cell(gx, inv[0], px)
        ci[1, w] = _axis_cell(gy, inv[1], py)
        ci[2, w] = _axis_cell(gz, inv[2], pz)
        lo[0, w], lo[1, w], lo[2, w] = gx[ci[0, w]], gy[ci[1, w]], gz[ci[2, w]]
        hi[0, w], hi[1, w], hi[2, w] = gx[ci[0, w] + 1], gy[ci[1, w] + 1], gz[ci[2, w] + 1]
        for a in range(3):
            sc[a, w] = 1.0 / (hi[a, w] - lo[a, w])  # kernel._relocate's 1 / width
    i, j, kk = ci[0, w], ci[1, w], ci[2, w]
    tx = (px - lo[0, w]) * sc[0, w]
    ty = (py - lo[1, w]) * sc[1, w]
    tz = (pz - lo[2, w]) * sc[2, w]
    dj = nz * 3
    di = ny * dj
    b = ((i * ny + j) * nz + kk) * 3
    u = _component(flat, b, di, dj, 0, tx, ty, tz)
    v = _component(flat, b, di, dj, 1, tx, ty, tz)
    s = _component(flat, b, di, dj, 2, tx, ty, tz)
    sp = math.sqrt(u * u + v * v + s * s)
    if param == 0:
        k[row, 0, w], k[row, 1, w], k[row, 2, w], k[row, 3, w] = u, v, s, sp
    else:
        r = 1.0 / sp
        k[row, 0, w], k[row, 1, w], k[row, 2, w], k[row, 3, w] = u * r, v * r, s * r, r
    return sp > 1e-150 and sp < 1e150


@njit(cache=True, inline="always")
def _stages(first, last, live, y, h, k, ma, yt, ok, param, vec, gx, gy, gz, period, inv, flat,
            ci, lo, hi, sc):
    """Stages first..last of every live lane: the points (summed in the scalar kernel's order),
    a prefetch of all their cells, then the evaluations."""
    ny, nz = vec.shape[1], vec.shape[2]
    for st in range(first, last + 1):
        for w in range(W):
            if live[w]:
                for a in range(3):
                    acc = 0.0
                    for m in range(st):
                        acc += ma[st, m] * k[m, a, w]
                    yt[a, w] = y[a, w] + h[w] * acc
                _prefetch_cell(vec, gx, gy, gz, period, inv, yt[0, w], yt[1, w], yt[2, w], -1)
        for w in range(W):
            if live[w]:
                ok[w] &= _eval(yt, w, param, gx, gy, gz, inv, flat, ny, nz, ci, lo, hi, sc, k,
                               st)


@njit(cache=True, parallel=True)
def lockstep(active, dirs, gx, gy, gz, period, inv, vec, ma, mb, mi, fo, io, sf, si,
             out_p, out_par, out_n):
    """Advance the started lines ``active`` in groups of W as far as the lock-step goes; their
    state goes back into ``sf``/``si`` for ``kernel._advance_line`` to continue."""
    B = out_p.shape[1]
    n_err, fs = mi[1], mi[2]
    param, max_steps = io[P_PARAM], io[P_MAXSTEPS]
    hmax, stag = fo[O_HMAX], fo[O_STAG]
    lim_ind = fo[O_MAXTIME] if param == 0 else fo[O_MAXLEN]
    lim_dep = fo[O_MAXLEN] if param == 0 else fo[O_MAXTIME]
    dlo = np.array([gx[0], gy[0], gz[0]])
    dhi = np.array([gx[gx.size - 1], gy[gy.size - 1], gz[gz.size - 1]])
    flat = vec.reshape(-1)  # C-contiguous (Field makes it so)
    for g in prange((active.size + W - 1) // W):
        y, yt, y1, k = np.empty((4, W)), np.empty((3, W)), np.empty((4, W)), np.empty((SMAX, 4, W))
        tau, h, d = np.zeros(W), np.zeros(W), np.ones(W)
        lo, hi, sc = np.zeros((3, W)), np.zeros((3, W)), np.zeros((3, W))  # cached cells
        ci = np.full((3, W), -1, np.int64)
        n_acc, n_rej = np.zeros(W, np.int64), np.zeros(W, np.int64)
        live, moved, ok = np.zeros(W, np.bool_), np.zeros(W, np.bool_), np.ones(W, np.bool_)
        nl = min(W, active.size - g * W)
        for w in range(nl):
            l = active[g * W + w]
            if si[l, I_STATUS] == RUNNING:
                live[w] = True
                for a in range(3):
                    y[a, w] = sf[l, S_Y + a]
                y[3, w] = sf[l, S_DEP]
                tau[w], h[w], d[w] = sf[l, S_TAU], sf[l, S_H], dirs[l]
                for a in range(4):
                    k[0, a, w] = sf[l, S_K0 + a]
                n_acc[w], n_rej[w] = si[l, I_NACC], si[l, I_NREJ]
        while True:
            # the checks at the top of the scalar kernel's loop, and the final clipped step: a
            # lane meeting any of them stops
            n_live = 0
            for w in range(W):
                if not live[w]:
                    continue
                speed = k[0, 3, w] if param == 0 else 1.0 / k[0, 3, w]
                stop = (out_n[g * W + w] >= B or not (speed >= stag) or speed == 0.0
                        or n_acc[w] + n_rej[w] >= max_steps
                        or abs(h[w]) >= lim_ind - abs(tau[w]))
                for a in range(3):
                    mv = d[w] * k[0, a, w]
                    if (y[a, w] <= dlo[a] and mv < 0.0) or (y[a, w] >= dhi[a] and mv > 0.0):
                        stop = True
                live[w] = not stop
                n_live += not stop
                ok[w] = True
            if n_live == 0:
                break
            _stages(1, n_err - 1, live, y, h, k, ma, yt, ok, param, vec, gx, gy, gz, period,
                    inv, flat, ci, lo, hi, sc)
            for w in range(W):
                if live[w]:
                    for a in range(4):
                        acc = 0.0
                        for m in range(n_err):
                            acc += mb[m] * k[m, a, w]
                        y1[a, w] = y[a, w] + h[w] * acc
            _stages(n_err, fs, live, y, h, k, ma, yt, ok, param, vec, gx, gy, gz, period, inv,
                    flat, ci, lo, hi, sc)
            # commit where the scalar kernel would take the step with no event
            for w in range(W):
                if not live[w]:
                    continue
                good = ok[w] and abs(y1[3, w]) < lim_dep and math.isfinite(
                    k[fs, 0, w] + k[fs, 1, w] + k[fs, 2, w] + k[fs, 3, w])
                for a in range(4):
                    good = good and math.isfinite(y1[a, w])
                for a in range(3):
                    good = good and dlo[a] <= y1[a, w] <= dhi[a]
                if not good:
                    live[w] = False
                    continue
                hs, tau0 = h[w], tau[w]
                for a in range(4):
                    y[a, w] = y1[a, w]
                    k[0, a, w] = k[fs, a, w]
                tau[w] = tau0 + hs
                n_acc[w] += 1
                h[w] = d[w] * min(abs(hs), hmax)
                moved[w] = True
                if hs != 0.0 or tau0 != tau[w]:
                    t_out = tau[w] if param == 0 else y[3, w]
                    s_out = y[3, w] if param == 0 else tau[w]
                    _put(out_p, out_par, out_n, g * W + w, y[0, w], y[1, w], y[2, w], t_out,
                         s_out)
        for w in range(nl):  # hand the lines back
            l = active[g * W + w]
            if moved[w]:
                for a in range(3):
                    sf[l, S_Y + a] = y[a, w]
                sf[l, S_DEP], sf[l, S_TAU], sf[l, S_H] = y[3, w], tau[w], h[w]
                for a in range(4):
                    sf[l, S_K0 + a] = k[0, a, w]
                si[l, I_NACC], si[l, I_NREJ], si[l, I_LASTREJ] = n_acc[w], n_rej[w], 0


@njit(cache=True)
def advance(active, seeds, dirs, spacings, phases, gx, gy, gz, period, inv, vec,
            mc, ma, mb, me, me2, mp, mi, fo, io, sf, si, out_p, out_par, out_n):
    """``kernel.advance``, with lines in lock-step where ``eligible`` (same results)."""
    if eligible(period, inv, mi, io):
        io[P_PASS] = PASS_SETUP
        advance_one_by_one(active, seeds, dirs, spacings, phases, gx, gy, gz, period, inv, vec,
                           mc, ma, mb, me, me2, mp, mi, fo, io, sf, si, out_p, out_par, out_n)
        lockstep(active, dirs, gx, gy, gz, period, inv, vec, ma, mb, mi, fo, io, sf, si,
                 out_p, out_par, out_n)
        io[P_PASS] = PASS_FINISH
    advance_one_by_one(active, seeds, dirs, spacings, phases, gx, gy, gz, period, inv, vec,
                       mc, ma, mb, me, me2, mp, mi, fo, io, sf, si, out_p, out_par, out_n)
    io[P_PASS] = PASS_FULL
