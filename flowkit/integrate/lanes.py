"""Lines in lock-step: the numba backend's path for plain (not cell-aware) stepping.

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
polynomial coefficients, stage sums, error norm and step size control), so the lines are
bit-identical to ``kernel.advance``'s (tests/test_lanes.py), for fixed steps and for the
embedded pairs alike.  Each lane has its own step size and error estimate: a rejected lane redoes
its step while the others advance, and a lane whose line stopped takes the group's next line.
The cell of a stage point is found as the scalar kernel finds it: one multiply on a uniform axis,
a fixed number of bisection rounds on a non-uniform one, the wrap on a periodic one, where the
kernel's cached cell is followed too (a cell found again could differ from it in the last bit of
its faces).  A lane commits only a step that the scalar kernel would commit with no event: its
stages finite, its end inside the domain and short of the dependent parameter's limit, room in
the output buffer.  The step that reaches the independent parameter's limit (``max_length`` in
arc length, ``max_time`` in time) is clipped there, as the scalar kernel clips it, and ends the
line.  At anything else — a boundary, NaN data, stagnation, a full buffer, ``max_steps``, a step
below the minimum — the lane stops before that step and ``kernel._advance_lines`` finishes the
line from the saved state.  ``why_not`` names what sends a launch to the scalar kernel whole
(cell-aware stepping, resampled output); the trace records it (``Lines.attrs["kernel_path"]``).
"""

from __future__ import annotations

import logging
import math
import os
import threading

import numpy as np
from numba import njit, prange, typeof

from ..jit import inline
from ..numba_cache import in_disk_cache
from .kernel import (
    ERR_HUGE,
    ERR_TINY,
    EXPO1_BETA,
    NORM_HUGE,
    NORM_TINY,
    R_MAXLEN,
    R_MAXTIME,
    _from_anchor,
    _next_step,
    _prefetch,
    _put,
    _retry,
)
from .kernel import advance as advance_one_by_one
from .methods import LOCKSTEP_STAGES as SMAX  # stages of the eligible methods
from .methods import lockstep_tableau
from .schema import (
    DONE,
    EMIT_STEPS,
    I_CELL,
    I_LASTREJ,
    I_NACC,
    I_NREJ,
    I_REASON,
    I_STATUS,
    I_STIFF,
    M_ADAPTIVE,
    M_FSAL,
    M_HASE2,
    M_KEXP,
    M_NERR,
    O_ATOL,
    O_BETA,
    O_FACMAX,
    O_FACMIN,
    O_HMAX,
    O_HMIN,
    O_MAXLEN,
    O_MAXTIME,
    O_RTOL,
    O_SAFETY,
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
    S_ANCHOR,
    S_DEP,
    S_ERRP,
    S_H,
    S_HI,
    S_K0,
    S_LO,
    S_TAU,
    S_Y,
)
from .stiffness import hlambda, stiff_update

W = 32  # lanes per group: enough cache misses in flight to cover the memory latency
CHUNK = 4 * W  # lines per group, taken in turn by its lanes


def why_not(period, inv, mi, io) -> str:
    """Why a launch goes to the scalar kernel whole ("" where the lanes take it): the one place
    that decides.  Plain Python: it runs once a launch, and ``advance`` compiles the lock-step
    only for launches that pass."""
    if not lockstep_tableau(mi):
        return "a method whose stages the lanes do not hold"
    if io[P_AWARE] != 0:
        return "cell-aware stepping"
    if io[P_EMIT] != EMIT_STEPS:
        return "resampled output"
    return ""


def eligible(period, inv, mi, io) -> bool:
    """True where the lock-step path applies (``why_not`` says nothing against it)."""
    return not why_not(period, inv, mi, io)


@inline
def _clamp(c, x):
    # not max/min: a NaN coordinate must become c[0], a valid index (the lane's step then fails)
    n = c.size
    xc = x if x >= c[0] else c[0]  # noqa: FURB136
    return xc if xc <= c[n - 1] else c[n - 1]  # noqa: FURB136


@inline
def _uniform_cell(c, inv, x):
    """Cell of x on a uniform bounded axis, as ``kernel._relocate`` finds it (clamped to the
    end cells), without branches: the lane loops that call it stay vector code."""
    n = c.size
    xc = _clamp(c, x)
    i = min(max(int((xc - c[0]) * inv), 0), n - 2)
    # rounding of (x - c0) * inv may land one cell off
    dn = xc < c[i]
    up = (xc > c[i + 1]) & (i < n - 2) & (xc >= c[i])
    return i - dn + up


@inline
def _bisect_cell(c, nb, x):
    """Cell of x on a non-uniform bounded axis: ``interp.locate_axis``'s bisection for the first
    node above x, as a fixed nb rounds (enough for the axis) of selects instead of branches."""
    n = c.size
    xc = _clamp(c, x)
    lo, hi = 0, n
    for _ in range(nb):
        mid = (lo + hi) >> 1
        below = xc < c[min(mid, n - 1)]
        run = lo < hi
        hi = mid if run & below else hi
        lo = mid + 1 if run & (not below) else lo
    return min(max(lo - 1, 0), n - 2)


@njit(cache=True)
def _inv_widths(c, per):
    """1 / width of every cell of an axis (``kernel._width``'s, the wrap cell's last)."""
    n = c.size
    wrap = per > 0.0 and c[0] + per - c[n - 1] > 0.0
    r = np.empty(n if wrap else n - 1)
    for i in range(n - 1):
        r[i] = 1.0 / (c[i + 1] - c[i])
    if wrap:
        r[n - 1] = 1.0 / (c[0] + per - c[n - 1])
    return r


@inline
def _rounds(n):
    """Bisection rounds that find the first node above x among n nodes: r with 2^r > n."""
    r = 1
    while (1 << r) <= n:
        r += 1
    return r


@inline
def _up(n, i, stride):
    """Offset in the flat field from a cell's lower to its upper corners along one axis (the
    wrap cell of a periodic axis: node 0 above its last node)."""
    return stride if i + 1 < n else -i * stride


@inline
def _locate(g, yt, a, c, per, inv, nb, stride, cached, kp, cn, cb):
    """Every lane's cell on axis a as ``kernel._relocate`` finds it: its index cn[g, a, w],
    the offset cn[g, 3 + a, w] of its upper corners in the flat field, its faces cb[g, a, w]
    and cb[g, 3 + a, w].  Where ``cached``, a lane whose kp[g, w] is set keeps its cell
    (``kernel._f``'s cache: the point strictly inside it).  One loop per kind of axis, the
    bounded ones vector code."""
    n = c.size
    if per > 0.0:
        # interp.locate_axis on the wrapped coordinate; the cell keeps the point's image
        wrap = c[0] + per - c[n - 1]
        for w in range(W):
            if kp[g, w] == 0:
                x = yt[g, a, w]
                xw = c[0] + (x - c[0]) % per
                if xw > c[n - 1]:
                    i = n - 2 if wrap <= 0.0 else n - 1
                elif inv > 0.0:
                    i = _uniform_cell(c, inv, xw)
                else:
                    i = _bisect_cell(c, nb, xw)
                lo = c[i] + (x - xw)
                cn[g, a, w], cn[g, 3 + a, w] = i, _up(n, i, stride)
                cb[g, a, w] = lo
                cb[g, 3 + a, w] = lo + (c[i + 1] - c[i] if i < n - 1 else wrap)
        return
    # a bounded axis: the offsets stay the stride (set when the lane took its line)
    if cached == 0:  # found afresh: off a periodic axis the cache's cell, where it has one
        if inv > 0.0:
            for w in range(W):
                cn[g, a, w] = _uniform_cell(c, inv, yt[g, a, w])
        else:
            for w in range(W):
                cn[g, a, w] = _bisect_cell(c, nb, yt[g, a, w])
        return
    for w in range(W):
        x = yt[g, a, w]
        i = _uniform_cell(c, inv, x) if inv > 0.0 else _bisect_cell(c, nb, x)
        keep = kp[g, w] != 0
        cn[g, a, w] = cn[g, a, w] if keep else i
        cb[g, a, w] = cb[g, a, w] if keep else c[i]
        cb[g, 3 + a, w] = cb[g, 3 + a, w] if keep else c[i + 1]


@inline
def _copy_cells(g, act, want, cn, cb, to_n, to_b):
    """Lane w's cell into the other copy where act[g, w] == want (0: every lane, 3: every lane
    with act[g, w] != 0)."""
    for r in range(6):
        for w in range(W):
            m = (want == 0) | (act[g, w] == want) | ((want == 3) & (act[g, w] != 0))
            to_n[g, r, w] = cn[g, r, w] if m else to_n[g, r, w]
            to_b[g, r, w] = cb[g, r, w] if m else to_b[g, r, w]


@inline
def _component(flat, b, di, dj, dk, c, tx, ty, tz):
    """Component c of the trilinear polynomial of the cell whose first corner starts at
    flat[b], its upper corners di, dj, dk further on each axis (all unsigned: a wrap cell's
    negative offset wraps around too): ``kernel._gather``'s coefficients in ``kernel._fc``'s
    Horner form."""
    v000 = np.float64(flat[b + c])  # (float64 before any arithmetic, as kernel._gather)
    v100 = np.float64(flat[b + di + c])
    v010 = np.float64(flat[b + dj + c])
    v110 = np.float64(flat[b + di + dj + c])
    v001 = np.float64(flat[b + dk + c])
    v101 = np.float64(flat[b + di + dk + c])
    v011 = np.float64(flat[b + dj + dk + c])
    v111 = np.float64(flat[b + di + dj + dk + c])
    a1 = v100 - v000
    a2 = v010 - v000
    a3 = v001 - v000
    a4 = v110 - v100 - v010 + v000
    a5 = v101 - v100 - v001 + v000
    a6 = v011 - v010 - v001 + v000
    a7 = v111 - v110 - v101 - v011 + v100 + v010 + v001 - v000
    return v000 + tx * (a1 + ty * (a4 + tz * a7) + tz * a5) + ty * (a2 + tz * a6) + tz * a3


@inline
def _evaluate(g, st, yt, cn, cb, k, ok, gx, gy, gz, rx, ry, rz, flat, ny, nz, param, wraps):
    """Stage st of every lane of group g into k[g, st]: ``kernel._f`` (in the cells cn, cb,
    ``_locate``'s, its polynomial evaluated), as one branch-free loop over the lanes that LLVM
    makes vector code.  ok[g, w] turns False where ``kernel._norm3`` would rescale (tiny or
    huge speeds).  Two loops: with a periodic axis (``wraps``) the faces and corner offsets of
    ``_locate``; without, the nodes and strides themselves (a select between the two in one
    loop cost a tenth of the lock-step's time)."""
    if wraps != 0:
        for w in range(W):
            i, j, kk = cn[g, 0, w], cn[g, 1, w], cn[g, 2, w]
            _lane(g, st, w, yt, k, ok, i, j, kk, cb[g, 0, w], cb[g, 1, w], cb[g, 2, w], rx, ry,
                  rz, np.uint64(cn[g, 3, w]), np.uint64(cn[g, 4, w]), np.uint64(cn[g, 5, w]),
                  flat, ny, nz, param)
    else:
        di, dj, dk = np.uint64(ny * nz * 3), np.uint64(nz * 3), np.uint64(3)
        for w in range(W):
            i, j, kk = cn[g, 0, w], cn[g, 1, w], cn[g, 2, w]
            _lane(g, st, w, yt, k, ok, i, j, kk, gx[i], gy[j], gz[kk], rx, ry, rz, di, dj, dk,
                  flat, ny, nz, param)


@inline
def _lane(g, st, w, yt, k, ok, i, j, kk, lx, ly, lz, rx, ry, rz, di, dj, dk, flat, ny, nz,
          param):
    """``_evaluate`` for lane w, in the cell (i, j, kk) with lower faces lx, ly, lz."""
    tx = (yt[g, 0, w] - lx) * rx[i]  # rx: kernel._relocate's 1 / width, tabulated
    ty = (yt[g, 1, w] - ly) * ry[j]
    tz = (yt[g, 2, w] - lz) * rz[kk]
    # unsigned indices: numba adds no negative-index wraparound to the gathers
    b = np.uint64(((i * ny + j) * nz + kk) * 3)
    u = _component(flat, b, di, dj, dk, np.uint64(0), tx, ty, tz)
    v = _component(flat, b, di, dj, dk, np.uint64(1), tx, ty, tz)
    s = _component(flat, b, di, dj, dk, np.uint64(2), tx, ty, tz)
    sp = math.sqrt(u * u + v * v + s * s)
    r = 1.0 / sp if param != 0 else 1.0  # u * 1.0 is u: time parameter, velocity as is
    k[g, st, 0, w] = u * r
    k[g, st, 1, w] = v * r
    k[g, st, 2, w] = s * r
    k[g, st, 3, w] = r if param != 0 else sp
    ok[g, w] &= (sp > NORM_TINY) & (sp < NORM_HUGE)


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
def _prefetch_lanes(g, live, cn, flat, ny, nz):
    """Ask the cache for every live lane's cell before any lane is evaluated (the corners'
    first and last components: two cache lines per corner pair), so that the misses of the
    lanes overlap; the prefetches themselves are one lane at a time."""
    for w in range(W):
        if live[g, w] != 0:
            b = ((cn[g, 0, w] * ny + cn[g, 1, w]) * nz + cn[g, 2, w]) * 3
            di, dj, e = cn[g, 3, w], cn[g, 4, w], cn[g, 5, w] + 2  # e: the (k + 1) corner's end
            _prefetch(flat, b)
            _prefetch(flat, b + e)
            _prefetch(flat, b + di)
            _prefetch(flat, b + di + e)
            _prefetch(flat, b + dj)
            _prefetch(flat, b + dj + e)
            _prefetch(flat, b + di + dj)
            _prefetch(flat, b + di + dj + e)

@inline
def _dot(g, n, coef, row, k, a, out):
    """out[g, w] = Σ_m<n coef[row, m] k[g, m, a, w], summed in the scalar kernel's order."""
    for w in range(W):
        out[g, w] = 0.0
    for m in range(n):
        c = coef[row, m]
        for w in range(W):
            out[g, w] += c * k[g, m, a, w]


@inline
def _error(g, n_err, mw, has_e2, fo, y, y1, hs, k, e5, e3, tmp, err, fin):
    """``kernel._step_end``'s error norm for every lane of group g into err[g]; fin[g, w] keeps
    1 only where y1 and the norm are finite and the squares neither over- nor underflowed
    (there the scalar kernel rescales: the lane hands that step back)."""
    for w in range(W):
        e5[g, w] = 0.0
        e3[g, w] = 0.0
    for a in range(3):
        _dot(g, n_err, mw, np.int64(1), k, a, tmp)
        for w in range(W):
            sc = fo[O_ATOL + a] + fo[O_RTOL + a] * max(abs(y[g, a, w]), abs(y1[g, a, w]))
            e5[g, w] += (tmp[g, w] / sc) ** 2
        if has_e2 != 0:
            _dot(g, n_err, mw, np.int64(2), k, a, tmp)
            for w in range(W):
                sc = fo[O_ATOL + a] + fo[O_RTOL + a] * max(abs(y[g, a, w]), abs(y1[g, a, w]))
                e3[g, w] += (tmp[g, w] / sc) ** 2
    for w in range(W):
        x5, x3 = e5[g, w], e3[g, w]
        if has_e2 != 0:
            den = x5 + 0.01 * x3
            e = 0.0 if den == 0.0 else abs(hs[g, w]) * x5 / math.sqrt(den * 3.0)
        else:
            e = abs(hs[g, w]) * math.sqrt(x5 / 3.0)
        err[g, w] = e
        fin[g, w] &= int(x5 + x3 > ERR_TINY) & int(x5 + x3 < ERR_HUGE) & int(math.isfinite(e))


@inline
def _hand_back(g, w, l, r_ind, y, tau, h, errp, k, n_acc, n_rej, lrej, stiff, anc, moved, done,
               kn, kb, sf, si):
    """Lane w's line l back into its state rows, for ``kernel._advance_lines`` to continue
    (and DONE with reason r_ind where its last step met the parameter's limit); kn, kb: its
    cell after its last step."""
    if moved[g, w] != 0:
        for a in range(3):
            si[l, I_CELL + a] = kn[g, a, w]
            sf[l, S_LO + a], sf[l, S_HI + a] = kb[g, a, w], kb[g, 3 + a, w]
        for a in range(3):
            sf[l, S_Y + a] = y[g, a, w]
        sf[l, S_DEP], sf[l, S_TAU], sf[l, S_H] = y[g, 3, w], tau[g, w], h[g, w]
        sf[l, S_ERRP] = errp[g, w]
        for a in range(4):
            sf[l, S_K0 + a] = k[g, 0, a, w]
            sf[l, S_ANCHOR + a] = anc[g, a, w]
        si[l, I_NACC], si[l, I_NREJ], si[l, I_LASTREJ] = n_acc[g, w], n_rej[g, w], lrej[g, w]
        si[l, I_STIFF] = stiff[g, w]
    if done[g, w] != 0:
        si[l, I_STATUS], si[l, I_REASON] = DONE, r_ind


# Only the prange loop runs in parallel: numba's other parallel rewrites turned every np.zeros
# below into a parallel loop of its own and fused them, a third of the kernel's compile time
# for allocations (the lines and the warm speed are the same)
_PRANGE_ONLY = {"prange": True, "numpy": False, "fusion": False, "comprehension": False,
                "reduction": False, "inplace_binop": False, "setitem": False, "stencil": False}


@njit(cache=True, parallel=_PRANGE_ONLY, error_model="numpy")
def lockstep(active, dirs, gx, gy, gz, period, inv, flat, ny, nz, mc, ma, mw, mi, fo, io, sf, si,
             out_p, out_par, out_n):
    """Advance the started lines ``active`` in groups of W as far as the lock-step goes; their
    state goes back into ``sf``/``si`` for ``kernel._advance_lines`` to continue.  ``mw``: the
    method's b, e and e2 as rows (``lockstep_args``).

    Every array the parallel loop touches is made before it and indexed by the group, none a
    view of another, and ``flat`` is the only view of the field: numba then marks them as not
    aliasing (it does so only when its alias analysis of the loop finds nothing), which LLVM's
    vectorizer needs for the gathers of ``_evaluate``."""
    B = out_p.shape[1]
    n_err, fs = mi[M_NERR], mi[M_FSAL]  # y1 takes n_err stages; stage fs is f(y1)
    adaptive, has_e2 = mi[M_ADAPTIVE], mi[M_HASE2]
    # stage fs at y1 itself (rk4, euler: its row of a is b): y1 summed once, before it
    y1_first = 1 if n_err == fs else 0
    for m in range(n_err):
        if ma[fs, m] != mw[0, m]:
            y1_first = 0
    param, max_steps, st_stiff = io[P_PARAM], io[P_MAXSTEPS], io[P_STIFF]
    hmin, hmax, stag = fo[O_HMIN], fo[O_HMAX], fo[O_STAG]
    safety, facmin, facmax, beta = fo[O_SAFETY], fo[O_FACMIN], fo[O_FACMAX], fo[O_BETA]
    expo1 = 1.0 / mi[M_KEXP] - EXPO1_BETA * beta
    lim_ind = fo[O_MAXTIME] if param == 0 else fo[O_MAXLEN]
    lim_dep = fo[O_MAXLEN] if param == 0 else fo[O_MAXTIME]
    # the domain's box; a periodic axis has no faces to leave by
    dlo = np.array([gx[0], gy[0], gz[0]])
    dhi = np.array([gx[gx.size - 1], gy[gy.size - 1], gz[gz.size - 1]])
    for a in range(3):
        if period[a] > 0.0:
            dlo[a], dhi[a] = -np.inf, np.inf
    G = (active.size + CHUNK - 1) // CHUNK
    # every lane's state; a stopped lane keeps being computed (its values unused), so zeros
    y, yt, y1 = np.zeros((G, 4, W)), np.zeros((G, 3, W)), np.zeros((G, 4, W))
    ys, stiff = np.zeros((G, 3, W)), np.zeros((G, W), np.int64)  # the stiffness test's
    # kernel._stalled's anchor (position, time), and 1 where the step tried leaves its ball
    anc, out = np.zeros((G, 4, W)), np.zeros((G, W), np.int8)
    k = np.zeros((G, SMAX, 4, W))
    tau, h, d = np.zeros((G, W)), np.zeros((G, W)), np.ones((G, W))
    errp, errpb, err = np.zeros((G, W)), np.zeros((G, W)), np.zeros((G, W))
    e5, e3, tmp = np.zeros((G, W)), np.zeros((G, W)), np.zeros((G, W))
    # 1 / width of every cell, as kernel._relocate divides (a gather instead of a division)
    rx, ry, rz = _inv_widths(gx, period[0]), _inv_widths(gy, period[1]), _inv_widths(gz, period[2])
    n_acc, n_rej = np.zeros((G, W), np.int64), np.zeros((G, W), np.int64)
    # int8 flags and int variables, not bools: numba's alias analysis counts a bool variable as
    # a possible alias, and then marks no array of the loop as not aliasing
    live, moved, ok = np.zeros((G, W), np.int8), np.zeros((G, W), np.int8), np.ones((G, W), np.int8)
    emit, hit, done = np.zeros((G, W), np.int8), np.zeros((G, W), np.int8), np.zeros((G, W), np.int8)
    lrej, act = np.zeros((G, W), np.int8), np.zeros((G, W), np.int8)
    hs, hn = np.zeros((G, W)), np.zeros((G, W))  # the step taken (h, or clipped); the next
    r_ind = R_MAXTIME if param == 0 else R_MAXLEN
    # every lane's cell (_locate's): index and upper-corner offsets, faces; kn, kb: as after
    # the lane's last step (a rejected one's: before the stages that follow the error test,
    # which the scalar kernel skips; en, eb: as there)
    cn, cb = np.zeros((G, 6, W), np.int64), np.zeros((G, 6, W))
    kn, kb = np.zeros((G, 6, W), np.int64), np.zeros((G, 6, W))
    en, eb = np.zeros((G, 6, W), np.int64), np.zeros((G, 6, W))
    kp = np.zeros((G, W), np.int8)  # 1: the lane's stage point is strictly inside its cell
    # on a periodic axis a cell found again may differ from the cached one in the last bit of
    # its faces (the rounding of the wrap): only then the cache is followed
    cached = np.int64(0)
    for a in range(3):
        cached |= int(period[a] > 0.0)
    strides = np.array([ny * nz * 3, nz * 3, 3])
    sizes = np.array([gx.size, gy.size, gz.size])
    # bisection rounds on non-uniform axes
    nb = np.array([_rounds(gx.size), _rounds(gy.size), _rounds(gz.size)])
    slot = np.zeros((G, W), np.int64)  # the line in each lane (its slot in active), -1: none
    n_act = active.size
    # the helpers' arguments typed (jit.helper): a literal, or prange's unsigned index in the
    # parallel loop next to the signed one numba types first, compiles each helper once more
    Z, I1, I2, I3, I4 = np.int64(0), np.int64(1), np.int64(2), np.int64(3), np.int64(4)
    no = np.bool_(False)
    for gu in prange(G):
        g = np.int64(gu)
        nxt, end = g * CHUNK, min((g + 1) * CHUNK, n_act)  # the group's lines, in turn
        for w in range(W):
            slot[g, w] = -1
        while True:
            # a lane whose line stopped hands it back and takes the group's next running line:
            # lines of different lengths (adaptive steps) keep the lanes busy
            for w in range(W):
                if live[g, w] != 0:
                    continue
                if slot[g, w] >= 0:
                    _hand_back(g, w, active[slot[g, w]], r_ind, y, tau, h, errp, k, n_acc,
                               n_rej, lrej, stiff, anc, moved, done, kn, kb, sf, si)
                    slot[g, w] = -1
                while nxt < end and slot[g, w] < 0:
                    l = active[nxt]
                    if si[l, I_STATUS] == RUNNING:
                        slot[g, w] = nxt
                        live[g, w], moved[g, w], done[g, w] = 1, 0, 0
                        for a in range(3):
                            y[g, a, w] = sf[l, S_Y + a]
                        y[g, 3, w] = sf[l, S_DEP]
                        tau[g, w], h[g, w], d[g, w] = sf[l, S_TAU], sf[l, S_H], dirs[l]
                        errp[g, w] = sf[l, S_ERRP]
                        errpb[g, w] = errp[g, w] ** beta  # as kernel._load_state
                        for a in range(4):
                            k[g, 0, a, w] = sf[l, S_K0 + a]
                        n_acc[g, w], n_rej[g, w] = si[l, I_NACC], si[l, I_NREJ]
                        lrej[g, w], stiff[g, w] = si[l, I_LASTREJ], si[l, I_STIFF]
                        for a in range(4):
                            anc[g, a, w] = sf[l, S_ANCHOR + a]
                        for a in range(3):  # the scalar kernel's cached cell
                            i = si[l, I_CELL + a]
                            cn[g, a, w], cn[g, 3 + a, w] = i, _up(sizes[a], i, strides[a])
                            cb[g, a, w], cb[g, 3 + a, w] = sf[l, S_LO + a], sf[l, S_HI + a]
                        for r in range(6):
                            kn[g, r, w], kb[g, r, w] = cn[g, r, w], cb[g, r, w]
                    nxt += 1
            # the checks at the top of the scalar kernel's loop: a lane meeting any of them stops
            n_live = 0
            for w in range(W):  # branch-free: vector code
                sl = max(slot[g, w], 0)  # (an empty lane reads a real slot)
                speed = k[g, 0, 3, w] if param == 0 else 1.0 / k[g, 0, 3, w]
                stop = (int(out_n[sl] >= B) | int(not (speed >= stag)) | int(speed == 0.0)
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
                if nxt >= end:
                    break
                continue
            # the stage points, a prefetch of their cells, then the evaluations, up to f(y1)
            for st in range(1, fs + 1):
                if st == fs and y1_first != 0:
                    _sums(g, n_err, mw, Z, y, hs, k, y1, I4)
                    for a in range(3):
                        for w in range(W):
                            yt[g, a, w] = y1[g, a, w]
                else:
                    _sums(g, st, ma, st, y, hs, k, yt, I3)
                if st == st_stiff:
                    for a in range(3):
                        for w in range(W):
                            ys[g, a, w] = yt[g, a, w]
                if cached != 0:
                    for w in range(W):
                        inside = 1
                        for a in range(3):
                            x = yt[g, a, w]
                            inside &= int(cb[g, a, w] < x) & int(x < cb[g, 3 + a, w])
                        kp[g, w] = inside
                _locate(g, yt, Z, gx, period[0], inv[0], nb[0], strides[0], cached, kp,
                        cn, cb)
                _locate(g, yt, I1, gy, period[1], inv[1], nb[1], strides[1], cached, kp,
                        cn, cb)
                _locate(g, yt, I2, gz, period[2], inv[2], nb[2], strides[2], cached, kp,
                        cn, cb)
                # the scalar kernel's rule: a stage at the c of the one before meets its cells
                if mc[st] != mc[st - 1]:
                    _prefetch_lanes(g, live, cn, flat, ny, nz)
                _evaluate(g, st, yt, cn, cb, k, ok, gx, gy, gz, rx, ry, rz, flat, ny, nz, param,
                          cached)
                if cached != 0 and st == n_err - 1:
                    _copy_cells(g, act, Z, cn, cb, en, eb)
            if y1_first == 0:
                _sums(g, n_err, mw, Z, y, hs, k, y1, I4)
            # act: 1 take the step (no event in it), 2 reject it (error above the tolerance),
            # 0 stop the lane before it (the scalar kernel takes it from there)
            for w in range(W):  # branch-free: vector code
                f1 = live[g, w] & ok[g, w]
                for a in range(4):
                    f1 &= int(math.isfinite(y1[g, a, w]))
                act[g, w] = f1
            if adaptive != 0:
                _error(g, n_err, mw, has_e2, fo, y, y1, hs, k, e5, e3, tmp, err, act)
            for w in range(W):
                good = int(abs(y1[g, 3, w]) < lim_dep) & int(math.isfinite(
                    k[g, fs, 0, w] + k[g, fs, 1, w] + k[g, fs, 2, w] + k[g, fs, 3, w]))
                for a in range(3):
                    good &= int(dlo[a] <= y1[g, a, w]) & int(y1[g, a, w] <= dhi[a])
                big = adaptive & int(err[g, w] > 1.0)
                act[g, w] = act[g, w] * (2 * big + (1 - big) * good)
            if adaptive != 0:  # kernel._stalled: the scalar kernel stops the line at that step
                for w in range(W):
                    d2, tol = _from_anchor(anc[g, 0, w], anc[g, 1, w], anc[g, 2, w],
                                           y1[g, 0, w], y1[g, 1, w], y1[g, 2, w], fo)
                    o = int(d2 > 1.0)
                    out[g, w] = o
                    t1 = (y1[g, 3, w] if param != 0 else
                          (d[g, w] * lim_ind if hit[g, w] != 0 else tau[g, w] + hs[g, w]))
                    stop = (1 - o) & int(abs(t1 - anc[g, 3, w]) * stag > tol) & int(act[g, w] == 1)
                    act[g, w] = act[g, w] * (1 - stop)
            # the step size control (a loop of scalar code: its powers), kernel's controller
            for w in range(W):
                if act[g, w] == 2:
                    hn[g, w], why = _retry(hs[g, w], err[g, w], no, hmin, safety, facmin,
                                           expo1)
                    if why >= 0:
                        act[g, w] = 0  # below the minimum step: the scalar kernel ends the line
                elif act[g, w] == 1:
                    if st_stiff >= 0:  # Hairer & Wanner's test (stiffness.stage_hlambda's sums)
                        num = 0.0
                        den = 0.0
                        for a in range(3):
                            num += (k[g, fs, a, w] - k[g, st_stiff, a, w]) ** 2
                            den += (y1[g, a, w] - ys[g, a, w]) ** 2
                        stiff[g, w] = stiff_update(stiff[g, w], hlambda(hs[g, w], num, den))
                    hnext = h[g, w]
                    if adaptive != 0:
                        hnext, errp[g, w], errpb[g, w] = _next_step(
                            err[g, w], errp[g, w], errpb[g, w], hs[g, w], h[g, w], lrej[g, w] != 0,
                            safety, facmin, facmax, beta, expo1)
                    hn[g, w] = d[g, w] * min(abs(hnext), hmax)
            if cached != 0:  # a rejected step's cell as at its error test, then the step's cell
                _copy_cells(g, act, I2, en, eb, cn, cb)
                _copy_cells(g, act, I3, cn, cb, kn, kb)
            # commit (branch-free: vector code), then emit the committed vertices
            for w in range(W):
                a_w = act[g, w]
                good, rej = int(a_w == 1), int(a_w == 2)
                hsw, tau0, last = hs[g, w], tau[g, w], hit[g, w]
                tau1 = d[g, w] * lim_ind if last != 0 else tau0 + hsw
                for a in range(4):
                    y[g, a, w] = y1[g, a, w] if good != 0 else y[g, a, w]
                    k[g, 0, a, w] = k[g, fs, a, w] if good != 0 else k[g, 0, a, w]
                tau[g, w] = tau1 if good != 0 else tau0
                h[g, w] = hn[g, w] if a_w != 0 else h[g, w]
                n_acc[g, w] += good
                n_rej[g, w] += rej
                lrej[g, w] = rej if a_w != 0 else lrej[g, w]
                moved[g, w] |= good | rej
                done[g, w] |= good & last  # the limit met: reason r_ind, as the scalar kernel
                live[g, w] = (good & (1 - last)) | rej
                emit[g, w] = good & (int(hsw != 0.0) | int(tau0 != tau1))
            if adaptive != 0:  # a step out of the ball moves the anchor there
                for w in range(W):
                    mv = int(act[g, w] == 1) & out[g, w]
                    for a in range(3):
                        anc[g, a, w] = y[g, a, w] if mv != 0 else anc[g, a, w]
                    t = tau[g, w] if param == 0 else y[g, 3, w]
                    anc[g, 3, w] = t if mv != 0 else anc[g, 3, w]
            for w in range(W):
                if emit[g, w] != 0:
                    t_out = tau[g, w] if param == 0 else y[g, 3, w]
                    s_out = y[g, 3, w] if param == 0 else tau[g, w]
                    _put(out_p, out_par, out_n, slot[g, w], y[g, 0, w], y[g, 1, w], y[g, 2, w],
                         t_out, s_out)
        for w in range(W):  # hand the last lines back
            if slot[g, w] >= 0:
                _hand_back(g, w, active[slot[g, w]], r_ind, y, tau, h, errp, k, n_acc, n_rej,
                           lrej, stiff, anc, moved, done, kn, kb, sf, si)


def lockstep_args(launch):
    """``lockstep``'s arguments from a launch (the method's b, e, e2 stacked into rows)."""
    L, f, m = launch, launch.field, launch.method
    mw = np.ascontiguousarray(np.stack([m.b, m.e, m.e2]))
    return (L.active, L.dirs, f.gx, f.gy, f.gz, f.period, f.inv, f.vec.reshape(-1), f.vec.shape[1],
            f.vec.shape[2], m.c, m.a, mw, m.info, L.fo, L.io, L.sf, L.si, L.out_p, L.out_par,
            L.out_n)


# The lock-step takes tens of seconds to compile on a fresh machine, and the scalar kernel gives
# the same lines.  Where numba's disk cache holds it, the launch loads it (a second); otherwise
# the launches go to the scalar kernel and ``compile_pending`` (called when a trace is done)
# compiles it in a background thread for the traces after.  Not during the trace: loading or
# compiling takes numba's compiler lock, which the trace's own kernels may still need.
# WAIT (FLOWKIT_LOCKSTEP_WAIT=1; ``flowkit compile`` and the tests): compile in the launch.
WAIT = os.environ.get("FLOWKIT_LOCKSTEP_WAIT", "") not in ("", "0")
COMPILING = "the lock-step kernel is not compiled yet"
_LOG = logging.getLogger("flowkit.compile")
_pending: dict = {}  # argument types -> None (to compile) or the thread compiling them


def _compiled(sig) -> bool:
    return sig in lockstep.overloads


def _compile(sig) -> None:
    try:
        lockstep.compile(sig)
    except Exception:  # noqa: BLE001 (a thread: the launches stay on the scalar kernel)
        _LOG.exception("compiling the lock-step kernel failed")


def _lockstep_ready(args) -> bool:
    """True when ``lockstep`` can run for these arguments now: compiled, in the disk cache
    (loaded here), or WAIT (compiled here); else it is left to ``compile_pending``."""
    if WAIT:
        return True
    sig = tuple(typeof(a) for a in args)
    if _compiled(sig):
        return True
    if sig not in _pending and in_disk_cache(lockstep, sig):
        lockstep.compile(sig)
        return True
    if sig not in _pending:
        _pending[sig] = None
        _LOG.info("%s: the scalar kernel traces until it is (the same lines); it compiles in "
                  "the background after this trace, and `flowkit compile lockstep` compiles "
                  "it once for every later run", COMPILING)
    return False


def compile_pending() -> None:
    """Start the background compile of the lock-step for the launches that went without it."""
    for sig, t in list(_pending.items()):
        if t is None:
            _pending[sig] = t = threading.Thread(target=_compile, args=(sig,), daemon=True,
                                                 name="flowkit-lockstep-compile")
            t.start()


def advance(launch) -> str:
    """``kernel.advance``, with lines in lock-step where ``why_not`` finds nothing against it
    (same results); returns the path taken, "lanes" or "scalar: <why>".  A Python function,
    not a compiled one: a compiled dispatcher would compile the lock-step (a third of the
    kernels' compile time) for every trace, where only plain (not cell-aware) traces run it."""
    L, f, m, io = launch, launch.field, launch.method, launch.io
    why = (why_not(f.period, f.inv, m.info, io) or ("a bricked field" if f.bk.size else "")
           or ("the Rosenbrock stepper" if L.stiff is not None else ""))
    if not why and not _lockstep_ready(lockstep_args(L)):
        why = COMPILING
    if not why:
        io[P_PASS] = PASS_SETUP
        advance_one_by_one(L)
        lockstep(*lockstep_args(L))
        io[P_PASS] = PASS_FINISH
    try:
        advance_one_by_one(L)
    finally:
        io[P_PASS] = PASS_FULL
    return f"scalar: {why}" if why else "lanes"
