"""Pathlines: particles carried by a time-dependent field given as a series of snapshots.

The velocity between two snapshots at times t_k < t_k+1 is interpolated linearly in time,
``v(x, t) = (1 - a) v_k(x) + a v_k+1(x)`` with ``a = (t - t_k) / (t_k+1 - t_k)``, and trilinearly in
space (``flowkit.fields.interp``).  The driver walks the snapshot intervals in time order
(reverse order for ``direction="backward"``) holding at most two snapshots in memory: snapshot
k is dropped before snapshot k+2 is loaded.  In each interval a numba kernel advances every
line with an adaptive explicit Runge–Kutta method taken from the method registry
(``methods.py``: the same tableau data the streamline kernel uses, dopri5 by default, with its
dense output); steps are clipped to the interval end because the interpolated field has a kink
in time there.

Why a kernel of its own: the streamline kernel (``kernel.py``) evaluates a steady field from the
8 corner values of one cell gathered once per cell; it has no notion of time in the field.  This
kernel shares the method tableaux, the trilinear interpolation (``interp.locate_axis``,
``interp.trilinear_vector``), the step-size controller, the dense output and the leading state
and option columns (``schema.py``) of ``kernel.py`` (its error norm is the same formula, kept in step by the tests on analytic
fields) but evaluates two snapshots per stage.

Seeds are released at given times (default: the start of the series, its end when backward).
Every line records why it stopped: ``out_of_domain`` (the last vertex ON the boundary, found on
the dense output), ``max_time`` (the duration since release, met exactly), ``max_length`` (on the
dense output), ``max_steps``, ``step_underflow``, ``nan_field``, ``seed_outside`` (outside the
domain, in a NaN cell, or released outside the series' time range: no vertex) and
``left_time_range`` (reached the last snapshot time, or the first one going backward, with time
to spare).  The ``time`` attribute is the physical time of each vertex (always stored).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..fields import Field
from ..fields.interp import locate_axis, trilinear_vector
from ..jit import inline, kernel
from ..lines import Lines
from ..threads import run_ranges
from . import attributes as _attributes
from .kernel import (
    ERRP_MIN,
    EXPO1_BETA,
    _dense,
    _initial_guess,
    _initial_step,
    _load_state,
    _next_step,
    _retry,
    _root,
    _save_state,
    _stage_point,
    _step_end,
)
from .options import OptionsError, TraceOptions
from .reasons import REASON_NAMES, Reason
from .schema import (
    DONE,
    I_NACC,
    I_NREJ,
    I_REASON,
    I_STATUS,
    M_ADAPTIVE,
    M_FSAL,
    M_HASE2,
    M_KEXP,
    M_NERR,
    M_STAGES,
    NEW,
    O_ATOL,
    O_BETA,
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
    P_MAXSTEPS,
    PATH_FLOAT_OPTIONS,
    PATH_FLOAT_STATE,
    PATH_INT_OPTIONS,
    PATH_INT_STATE,
    RUNNING,
    S_TAU,
)
from .trace import typical_speed

# the rows of a pathline (schema.py): the streamline kernel's leading columns, read and written
# by kernel._load_state / _save_state (time is the parameter, arc length the dependent one), and
# a last-rejection flag of its own; options up to O_STAG; io holds only P_MAXSTEPS
NF, NI = PATH_FLOAT_STATE.size, PATH_INT_STATE.size
NFO, NIO = PATH_FLOAT_OPTIONS.size, PATH_INT_OPTIONS.size
I_LASTREJ = PATH_INT_STATE["I_LASTREJ"]

POINT_ATTRIBUTES = ("time", "arc_length", "speed", "velocity", "vorticity", "vorticity_magnitude",
                    "distance_to_seed")
BUFFER_VERTICES = 1 << 22  # vertices held by one kernel launch (all lines together)

R_OUT, R_MAXLEN, R_MAXTIME = int(Reason.OUT_OF_DOMAIN), int(Reason.MAX_LENGTH), int(Reason.MAX_TIME)
R_MAXSTEPS, R_STAG = int(Reason.MAX_STEPS), int(Reason.STAGNATION)
R_SEED, R_LEFT = int(Reason.SEED_OUTSIDE), int(Reason.LEFT_TIME_RANGE)


# -- the kernel -------------------------------------------------------------------------------
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
def _velocity(x, y, z, t, gx, gy, gz, period, inv, v0, v1, t0, t1, k, row):
    """(1 - a) v0 + a v1 at (x, y, z) into k[row, 0:3] and the speed into k[row, 3];
    returns False for NaN data or a NaN position."""
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


# One function with the loop over the lines inside: a line function called from a range
# function was compiled, and optimised again inside its caller, twice (seconds on a fresh
# machine).  Without NRT (no reference counting in the step loop, as kernel._advance_lines; nothing
# allocated here: the scratch arrays come from _range) and without the GIL, so that threads run
# ranges side by side (threads.run_ranges).
@kernel(nogil=True)
def _lines(start, stop, active, seeds, release, d, goal, gx, gy, gz, period, inv, v0, v1, t0, t1,
           mc, ma, mb, me, me2, mp, mi, fo, io, sf, si, out_p, out_t, out_s, out_n, k, Q, yt, y,
           y1):
    """``_advance`` for the slots start..stop-1 (lines ``active[start:stop]``), one after the
    other.  Scratch of one line, reused by the next: k (the stages' velocity and speed), Q (the
    dense output's coefficients), yt (a stage point), y and y1 (position and arc length at the
    step's start and end)."""
    B = out_p.shape[1]
    S, n_err, fs, kexp = mi[M_STAGES], mi[M_NERR], mi[M_FSAL], mi[M_KEXP]
    adaptive, has_e2 = mi[M_ADAPTIVE] != 0, mi[M_HASE2] != 0
    q = mp.shape[1]
    safety, facmin, facmax, beta = fo[O_SAFETY], fo[O_FACMIN], fo[O_FACMAX], fo[O_BETA]
    hmin, hmax, stag, maxlen = fo[O_HMIN], fo[O_HMAX], fo[O_STAG], fo[O_MAXLEN]
    max_steps = io[P_MAXSTEPS]
    expo1 = 1.0 / kexp - EXPO1_BETA * beta
    for slot in range(start, stop):
        l = active[slot]
        out_n[slot] = 0
        tlim = release[l] + d * fo[O_MAXTIME]

        if si[l, I_STATUS] == NEW:
            px, py, pz = seeds[l, 0], seeds[l, 1], seeds[l, 2]
            inside = True
            for a in range(3):
                c = gx if a == 0 else (gy if a == 1 else gz)
                if period[a] == 0.0 and not (c[0] <= seeds[l, a] <= c[c.size - 1]):
                    inside = False
            t = release[l]
            # constants to the compiled (not inlined) helpers typed: a literal 0 compiles one more
            # copy of the helper per value (as in kernel.py)
            if not (inside and _velocity(px, py, pz, t, gx, gy, gz, period, inv, v0, v1, t0, t1, k,
                                         np.int64(0))):
                si[l, I_STATUS] = DONE
                si[l, I_REASON] = R_SEED
                continue
            y[0], y[1], y[2], y[3] = px, py, pz, 0.0
            n_acc = 0
            n_rej = 0
            last_rej = False
            errp = ERRP_MIN
            errpb = errp ** beta
            h = fo[O_H0]
            if h <= 0.0:
                h0, d1 = _initial_guess(fo, y, k)
                h0 = min(h0, hmax, max(abs(goal - t), 1e-300))
                for a in range(3):
                    yt[a] = y[a] + d * h0 * k[0, a]
                ok = _velocity(yt[0], yt[1], yt[2], t + d * h0, gx, gy, gz, period, inv,
                               v0, v1, t0, t1, k, np.int64(1))
                h = _initial_step(fo, y, k, h0, d1, kexp, ok)
            h = d * min(h, hmax)
            si[l, I_STATUS] = RUNNING
            out_p[slot, 0, 0], out_p[slot, 0, 1], out_p[slot, 0, 2] = px, py, pz
            out_t[slot, 0] = t
            out_s[slot, 0] = 0.0
            out_n[slot] = 1
        else:
            t, h, errp, errpb, n_acc, n_rej, last_rej = _load_state(sf, si, l, y, k, np.int64(I_LASTREJ), beta)

        reason = -1
        while out_n[slot] < B and t != goal:
            if n_acc + n_rej >= max_steps:
                reason = R_MAXSTEPS
                break
            if stag > 0.0 and not (k[0, 3] >= stag):
                reason = R_STAG
                break
            out = False  # standing on a bounded end and moving outwards
            for a in range(3):
                c = gx if a == 0 else (gy if a == 1 else gz)
                mv = d * k[0, a]
                if period[a] == 0.0 and ((y[a] <= c[0] and mv < 0.0) or (y[a] >= c[c.size - 1] and mv > 0.0)):
                    out = True
            if out:
                reason = R_OUT
                break
            # step size: the controller's, clipped to the interval end or the time limit
            hs = h
            rem_goal = d * (goal - t)
            rem_lim = d * (tlim - t)
            rem = min(rem_goal, rem_lim)
            hit = abs(hs) >= rem
            if hit:
                hs = d * rem
            for st in range(1, n_err):
                _stage_point(ma, k, st, y, hs, yt)
                if not _velocity(yt[0], yt[1], yt[2], t + mc[st] * hs, gx, gy, gz, period, inv,
                                 v0, v1, t0, t1, k, st):
                    k[st, 0] = np.nan
            y1[3], err, finite = _step_end(y, k, hs, mb, me, me2, n_err, adaptive, has_e2, fo, y1)
            if finite and err <= 1.0:  # stages up to f(y1) and those only the dense output uses
                for st in range(n_err, S):
                    _stage_point(ma, k, st, y, hs, yt)
                    if not _velocity(yt[0], yt[1], yt[2], t + mc[st] * hs, gx, gy, gz, period, inv,
                                     v0, v1, t0, t1, k, st):
                        finite = False
            if not (finite and err <= 1.0):  # NaN data met by a stage, or an error too large
                n_rej += 1
                last_rej = True
                h, reason = _retry(hs, err, not finite or not err > 1.0, hmin, safety, facmin, expo1)
                if reason >= 0:
                    break
                continue
            # accepted
            hnext, errp, errpb = _next_step(err, errp, errpb, hs, h, last_rej, safety, facmin, facmax,
                                            beta, expo1)
            hnext = d * min(abs(hnext), hmax)
            last_rej = False
            n_acc += 1
            # events on the dense output: a bounded end of the domain, the arc-length limit
            for a in range(4):
                for j in range(q):
                    acc = 0.0
                    for m in range(S):
                        acc += mp[m, j] * k[m, a]
                    Q[a, j] = acc
            th = 1.0
            ev_axis = -1
            ev_face = 0.0
            for a in range(3):
                c = gx if a == 0 else (gy if a == 1 else gz)
                if period[a] != 0.0:
                    continue
                if y1[a] < c[0]:
                    tha = _root(Q, a, q, y[a], hs, c[0], -1.0, 1.0)
                    face = c[0]
                elif y1[a] > c[c.size - 1]:
                    tha = _root(Q, a, q, y[a], hs, c[c.size - 1], 1.0, 1.0)
                    face = c[c.size - 1]
                else:
                    continue
                if tha <= th:
                    th = tha
                    ev_axis = a
                    ev_face = face
            ev_len = False
            if y1[3] >= maxlen:
                thl = _root(Q, np.int64(3), q, y[3], hs, maxlen, 1.0, 1.0)
                if thl < th or ev_axis < 0:
                    th = thl
                    ev_len = True
                    ev_axis = -1
            if ev_axis >= 0 or ev_len:
                for a in range(4):
                    y[a] = _dense(Q, a, q, y[a], hs, th)
                if ev_len:
                    y[3] = maxlen
                    reason = R_MAXLEN
                else:
                    y[ev_axis] = ev_face
                    reason = R_OUT
                t = t + th * hs
            else:
                for a in range(4):
                    y[a] = y1[a]
                    k[0, a] = k[fs, a]
                if hit:
                    if rem_lim <= rem_goal:
                        t = tlim
                        reason = R_MAXTIME
                    else:
                        t = goal
                else:
                    t = t + hs
            h = hnext
            n = out_n[slot]
            out_p[slot, n, 0], out_p[slot, n, 1], out_p[slot, n, 2] = y[0], y[1], y[2]
            out_t[slot, n] = t
            out_s[slot, n] = y[3]
            out_n[slot] = n + 1
            if reason >= 0:
                break

        _save_state(sf, si, l, y, k, t, h, errp, n_acc, n_rej, last_rej, np.int64(I_LASTREJ))
        if reason >= 0:
            si[l, I_STATUS] = DONE
            si[l, I_REASON] = reason


def _range(start, stop, *args):
    """``_lines`` with scratch arrays of its own (one set per range)."""
    mp, mi = args[19], args[20]
    _lines(start, stop, *args, np.empty((mi[M_STAGES], 4)), np.empty((4, mp.shape[1])),
           np.empty(3), np.empty(4), np.empty(4))


def _advance(active, seeds, release, d, goal, gx, gy, gz, period, inv, v0, v1, t0, t1,
             mc, ma, mb, me, me2, mp, mi, fo, io, sf, si, out_p, out_t, out_s, out_n):
    """Advance the lines ``active`` to ``goal`` (or their end) inside one snapshot interval, or
    until each has written B vertices; the lines go to numba's thread count of Python threads
    (``threads.run_ranges``): a prange loop around the kernel cost seconds more to compile."""
    run_ranges(_range, active.size, active, seeds, release, d, goal, gx, gy, gz, period,
               inv, v0, v1, t0, t1, mc, ma, mb, me, me2, mp, mi, fo, io, sf, si, out_p, out_t, out_s,
               out_n)


# -- the driver -------------------------------------------------------------------------------
def pathlines(series, seeds, release=None, options: TraceOptions | None = None, *,
              vector: str = "U", load: dict | None = None, **kw) -> Lines:
    """Pathlines from ``seeds`` ((n, 3)) released at ``release`` (a time or one per seed; default
    the first snapshot time, the last when ``direction="backward"``).

    ``series``: a ``.series`` file, glob or multi-snapshot HDF5 path (``load_series``), or a list of
    ``(time, Field | path | SnapshotRef)`` with at least two distinct times.  Snapshots are loaded
    as the sweep reaches them and dropped when it has passed them (at most two in memory).
    ``vector`` names the vector array of snapshot files; ``load``: load_field's other keywords for
    them (a mesh's ``resample=``, ``data=``).  ``options``/``kw``: TraceOptions (method, rtol, atol, max_time = duration since release,
    max_length, max_steps, step, min_step, max_step, stagnation, direction forward|backward,
    attributes among time, arc_length, speed, velocity, vorticity, vorticity_magnitude,
    distance_to_seed and scalar names; velocity, vorticity and scalars interpolated linearly in
    time between the two snapshots around each vertex).
    """
    opts = _check_options(options if options is not None else TraceOptions(), kw)
    times, sources = _series(series)
    seeds = np.ascontiguousarray(np.atleast_2d(np.asarray(seeds, np.float64)))
    if seeds.ndim != 2 or seeds.shape[1] != 3:
        raise ValueError(f"seeds must have shape (n, 3), got {np.shape(seeds)}")
    n = seeds.shape[0]
    d = -1.0 if opts.direction == "backward" else 1.0
    if release is None:
        release = times[-1] if d < 0 else times[0]
    release = np.ascontiguousarray(np.broadcast_to(np.asarray(release, np.float64), (n,)))
    if not np.all(np.isfinite(release)):
        raise ValueError("release times must be finite")
    order = range(len(times) - 1) if d > 0 else range(len(times) - 2, -1, -1)
    sf = np.zeros((n, NF))
    si = np.zeros((n, NI), np.int64)
    chunks = []  # (owner, points, time, arc length, attributes) per launch
    method = opts.method_obj
    mc, ma, mb, me, me2, mp, mi = method.kernel_arrays()
    held: dict[int, Field] = {}
    setup = fa = fb = None
    for k in order:
        fa = fb = None  # no reference may keep a passed snapshot alive
        for old in [i for i in held if i not in (k, k + 1)]:
            del held[old]  # drop the snapshot the sweep has passed before loading the next one
        for i in (k, k + 1):
            if i not in held:
                held[i] = _load(sources[i], vector, load or {})
        fa, fb = held[k], held[k + 1]
        if setup is None:
            setup = _Setup(fa, opts)
        setup.check_grid(fb)
        ta, tb = times[k], times[k + 1]
        goal = tb if d > 0 else ta
        status = si[:, I_STATUS]
        if d > 0:
            starts = (release >= ta) & ((release < tb) | ((release == tb) & (k == len(times) - 2)))
        else:
            starts = (release <= tb) & ((release > ta) | ((release == ta) & (k == 0)))
        active = np.flatnonzero((status == RUNNING) | ((status == NEW) & starts))
        while active.size:
            B = int(min(4096, max(16, BUFFER_VERTICES // active.size)))
            out_p = np.empty((active.size, B, 3))
            out_t = np.empty((active.size, B))
            out_s = np.empty((active.size, B))
            out_n = np.zeros(active.size, np.int64)
            _advance(active, seeds, release, d, goal, *setup.grid, fa.vector, fb.vector, ta, tb,
                     mc, ma, mb, me, me2, mp, mi, setup.fo, setup.io, sf, si, out_p, out_t, out_s, out_n)
            keep = np.arange(B)[None, :] < out_n[:, None]
            owner = np.repeat(active, out_n)
            pts, tv = out_p[keep], out_t[keep]
            chunks.append((owner, pts, tv, out_s[keep],
                           _sampled(opts.attributes, fa, fb, ta, tb, pts, tv)))
            busy = (si[active, I_STATUS] == RUNNING) & (sf[active, S_TAU] != goal)
            active = active[busy]
    still = si[:, I_STATUS]
    si[still == RUNNING, I_REASON] = R_LEFT
    si[still == NEW, I_REASON] = R_SEED  # released outside the time range
    return _assemble(chunks, n, seeds, release, si, opts, times, sources, fa)


def _check_options(opts: TraceOptions, kw) -> TraceOptions:
    if not isinstance(opts, TraceOptions):
        raise TypeError(f"options must be a TraceOptions, got {type(opts).__name__}")
    opts = opts.replace(**kw) if kw else opts
    if opts.direction not in ("forward", "backward"):
        raise OptionsError(f"pathlines: option direction must be forward or backward, "
                           f"got {opts.direction!r}")
    if opts.parameter != "time":
        raise OptionsError(f"pathlines: option parameter must be time, got {opts.parameter!r}")
    if not opts.method_obj.adaptive:
        raise OptionsError(f"pathlines: option method must be adaptive, got {opts.method_name!r}")
    if opts.spacing is not None or opts.count is not None:
        raise OptionsError("pathlines: options spacing and count are not supported "
                           "(vertices are the accepted steps)")
    return opts


def _series(series) -> tuple[np.ndarray, list]:
    if isinstance(series, (str, Path)):
        from ..fields.readers import load_series

        series = load_series(series)
    entries = sorted(((float(t), src) for t, src in series), key=lambda e: e[0])
    times = np.array([t for t, _ in entries])
    if times.size < 2 or np.any(np.diff(times) <= 0):
        raise ValueError(f"pathlines need at least two snapshots with distinct times, got times "
                         f"{times.tolist()}")
    return times, [src for _, src in entries]


def _load(src, vector, load) -> Field:
    if isinstance(src, Field):
        return src
    from ..fields.readers import load_field

    return load_field(src, vector=vector, **load)


class _Setup:
    """Kernel options derived once from the first snapshot (as streamlines derive them)."""

    def __init__(self, f: Field, opts: TraceOptions):
        g = f.grid
        self.grid = g.kernel_args()
        self.shape, self.axes = g.shape, (g.x, g.y, g.z)
        self.scalars = set(f.scalars)
        for a in opts.attributes:
            if a not in POINT_ATTRIBUTES and a not in f.scalars:
                have = ", ".join(list(POINT_ATTRIBUTES) + sorted(f.scalars))
                raise KeyError(f"{f.source}: unknown pathline attribute '{a}' (available: {have})")
        ext = float(np.max(g.bounds[:, 1] - g.bounds[:, 0]))
        vtyp = typical_speed(f)  # sampled: the full median costs 3x a float32 field's memory
        cross = g.min_cell_size / (vtyp if vtyp > 0 else 1.0)
        fo = np.zeros(NFO)
        fo[O_RTOL:O_RTOL + 3] = opts.rtol
        fo[O_ATOL:O_ATOL + 3] = opts.rtol * ext if opts.atol is None else opts.atol
        fo[O_SAFETY], fo[O_FACMIN], fo[O_FACMAX] = opts.safety, opts.min_factor, opts.max_factor
        fo[O_BETA] = opts.beta
        fo[O_H0] = opts.step or 0.0
        fo[O_HMIN] = opts.min_step if opts.min_step is not None else 1e-10 * cross
        fo[O_HMAX] = opts.max_step if opts.max_step is not None else np.inf
        fo[O_MAXLEN], fo[O_MAXTIME] = opts.max_length, opts.max_time
        # a particle at rest may move later: no stagnation stop unless asked for explicitly
        fo[O_STAG] = opts.stagnation if opts.stagnation is not None else 0.0
        self.fo = fo
        io = np.zeros(NIO, np.int64)
        io[P_MAXSTEPS] = opts.max_steps
        self.io = io

    def check_grid(self, f: Field):
        g = f.grid
        if g.shape != self.shape or not all(np.array_equal(a, b) for a, b in
                                            zip((g.x, g.y, g.z), self.axes)):
            raise ValueError(f"{f.source}: snapshot grid {g.shape} differs from the first "
                             f"snapshot's {self.shape}; pathlines need one grid for the series")


def _sampled(names, fa: Field, fb: Field, ta, tb, pts, tv) -> dict:
    """Attributes that need the field at the vertices, interpolated in time like the velocity
    (the vorticity: each snapshot's, from its node curl at the vertices' cells)."""
    out = {}
    a = ((tv - ta) / (tb - ta))
    for name in names:
        if name in ("speed", "velocity"):
            if "velocity" not in out:
                out["velocity"] = (1 - a)[:, None] * fa.sample(pts)[0] + a[:, None] * fb.sample(pts)[0]
        elif name in ("vorticity", "vorticity_magnitude"):
            if "vorticity" not in out:
                wa, wb = _attributes.vorticity_at(fa, pts), _attributes.vorticity_at(fb, pts)
                out["vorticity"] = (1 - a)[:, None] * wa + a[:, None] * wb
        elif name in fa.scalars:
            out[name] = (1 - a) * fa.sample_scalar(name, pts)[0] + a * fb.sample_scalar(name, pts)[0]
    return out


def _assemble(chunks, n, seeds, release, si, opts, times, sources, field=None) -> Lines:
    """One Lines from the launches' vertices: grouped by line, each in integration order (the
    sweep visits the intervals in that order; backward lines run from the release back in time)."""
    if chunks:
        owner = np.concatenate([c[0] for c in chunks])
        order = np.argsort(owner, kind="stable")
        owner = owner[order]
        pts = np.concatenate([c[1] for c in chunks])[order]
        tv = np.concatenate([c[2] for c in chunks])[order]
        sv = np.concatenate([c[3] for c in chunks])[order]
        sampled = {k: np.concatenate([c[4][k] for c in chunks])[order] for k in chunks[0][4]}
    else:
        owner, pts, tv, sv = np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0), np.zeros(0)
        sampled = {**{k: np.zeros(0) for k in opts.attributes}, "velocity": np.zeros((0, 3)),
                   "vorticity": np.zeros((0, 3))}
    pd = {"time": tv}
    for name in opts.attributes:
        if name == "arc_length":
            pd[name] = sv
        elif name == "distance_to_seed":
            pd[name] = np.linalg.norm(pts - seeds[owner], axis=1)
        elif name == "speed":
            pd[name] = np.linalg.norm(sampled["velocity"], axis=1)
        elif name == "vorticity_magnitude":
            pd[name] = np.linalg.norm(sampled["vorticity"], axis=1)
        elif name != "time":
            pd[name] = sampled[name]
    offsets = np.concatenate([[0], np.cumsum(np.bincount(owner, minlength=n))])
    ld = {"seed_id": np.arange(n, dtype=np.int64), "reason": si[:, I_REASON].astype(np.int8),
          "n_accepted": si[:, I_NACC].astype(np.int32), "n_rejected": si[:, I_NREJ].astype(np.int32),
          "release_time": release.copy()}
    attrs = {"kind": "pathlines", "method": opts.method_name, "rtol": str(opts.rtol),
             "atol": str(opts.atol), "parameter": "time", "direction": opts.direction,
             "max_length": opts.max_length, "max_time": opts.max_time, "max_steps": opts.max_steps,
             "snapshot_times": np.asarray(times, np.float64),
             "source": str(sources[0].source if isinstance(sources[0], Field) else sources[0]),
             "reason_names": ",".join(REASON_NAMES)}
    if field is not None:  # units of the attributes (one snapshot's time does not apply)
        attrs.update({k: v for k, v in _attributes.metadata(field, pd).items()
                      if k != "snapshot_time"})
    return Lines(pts, offsets, pd, ld, attrs)
