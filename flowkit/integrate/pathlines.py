"""Pathlines: particles carried by a time-dependent field given as a series of snapshots.

The velocity between two snapshots at times t_k < t_k+1 is interpolated linearly in time,
``v(x, t) = (1 - a) v_k(x) + a v_k+1(x)`` with ``a = (t - t_k) / (t_k+1 - t_k)``, and trilinearly in
space (``flowkit.fields.interp``).  The driver walks the snapshot intervals in time order
(reverse order for ``direction="backward"``) holding at most two snapshots: snapshot k is dropped
before snapshot k+2 is loaded.  In each interval the tracing kernel's step loop
(``kernel._advance_lines``, with the field between the two snapshots as its evaluator:
``unsteady.py``) advances every line with an explicit Runge–Kutta method from the method
registry: dopri5 by default, adaptive with its dense output, or at fixed steps (rk4, euler:
``step``, by default half the time to cross the smallest cell at the typical speed); steps are
clipped to the interval end because the interpolated field has a kink in time there.

Snapshots whose vectors are stored in files are read as streamlines read a field: brick by
brick within the memory budget (``TraceOptions.memory``, ``bricks.brick_budget``), only where
the lines go.  One pool of slots holds the bricks of both snapshots of an interval under one
table (``bricks.BrickPool`` with two sources), the lines advance in rounds (``rounds.py``), and
from one interval to the next the snapshot both share keeps its bricks.  The lines, reasons and
attributes are those read whole, bit for bit.

Seeds are released at given times (default: the start of the series, its end when backward).
Every line records why it stopped: ``out_of_domain`` (the last vertex ON the boundary, found on
the dense output), ``max_time`` (the duration since release, met exactly), ``max_length`` (on the
dense output), ``max_steps``, ``step_underflow``, ``nan_field``, ``seed_outside`` (outside the
domain, in a NaN cell, or released outside the series' time range: no vertex) and
``left_time_range`` (reached the last snapshot time, or the first one going backward, with time
to spare).  The ``time`` attribute is the physical time of each vertex (always stored).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..fields import Field
from ..fields.bricks import NO_BRICKS, BrickPool, brick_budget, cell_nodes
from ..lines import Lines
from ..threads import run_ranges
from . import attributes as _attributes
from . import kernel as K
from .options import OptionsError, TraceOptions
from .reasons import REASON_NAMES, Reason
from .rounds import Rounds, serve
from .trace import typical_speed

POINT_ATTRIBUTES = ("time", "arc_length", "speed", "velocity", "vorticity", "vorticity_magnitude",
                    "distance_to_seed")
SAMPLED = ("speed", "velocity", "vorticity", "vorticity_magnitude")  # (and scalars)
BUFFER_VERTICES = 1 << 22  # vertices held by one kernel launch (all lines together)
R_SEED, R_LEFT = int(Reason.SEED_OUTSIDE), int(Reason.LEFT_TIME_RANGE)


def _advance(active, seeds, dirs, release, goal, grid, v0, v1, bk, t0, t1, method, fo, io, sf,
             si, out_p, out_par, out_n):
    """Advance the lines ``active`` to ``goal`` (or their end) inside one snapshot interval, or
    until each has written B vertices or waits for a brick: the streamline step loop with the
    field between two snapshots (``kernel._advance_lines``' ``vb``), the lines shared among
    numba's threads."""
    none = np.zeros(seeds.shape[0])
    run_ranges(K._advance_range, active.size, active, seeds, dirs, none, none, *grid, v0,
               bk, *method, fo, io, sf, si, out_p, out_par, out_n, v1,
               np.concatenate([[t0, t1, goal], release]), None)


# -- the driver -------------------------------------------------------------------------------
def pathlines(series, seeds, release=None, options: TraceOptions | None = None, *,
              vector: str = "U", load: dict | None = None, **kw) -> Lines:
    """Pathlines from ``seeds`` ((n, 3)) released at ``release`` (a time or one per seed; default
    the first snapshot time, the last when ``direction="backward"``).

    ``series``: a ``.series`` file, glob or multi-snapshot HDF5 path (``load_series``), or a list of
    ``(time, Field | path | SnapshotRef)`` with at least two distinct times.  Snapshots are loaded
    as the sweep reaches them and dropped when it has passed them (at most two held: in
    memory, or a large file's bricks where the lines go, within ``memory``).  ``vector`` names
    the vector array of snapshot files; ``load``: load_field's other keywords for them (a mesh's
    ``resample=``, ``data=``).  ``options``/``kw``: TraceOptions (method, rtol, atol, max_time =
    duration since release, max_length, max_steps, step, min_step, max_step, stagnation,
    direction forward|backward, memory, attributes among time, arc_length, speed, velocity,
    vorticity, vorticity_magnitude, distance_to_seed and scalar names; velocity, vorticity and
    scalars interpolated linearly in time between the two snapshots around each vertex).
    Snapshots read brick by brick add ``bricks_read``, ``field_bytes_read``, ``brick_rounds``
    and ``brick_pool_bytes`` to the attrs (over the whole sweep).
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
    dirs = np.full(n, d)
    sf = np.zeros((n, K.NF))
    si = np.zeros((n, K.NI), np.int64)
    chunks = []  # (owner, points, time, arc length, attributes) per interval
    method = opts.method_obj
    arrays = method.kernel_arrays()
    held: dict[int, Field] = {}
    setup = fa = fb = pool = None
    n_rounds = 0
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
        status = si[:, K.I_STATUS]
        if d > 0:
            starts = (release >= ta) & ((release < tb) | ((release == tb) & (k == len(times) - 2)))
        else:
            starts = (release <= tb) & ((release > ta) | ((release == ta) & (k == 0)))
        active = np.flatnonzero((status == K.RUNNING) | ((status == K.NEW) & starts))
        pool = _bricks(pool, fa, fb, opts.memory)
        if pool is None:
            v0, v1, bk, rounds = *_alike(fa.vector, fb.vector), NO_BRICKS, None
        else:
            v0, v1, bk = *pool.pools, pool.bk
            rounds = Rounds(pool, n, cells=_cells(fa.grid, seeds, sf))
        run = _Pass(seeds, dirs, release, goal, setup, v0, v1, bk, ta, tb, arrays, sf, si)
        parts = []
        for got, _, was_round in serve(active, si, run, rounds):
            parts.append(got)
            n_rounds += was_round
        v0 = v1 = run = None
        vertices = [np.concatenate(c) for c in zip(*parts)]
        if vertices and vertices[0].size:  # with their attributes, from the two snapshots
            owner, pts, tv, sv = vertices
            if pool is not None and opts.attributes:
                pool.release()  # (its pages back while they read near the vertices)
            chunks.append((owner, pts, tv, sv, _sampled(opts.attributes, fa, fb, ta, tb, pts, tv,
                                                         pool is not None)))
    still = si[:, K.I_STATUS]
    si[still == K.RUNNING, K.I_REASON] = R_LEFT
    si[still == K.NEW, K.I_REASON] = R_SEED  # released outside the time range
    lines = _assemble(chunks, n, seeds, release, si, opts, times, sources, fa)
    if pool is not None:
        lines.attrs.update(pool.attrs(n_rounds))
    return lines


class _Pass:
    """One pass of an interval's lines ``ready`` (``rounds.serve``): their vertices (owner,
    points, time, arc length) and which of them have more to do in the interval (running short
    of its end, or waiting for a brick)."""

    def __init__(self, seeds, dirs, release, goal, setup, v0, v1, bk, ta, tb, method, sf, si):
        self.args = (seeds, dirs, release, goal, setup.grid, v0, v1, bk, ta, tb, method,
                     setup.fo, setup.io, sf, si)
        self.goal, self.sf, self.si = goal, sf, si

    def __call__(self, ready):
        B = int(min(4096, max(16, BUFFER_VERTICES // ready.size)))
        out_p = np.empty((ready.size, B, 3))
        out_par = np.empty((ready.size, B, 2))
        out_n = np.zeros(ready.size, np.int64)
        _advance(ready, *self.args, out_p, out_par, out_n)
        keep = np.arange(B)[None, :] < out_n[:, None]
        got = np.repeat(ready, out_n), out_p[keep], out_par[:, :, 0][keep], out_par[:, :, 1][keep]
        si = self.si[ready]
        busy = (((si[:, K.I_STATUS] == K.RUNNING) & (self.sf[ready, K.S_TAU] != self.goal))
                | (si[:, K.I_WAIT] > 0))
        return got, busy


def _bricks(pool, fa: Field, fb: Field, memory):
    """The BrickPool an interval reads the vectors of its snapshots ``fa`` and ``fb`` through
    (``pool``, the last interval's, where it can follow them), or None where both are read
    whole (``bricks.brick_budget``)."""
    budget = brick_budget((fa, fb), memory)
    if budget is None:
        return None
    sources = [fa.stored_vector(), fb.stored_vector()]
    if pool is not None and pool.holds(sources):
        pool.follow(sources)
        return pool
    new = BrickPool(sources[0], fa.grid, budget, more=sources[1:],
                    dtype=np.result_type(*(s.dtype for s in sources)))
    if pool is not None:  # (what the last pool read: counted over the whole sweep)
        new.loads, new.bytes_read = pool.loads, pool.bytes_read
    return new


def _cells(grid, seeds, sf):
    """``Rounds``' cells of pathlines (``cells(rows, si)``): the cell holding each line's point,
    its seed before it starts (the step loop keeps no cell for them)."""
    def cells(rows, si):
        running = (si[rows, K.I_STATUS] == K.RUNNING)[:, None]
        return cell_nodes(grid, np.where(running, sf[rows, K.S_Y:K.S_Y + 3], seeds[rows]))
    return cells


def _check_options(opts: TraceOptions, kw) -> TraceOptions:
    if not isinstance(opts, TraceOptions):
        raise TypeError(f"options must be a TraceOptions, got {type(opts).__name__}")
    opts = opts.replace(**kw) if kw else opts
    if opts.direction not in ("forward", "backward"):
        raise OptionsError(f"pathlines: option direction must be forward or backward, "
                           f"got {opts.direction!r}")
    if opts.parameter != "time":
        raise OptionsError(f"pathlines: option parameter must be time, got {opts.parameter!r}")
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


def _alike(v0, v1):
    """The two snapshots' node arrays in one type (float64 where they differ: exact)."""
    if v0.dtype == v1.dtype:
        return v0, v1
    return v0.astype(np.float64), v1.astype(np.float64)


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
        fo = np.zeros(K.NFO)
        fo[K.O_RTOL:K.O_RTOL + 3] = opts.rtol
        fo[K.O_ATOL:K.O_ATOL + 3] = opts.rtol * ext if opts.atol is None else opts.atol
        fo[K.O_SAFETY], fo[K.O_FACMIN], fo[K.O_FACMAX] = (opts.safety, opts.min_factor,
                                                          opts.max_factor)
        fo[K.O_BETA] = opts.beta
        if opts.method_obj.adaptive:
            fo[K.O_H0] = opts.step or 0.0
        else:  # fixed steps: half the time to cross the smallest cell at the typical speed
            fo[K.O_H0] = opts.step if opts.step is not None else 0.5 * cross
        fo[K.O_HMIN] = opts.min_step if opts.min_step is not None else 1e-10 * cross
        fo[K.O_HMAX] = opts.max_step if opts.max_step is not None else np.inf
        fo[K.O_MAXLEN], fo[K.O_MAXTIME] = opts.max_length, opts.max_time
        # a particle at rest may move later: no stagnation stop unless asked for explicitly
        fo[K.O_STAG] = opts.stagnation if opts.stagnation is not None else 0.0
        self.fo = fo
        # plain stepping (each stage in its own cell), vertices at the accepted steps, time the
        # parameter, no stiffness test
        io = np.zeros(K.NIO, np.int64)
        io[K.P_MAXSTEPS] = opts.max_steps
        io[K.P_PARAM], io[K.P_AWARE], io[K.P_EMIT] = 0, 0, K.EMIT_STEPS
        io[K.P_PASS], io[K.P_STIFF] = K.PASS_FULL, -1
        self.io = io

    def check_grid(self, f: Field):
        g = f.grid
        if g.shape != self.shape or not all(np.array_equal(a, b) for a, b in
                                            zip((g.x, g.y, g.z), self.axes)):
            raise ValueError(f"{f.source}: snapshot grid {g.shape} differs from the first "
                             f"snapshot's {self.shape}; pathlines need one grid for the series")


def _sampled(names, fa: Field, fb: Field, ta, tb, pts, tv, bricked=False) -> dict:
    """Attributes that need the field at the vertices (the velocity, for speed too; the
    vorticity, each snapshot's node curl at the vertices' cells; scalars), each snapshot's
    interpolated in time like the velocity.  Read near the vertices only where ``bricked`` or
    a snapshot is large (``attributes.compute``)."""
    want = list(dict.fromkeys({"speed": "velocity", "vorticity_magnitude": "vorticity"}.get(n, n)
                              for n in names if n in SAMPLED or n in fa.scalars))
    if not want:
        return {}
    a = (tv - ta) / (tb - ta)
    at_a = _attributes.compute(fa, want, pts, None, None, None, bricked)
    at_b = _attributes.compute(fb, want, pts, None, None, None, bricked)
    out = {}
    for name in want:
        w = a.reshape((-1,) + (1,) * (at_a[name].ndim - 1))
        out[name] = (1 - w) * at_a[name] + w * at_b[name]
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
    ld = {"seed_id": np.arange(n, dtype=np.int64), "reason": si[:, K.I_REASON].astype(np.int8),
          "n_accepted": si[:, K.I_NACC].astype(np.int32),
          "n_rejected": si[:, K.I_NREJ].astype(np.int32),
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
