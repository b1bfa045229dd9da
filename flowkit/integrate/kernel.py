"""The numba integrator: explicit Runge–Kutta from tableau data, lines shared among threads.

Algorithm (the OpenCL backend reproduces it step for step; docs/integrator.md says more):

* State of a line = position y (3), the independent parameter ``tau`` (time, or arc length when
  ``param == 1``), the dependent one ``dep`` integrated as a 4th ODE component (ds/dt = |v|, or
  dt/ds = 1/|v|), the controller's next step ``h`` (signed: negative for backward lines) and the
  first stage ``k0`` of the next step.  All stages are 4-vectors; only the position enters the
  error norm.
* The field is evaluated from the 8 corner values of one cell, gathered once per cell into the
  coefficients of the trilinear polynomial.  Cell-aware (``aware``): every stage of a step uses
  the polynomial of the cell the step starts in (outside the cell it is the same smooth
  polynomial, extended); an accepted step whose end leaves the cell is cut where the dense
  output first meets a face; the coordinate is snapped onto the face, the line moves to the
  neighbour cell and the next step starts with a fresh k0 there.  Steps (fixed ones too) are
  also capped at ``cellfac`` times the straight-line time to the exit face so that little work
  is cut away and no stage reaches far beyond the cell.  Adaptive methods may instead try a
  step across faces (``P_CROSS``, below), kept when the error estimate and a bound on the faces'
  kinks allow it, so that a looser tolerance costs fewer steps.
  Otherwise each stage looks up its own cell (cached while it stays in the same cell), using the
  boundary cell's polynomial, extended, for stages just outside a bounded domain.
* Events inside an accepted step are found on the dense output (Illinois root finding in θ):
  leaving the cell/domain, and the dependent parameter reaching its limit.  The independent
  parameter's limit is met by clipping the step.  Earliest event wins.
* Output: each launch writes at most ``B`` vertices per line into (n_active, B) buffers.  A line
  whose buffer is full suspends with its whole state in ``sf``/``si`` (including a pending dense
  polynomial when resampling) and continues, bit for bit, in the next launch.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import compile_notice
from ..fields.bricks import B_NODES, B_SIZE, axis_bricks, missing_brick, slot_of
from ..fields.interp import locate_axis, prefetch_cell, prefetch_corners
from ..jit import helper, inline, kernel
from ..jit import prefetch as _prefetch  # noqa: F401 (lanes.py, benchmarks)
from ..threads import run_ranges
from . import rosenbrock
from .cell import NORM_HUGE, NORM_TINY, _fc, _norm3  # noqa: F401 (lanes.py, OpenCL)
from .reasons import Reason

# the state, option and method-info columns (schema.py), all of them: callers address them as
# kernel.X too
from .schema import (  # noqa: F401
    DONE,
    EMIT_FINAL,
    EMIT_SPACING,
    EMIT_STEPS,
    EV_BOUNDARY,
    EV_DEPLIM,
    EV_FACE,
    EV_NONE,
    I_CELL,
    I_FINAL,
    I_KFAIL,
    I_KWAIT,
    I_LASTREJ,
    I_M,
    I_NACC,
    I_NCROSS,
    I_NREJ,
    I_NSTIFF,
    I_PEND,
    I_REASON,
    I_ROS,
    I_STATUS,
    I_STIFF,
    I_WAIT,
    M_ADAPTIVE,
    M_FSAL,
    M_HASE2,
    M_KEXP,
    M_NERR,
    M_STAGES,
    NEW,
    NF,
    NFO,
    NI,
    NIO,
    NMI,
    O_ATOL,
    O_BETA,
    O_CELLFAC,
    O_FACMAX,
    O_FACMIN,
    O_H0,
    O_HMAX,
    O_HMIN,
    O_MAXLEN,
    O_MAXTIME,
    O_RTOL,
    O_SAFETY,
    O_STAG,
    P_AWARE,
    P_CROSS,
    P_EMIT,
    P_MAXSTEPS,
    P_PARAM,
    P_PASS,
    P_ROS,
    P_STIFF,
    PASS_FINISH,
    PASS_FULL,
    PASS_SETUP,
    QMAX,
    RUNNING,
    S_ANCHOR,
    S_DEP,
    S_ERRP,
    S_H,
    S_HI,
    S_HK,
    S_HS,
    S_K0,
    S_LAST_S,
    S_LO,
    S_Q,
    S_TAU,
    S_TAU0,
    S_TH,
    S_Y,
    S_Y0,
)
from .stiffness import (
    HLAMBDA_STIFF,
    STIFF_BIT,
    spectral_radius_bound,
    stage_hlambda,
    stiff_update,
)
from .unsteady import stage, velocity

# P_CROSS (cell-aware, adaptive): a step the controller wants longer than the cell cap is tried
# across faces, each stage in its own cell, and kept when its error estimate passes; otherwise
# the step ends on the face as usual.  The kink at a face makes the error of such a step grow
# like h^2, so the longest crossing step has its own controller (S_HK): shrunk by a rejected
# crossing, grown on every face the line steps through.
KINK_CELLS, KINK_GROW, KINK_SHRINK_MIN = 3.0, 1.15, 0.1
# a crossing refused n times in a row is not tried again for 2^(KINK_BACKOFF_BITS (n - 1)) - 1
# capped steps, n at most KINK_FAIL_MAX
KINK_BACKOFF_BITS, KINK_FAIL_MAX = 2, 10

# The step loop's other tuning constants, by name: the OpenCL template renders these very values
# (opencl/codegen.py reads every upper-case number of this module)
ERR_TINY, ERR_HUGE = 1e-250, 1e250  # _step_end: the same for the error norm's sum of squares
E3_WEIGHT = 0.01  # DOP853's error norm |e5|² / sqrt(|e5|² + E3_WEIGHT |e3|²) (Hairer)
NAN_SHRINK = 0.25  # _retry: a step that met NaN data is tried again this much shorter
ERRP_MIN = 1e-4  # _next_step: the PI controller remembers an error of at least this
EXPO1_BETA = 0.75  # the controller's error exponent 1/k - EXPO1_BETA beta (Hairer's dopri5)
# Hairer's initial step (_initial_guess, _initial_step): h0 = HINIT_FRAC |y0| / |f(y0)| (HINIT_H
# where either norm is below HINIT_TINY), h1 = (HINIT_FRAC / max(|f|, |f'|))^(1/k) (where that
# max is below HINIT_FLAT, max(HINIT_H, HINIT_SHRINK h0)), the step min(HINIT_GROW h0, h1)
HINIT_TINY, HINIT_H, HINIT_FRAC, HINIT_FLAT = 1e-5, 1e-6, 0.01, 1e-15
HINIT_SHRINK, HINIT_GROW = 1e-3, 100.0
HINIT_MIN_STEP = 1e-300  # _start_path: the shortest first guess (a release at an interval's end)
H_AT_REST = 1.0  # _start: the first step of a line whose seed is at rest (it stagnates at once)
ROOT_ITERS, ROOT_TOL = 60, 4e-16  # _root: Newton iterations at most, and the θ it resolves
NO_TIMES = np.zeros(0)  # tp of a steady field
DENSE_DEGREE = np.int64(rosenbrock.DENSE_DEGREE)  # the Rosenbrock stepper's (typed: a helper's argument)
END_DUP = 1e-9  # _emit_pending: a resampled vertex this close to the end (in spacings) is the end

R_OUT = int(Reason.OUT_OF_DOMAIN)
R_MAXLEN = int(Reason.MAX_LENGTH)
R_MAXTIME = int(Reason.MAX_TIME)
R_MAXSTEPS = int(Reason.MAX_STEPS)
R_STAG = int(Reason.STAGNATION)
R_UNDER = int(Reason.STEP_UNDERFLOW)
R_NAN = int(Reason.NAN_FIELD)
R_SEED = int(Reason.SEED_OUTSIDE)

# The step loop's helpers: ``inline`` on the per-step path, ``helper`` off it (flowkit/jit.py).


# -- cells ----------------------------------------------------------------------------------
@inline
def _n_cells(c, period):
    n = c.size
    if period > 0.0 and c[0] + period - c[n - 1] > 0.0:
        return n  # the wrap cell joins the last node to the first node's image
    return n - 1


@inline
def _width(c, period, i):
    n = c.size
    if i < n - 1:
        return c[i + 1] - c[i]
    return c[0] + period - c[n - 1]


@helper
def _locate_cell(c, period, inv, x):
    """(i, lo, hi) of the cell of x on one axis; bounded axes clamp to the end cells."""
    n = c.size
    if period > 0.0:
        i, _ = locate_axis(c, period, inv, x)
        xw = c[0] + (x - c[0]) % period
        lo = c[i] + (x - xw)
        return i, lo, lo + _width(c, period, i)
    xc = min(max(x, c[0]), c[n - 1])
    i, _ = locate_axis(c, 0.0, inv, xc)
    return i, c[i], c[i + 1]


@inline
def _brick_across(bk, a, up, gx, gy, gz, period, ci):
    """``_brick`` of the cell through ci's face on axis a (-1 also where there is none)."""
    c = gx if a == 0 else (gy if a == 1 else gz)
    i = ci[a] + (1 if up else -1)
    n = _n_cells(c, period[a])
    if i < 0 or i >= n:
        if period[a] == 0.0:
            return -1
        i = 0 if i >= n else n - 1
    return missing_brick(bk, i if a == 0 else ci[0], i if a == 1 else ci[1], i if a == 2 else ci[2])


@helper
def _brick_at(bk, gx, gy, gz, period, inv, p):
    """``_brick`` of the cell ``_relocate`` finds for point p."""
    i, _, _ = _locate_cell(gx, period[0], inv[0], p[0])
    j, _, _ = _locate_cell(gy, period[1], inv[1], p[1])
    k, _, _ = _locate_cell(gz, period[2], inv[2], p[2])
    return missing_brick(bk, i, j, k)


@inline
def _gather(vec, bk, ci, coef):
    """Coefficients of the trilinear polynomial of cell ci; False when a corner is not finite.

    ``bk`` empty: ``vec`` is the whole field.  Otherwise the field is bricked (``bricks.py``):
    ``vec`` is the pool of resident bricks and ``bk`` its table; a cell with a corner in a
    brick that is not resident puts the brick's number in ci[3] (the step loop then suspends
    the line, which waits for the brick) and gives NaN."""
    i, j, k = ci[0], ci[1], ci[2]
    # corner (x, y, z bits) at vec[r_xyz, j_y, k_z]: whole field, the row is the node's index;
    # bricked, the corner's slot's rows from slot * size on, then its index in the brick
    if bk.size == 0:
        nx, ny, nz = vec.shape[0], vec.shape[1], vec.shape[2]
        # upper corners (node 0 after the last on a wrapped axis), without integer division
        i1 = i + 1 if i + 1 < nx else 0
        j0, j1 = j, (j + 1 if j + 1 < ny else 0)
        k0, k1 = k, (k + 1 if k + 1 < nz else 0)
        r000 = r010 = r001 = r011 = i
        r100 = r110 = r101 = r111 = i1
    else:
        # (no cell: a stage point made of NaN, after a missing brick left NaN in k)
        missing = missing_brick(bk, i, j, k) if i >= 0 and j >= 0 and k >= 0 else ci[3]
        if missing >= 0 or i < 0 or j < 0 or k < 0:
            ci[3] = missing
            for m in range(8):
                for c in range(3):
                    coef[m, c] = np.nan
            return False
        bx0, l0, bx1, l1 = axis_bricks(bk[B_SIZE], bk[B_NODES], i)
        by0, j0, by1, j1 = axis_bricks(bk[B_SIZE + 1], bk[B_NODES + 1], j)
        bz0, k0, bz1, k1 = axis_bricks(bk[B_SIZE + 2], bk[B_NODES + 2], k)
        size = bk[B_SIZE]
        r000 = slot_of(bk, bx0, by0, bz0) * size + l0
        r100 = slot_of(bk, bx1, by0, bz0) * size + l1
        r010 = slot_of(bk, bx0, by1, bz0) * size + l0
        r110 = slot_of(bk, bx1, by1, bz0) * size + l1
        r001 = slot_of(bk, bx0, by0, bz1) * size + l0
        r101 = slot_of(bk, bx1, by0, bz1) * size + l1
        r011 = slot_of(bk, bx0, by1, bz1) * size + l0
        r111 = slot_of(bk, bx1, by1, bz1) * size + l1
    bad = 0.0
    for c in range(3):  # (float64 before any arithmetic: a float32 field gives the same lines)
        v000 = np.float64(vec[r000, j0, k0, c])
        v100 = np.float64(vec[r100, j0, k0, c])
        v010 = np.float64(vec[r010, j1, k0, c])
        v110 = np.float64(vec[r110, j1, k0, c])
        v001 = np.float64(vec[r001, j0, k1, c])
        v101 = np.float64(vec[r101, j0, k1, c])
        v011 = np.float64(vec[r011, j1, k1, c])
        v111 = np.float64(vec[r111, j1, k1, c])
        coef[0, c] = v000
        coef[1, c] = v100 - v000
        coef[2, c] = v010 - v000
        coef[3, c] = v001 - v000
        coef[4, c] = v110 - v100 - v010 + v000
        coef[5, c] = v101 - v100 - v001 + v000
        coef[6, c] = v011 - v010 - v001 + v000
        coef[7, c] = v111 - v110 - v101 - v011 + v100 + v010 + v001 - v000
        for m in range(8):
            bad += coef[m, c] * 0.0  # NaN once any coefficient is not finite; no branches
    return bad == 0.0


@helper
def _relocate(gx, gy, gz, period, inv, vec, bk, px, py, pz, ci, cf, coef):
    i, lo, hi = _locate_cell(gx, period[0], inv[0], px)
    ci[0] = i
    cf[0] = lo
    cf[3] = hi
    cf[6] = 1.0 / _width(gx, period[0], i)
    i, lo, hi = _locate_cell(gy, period[1], inv[1], py)
    ci[1] = i
    cf[1] = lo
    cf[4] = hi
    cf[7] = 1.0 / _width(gy, period[1], i)
    i, lo, hi = _locate_cell(gz, period[2], inv[2], pz)
    ci[2] = i
    cf[2] = lo
    cf[5] = hi
    cf[8] = 1.0 / _width(gz, period[2], i)
    return _gather(vec, bk, ci, coef)


@helper
def _copy_cell(ci, cf, coef, ci_to, cf_to, coef_to):
    for a in range(3):
        ci_to[a] = ci[a]
    for a in range(9):
        cf_to[a] = cf[a]
    for m in range(8):
        for a in range(3):
            coef_to[m, a] = coef[m, a]


@inline
def _f(px, py, pz, param, aware, gx, gy, gz, period, inv, vec, bk, ci, cf, coef, k, row):
    """Right-hand side at p: cell-aware, the current cell's polynomial; otherwise the polynomial
    of the cell holding p, looked up unless p is strictly inside the cached cell.  A point on a
    face is located afresh, so the cell (and the rounding) depends on the point alone, not on
    the cell the line came from: lanes.py locates every point and gets the same lines.  NaN
    for a NaN cell."""
    if not aware and not (ci[0] >= 0 and cf[0] < px < cf[3] and cf[1] < py < cf[4]
                          and cf[2] < pz < cf[5]):
        _relocate(gx, gy, gz, period, inv, vec, bk, px, py, pz, ci, cf, coef)
    return _fc(px, py, pz, param, cf, coef, k, row)


@inline
def _move(a, up, c, per, vec, bk, ci, cf, coef):
    """Step the current cell through its face on axis a; 0 ok, 1 left the domain, 2 NaN cell."""
    if up:
        i = ci[a] + 1
        if i >= _n_cells(c, per):
            if per == 0.0:
                return 1
            i = 0
        wdt = _width(c, per, i)
        cf[a] = cf[3 + a]
        cf[3 + a] = c[i + 1] if per == 0.0 else cf[a] + wdt
    else:
        i = ci[a] - 1
        if i < 0:
            if per == 0.0:
                return 1
            i = _n_cells(c, per) - 1
        wdt = _width(c, per, i)
        cf[3 + a] = cf[a]
        cf[a] = c[i] if per == 0.0 else cf[3 + a] - wdt
    ci[a] = i
    cf[6 + a] = 1.0 / wdt
    return 0 if _gather(vec, bk, ci, coef) else 2


@inline
def _move_axis(a, up, gx, gy, gz, period, vec, bk, ci, cf, coef):
    # the axis array chosen at run time: no reference counting here (no NRT in the step loop),
    # and one copy of _move at each call site rather than one per axis
    c = gx if a == 0 else (gy if a == 1 else gz)
    return _move(a, up, c, period[a], vec, bk, ci, cf, coef)


@inline
def _through_face(a, up, y, param, gx, gy, gz, period, vec, bk, ci, cf, coef, k):
    """Into the neighbour cell through the current cell's face on axis a (the upper one if up),
    k0 = f(y) there: 0 ok, 1 left the domain, 2 a NaN cell."""
    res = _move_axis(a, up, gx, gy, gz, period, vec, bk, ci, cf, coef)
    if res == 0:
        _fc(y[0], y[1], y[2], param, cf, coef, k, np.int64(0))
    return res


@inline
def _onto_next_cell(d, y, k, param, gx, gy, gz, period, vec, bk, ci, cf, coef):
    """Cell-aware, before a step: where the line stands on a face of its cell moving outwards
    (along d k0), into the neighbour cell; elsewhere back into the cell where rounding left the
    point a hair outside.  The reason to stop (R_OUT, R_NAN), or -1."""
    for a in range(3):
        mv = d * k[0, a]
        up = y[a] >= cf[3 + a] and mv > 0.0
        if up or (y[a] <= cf[a] and mv < 0.0):
            y[a] = cf[3 + a] if up else cf[a]
            res = _through_face(a, up, y, param, gx, gy, gz, period, vec, bk, ci, cf, coef, k)
            if res != 0:
                return R_OUT if res == 1 else R_NAN
        else:
            y[a] = min(max(y[a], cf[a]), cf[3 + a])
    return -1


@inline
def _exit_time(d, y, k, cf):
    """The step (in the line's parameter) at which y + h d k0 leaves the current cell, and
    the axis of the face it leaves by (-1: none)."""
    t_exit = np.inf
    axis = -1
    for a in range(3):
        mv = d * k[0, a]
        if mv > 0.0:
            ta = (cf[3 + a] - y[a]) / mv
        elif mv < 0.0:
            ta = (y[a] - cf[a]) / -mv
        else:
            continue
        if ta < t_exit:
            axis = a
        t_exit = min(t_exit, ta)
    return t_exit, axis


@inline
def _stage_point(ma, k, st, y, hs, yt):
    """yt = y + hs * Σ_m<st ma[st, m] k[m] (position): the three sums advance together over m,
    each adding its terms in the same order as a sum per component would."""
    a0 = 0.0
    a1 = 0.0
    a2 = 0.0
    for m in range(st):
        c = ma[st, m]
        a0 += c * k[m, 0]
        a1 += c * k[m, 1]
        a2 += c * k[m, 2]
    yt[0] = y[0] + hs * a0
    yt[1] = y[1] + hs * a1
    yt[2] = y[2] + hs * a2


# -- dense output -----------------------------------------------------------------------------
@inline
def _stage(ma, mc, k, st, y, hs, yt, tau, param, inc, gx, gy, gz, period, inv, vec, bk, ci, cf,
           coef, vb, tp):
    """Stage st of an explicit step of hs from (y, tau): its point into yt, the field there into
    k[st], by the loop's evaluator: the two snapshots ``vec`` and ``vb`` (pathlines, vb not
    None), the cell the step starts in (``inc``), or the cell holding the point."""
    _stage_point(ma, k, st, y, hs, yt)
    if vb is not None:
        stage(yt, tau + mc[st] * hs, gx, gy, gz, period, inv, vec, vb, bk, tp, k, st, ci)
    elif inc:
        _fc(yt[0], yt[1], yt[2], param, cf, coef, k, st)
    else:
        _f(yt[0], yt[1], yt[2], param, inc, gx, gy, gz, period, inv, vec, bk, ci, cf, coef, k, st)


@inline
def _dense(qd, comp, q, y0, hs, th):
    """y0 + hs * Σ_j Q[comp, j] θ^(j+1), Q the step's dense coefficients (4, QMAX)."""
    acc = 0.0
    for j in range(q - 1, -1, -1):
        acc = acc * th + qd[comp, j]
    return y0 + hs * (th * acc)


@inline
def _root(qd, comp, q, y0, hs, target, sgn, thi):
    """θ in [0, thi] where the dense output of ``comp`` meets ``target``, going from
    sgn * (value - target) < 0 to >= 0: safeguarded Newton from the secant estimate."""
    a = 0.0
    ga = sgn * (y0 - target)
    if ga > 0.0:
        return 0.0
    b = thi
    gb = sgn * (_dense(qd, comp, q, y0, hs, b) - target)
    if gb < 0.0:
        return thi  # only rounding keeps the dense end short of the event
    # from the secant estimate; on the face itself (ga == 0) look for the crossing after θ = 0
    th = a - ga * (b - a) / (gb - ga) if ga < 0.0 else 0.5 * b
    for _ in range(ROOT_ITERS):
        r = 0.0
        dr = 0.0
        for j in range(q - 1, -1, -1):
            dr = dr * th + r
            r = r * th + qd[comp, j]
        g = sgn * (y0 + hs * (th * r) - target)
        if g == 0.0 and th > 0.0:
            return th
        if g > 0.0:
            b = th
        else:
            a = th
        dg = sgn * hs * (r + th * dr)
        nxt = th - g / dg
        if not (nxt > a and nxt < b):
            nxt = 0.5 * (a + b)
        if abs(nxt - th) <= ROOT_TOL or b - a <= ROOT_TOL:
            return nxt
        th = nxt
    return th


# -- output ---------------------------------------------------------------------------------------
@inline
def _put(out_p, out_par, out_n, slot, px, py, pz, t, s):
    n = out_n[slot]
    out_p[slot, n, 0] = px
    out_p[slot, n, 1] = py
    out_p[slot, n, 2] = pz
    out_par[slot, n, 0] = t
    out_par[slot, n, 1] = s
    out_n[slot] = n + 1


@helper
def _emit_pending(l, slot, sf, si, d, param, q, spacing, phase, out_p, out_par, out_n, B):
    """Emit the resampled vertices of the last step (and the final vertex once the line is done).

    Returns False when the buffer filled up first (the line suspends; the rest stays pending).
    """
    C0, C1, C2, C3 = np.int64(0), np.int64(1), np.int64(2), np.int64(3)  # typed (see helper)
    if si[l, I_PEND] != 0:
        hs = sf[l, S_HS]
        th_end = sf[l, S_TH]
        tau0 = sf[l, S_TAU0]
        dep0 = sf[l, S_Y0 + 3]
        s_end = sf[l, S_DEP] if param == 0 else sf[l, S_TAU]
        qd = sf[l, S_Q:S_Q + 4 * QMAX].reshape((4, QMAX))  # the step's dense coefficients
        while True:
            m = si[l, I_M]
            target = phase + m * spacing
            if target > d * s_end:
                break
            if out_n[slot] >= B:
                return False
            if target == d * s_end:
                px, py, pz = sf[l, S_Y], sf[l, S_Y + 1], sf[l, S_Y + 2]
                t = sf[l, S_TAU] if param == 0 else sf[l, S_DEP]
            else:
                if param == 1:
                    th = (d * target - tau0) / hs
                else:
                    th = _root(qd, C3, q, dep0, hs, d * target, d, th_end)
                px = _dense(qd, C0, q, sf[l, S_Y0], hs, th)
                py = _dense(qd, C1, q, sf[l, S_Y0 + 1], hs, th)
                pz = _dense(qd, C2, q, sf[l, S_Y0 + 2], hs, th)
                t = tau0 + th * hs if param == 0 else _dense(qd, C3, q, dep0, hs, th)
            _put(out_p, out_par, out_n, slot, px, py, pz, t, d * target)
            sf[l, S_LAST_S] = d * target
            si[l, I_M] = m + 1
        si[l, I_PEND] = 0
    if si[l, I_FINAL] != 0:
        s_end = sf[l, S_DEP] if param == 0 else sf[l, S_TAU]
        t_end = sf[l, S_TAU] if param == 0 else sf[l, S_DEP]
        dup = abs(sf[l, S_LAST_S] - s_end) <= END_DUP * spacing
        if dup and out_n[slot] > 0:
            out_n[slot] -= 1  # replace a resampled vertex that coincides with the end
        elif dup:
            si[l, I_FINAL] = 0
            return True
        if out_n[slot] >= B:
            return False
        _put(out_p, out_par, out_n, slot, sf[l, S_Y], sf[l, S_Y + 1], sf[l, S_Y + 2], t_end, s_end)
        sf[l, S_LAST_S] = s_end
        si[l, I_FINAL] = 0
    return True


@helper
def _err_rescaled(hs, k, me, me2, n_err, has_e2, fo, y, y1):
    """The step's error norm with h inside the squares: the value of the loop's formula (h
    outside), used only where (e / sc)² over- or underflows (speeds beyond about 1e±150)."""
    e5 = 0.0
    e3 = 0.0
    for a in range(3):
        sc = fo[O_ATOL + a] + fo[O_RTOL + a] * max(abs(y[a]), abs(y1[a]))
        ea = 0.0
        eb = 0.0
        for m in range(n_err):
            ea += me[m] * k[m, a]
            eb += me2[m] * k[m, a]
        e5 += (hs * ea / sc) ** 2
        e3 += (hs * eb / sc) ** 2
    if has_e2:
        den = e5 + E3_WEIGHT * e3
        return 0.0 if den == 0.0 else e5 / math.sqrt(den * 3.0)
    return math.sqrt(e5 / 3.0)


@inline
def _step_end(y, k, hs, mb, me, me2, n_err, adaptive, has_e2, fo, y1):
    """The end of a step hs from y with the stages k: y1 = y + hs Σ b_m k_m (position into y1,
    the dependent parameter returned) and, adaptive, the error norm: the RMS over the position
    of the embedded estimate scaled by atol + rtol max(|y|, |y1|) (with DOP853's second
    estimate, Hairer's |e5|² / sqrt(|e5|² + 0.01 |e3|²)).  (dep1, err, all finite).  Shared
    by the streamline and pathline kernels."""
    finite = True
    e5 = 0.0
    e3 = 0.0
    dep1 = 0.0
    for a in range(4):
        acc = 0.0
        for m in range(n_err):
            acc += mb[m] * k[m, a]
        v1 = y[a] + hs * acc
        if not math.isfinite(v1):
            finite = False
        if a < 3:
            y1[a] = v1
        else:
            dep1 = v1
        if adaptive and a < 3:
            sc = fo[O_ATOL + a] + fo[O_RTOL + a] * max(abs(y[a]), abs(v1))
            ea = 0.0
            for m in range(n_err):
                ea += me[m] * k[m, a]
            e5 += (ea / sc) ** 2
            if has_e2:  # (e3 stays 0 without a second estimate: me2 is all zeros then)
                eb = 0.0
                for m in range(n_err):
                    eb += me2[m] * k[m, a]
                e3 += (eb / sc) ** 2
    err = 0.0
    if adaptive:
        if has_e2:
            den = e5 + E3_WEIGHT * e3
            err = 0.0 if den == 0.0 else abs(hs) * e5 / math.sqrt(den * 3.0)
        else:
            err = abs(hs) * math.sqrt(e5 / 3.0)
        if finite and not (e5 + e3 > ERR_TINY and e5 + e3 < ERR_HUGE):
            err = _err_rescaled(hs, k, me, me2, n_err, has_e2, fo, y, y1)  # (huge speeds)
        if not math.isfinite(err):
            finite = False
    return dep1, err, finite


@inline
def _retry(hs, err, nan, hmin, safety, facmin, expo1):
    """The step after a rejected step hs: a quarter of it after NaN data (``nan``: a stage or y1
    met a NaN cell, or a zero speed in arc-length mode), else the controller's cut for the error
    norm err; and the reason to stop instead (R_NAN, R_UNDER; -1: retry) when it falls below
    hmin.  Shared with the pathline and Rosenbrock kernels."""
    if nan:
        h = NAN_SHRINK * hs
        stop = R_NAN
    else:
        h = hs * max(facmin, safety * err ** (-expo1))
        stop = R_UNDER
    return h, (stop if abs(h) < hmin else -1)


@inline
def _from_anchor(ax, ay, az, px, py, pz, fo):
    """(squared distance from the anchor a to the point p in units of the tolerance, the
    smallest per-axis tolerance): ``_stalled``'s measures, shared with the lanes."""
    d2 = 0.0
    tol = np.inf
    for i in range(3):
        x = ax if i == 0 else (ay if i == 1 else az)
        p = px if i == 0 else (py if i == 1 else pz)
        sc = fo[O_ATOL + i] + fo[O_RTOL + i] * max(abs(x), abs(p))
        d2 += ((p - x) / sc) ** 2
        tol = min(tol, sc)
    return d2, tol


@inline
def _stalled(sf, l, y1, t1, fo):
    """The stagnation test on the line's progress, after an accepted step to y1 at time t1.

    The speed test at the loop head reads the field at the line's point.  Where the flow runs
    onto a no-slip wall (nodes at rest), a line that comes within its tolerance of the wall
    takes explicit steps far beyond their stability interval: the error estimate, proportional
    to that distance, still passes, and the line hovers there, or cycles toward the wall and
    back, at a point where the field is still faster than the threshold, until ``max_steps``.
    So line l also stagnates when it has not left the ball of its tolerance (atol + rtol |y|
    per axis) around its anchor for longer than the stagnation speed needs to cross that
    tolerance: it moved slower than the threshold.  Leaving the ball moves the anchor (S_ANCHOR:
    position, then time) to y1, t1."""
    d2, tol = _from_anchor(sf[l, S_ANCHOR], sf[l, S_ANCHOR + 1], sf[l, S_ANCHOR + 2], y1[0],
                           y1[1], y1[2], fo)
    if d2 > 1.0:
        for a in range(3):
            sf[l, S_ANCHOR + a] = y1[a]
        sf[l, S_ANCHOR + 3] = t1
        return False
    return abs(t1 - sf[l, S_ANCHOR + 3]) * fo[O_STAG] > tol


@inline
def _next_step(err, errp, errpb, hs, h, last_rej, safety, facmin, facmax, beta, expo1):
    """Hairer's PI controller with Gustafsson's memory, after an accepted step of hs (h: the
    step the controller had asked for): (next step, errp, errp ** beta).  beta = 0 (the
    Rosenbrock stepper's): the I-controller, in the reject rule's form."""
    if err == 0.0:
        g = facmax
    elif beta == 0.0:
        g = min(facmax, max(facmin, safety * err ** (-expo1)))
    else:
        g = min(facmax, max(facmin, safety * errpb / err ** expo1))
    if last_rej:
        g = min(g, 1.0)
    if max(err, ERRP_MIN) != errp:  # errp ** beta only when errp changes (often ERRP_MIN)
        errp = max(err, ERRP_MIN)
        errpb = errp ** beta
    hnext = hs * g
    if g >= 1.0 and abs(h) > abs(hnext):
        hnext = h  # the step was cut by the cell cap or a limit, not by its error
    return hnext, errp, errpb


@helper
def _scaled_rms(fo, y, k, i, j):
    """RMS over the position of (k[i] - k[j]) (k[i] alone when j < 0) scaled by atol + rtol |y|,
    rescaled where the squares overflow (huge speeds)."""
    w0 = (k[i, 0] - (k[j, 0] if j >= 0 else 0.0)) / (fo[O_ATOL] + fo[O_RTOL] * abs(y[0]))
    w1 = (k[i, 1] - (k[j, 1] if j >= 0 else 0.0)) / (fo[O_ATOL + 1] + fo[O_RTOL + 1] * abs(y[1]))
    w2 = (k[i, 2] - (k[j, 2] if j >= 0 else 0.0)) / (fo[O_ATOL + 2] + fo[O_RTOL + 2] * abs(y[2]))
    r = math.sqrt((w0 ** 2 + w1 ** 2 + w2 ** 2) / 3.0)
    if not (r < math.inf):
        r = _norm3(w0, w1, w2) / math.sqrt(3.0)
    return r


@inline
def _initial_guess(fo, y, k):
    """First half of Hairer's initial step (Hairer, Nørsett & Wanner I, II.4), on the position:
    (h0, |f(y0)|) from the scaled norms of y0 and f(y0) = k[0].  The caller evaluates the field
    at y0 + h0 k[0] into k[1] and passes both to ``_initial_step``.  Shared with pathlines."""
    d0 = 0.0
    for a in range(3):
        d0 += (y[a] / (fo[O_ATOL + a] + fo[O_RTOL + a] * abs(y[a]))) ** 2
    d0 = math.sqrt(d0 / 3.0)
    d1 = _scaled_rms(fo, y, k, np.int64(0), np.int64(-1))  # typed (see helper)
    return (HINIT_H if (d0 < HINIT_TINY or d1 < HINIT_TINY) else HINIT_FRAC * d0 / d1), d1


@inline
def _initial_step(fo, y, k, h0, d1, kexp, ok):
    """Second half: the step from the change of f over h0 (k[1] - k[0]); ``ok`` False when the
    second evaluation failed (NaN data)."""
    d2 = _scaled_rms(fo, y, k, np.int64(1), np.int64(0)) / h0
    if not ok or max(d1, d2) <= HINIT_FLAT or not math.isfinite(d2):
        h1 = max(HINIT_H, h0 * HINIT_SHRINK)
    else:
        h1 = (HINIT_FRAC / max(d1, d2)) ** (1.0 / kexp)
    return min(HINIT_GROW * h0, h1)


@inline
def _load_state(sf, si, l, y, k, i_lastrej, beta):
    """A suspended line's step state (written by ``_save_state``): the position and dependent
    variable into y, f(y) into k[0]; returns (parameter, h, errp, errp ** beta, accepted,
    rejected, last step rejected).  The pathline kernel keeps the same float columns."""
    for a in range(3):
        y[a] = sf[l, S_Y + a]
    y[3] = sf[l, S_DEP]
    for a in range(4):
        k[0, a] = sf[l, S_K0 + a]
    errp = sf[l, S_ERRP]
    return (sf[l, S_TAU], sf[l, S_H], errp, errp ** beta, si[l, I_NACC], si[l, I_NREJ],
            si[l, i_lastrej] != 0)


@inline
def _save_state(sf, si, l, y, k, tau, h, errp, n_acc, n_rej, last_rej, i_lastrej):
    for a in range(3):
        sf[l, S_Y + a] = y[a]
    sf[l, S_DEP] = y[3]
    sf[l, S_TAU] = tau
    sf[l, S_H] = h
    sf[l, S_ERRP] = errp
    for a in range(4):
        sf[l, S_K0 + a] = k[0, a]
    si[l, I_NACC] = n_acc
    si[l, I_NREJ] = n_rej
    si[l, i_lastrej] = 1 if last_rej else 0


# -- lines ------------------------------------------------------------------------------------
@helper
def _store(sf, si, l, y, k, tau, h, errp, n_acc, n_rej, last_rej, hk, n_cross, kfail, kwait,
           cf, ci):
    """The line's whole state into its rows, for ``_load_state`` and the cell restore."""
    _save_state(sf, si, l, y, k, tau, h, errp, n_acc, n_rej, last_rej, np.int64(I_LASTREJ))
    sf[l, S_HK] = hk
    si[l, I_NCROSS], si[l, I_KFAIL], si[l, I_KWAIT] = n_cross, kfail, kwait
    for a in range(3):
        sf[l, S_LO + a] = cf[a]
        sf[l, S_HI + a] = cf[3 + a]
        si[l, I_CELL + a] = ci[a]


@helper
def _start(l, slot, seeds, dirs, phases, gx, gy, gz, period, inv, vec, bk, kexp, fo, io, sf, si,
           out_p, out_par, out_n, k, coef, cf, ci, y, yt, dlo, dhi):
    """Start line l at its seed: the first vertex, the initial step, and the state of a line
    suspended before its first step (``_load_state``); False when the seed lies outside the
    domain or in NaN data (the line is done) or where a brick is not resident (ci[3]: it
    waits).  Compiled once and called (once per line)."""
    C0, C1 = np.int64(0), np.int64(1)  # typed (see helper)
    param, aware, emit = io[P_PARAM], io[P_AWARE] != 0, io[P_EMIT]
    d, phase = dirs[l], phases[l]
    px, py, pz = seeds[l, 0], seeds[l, 1], seeds[l, 2]
    inside = math.isfinite(px) and math.isfinite(py) and math.isfinite(pz)
    for a in range(3):
        x = seeds[l, a]
        if period[a] == 0.0 and not (dlo[a] <= x <= dhi[a]):
            inside = False
    sp = np.nan
    if inside:
        _relocate(gx, gy, gz, period, inv, vec, bk, px, py, pz, ci, cf, coef)
        sp = _fc(px, py, pz, param, cf, coef, k, C0)
    if ci[3] >= 0:
        return False  # its brick is not resident: the line waits, NEW
    if not (inside and math.isfinite(sp)):
        si[l, I_STATUS] = DONE
        si[l, I_REASON] = R_SEED
        return False
    y[0], y[1], y[2], y[3] = px, py, pz, 0.0
    ros_first = io[P_ROS] != 0  # (the Rosenbrock stepper from the seed)
    si[l, I_ROS] = 1 if ros_first else 0
    h = fo[O_H0]
    if h <= 0.0 and ros_first:
        h = rosenbrock.initial_step(cf, sp, param)
    elif h <= 0.0 and sp > 0.0:
        h0, d1 = _initial_guess(fo, y, k)
        for a in range(3):
            yt[a] = y[a] + d * h0 * k[0, a]
        _f(yt[0], yt[1], yt[2], param, aware, gx, gy, gz, period, inv, vec, bk, ci, cf, coef, k, C1)
        if ci[3] >= 0:
            return False
        h = _initial_step(fo, y, k, h0, d1, kexp, np.bool_(True))
    elif h <= 0.0:
        h = H_AT_REST
    h = d * min(h, fo[O_HMAX])
    zero = np.int64(0)
    _store(sf, si, l, y, k, 0.0, h, ERRP_MIN, zero, zero, np.bool_(False), abs(h), zero, zero, zero,
           cf, ci)
    si[l, I_PEND] = si[l, I_FINAL] = 0
    for a in range(4):  # the seed, at time 0
        sf[l, S_ANCHOR + a] = y[a]
    si[l, I_STATUS] = RUNNING
    sf[l, S_LAST_S] = -np.inf
    si[l, I_M] = 0
    if emit == EMIT_STEPS or (emit == EMIT_SPACING and phase == 0.0):
        _put(out_p, out_par, out_n, slot, px, py, pz, 0.0, 0.0)
        sf[l, S_LAST_S] = 0.0
        si[l, I_M] = 1 if emit == EMIT_SPACING else 0
    return True


@helper
def _start_path(l, slot, seeds, dirs, gx, gy, gz, period, inv, v0, v1, bk, tp, kexp, fo, sf,
                si, out_p, out_par, out_n, k, coef, cf, ci, y, yt):
    """``_start`` for a pathline: released at tp[3 + l] into the field between the snapshots
    v0 and v1 (at tp[0], tp[1]); its initial step no longer than the time left to tp[2].  False
    when the seed lies outside the domain or in NaN data (the line is done) or where a brick is
    not resident (ci[3]: it waits)."""
    d = dirs[l]
    px, py, pz = seeds[l, 0], seeds[l, 1], seeds[l, 2]
    inside = True
    for a in range(3):
        c = gx if a == 0 else (gy if a == 1 else gz)
        if period[a] == 0.0 and not (c[0] <= seeds[l, a] <= c[c.size - 1]):
            inside = False
    t = tp[3 + l]
    if not (inside and velocity(px, py, pz, t, gx, gy, gz, period, inv, v0, v1, bk, tp[0], tp[1],
                                k, np.int64(0), ci)):
        if ci[3] < 0:
            si[l, I_STATUS] = DONE
            si[l, I_REASON] = R_SEED
        return False
    y[0], y[1], y[2], y[3] = px, py, pz, 0.0
    hmax = fo[O_HMAX]
    h = fo[O_H0]
    if h <= 0.0:
        h0, d1 = _initial_guess(fo, y, k)
        h0 = min(h0, hmax, max(abs(tp[2] - t), HINIT_MIN_STEP))
        for a in range(3):
            yt[a] = y[a] + d * h0 * k[0, a]
        ok = velocity(yt[0], yt[1], yt[2], t + d * h0, gx, gy, gz, period, inv, v0, v1, bk, tp[0],
                      tp[1], k, np.int64(1), ci)
        if ci[3] >= 0:
            return False
        h = _initial_step(fo, y, k, h0, d1, kexp, ok)
    h = d * min(h, hmax)
    zero = np.int64(0)
    _store(sf, si, l, y, k, t, h, ERRP_MIN, zero, zero, np.bool_(False), abs(h), zero, zero, zero,
           cf, ci)
    si[l, I_PEND] = si[l, I_FINAL] = 0
    si[l, I_STATUS] = RUNNING
    _put(out_p, out_par, out_n, slot, px, py, pz, t, 0.0)
    return True


# Compiled without NRT, so without reference counting: every array here is the caller's.  With
# NRT, each array handed to an inlined helper in the step loop cost an atomic increment and
# decrement, a fifth of a plain rk4 step's time (measured); NRT cannot allocate, hence the
# scratch arrays from _advance_range
@kernel(nogil=True, error_model="numpy")
def _advance_lines(start, stop, active, seeds, dirs, spacings, phases, gx, gy, gz, period, inv,
                   vec, bk, mc, ma, mb, me, me2, mp, mi, fo, io, sf, si, out_p, out_par, out_n,
                   vb, tp, ros, k, coef, cf, ci, y, yt, ys, y1, dlo, dhi, qd, coef0, cf0, ci0,
                   yk_s, coef_s, cf_s, ci_s, kk, J, W, Wi, g, u, rhs):
    """The lines ``active[start:stop]`` one after the other (slots start..stop-1), without the
    GIL, so that threads run ranges side by side (``threads.run_ranges``).

    A bricked field (``bk`` not empty): a step commits nothing until every cell it reads is
    resident.  Each step starts from a copy of the line's point, k0 and cell (``*_s``); where a
    cell's brick is missing (ci[3]), the line goes back to that copy and suspends, waiting for
    the brick (si[l, I_WAIT]), to take the same step again once it is there.

    The field evaluator and the stepper are compile-time choices: numba compiles this loop once
    per type of ``vb`` and ``ros`` and drops the branches of the ones that are None (arrays
    inside a tuple cannot be handed on without NRT).  ``vb``, for pathlines: the snapshot at
    time tp[1], ``vec`` the one at tp[0] (bricked: the two snapshots' pools, ``bk`` the table
    of both); the field between them (``unsteady.py``; plain stepping, time the parameter
    ``tau``, absolute); lines start at their release times ``tp[3 + l]`` and stop at tp[2], the
    end of the interval, to go on in the next one.
    ``ros``: the Rosenbrock stepper's table (``rosenbrock.table``), for the lines with
    si[l, I_ROS] set: from their seeds (io[P_ROS]), or from the step where the explicit
    stepper's stiffness test flags them (``auto``); cell-aware, never across faces, with the
    I-controller and its Hermite dense output; kk, J, W, Wi, g, u, rhs its scratch."""
    S, n_err, fs, adaptive, kexp = mi[M_STAGES], mi[M_NERR], mi[M_FSAL], mi[M_ADAPTIVE] != 0, mi[M_KEXP]
    has_e2 = mi[M_HASE2] != 0
    C0, C1, C2, C3 = np.int64(0), np.int64(1), np.int64(2), np.int64(3)  # typed (see helper)
    q = mp.shape[1]
    param, aware, emit = io[P_PARAM], io[P_AWARE] != 0, io[P_EMIT]
    max_steps = io[P_MAXSTEPS]
    st_stiff = io[P_STIFF]
    cross = aware and adaptive and io[P_CROSS] != 0
    wraps = period[0] > 0.0 or period[1] > 0.0 or period[2] > 0.0
    safety, facmin, facmax, beta = fo[O_SAFETY], fo[O_FACMIN], fo[O_FACMAX], fo[O_BETA]
    hmin, hmax, cellfac, stag = fo[O_HMIN], fo[O_HMAX], fo[O_CELLFAC], fo[O_STAG]
    lim_ind = fo[O_MAXTIME] if param == 0 else fo[O_MAXLEN]
    lim_dep = fo[O_MAXLEN] if param == 0 else fo[O_MAXTIME]
    r_ind = R_MAXTIME if param == 0 else R_MAXLEN
    r_dep = R_MAXLEN if param == 0 else R_MAXTIME
    expo1 = 1.0 / kexp - EXPO1_BETA * beta
    n_step = max(n_err, fs + 1)  # the stages of every step (the last one: f(y1))
    if ros is not None:  # its f(y1) row, controller exponent
        ns = np.int64(ros.shape[0] - 1)
        expo1_ros = 1.0 / ros[ns, 0]
    B = out_p.shape[1]
    mode = io[P_PASS]
    bricked = bk.size > 0
    for slot in range(start, stop):
        l = active[slot]
        if mode != PASS_FINISH:
            out_n[slot] = 0
        elif si[l, I_STATUS] == DONE:
            continue
        setup_only = mode == PASS_SETUP
        d = dirs[l]
        spacing, phase = spacings[l], phases[l]
        if si[l, I_STATUS] == DONE:  # only a pending emission left
            _emit_pending(l, slot, sf, si, d, param, q, spacing, phase, out_p, out_par, out_n, B)
            continue
        ci[0] = ci[1] = ci[2] = ci[3] = -1
        si[l, I_WAIT] = 0
        dlo[0], dlo[1], dlo[2] = gx[0], gy[0], gz[0]
        dhi[0], dhi[1], dhi[2] = gx[gx.size - 1], gy[gy.size - 1], gz[gz.size - 1]

        if si[l, I_STATUS] == NEW:
            if vb is None:
                started = _start(l, slot, seeds, dirs, phases, gx, gy, gz, period, inv, vec, bk,
                                 kexp, fo, io, sf, si, out_p, out_par, out_n, k, coef, cf, ci, y,
                                 yt, dlo, dhi)
            else:
                started = _start_path(l, slot, seeds, dirs, gx, gy, gz, period, inv, vec,
                                      vb, bk, tp, kexp, fo, sf, si, out_p, out_par, out_n, k,
                                      coef, cf, ci, y, yt)
            if not started:
                si[l, I_WAIT] = ci[3] + 1
                continue
        if vb is None:  # the parameter's value at the limit
            tau_lim = d * lim_ind
        else:
            tau_lim = tp[3 + l] + d * lim_ind
        # the stepper's: f(y1) row, dense degree, controller, cell-aware, adaptive, crossing
        rosl = False
        fsl, ql, expo1l, betal, awl, adl, crossl = fs, q, expo1, beta, aware, adaptive, cross
        if ros is not None and si[l, I_ROS] != 0:
            rosl = True
            fsl, ql, expo1l, betal, awl, adl, crossl = ns, DENSE_DEGREE, expo1_ros, 0.0, True, True, False
        # (a new line starts from the state _start wrote, as a suspended line resumes)
        tau, h, errp, errpb, n_acc, n_rej, last_rej = _load_state(sf, si, l, y, k, np.int64(I_LASTREJ), betal)
        hk = sf[l, S_HK]
        n_cross, kfail, kwait = si[l, I_NCROSS], si[l, I_KFAIL], si[l, I_KWAIT]
        # the line's cell as it was: cell-aware, the one it steps in; plain on a periodic grid,
        # the cached one (a periodic cell's faces carry the rounding of the point that found
        # it, so a cell found again could differ in the last bit: a suspended line resumes bit
        # for bit only so; elsewhere the cell found again is the same)
        if awl or (wraps and si[l, I_CELL] >= 0):
            for a in range(3):
                ci[a] = si[l, I_CELL + a]
                cf[a] = sf[l, S_LO + a]
                cf[3 + a] = sf[l, S_HI + a]
            cf[6] = 1.0 / _width(gx, period[0], ci[0])
            cf[7] = 1.0 / _width(gy, period[1], ci[1])
            cf[8] = 1.0 / _width(gz, period[2], ci[2])
            _gather(vec, bk, ci, coef)
            if ci[3] >= 0:
                si[l, I_WAIT] = ci[3] + 1
                continue
        if not _emit_pending(l, slot, sf, si, d, param, ql, spacing, phase, out_p, out_par, out_n, B):
            continue

        reason = -1
        hk_s, kwait_s = hk, kwait
        suspended = setup_only  # (lanes.py's setup pass: the line stops before its first step)
        while not suspended:
            if out_n[slot] >= B:
                suspended = True
                break
            speed = k[0, 3] if param == 0 else 1.0 / k[0, 3]
            if vb is None:
                if not (speed >= stag) or speed == 0.0:
                    reason = R_STAG
                    break
            else:  # at the interval's end: on in the next one; at rest now, it may move later
                if tau == tp[2]:
                    suspended = True
                    break
                if stag > 0.0 and not (speed >= stag):
                    reason = R_STAG
                    break
            if n_acc + n_rej >= max_steps:
                reason = R_MAXSTEPS
                break
            if bricked:  # what a step that meets a missing brick goes back to
                for a in range(4):
                    yk_s[a] = y[a]
                    yk_s[4 + a] = k[0, a]
                _copy_cell(ci, cf, coef, ci_s, cf_s, coef_s)
                hk_s, kwait_s = hk, kwait
            # where the line stands: on a face moving outwards -> next cell, or out of the domain
            if awl:
                reason = _onto_next_cell(d, y, k, param, gx, gy, gz, period, vec, bk, ci, cf, coef)
                if ci[3] >= 0:
                    reason = -1
                    suspended = True
                    break
                if reason >= 0:
                    break
            else:
                for a in range(3):
                    mv = d * k[0, a]
                    if period[a] == 0.0 and (
                            (y[a] <= dlo[a] and mv < 0.0) or (y[a] >= dhi[a] and mv > 0.0)):
                        reason = R_OUT
                if reason >= 0:
                    break

            # step size: controller, cell cap (or a step across faces), parameter limit
            hs = h
            long = False
            t_exit = np.inf
            ax_exit = -1
            if awl:  # (fixed steps too: their stages would extend the cell's polynomial far out)
                t_exit, ax_exit = _exit_time(d, y, k, cf)
                cap = cellfac * t_exit
                if cap > 0.0 and abs(hs) > cap:
                    if crossl and kwait == 0 and hk > KINK_CELLS * cap:
                        hs = d * min(abs(hs), hk)
                        long = True
                    else:
                        hs = d * cap
                        if crossl:  # (the crossing controller's state, only where it is used)
                            hk *= KINK_GROW
                            kwait = max(kwait - 1, 0)
            hit_lim = False
            hit_goal = False  # (pathlines) the step ends at the interval's end
            if vb is None:
                rem = lim_ind - abs(tau)
            else:
                rem = d * (tau_lim - tau)
                rem_goal = d * (tp[2] - tau)
                if rem_goal < rem:
                    rem = rem_goal
                    hit_goal = True
            if abs(hs) >= rem:
                hs = d * rem
                hit_lim = not hit_goal
            else:
                hit_goal = False
            # fetch the cells the step is headed for (predicted along k0) now, so that their memory
            # latency overlaps the arithmetic instead of stalling a dependent chain: cell-aware, the
            # end's (gathered at the face); plain, each stage's (a step spans cells, each stage
            # gathers its own)
            inc = awl and not long  # every stage from the cell the step starts in
            if long:
                _copy_cell(ci, cf, coef, ci0, cf0, coef0)
            # (not in a bricked field's pool, whose layout is not the grid's)
            if inc and ax_exit >= 0 and not bricked:  # the neighbour across the exit face
                nb0, nb1, nb2 = ci[0], ci[1], ci[2]
                step = 1 if d * k[0, ax_exit] > 0.0 else -1
                if ax_exit == 0:
                    nb0 += step
                elif ax_exit == 1:
                    nb1 += step
                else:
                    nb2 += step
                # (an index off the grid only asks for an address nobody reads: no fault)
                prefetch_corners(vec, C3, gx.size, gy.size, gz.size, nb0, nb1, nb2)
            elif not bricked:
                last = np.int64(-1)
                for st in range(1, n_step):
                    if mc[st] != mc[st - 1]:
                        ch = mc[st] * hs
                        last = prefetch_cell(vec, C3, gx, gy, gz, period, inv,
                                             y[0] + ch * k[0, 0], y[1] + ch * k[0, 1],
                                             y[2] + ch * k[0, 2], last)

            # stages
            if ros is not None and rosl:
                err, finite = rosenbrock.step(y, hs, param, cf, coef, ros, fo, k, kk, J, g, u, W,
                                             Wi, yt, rhs, y1)
                y1x, y1y, y1z, dep1 = y1[0], y1[1], y1[2], y1[3]
            else:
                for st in range(1, n_err):
                    _stage(ma, mc, k, st, y, hs, yt, tau, param, inc, gx, gy, gz, period, inv, vec,
                           bk, ci, cf, coef, vb, tp)
                    if st == st_stiff:
                        ys[0], ys[1], ys[2] = yt[0], yt[1], yt[2]
                dep1, err, finite = _step_end(y, k, hs, mb, me, me2, n_err, adaptive, has_e2, fo, y1)
                y1x, y1y, y1z = y1[0], y1[1], y1[2]
                if finite and not (adaptive and err > 1.0):  # the remaining stages up to f(y1)
                    for st in range(n_err, fs + 1):
                        _stage(ma, mc, k, st, y, hs, yt, tau, param, inc, gx, gy, gz, period, inv,
                               vec, bk, ci, cf, coef, vb, tp)
                    if long:
                        # the kink bound: the field at y1 against the start cell's polynomial there,
                        # times the time past the first face, bounds what the faces' kinks moved y1
                        # (the embedded estimate, blind to kinks, sees a fraction of it)
                        t_past = abs(hs) - t_exit
                        _fc(y1x, y1y, y1z, param, cf0, coef0, k, np.int64(S))
                        ek = 0.0
                        for a in range(3):
                            sc = fo[O_ATOL + a] + fo[O_RTOL + a] * max(abs(y[a]), abs(y1[a]))
                            ek += ((k[S, a] - k[fs, a]) * t_past / sc) ** 2
                        ek = math.sqrt(ek / 3.0)
                        if math.isfinite(ek):
                            err = max(err, ek)
                        else:
                            finite = False
            if ci[3] >= 0:  # a brick is missing
                suspended = True
                break
            if long and not (finite and err <= 1.0):
                # the kink at the faces costs more than the tolerance (or NaN data lies beyond, y1
                # included: f(y1) entered the kink bound):
                # back to the cell the step started in, to end this step on its face
                _copy_cell(ci0, cf0, coef0, ci, cf, coef)
                n_rej += 1
                hk = abs(hs) * (max(KINK_SHRINK_MIN, safety / math.sqrt(err)) if finite
                                else KINK_SHRINK_MIN)
                kfail = min(kfail + 1, KINK_FAIL_MAX)
                kwait = (1 << (KINK_BACKOFF_BITS * (kfail - 1))) - 1
                continue
            # rejected: NaN data met by a stage, an error above the tolerance, or y1 itself in
            # a NaN cell (f(y1), computed once the step passed its error test)
            too_big = adl and err > 1.0
            if not finite or too_big or not math.isfinite(k[fsl, 0] + k[fsl, 1] + k[fsl, 2] + k[fsl, 3]):
                n_rej += 1
                last_rej = True
                h, reason = _retry(hs, err, not finite or not too_big, hmin, safety, facmin, expo1l)
                if reason >= 0:
                    break
                continue

            # accepted: events inside the step, on the dense output
            ev = EV_NONE
            ev_axis = np.int64(-1)
            ev_face = 0.0
            need_face = False
            for a in range(3):
                v1 = y1x if a == 0 else (y1y if a == 1 else y1z)
                if inc:
                    if v1 < cf[a] or v1 > cf[3 + a]:
                        need_face = True
                elif period[a] == 0.0 and (v1 < dlo[a] or v1 > dhi[a]):
                    need_face = True
            need_dep = abs(dep1) >= lim_dep
            if ros is not None and rosl and (need_face or need_dep):
                rosenbrock.hermite(y, y1, k, hs, ns, qd)
            elif need_face or need_dep or emit == EMIT_SPACING:
                for st in range(fs + 1, S):  # stages only the dense output uses
                    _stage(ma, mc, k, st, y, hs, yt, tau, param, inc, gx, gy, gz, period, inv, vec,
                           bk, ci, cf, coef, vb, tp)
                for a in range(4):
                    for j in range(q):
                        acc = 0.0
                        for m in range(S):
                            acc += mp[m, j] * k[m, a]
                        qd[a, j] = acc
                if emit == EMIT_SPACING:  # kept with the line: emission may continue next launch
                    for a in range(4):
                        for j in range(q):
                            sf[l, S_Q + a * QMAX + j] = qd[a, j]
            th = 1.0
            if need_face:
                for a in range(3):
                    v1 = y1x if a == 0 else (y1y if a == 1 else y1z)
                    if inc:
                        lo_a, hi_a = cf[a], cf[3 + a]
                    elif period[a] == 0.0:
                        lo_a, hi_a = dlo[a], dhi[a]
                    else:
                        continue
                    if v1 < lo_a:
                        tha = _root(qd, a, ql, y[a], hs, lo_a, -1.0, 1.0)
                        face = lo_a
                    elif v1 > hi_a:
                        tha = _root(qd, a, ql, y[a], hs, hi_a, 1.0, 1.0)
                        face = hi_a
                    else:
                        continue
                    if tha < th or ev == EV_NONE:
                        th = tha
                        ev_axis = a
                        ev_face = face
                        ev = EV_FACE
            if need_dep:
                thd = _root(qd, C3, ql, y[3], hs, d * lim_dep, d, 1.0)
                if ev == EV_NONE or thd < th:
                    th = thd
                    ev = EV_DEPLIM
            if ev == EV_FACE and not inc:
                ev = EV_BOUNDARY
            if bricked:  # the cell the line moves to after the step
                if ev == EV_FACE:
                    ci[3] = _brick_across(bk, ev_axis, ev_face == cf[3 + ev_axis], gx, gy, gz,
                                          period, ci)
                elif long and ev == EV_NONE and not (cf[0] <= y1x <= cf[3] and cf[1] <= y1y <= cf[4]
                                                     and cf[2] <= y1z <= cf[5]):
                    ci[3] = _brick_at(bk, gx, gy, gz, period, inv, y1)
                if ci[3] >= 0:
                    suspended = True
                    break
            # (pathlines: a particle at rest now may move later)
            if vb is None and adl and _stalled(sf, l, y1, (tau_lim if hit_lim else tau + hs)
                                                      if param == 0 else dep1, fo):
                reason = R_STAG
                break
            to_ros = False
            if ros is not None and rosl:  # h ρ(J), ρ bounded by the row sums
                hlam = abs(hs) * spectral_radius_bound(J)
                si[l, I_STIFF] = stiff_update(si[l, I_STIFF], hlam)
                if hlam > HLAMBDA_STIFF:
                    si[l, I_NSTIFF] += 1
            elif st_stiff >= 0:  # Hairer & Wanner's stiffness test on the accepted step
                si[l, I_STIFF] = stiff_update(si[l, I_STIFF],
                                              stage_hlambda(hs, k, fs, st_stiff, ys, y1))
                # (auto: a line flagged stiff goes on with the Rosenbrock stepper)
                to_ros = ros is not None and (si[l, I_STIFF] & STIFF_BIT) != 0
            if adl:
                hnext, errp, errpb = _next_step(err, errp, errpb, hs, h, last_rej, safety, facmin,
                                                facmax, betal, expo1l)
            else:
                hnext = h
            last_rej = False
            hnext = d * min(abs(hnext), hmax)

            # commit the step
            n_acc += 1
            tau0 = tau
            if emit == EMIT_SPACING:
                for a in range(4):
                    sf[l, S_Y0 + a] = y[a]
                sf[l, S_TAU0] = tau
                sf[l, S_HS] = hs
                sf[l, S_TH] = th
            if ev == EV_NONE:
                y[0], y[1], y[2], y[3] = y1x, y1y, y1z, dep1
                tau = tau_lim if hit_lim else tau + hs
                if vb is not None and hit_goal:
                    tau = tp[2]
                for a in range(4):
                    k[0, a] = k[fsl, a]
                if long:  # the line's cell is now the one y1 lies in
                    n_cross += 1
                    kfail = 0
                    hk = abs(hs) * (facmax if err == 0.0 else min(facmax, safety / math.sqrt(err)))
                    if not (cf[0] <= y[0] <= cf[3] and cf[1] <= y[1] <= cf[4]
                            and cf[2] <= y[2] <= cf[5]):
                        # (k0 = f(y1) came from the cell holding y1 already, or from its neighbour
                        # on a shared face: the same value)
                        _relocate(gx, gy, gz, period, inv, vec, bk, y[0], y[1], y[2], ci, cf, coef)
            else:
                ynew0 = _dense(qd, C0, ql, y[0], hs, th)
                ynew1 = _dense(qd, C1, ql, y[1], hs, th)
                ynew2 = _dense(qd, C2, ql, y[2], hs, th)
                ydep = d * lim_dep if ev == EV_DEPLIM else _dense(qd, C3, ql, y[3], hs, th)
                y[0], y[1], y[2], y[3] = ynew0, ynew1, ynew2, ydep
                if ev == EV_FACE or ev == EV_BOUNDARY:
                    y[ev_axis] = ev_face
                tau = tau + th * hs
                hit_lim = False
                hit_goal = False
                if ev == EV_FACE:
                    # through the face (whatever the velocity there says); start afresh in the new cell
                    res = _through_face(ev_axis, ev_face == cf[3 + ev_axis], y, param, gx, gy, gz,
                                        period, vec, bk, ci, cf, coef, k)
                    if res == 1:
                        ev = EV_BOUNDARY
                    elif res == 2:
                        reason = R_NAN
            if ev == EV_BOUNDARY:
                reason = R_OUT
            elif ev == EV_DEPLIM:
                reason = r_dep
            elif hit_lim:
                reason = r_ind
            h = hnext
            if emit == EMIT_STEPS:
                if th * hs != 0.0 or tau0 != tau:
                    t_out = tau if param == 0 else y[3]
                    s_out = y[3] if param == 0 else tau
                    _put(out_p, out_par, out_n, slot, y[0], y[1], y[2], t_out, s_out)
            elif emit == EMIT_SPACING:
                si[l, I_PEND] = 1
                sf[l, S_DEP] = y[3]
                sf[l, S_TAU] = tau
                for a in range(3):
                    sf[l, S_Y + a] = y[a]
                if not _emit_pending(l, slot, sf, si, d, param, ql, spacing, phase,
                                     out_p, out_par, out_n, B):
                    if reason >= 0:
                        si[l, I_FINAL] = 1
                        si[l, I_REASON] = reason
                        si[l, I_STATUS] = DONE
                        reason = -2  # done, final vertex still pending
                    suspended = True
                    break
            if reason >= 0:
                break
            if hit_goal:
                suspended = True
                break
            if ros is not None and to_ros:  # on with the Rosenbrock stepper, cell-aware
                rosl = True
                si[l, I_ROS] = 1
                fsl, ql, expo1l, betal, awl, adl, crossl = ns, DENSE_DEGREE, expo1_ros, 0.0, True, True, False
                if not aware:  # (plain: the cached cell is the last stage's, not the point's)
                    _relocate(gx, gy, gz, period, inv, vec, bk, y[0], y[1], y[2], ci, cf, coef)
                    _fc(y[0], y[1], y[2], param, cf, coef, k, C0)

        if ci[3] >= 0:  # back to where the step started, to wait for the brick
            for a in range(4):
                y[a] = yk_s[a]
                k[0, a] = yk_s[4 + a]
            _copy_cell(ci_s, cf_s, coef_s, ci, cf, coef)
            hk, kwait = hk_s, kwait_s
            si[l, I_WAIT] = ci[3] + 1
        # save the state
        _store(sf, si, l, y, k, tau, h, errp, n_acc, n_rej, last_rej, hk, n_cross, kfail, kwait,
               cf, ci)
        if suspended:
            continue
        si[l, I_STATUS] = DONE
        si[l, I_REASON] = reason
        if emit != EMIT_STEPS:
            si[l, I_FINAL] = 1
            _emit_pending(l, slot, sf, si, d, param, q, spacing, phase, out_p, out_par, out_n, B)


def _scratch(n_rows, ns):
    """The step loop's scratch arrays (one line's worth, reused by the next line of a range);
    ``ns``: the Rosenbrock stepper's stages."""
    return (np.empty((n_rows, 4)),  # k: the stages, and a spare row
            np.empty((8, 3)), np.empty(9), np.empty(4, np.int64),  # the cached cell: polynomial,
            np.empty(4), np.empty(3), np.empty(3), np.empty(4),  # faces, index (and a missing
            # brick); y, yt, ys, y1 (the Rosenbrock step's with its dependent parameter)
            np.empty(3), np.empty(3),  # domain bounds
            np.empty((4, QMAX)),  # dense coefficients
            np.empty((8, 3)), np.empty(9), np.empty(3, np.int64),  # a crossing step's start cell
            # a step's start on a bricked field: point and k0, cell
            np.empty(8), np.empty((8, 3)), np.empty(9), np.empty(3, np.int64),
            # the Rosenbrock step's: stage increments, J, W, W^-1, ∇|u|, u, right-hand side
            np.empty((ns, 4)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty(3),
            np.empty(3), np.empty(4))


def _advance_range(start, stop, *args):
    """``_advance_lines`` with scratch arrays of its own (one set per range)."""
    ros = args[-1]
    ns = 1 if ros is None else ros.shape[0] - 1
    _advance_lines(start, stop, *args, *_scratch(max(int(args[18][M_STAGES]), ns) + 1, ns))


def advance(launch):
    """Advance the lines ``launch.active`` (a ``launch.Launch``) until each is done or has filled
    its B output slots.

    ``io[P_PASS]``: PASS_FULL that; PASS_SETUP start or resume each line and stop it before its
    first step; PASS_FINISH continue the lines not done, after the vertices already in the
    buffers (lanes.py).  The lines are shared among numba's threads in ranges
    (``threads.run_ranges``) rather than by a ``prange``: a parallel loop around the kernel
    costs several seconds more to compile on every fresh machine."""
    from .. import parallel_compile  # (here: `python -m flowkit.parallel_compile` runs it)

    parallel_compile.start("flowkit.integrate.kernel._advance_lines", _advance_lines,
                           str(launch.field.vec.dtype))
    run_ranges(_advance_range, launch.active.size, *launch.arrays(), None, NO_TIMES, launch.stiff)


_VB = _advance_lines.py_func.__code__.co_varnames.index("vb")
_ROS = _advance_lines.py_func.__code__.co_varnames.index("ros")


def _variant(args) -> str:
    """The step loop's variant from its argument types: the compile notices' name for it."""
    from numba.core import types

    return (":pathlines" if args[_VB] != types.none else
            ":rosenbrock" if args[_ROS] != types.none else "")


compile_notice.VARIANTS["flowkit.integrate.kernel._advance_lines"] = _variant


@njit(cache=True)
def pack(active, out_p, out_par, out_n, pts, t, s, owner):
    """Copy the vertices of one pass (``out_n[n]`` of line ``active[n]`` in row n of the pass
    buffers) into the flat arrays ``pts``/``t``/``s``/``owner``, line after line in the order
    of ``active``.  A sequential copy: memory-bound, it gains little from threads, and a
    parallel loop costs a second more to compile on a fresh machine."""
    r = 0
    for n in range(active.size):
        line = active[n]
        for m in range(out_n[n]):
            pts[r, 0] = out_p[n, m, 0]
            pts[r, 1] = out_p[n, m, 1]
            pts[r, 2] = out_p[n, m, 2]
            t[r] = out_par[n, m, 0]
            s[r] = out_par[n, m, 1]
            owner[r] = line
            r += 1
