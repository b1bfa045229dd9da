"""Lines in lock-step: the numba backend's path for fixed-step methods on uniform grids.

``kernel._advance_lines`` follows one line at a time, and a line is a chain of dependent work:
the next stage's point needs this stage's velocity, which needs this stage's cell corners, which
on a large field are often cache misses.  Here a thread advances ``W`` lines side by side, one
stage of all of them at a time: the stage points of every lane, then a prefetch of every lane's
cell (so the misses of different lines overlap instead of queueing), then the evaluations.  The
stage sums and the evaluations are loops over the lanes with no branches, which LLVM turns into
vector code (on AVX-512: gathers of the cell corners, eight lanes per instruction);
the loop over the lanes is the innermost loop, and every lane is computed whether it is still
running or not (a stopped lane's values are not used).

The arithmetic of a step is the scalar kernel's, operation for operation (the same cell choice,
polynomial coefficients, stage sums and step update), so the lines are bit-identical to
``kernel.advance``'s (tests/test_lanes.py).  The cell of a stage point is located afresh every
time: the scalar kernel keeps its cached cell only while a point is strictly inside it, where
locating it again gives the same cell, so the choice depends on the point alone.  A lane commits
only a step that the scalar kernel would commit with no event: its stages finite, its end inside
the domain and short of the dependent parameter's limit, room in the output buffer.  The step
that reaches the independent parameter's limit (``max_length`` in arc length, ``max_time`` in
time) is clipped there, as the scalar kernel clips it, and ends the line.  At anything else — a
boundary, NaN data, stagnation, a full buffer, ``max_steps`` — the lane stops before that step
and ``kernel._advance_lines`` finishes the line from the saved state.  Adaptive methods,
cell-aware stepping, resampled output, periodic and non-uniform axes go to the scalar kernel
whole (``eligible``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..jit import inline
from .kernel import R_MAXLEN, R_MAXTIME, _prefetch, _put
from .kernel import advance as advance_one_by_one
from .methods import LOCKSTEP_STAGES as SMAX  # stages of the eligible methods
from .methods import lockstep_tableau
from .schema import (
    DONE,
    EMIT_STEPS,
    I_LASTREJ,
    I_NACC,
    I_NREJ,
    I_REASON,
    I_STATUS,
    M_FSAL,
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
)

W = 32  # lines per group: enough cache misses in flight to cover the memory latency


def eligible(period, inv, ma, mb, mi, io) -> bool:
    """True where the lock-step path applies: a method the registry calls lock-step
    (``methods.lockstep_tableau``: fixed step, at most SMAX stages, its f(y1) stage at y1),
    plain stepping, a vertex per step, no stiffness test, every axis uniform and bounded.  Plain
    Python: it runs once a launch, and ``advance`` compiles the lock-step only for launches that
    pass."""
    if not lockstep_tableau(ma, mb, mi) or io[P_AWARE] != 0 or io[P_EMIT] != EMIT_STEPS \
            or io[P_STIFF] >= 0:
        return False
    return bool(np.all(period == 0.0) and np.all(inv > 0.0))


@inline
def _axis_cell(c, inv, x):
    """Cell of x on a uniform bounded axis, as ``kernel._relocate`` finds it (clamped to the
    end cells), without branches: the lane loops that call it stay vector code."""
    n = c.size
    # not max/min: a NaN coordinate must become c[0], a valid index (the lane's step then fails)
    xc = x if x >= c[0] else c[0]  # noqa: FURB136
    xc = xc if xc <= c[n - 1] else c[n - 1]  # noqa: FURB136
    i = min(max(int((xc - c[0]) * inv), 0), n - 2)
    # rounding of (x - c0) * inv may land one cell off
    dn = xc < c[i]
    up = (xc > c[i + 1]) & (i < n - 2) & (xc >= c[i])
    return i - dn + up


U3 = np.uint64(3)  # unsigned indices: numba adds no negative-index wraparound to the gathers


@inline
def _component(flat, b, di, dj, c, tx, ty, tz):
    """Component c of the trilinear polynomial of the cell whose first corner starts at
    flat[b] (b, di, dj, c unsigned): ``kernel._gather``'s coefficients in ``kernel._fc``'s
    Horner form."""
    v000 = flat[b + c]
    v100 = flat[b + di + c]
    v010 = flat[b + dj + c]
    v110 = flat[b + di + dj + c]
    v001 = flat[b + U3 + c]
    v101 = flat[b + di + U3 + c]
    v011 = flat[b + dj + U3 + c]
    v111 = flat[b + di + dj + U3 + c]
    a1 = v100 - v000
    a2 = v010 - v000
    a3 = v001 - v000
    a4 = v110 - v100 - v010 + v000
    a5 = v101 - v100 - v001 + v000
    a6 = v011 - v010 - v001 + v000
    a7 = v111 - v110 - v101 - v011 + v100 + v010 + v001 - v000
    return v000 + tx * (a1 + ty * (a4 + tz * a7) + tz * a5) + ty * (a2 + tz * a6) + tz * a3


@inline
def _evaluate(g, st, yt, k, ok, rx, ry, rz, gx, gy, gz, inv, flat, ny, nz, param):
    """Stage st of every lane of group g into k[g, st]: ``kernel._f`` (the cell located, its
    polynomial evaluated), as one branch-free loop over the lanes that LLVM makes vector code.
    ok[g, w] turns False where ``kernel._norm3`` would rescale (tiny or huge speeds)."""
    dj = np.uint64(nz * 3)
    di = np.uint64(ny * nz * 3)
    for w in range(W):
        px, py, pz = yt[g, 0, w], yt[g, 1, w], yt[g, 2, w]
        i = _axis_cell(gx, inv[0], px)
        j = _axis_cell(gy, inv[1], py)
        kk = _axis_cell(gz, inv[2], pz)
        lx, ly, lz = gx[i], gy[j], gz[kk]
        sx, sy, sz = rx[i], ry[j], rz[kk]  # kernel._relocate's 1 / width, tabulated
        tx = (px - lx) * sx
        ty = (py - ly) * sy
        tz = (pz - lz) * sz
        b = np.uint64(((i * ny + j) * nz + kk) * 3)
        u = _component(flat, b, di, dj, np.uint64(0), tx, ty, tz)
        v = _component(flat, b, di, dj, np.uint64(1), tx, ty, tz)
        s = _component(flat, b, di, dj, np.uint64(2), tx, ty, tz)
        sp = math.sqrt(u * u + v * v + s * s)
        r = 1.0 / sp if param != 0 else 1.0  # u * 1.0 is u: time parameter, velocity as is
        k[g, st, 0, w] = u * r
        k[g, st, 1, w] = v * r
        k[g, st, 2, w] = s * r
        k[g, st, 3, w] = r if param != 0 else sp
        ok[g, w] &= (sp > 1e-150) & (sp < 1e150)


@inline
def _sums(g, n, coef, row, y, h, k, out, comps):
    """out[g, a, w] = y[g, a, w] + h[g, w] * Σ_m<n coef[row, m] k[g, m, a, w] for a < comps,
    summed in the scalar kernel's order; the lane loops innermost, so they are vector code."""
    for a in range(comps):
        for w in range(W):
            out[g, a, w] = 0.0
        for m in range(n):
            c = coef[row, m]
            for w in range(W):
                out[g, a, w] += c * k[g, m, a, w]
        for w in range(W):
            out[g, a, w] = y[g, a, w] + h[g, w] * out[g, a, w]


@inline
def _node(c, inv, x):
    """Cell index of x by one multiply, clamped (only to choose what to prefetch):
    ``kernel._node_index`` without its branches (periodic wrap, non-uniform axis), which
    ``eligible`` excludes here.  A NaN point gives some index: a prefetch of any address is
    harmless."""
    r = min(max((x - c[0]) * inv, 0.0), c.size - 2.0)
    return int(r)


@inline
def _prefetch_lanes(g, live, yt, gx, gy, gz, inv, flat, ny, nz, pb):
    """Ask the cache for every live lane's cell before any lane is evaluated (the corners'
    first and last components: two cache lines per corner pair).  The cells are found in a
    loop of vector code; only the prefetches themselves are one lane at a time."""
    for w in range(W):
        pb[g, w] = ((_node(gx, inv[0], yt[g, 0, w]) * ny + _node(gy, inv[1], yt[g, 1, w])) * nz
                    + _node(gz, inv[2], yt[g, 2, w])) * 3
    dj = nz * 3
    di = ny * dj
    for w in range(W):
        if live[g, w] != 0:
            b = pb[g, w]
            _prefetch(flat, b)
            _prefetch(flat, b + 5)
            _prefetch(flat, b + di)
            _prefetch(flat, b + di + 5)
            _prefetch(flat, b + dj)
            _prefetch(flat, b + dj + 5)
            _prefetch(flat, b + di + dj)
            _prefetch(flat, b + di + dj + 5)


@njit(cache=True, parallel=True, error_model="numpy")
def lockstep(active, dirs, gx, gy, gz, inv, flat, ny, nz, mc, ma, mi, fo, io, sf, si,
             out_p, out_par, out_n):
    """Advance the started lines ``active`` in groups of W as far as the lock-step goes; their
    state goes back into ``sf``/``si`` for ``kernel._advance_lines`` to continue.

    Every array the parallel loop touches is made before it and indexed by the group, none a
    view of another, and ``flat`` is the only view of the field: numba then marks them as not
    aliasing (it does so only when its alias analysis of the loop finds nothing), which LLVM's
    vectorizer needs for the gathers of ``_evaluate``."""
    B = out_p.shape[1]
    fs = mi[M_FSAL]  # the f(y1) stage; y1 takes the stages before it (eligible: n_err == fs)
    param, max_steps = io[P_PARAM], io[P_MAXSTEPS]
    hmax, stag = fo[O_HMAX], fo[O_STAG]
    lim_ind = fo[O_MAXTIME] if param == 0 else fo[O_MAXLEN]
    lim_dep = fo[O_MAXLEN] if param == 0 else fo[O_MAXTIME]
    dlo = np.array([gx[0], gy[0], gz[0]])
    dhi = np.array([gx[gx.size - 1], gy[gy.size - 1], gz[gz.size - 1]])
    G = (active.size + W - 1) // W
    # every lane's state; a stopped lane keeps being computed (its values unused), so zeros
    y, yt, y1 = np.zeros((G, 4, W)), np.zeros((G, 3, W)), np.zeros((G, 4, W))
    k = np.zeros((G, SMAX, 4, W))
    tau, h, d = np.zeros((G, W)), np.zeros((G, W)), np.ones((G, W))
    # 1 / width of every cell, as kernel._relocate divides (a gather instead of a division)
    rx, ry, rz = 1.0 / (gx[1:] - gx[:-1]), 1.0 / (gy[1:] - gy[:-1]), 1.0 / (gz[1:] - gz[:-1])
    n_acc, n_rej = np.zeros((G, W), np.int64), np.zeros((G, W), np.int64)
    # int8 flags and int variables, not bools: numba's alias analysis counts a bool variable as
    # a possible alias, and then marks no array of the loop as not aliasing
    live, moved, ok = np.zeros((G, W), np.int8), np.zeros((G, W), np.int8), np.ones((G, W), np.int8)
    emit, hit, done = np.zeros((G, W), np.int8), np.zeros((G, W), np.int8), np.zeros((G, W), np.int8)
    hs = np.zeros((G, W))  # the step taken: h, or clipped at the parameter's limit
    r_ind = R_MAXTIME if param == 0 else R_MAXLEN
    pb = np.zeros((G, W), np.int64)  # prefetched cells
    n_act = active.size
    for g in prange(G):
        nl = min(W, n_act - g * W)
        for w in range(nl):
            l = active[g * W + w]
            if si[l, I_STATUS] == RUNNING:
                live[g, w] = 1
                for a in range(3):
                    y[g, a, w] = sf[l, S_Y + a]
                y[g, 3, w] = sf[l, S_DEP]
                tau[g, w], h[g, w], d[g, w] = sf[l, S_TAU], sf[l, S_H], dirs[l]
                for a in range(4):
                    k[g, 0, a, w] = sf[l, S_K0 + a]
                n_acc[g, w], n_rej[g, w] = si[l, I_NACC], si[l, I_NREJ]
        while True:
            # the checks at the top of the scalar kernel's loop: a lane meeting any of them stops
            n_live = 0
            for w in range(W):  # branch-free: vector code
                slot = min(g * W + w, n_act - 1)  # (lanes past the last line read a real slot)
                speed = k[g, 0, 3, w] if param == 0 else 1.0 / k[g, 0, 3, w]
                stop = (int(out_n[slot] >= B) | int(not (speed >= stag)) | int(speed == 0.0)
                        | int(n_acc[g, w] + n_rej[g, w] >= max_steps))
                for a in range(3):
                    mv = d[g, w] * k[g, 0, a, w]
                    stop |= (int((y[g, a, w] <= dlo[a]) & (mv < 0.0))
                             | int((y[g, a, w] >= dhi[a]) & (mv > 0.0)))
                # the step, clipped where it reaches the parameter's limit (the line's last)
                rem = lim_ind - abs(tau[g, w])
                last = int(abs(h[g, w]) >= rem)
                hit[g, w] = last
                hs[g, w] = d[g, w] * rem if last != 0 else h[g, w]
                lv = live[g, w] & (1 - stop)
                live[g, w] = lv
                n_live += lv
                ok[g, w] = 1
            if n_live == 0:
                break
            # the stage points, a prefetch of their cells, then the evaluations; the last stage
            # (f(y1), eligible says) is at y1 itself
            for st in range(1, fs + 1):
                if st < fs:
                    _sums(g, st, ma, st, y, hs, k, yt, 3)
                else:
                    _sums(g, st, ma, st, y, hs, k, y1, 4)
                    for a in range(3):
                        for w in range(W):
                            yt[g, a, w] = y1[g, a, w]
                # the scalar kernel's rule: a stage at the c of the one before meets its cells
                if mc[st] != mc[st - 1]:
                    _prefetch_lanes(g, live, yt, gx, gy, gz, inv, flat, ny, nz, pb)
                _evaluate(g, st, yt, k, ok, rx, ry, rz, gx, gy, gz, inv, flat, ny, nz, param)
            # commit where the scalar kernel would take the step with no event (branch-free:
            # vector code), then emit the committed vertices
            for w in range(W):
                good = (live[g, w] & ok[g, w] & int(abs(y1[g, 3, w]) < lim_dep)
                        & int(math.isfinite(k[g, fs, 0, w] + k[g, fs, 1, w] + k[g, fs, 2, w]
                                            + k[g, fs, 3, w])))
                for a in range(4):
                    good &= int(math.isfinite(y1[g, a, w]))
                for a in range(3):
                    good &= int(dlo[a] <= y1[g, a, w]) & int(y1[g, a, w] <= dhi[a])
                hsw, tau0, last = hs[g, w], tau[g, w], hit[g, w]
                tau1 = d[g, w] * lim_ind if last != 0 else tau0 + hsw
                for a in range(4):
                    y[g, a, w] = y1[g, a, w] if good != 0 else y[g, a, w]
                    k[g, 0, a, w] = k[g, fs, a, w] if good != 0 else k[g, 0, a, w]
                tau[g, w] = tau1 if good != 0 else tau0
                h[g, w] = d[g, w] * min(abs(h[g, w]), hmax) if good != 0 else h[g, w]
                n_acc[g, w] += good
                moved[g, w] |= good
                done[g, w] |= good & last  # the limit met: reason r_ind, as the scalar kernel
                live[g, w] = good & (1 - last)
                emit[g, w] = good & (int(hsw != 0.0) | int(tau0 != tau1))
            for w in range(W):
                if emit[g, w] != 0:
                    t_out = tau[g, w] if param == 0 else y[g, 3, w]
                    s_out = y[g, 3, w] if param == 0 else tau[g, w]
                    _put(out_p, out_par, out_n, g * W + w, y[g, 0, w], y[g, 1, w], y[g, 2, w],
                         t_out, s_out)
        for w in range(nl):  # hand the lines back
            l = active[g * W + w]
            if moved[g, w] != 0:
                for a in range(3):
                    sf[l, S_Y + a] = y[g, a, w]
                sf[l, S_DEP], sf[l, S_TAU], sf[l, S_H] = y[g, 3, w], tau[g, w], h[g, w]
                for a in range(4):
                    sf[l, S_K0 + a] = k[g, 0, a, w]
                si[l, I_NACC], si[l, I_NREJ], si[l, I_LASTREJ] = n_acc[g, w], n_rej[g, w], 0
            if done[g, w] != 0:
                si[l, I_STATUS], si[l, I_REASON] = DONE, r_ind


def advance(launch):
    """``kernel.advance``, with lines in lock-step where ``eligible`` (same results).  A Python
    function, not a compiled one: a compiled dispatcher would compile the lock-step (a third of
    the kernels' compile time) for every trace, where only fixed-step plain traces run it."""
    L, f, m, io = launch, launch.field, launch.method, launch.io
    if eligible(f.period, f.inv, m.a, m.b, m.info, io):
        io[P_PASS] = PASS_SETUP
        advance_one_by_one(L)
        lockstep(L.active, L.dirs, f.gx, f.gy, f.gz, f.inv, f.vec.reshape(-1), f.vec.shape[1],
                 f.vec.shape[2], m.c, m.a, m.info, L.fo, io, L.sf, L.si, L.out_p, L.out_par,
                 L.out_n)
        io[P_PASS] = PASS_FINISH
    try:
        advance_one_by_one(L)
    finally:
        io[P_PASS] = PASS_FULL
