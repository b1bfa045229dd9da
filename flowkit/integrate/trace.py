"""The public tracing API: ``trace`` (Lines in memory) and ``trace_to_file`` (streamed to HDF5).

Seeds are traced in batches; each batch runs the numba kernel in passes: a pass advances every
unfinished line until it ends or fills its vertex budget, the host keeps the vertices and
relaunches the unfinished lines (nothing is ever truncated).  With ``count`` a first pass only
measures each line's length, a second resamples it.  ``direction="both"`` traces two half-lines
per seed and joins them through the seed: vertices ordered along the line, time and arc length
negative before the seed.
"""

from __future__ import annotations

import sys
import weakref

import numpy as np

from ..fields import Field
from ..fields.bricks import POOL_SHARE, BrickPool, brick_budget
from ..fields.stored import FieldMemoryError, fmt_bytes
from ..lines import Lines
from . import attributes as _attributes
from . import kernel as K
from . import lanes, rosenbrock
from .launch import FieldArrays, Launch, MethodArrays
from .methods import get_method
from .options import OptionsError, TraceOptions
from .reasons import REASON_NAMES
from .rounds import Rounds, serve
from .stiffness import STIFF_BIT

BUFFER_BYTES = 32 << 20  # output buffer of one pass: (tasks, budget) vertices of 40 bytes
MAX_BUDGET = 1024  # vertices per line per pass (longer lines continue in the next pass)
BATCH_SEEDS = 16384
CELL_CAP = 1.25  # cell-aware steps: at most this times the straight-line time to the exit face
PROGRESS_MIN_SEEDS = 20000


def trace(field: Field, seeds, options: TraceOptions | None = None, *, backend="numba",
          empty: str = "raise", **kw) -> Lines:
    """Streamlines of ``field`` from ``seeds`` ((n, 3) or (3,)); ``kw`` overrides ``options``.

    ``backend``: "numba" (CPU, all cores), "opencl[:PLATFORM[:DEVICE]]", or a callable that
    advances the lines of a ``launch.Launch`` as ``kernel.advance`` does.
    ``empty``: when no line has two vertices (every seed outside the domain, a field at rest),
    "raise" an EmptyResultError saying why, "warn" (an EmptyResultWarning) or "ignore"; the
    lines are returned in the last two cases.
    """
    opts = resolve_options(options, kw)
    seeds = _seeds(seeds)
    setup = Setup(field, opts, backend)
    try:
        parts = list(_batches(field, seeds, opts, setup))
    finally:
        lanes.compile_pending()
    if len(parts) == 1:
        lines = parts[0]  # no copy
    else:
        lines = Lines.concatenate(parts) if parts else _empty(field, opts)
    lines.attrs = {**line_attrs(field, opts, setup.path), **setup.reads()}
    check_result(len(seeds), int(np.count_nonzero(lines.n_vertices >= 2)),
                 lines.line_data["reason"], empty)
    return lines


class EmptyResultError(ValueError):
    """A trace that gave no line of two vertices; the message says why."""


class EmptyResultWarning(UserWarning):
    """``trace(..., empty="warn")``: no line of two vertices."""


EMPTY = ("raise", "warn", "ignore")


def check_result(n_seeds: int, n_drawable: int, reasons: np.ndarray, empty: str = "raise"):
    """Raise (or warn) when ``n_drawable`` (lines of two vertices or more) is 0, naming why:
    no seed inside the domain, or the reasons the lines ended at their seeds."""
    if empty not in EMPTY:
        raise ValueError(f"empty = {empty!r}: expected one of {', '.join(EMPTY)}")
    if n_drawable or not n_seeds or empty == "ignore":
        return
    codes, counts = np.unique(np.asarray(reasons), return_counts=True)
    why = ", ".join(f"{REASON_NAMES[c]} {n}" for c, n in zip(codes, counts))
    if codes.size and set(codes.tolist()) <= {int(K.R_SEED)}:
        msg = (f"no seed lies inside the domain: all {n_seeds} seeds are outside it or in NaN "
               "cells; check the seeds' coordinates against the field's bounds (flowkit info)")
    else:
        msg = (f"no line has two vertices ({n_seeds} seeds; reasons: {why}): the field may be at "
               "rest where the seeds are, or the stagnation threshold too high")
    if empty == "warn":
        import warnings

        warnings.warn(msg, EmptyResultWarning, stacklevel=3)
    else:
        raise EmptyResultError(msg)


def trace_to_file(field: Field, seeds, path, options: TraceOptions | None = None, *,
                  batch_seeds: int = 4096, position_dtype="float32", backend="numba",
                  empty: str = "raise", setup=None, write_behind: bool = False, **kw):
    """Trace and stream each batch of ``batch_seeds`` seeds to the HDF5 file ``path``.

    Peak memory is bounded by one batch, whatever the number of seeds: the pass buffer
    (40 bytes x max(16, min(1024, 32 MiB / (40 x tasks))) vertices per task, at most ~32 MiB
    unless a batch has over 52k tasks) plus the batch's vertices, held about twice while they are
    ordered, at 40 bytes each plus 8 bytes per attribute component: ~100 MB for 4096 seeds of
    250 vertices.  The file appears atomically when complete.  Returns the path.  ``empty``: as
    for ``trace`` (raised before the file appears).  ``setup``: what runs the passes of each
    batch in place of ``Setup(field, opts, backend)`` (the scale-out's block mode: the same
    ``run``, ``reads`` and ``path``, on workers).  ``write_behind``: each batch is written in a
    thread while the next one is traced (two batches held): for a ``setup`` whose passes run
    elsewhere, so that this process waits for them and writes at once.
    """
    from concurrent.futures import ThreadPoolExecutor, wait

    from ..io.lines_h5 import LinesWriter

    opts = resolve_options(options, kw)
    seeds = _seeds(seeds)
    writer = writing = None
    behind = ThreadPoolExecutor(1, thread_name_prefix="flowkit-write") if write_behind else None
    drawable, reasons = 0, []
    try:
        setup = Setup(field, opts, backend) if setup is None else setup
        for part in _batches(field, seeds, opts, setup, batch_seeds):
            part.attrs = {**line_attrs(field, opts, setup.path), **setup.reads()}
            drawable += int(np.count_nonzero(part.n_vertices >= 2))
            if not drawable:  # (kept only while nothing is drawable: for the message)
                reasons.append(part.line_data["reason"])
            if writer is None:
                writer = LinesWriter.like(part, path, position_dtype=position_dtype)
            if writing is not None:
                writing.result()  # (the batches in order; an error in writing raised here)
            writing = None if behind is None else behind.submit(writer.append, part)
            if behind is None:
                writer.append(part)
        if writing is not None:
            writing.result()
        if writer is None:
            none = _empty(field, opts)
            none.attrs = line_attrs(field, opts)
            writer = LinesWriter.like(none, path, position_dtype=position_dtype)
        check_result(len(seeds), drawable, np.concatenate(reasons) if reasons else
                     np.zeros(0, np.int8), empty)
        writer.set_attrs(setup.reads())  # (over all batches)
        return writer.close()
    except BaseException:
        if writing is not None:
            wait([writing])  # (not aborted under an append)
        if writer is not None:
            writer.abort()
        raise
    finally:
        if behind is not None:
            behind.shutdown()
        lanes.compile_pending()


# -- options, stagnation and metadata as trace resolves them (the seeders use them too) ------
def resolve_options(options, kw) -> TraceOptions:
    """The options ``trace(field, seeds, options, **kw)`` runs with: ``options`` (a TraceOptions
    or None for the defaults) with ``kw`` replaced."""
    opts = options if options is not None else TraceOptions()
    if not isinstance(opts, TraceOptions):
        raise TypeError(f"options must be a TraceOptions, got {type(opts).__name__}")
    return opts.replace(**kw) if kw else opts


def line_attrs(field: Field, opts: TraceOptions, path: str | None = None) -> dict:
    """The ``Lines.attrs`` that ``trace`` records: the options, the field's source and box, and
    the ``path`` the lines took (``Setup.path``), where known."""
    return {**_attributes.metadata(field, opts.attributes),
        **({"kernel_path": path} if path else {}),
        "method": opts.method_name, "rtol": str(opts.rtol), "atol": str(opts.atol),
        "parameter": opts.parameter, "direction": opts.direction,
        "cell_aware": int(opts.cell_aware),
        "cross_faces": int(opts.cross_faces), "max_length": opts.max_length, "max_time": opts.max_time,
        "max_steps": opts.max_steps, "source": str(field.source), "reason_names": ",".join(REASON_NAMES),
        # the field's box "xmin xmax ymin ymax zmin zmax" (text, like the tolerances: it reads
        # back the same from every writer): the viewer's outline
        "domain_bounds": " ".join(repr(float(v)) for v in field.grid.bounds.ravel()),
    }


def stagnation_speed(field: Field, opts: TraceOptions, speed: float | None = None) -> float:
    """The speed below which ``trace`` stops a line: ``stagnation``, or ``stagnation_rel`` times
    the field's typical speed (``speed`` where known)."""
    if opts.stagnation is not None:
        return opts.stagnation
    return opts.stagnation_rel * (typical_speed(field) if speed is None else speed)


# -- internals --------------------------------------------------------------------------------
def _seeds(seeds) -> np.ndarray:
    s = np.asarray(seeds, dtype=np.float64)
    if s.ndim == 1 and s.size == 3:
        s = s[None, :]
    if s.ndim != 2 or s.shape[1] != 3:
        raise ValueError(f"seeds must have shape (n, 3), got {np.shape(seeds)}")
    return np.ascontiguousarray(s)


def _empty(field, opts) -> Lines:
    pd = {}
    for n in opts.attributes:
        pd[n] = np.zeros((0, 3)) if n in ("velocity", "vorticity") else np.zeros(0)
    ld = {"seed_id": np.zeros(0, np.int64), "reason": np.zeros(0, np.int8),
          "n_accepted": np.zeros(0, np.int32), "n_rejected": np.zeros(0, np.int32),
          "n_crossing": np.zeros(0, np.int32), "stiff": np.zeros(0, np.int8)}
    if opts.direction == "both":
        ld["reason_backward"] = np.zeros(0, np.int8)
    return Lines(np.zeros((0, 3)), np.zeros(1, np.int64), pd, ld)


SPEED_NODES = 1 << 17  # every node of a field this small; else SPEED_BLOCKS^3 blocks
SPEED_BLOCKS, SPEED_BLOCK, SPEED_ALIGN = 4, 12, 64  # per axis; nodes along a block's edge; its
# start a multiple of this (the common chunk size: a chunked file gives a block from one chunk)


def typical_speed(field: Field) -> float:
    """Field.typical_speed on a sample: every node of a small field, else 64 blocks of 12^3
    nodes spread over the grid.  It only scales defaults (stagnation threshold, minimum and
    fixed steps), and the full median costs seconds on large grids (the median of 10^5 speeds
    is still good to a few 0.1 %).  Blocks, not a stride: a strided sample of a chunked file
    reads every chunk, blocks read 64 of them, so a trace under a memory budget finds the same
    value (and the same lines) as one in memory.  Kept with the field for its vector (an array
    changed in place is not noticed)."""
    memo = getattr(field, "_typical_speed_memo", None)
    held = field._vector
    if memo is not None and memo[0]() is held:
        return memo[1]
    value = _sampled_speed(field)
    field._typical_speed_memo = (weakref.ref(held), value)
    return value


def _sampled_speed(field: Field) -> float:
    shape = field.grid.shape
    if np.prod(shape) <= SPEED_NODES:
        boxes = [(slice(None),) * 3]
    else:
        starts = []
        for n in shape:
            m = min(SPEED_BLOCK, n)
            at = {min(n - m, i * (n - m) // (SPEED_BLOCKS - 1) // SPEED_ALIGN * SPEED_ALIGN)
                  for i in range(SPEED_BLOCKS)}
            starts.append([slice(a, a + m) for a in sorted(at)])
        boxes = [(sx, sy, sz) for sx in starts[0] for sy in starts[1] for sz in starts[2]]
    sp = []
    for box in boxes:
        v = field.vector_box(box).astype(np.float64)  # (as float64 data's)
        sp.append(np.hypot(np.hypot(v[..., 0], v[..., 1]), v[..., 2]).ravel())  # no overflow
    sp = np.concatenate(sp)
    sp = sp[np.isfinite(sp) & (sp > 0)]
    return float(np.median(sp)) if sp.size else 0.0


class Setup:
    """Kernel arguments derived once per trace from the field and the options."""

    def __init__(self, field: Field, opts: TraceOptions, backend="numba", pool=None,
                 speed: float | None = None):
        """``pool``: the BrickPool to read the vector through in place of ``brick_pool``'s;
        ``speed``: the field's ``typical_speed`` where known (both: a worker's in the
        scale-out's block mode, which reads only its bricks)."""
        _attributes.check(field, opts.attributes)
        self.advance = _backend(backend)
        # a backend that computes the requested attributes itself (OpenCL: in its kernel) returns
        # a callable writing them into out_par's columns after (t, s) and decoding them
        bind = getattr(self.advance, "bind_attributes", None)
        if bind is not None and opts.attributes:
            self.advance = bind(field, opts.attributes)
        self.n_columns = getattr(self.advance, "n_columns", 0)
        self.point_data = None  # the last run's backend attributes, in its vertex order
        # what ran the passes: lanes.advance names its path; another backend by its name
        self.paths = set()
        self.backend_name = backend.split(":")[0] if isinstance(backend, str) else "callable"
        entry = opts.entry
        _check_backend(entry, backend)
        g = field.grid
        # the stepper lines start with: an explicit tableau, or (a Rosenbrock entry) the
        # Rosenbrock stepper, whose loop takes a tableau too: the default's, unused, so that
        # ros34pw2 and auto share one compiled variant
        ros = entry if entry.kind == "rosenbrock" else entry.switch_to
        self.stiff = None if ros is None else rosenbrock.table(ros)
        m = entry.explicit if entry.explicit is not None else get_method(TraceOptions.method)
        self.method = m
        self.grid = g.kernel_args()
        self.bricks = brick_pool(field, opts, backend) if pool is None else pool
        self.rounds = 0  # passes that ran the lines of one block of bricks (rounds.Rounds)
        self.progress = opts.progress if opts.progress is not None else sys.stderr.isatty()
        if self.bricks is None:
            self.vec = field.vector
            fa = FieldArrays.of(field)
        else:  # (read brick by brick: the explicit kernel only, brick_pool checked)
            self.vec = None
            fa = FieldArrays(*self.grid, self.bricks.pool, self.bricks.bk)
        self.arrays = fa, MethodArrays.of(m)
        ext = float(np.max(g.bounds[:, 1] - g.bounds[:, 0]))
        cell = g.min_cell_size
        vtyp = typical_speed(field) if speed is None else speed
        # time needed to cross the smallest cell at the typical speed (or its arc length)
        cross = cell if opts.parameter == "arc_length" else cell / (vtyp if vtyp > 0 else 1.0)
        fo = np.zeros(K.NFO)
        fo[K.O_RTOL:K.O_RTOL + 3] = opts.rtol
        fo[K.O_ATOL:K.O_ATOL + 3] = opts.rtol if opts.atol is None else opts.atol
        if opts.atol is None:
            fo[K.O_ATOL:K.O_ATOL + 3] *= ext
        fo[K.O_SAFETY], fo[K.O_FACMIN], fo[K.O_FACMAX] = opts.safety, opts.min_factor, opts.max_factor
        fo[K.O_BETA] = opts.beta
        if entry.adaptive:
            fo[K.O_H0] = opts.step or 0.0
        else:
            fo[K.O_H0] = opts.step if opts.step is not None else 0.5 * cross
        fo[K.O_HMIN] = opts.min_step if opts.min_step is not None else 1e-10 * cross
        fo[K.O_HMAX] = opts.max_step if opts.max_step is not None else np.inf
        fo[K.O_MAXLEN], fo[K.O_MAXTIME] = opts.max_length, opts.max_time
        fo[K.O_STAG] = stagnation_speed(field, opts, vtyp)
        fo[K.O_CELLFAC] = CELL_CAP
        self.fo = fo
        io = np.zeros(K.NIO, np.int64)
        io[K.P_MAXSTEPS] = opts.max_steps
        io[K.P_PARAM] = 1 if opts.parameter == "arc_length" else 0
        io[K.P_AWARE] = int(opts.cell_aware)
        io[K.P_CROSS] = int(opts.cross_faces)
        # Hairer & Wanner's stiffness test on the method's stage pair at c = 1, where it has one
        stiff = m.stiffness_stage
        io[K.P_STIFF] = -1 if stiff is None else stiff
        if entry.kind == "rosenbrock":  # (cell-aware: its Jacobian is the cell polynomial's)
            io[K.P_ROS], io[K.P_AWARE], io[K.P_CROSS], io[K.P_STIFF] = 1, 1, 0, -1
        self.io = io

    def tasks(self, n, emit):
        """The int options and the zeroed float and int states of ``n`` new tasks that emit
        ``emit`` (K.EMIT_STEPS, EMIT_SPACING or EMIT_FINAL)."""
        io = self.io.copy()
        io[K.P_EMIT] = emit
        return io, np.zeros((n, K.NF)), np.zeros((n, K.NI), np.int64)

    def buffers(self, n, budget):
        """Output buffers of a pass for up to ``n`` tasks of ``budget`` vertices each."""
        return (np.empty((n, budget, 3)), np.empty((n, budget, 2 + self.n_columns)),
                np.zeros(n, np.int64))

    def advance_pass(self, active, seeds, dirs, spacing, phase, io, sf, si, out):
        """One pass: advance the tasks ``active`` until each is done or has filled its row of
        the ``buffers`` ``out`` (at least active.size rows).  Returns the pass's vertices
        (points, t, s, owner), grouped by task in the order of ``active``, the backend's
        attribute columns in that order (None without), and which of ``active`` have more to
        give (a task left out of the next pass stays where it is)."""
        out_p, out_par, out_n = (b[:active.size] for b in out)
        ran = self.advance(Launch(active, seeds, dirs, spacing, phase, *self.arrays, self.fo,
                                  io, sf, si, out_p, out_par, out_n, self.stiff))
        self.paths.add(f"numba {ran}" if isinstance(ran, str) else self.backend_name)
        m = int(out_n.sum())
        part = np.empty((m, 3)), np.empty(m), np.empty(m), np.empty(m, np.int64)
        K.pack(active, out_p, out_par, out_n, *part)  # grouped by line
        cols = None
        if self.n_columns:  # the backend's attribute columns, in pack's order
            cols = out_par[:, :, 2:][np.arange(out_p.shape[1])[None, :] < out_n[:, None]]
        return part, cols, unfinished(si[active])

    def passes(self, active, seeds, dirs, spacing, phase, io, sf, si, out, rounds=None,
               owned=None):
        """Passes (``advance_pass``) until every task of ``active`` is done, or, with
        ``rounds`` (a Rounds) and ``owned`` (its blocks this process serves), waits for a brick
        of a block it does not own; yields each pass's vertices, attribute columns and the
        number of tasks left."""
        def run(ready):
            part, cols, busy = self.advance_pass(ready, seeds, dirs, spacing, phase, io, sf, si,
                                                 out)
            return (part, cols), busy

        for (part, cols), left, was_round in serve(active, si, run, rounds, owned):
            self.rounds += was_round
            yield part, cols, left

    def run(self, seeds, dirs, emit, spacing, phase, budget):
        """Run tasks to completion; returns (points, t, s, owner, si) with vertices grouped by
        task in order along each task's half-line."""
        n = seeds.shape[0]
        io, sf, si = self.tasks(n, emit)
        chunks = []  # per pass: (points, t, s, owner)
        # one allocation, reused by every pass (later ones have fewer lines)
        out = self.buffers(n, pass_budget(n, emit, budget))
        extra = []
        rounds = None if self.bricks is None else Rounds(self.bricks, n)
        bar = self._bar(n)
        for part, cols, left in self.passes(np.arange(n, dtype=np.int64), seeds, dirs, spacing,
                                            phase, io, sf, si, out, rounds):
            chunks.append(part)
            if cols is not None:
                extra.append(cols)
            if bar is not None:
                bar.update(n - left - bar.n)
                bar.set_postfix_str(f"{fmt_bytes(self.bricks.bytes_read)} read", refresh=False)
        if bar is not None:
            bar.close()
        if len(chunks) == 1:  # one pass: already grouped by line, in order
            self._keep_point_data(extra, chunks[0][1], chunks[0][2], None)
            return (*chunks[0], si)
        pts, t, s, owner = (np.concatenate(c) for c in zip(*chunks))
        order = np.argsort(owner, kind="stable")
        t, s = t[order], s[order]
        self._keep_point_data(extra, t, s, order)
        return pts[order], t, s, owner[order], si

    def _bar(self, n):
        """Progress of a bricked trace (lines done, bytes read), where asked for: its rounds
        may take minutes whatever the number of seeds."""
        if self.bricks is None or not self.progress:
            return None
        from tqdm import tqdm

        return tqdm(total=n, unit="line", desc="trace (bricks)", smoothing=0.1)

    def reads(self) -> dict:
        """Lines.attrs entries of a field read brick by brick: what was read, and the pool."""
        return {} if self.bricks is None else self.bricks.attrs(self.rounds)

    @property
    def path(self) -> str:
        """The paths the passes took so far ("numba lanes", "numba scalar: cell-aware
        stepping", "opencl", "driver: ros34pw2"...), joined by "; "."""
        return "; ".join(sorted(self.paths))

    def _keep_point_data(self, extra, t, s, order):
        self.point_data = None
        if self.n_columns:
            cols = np.concatenate(extra)
            self.point_data = self.advance.point_data(t, s, cols if order is None else cols[order])


def pass_budget(n: int, emit: int, budget: int | None) -> int:
    """Vertices per task in one pass of ``n`` tasks: ``budget`` (option budget), else what a
    BUFFER_BYTES buffer holds (16 to MAX_BUDGET); 2 where only the final vertex is kept."""
    if emit == K.EMIT_FINAL:
        return 2
    return budget or int(min(MAX_BUDGET, max(16, BUFFER_BYTES // (40 * n))))


def unfinished(si) -> np.ndarray:
    """Which tasks (rows of the int state) have more to do or to emit."""
    return (si[:, K.I_STATUS] != K.DONE) | (si[:, K.I_PEND] != 0) | (si[:, K.I_FINAL] != 0)


def brick_pool(field: Field, opts: TraceOptions, backend="numba"):
    """The BrickPool a trace reads ``field``'s vector through (brick by brick, only where lines
    go, within ``bricks.brick_budget``), or None where the vector is in memory already or is
    read whole: small, or fitting the budget where the method or backend cannot read bricks."""
    budget = brick_budget([field], opts.memory)
    if budget is None:
        return None
    stored = field.stored_vector()
    fits = stored.nbytes <= POOL_SHARE * budget
    entry = opts.entry
    # (a plain line that switches to the Rosenbrock stepper locates its cell afresh, at a
    # point whose brick need not be resident: auto goes brick by brick cell-aware only)
    why = ("the numba backend" if backend != "numba"
           else f"method {entry.name} without cell-aware stepping"
           if entry.switch_to is not None and not opts.cell_aware else "")
    if why and fits:
        return None
    if why:
        raise FieldMemoryError(
            f"{stored.where}: {fmt_bytes(stored.nbytes)} do not fit the memory budget of "
            f"{fmt_bytes(budget)}; a field read brick by brick is traced on the numba "
            f"backend, not by {why}: give --memory "
            f"{fmt_bytes(stored.nbytes / POOL_SHARE)} or more, or another method")
    return BrickPool(stored, field.grid, budget)


def _check_backend(entry, backend) -> None:
    """The method runs on the backend: a callable stands in for the explicit stepper."""
    if callable(backend):
        ok, kind = entry.kind == "explicit", "callable"
    else:
        kind = str(backend).split(":")[0]
        ok = kind in entry.backends
    if not ok:
        raise OptionsError(f"method {entry.name} runs on the {' and '.join(entry.backends)} "
                           f"backend{'s' if len(entry.backends) > 1 else ''} only, got backend "
                           f"{backend if kind == 'callable' else repr(backend)}")


def _backend(backend):
    if callable(backend):
        return backend
    if backend == "numba":
        return lanes.advance  # kernel.advance, lines in lock-step where that applies
    if isinstance(backend, str) and backend.split(":")[0] == "opencl":
        from .opencl.backend import OpenCLAdvance

        return OpenCLAdvance(backend)
    raise ValueError(f"unknown backend {backend!r}; use 'numba' or 'opencl[:PLATFORM[:DEVICE]]'")


def _batches(field, seeds, opts, setup, batch_seeds=BATCH_SEEDS):
    n = seeds.shape[0]
    show = opts.progress if opts.progress is not None else (n >= PROGRESS_MIN_SEEDS and sys.stderr.isatty())
    bar = None
    if show:
        from tqdm import tqdm
        bar = tqdm(total=n, unit="seed", desc="trace", smoothing=0.1)
    try:
        for start in range(0, n, batch_seeds):
            part = _trace_batch(field, setup, seeds[start:start + batch_seeds], opts, start)
            if bar is not None:
                bar.update(len(part))
            yield part
    finally:
        if bar is not None:
            bar.close()


def _trace_batch(field, setup: Setup, seeds, opts: TraceOptions, id0: int) -> Lines:
    n = seeds.shape[0]
    both = opts.direction == "both"
    if both:  # task 2i: backward half, 2i + 1: forward half
        tseeds = np.repeat(seeds, 2, axis=0)
        dirs = np.tile(np.array([-1.0, 1.0]), n)
    else:
        tseeds = seeds
        dirs = np.full(n, -1.0 if opts.direction == "backward" else 1.0)
    nt = tseeds.shape[0]
    spacing = np.zeros(nt)
    phase = np.zeros(nt)
    emit = K.EMIT_STEPS
    if opts.spacing is not None:
        emit = K.EMIT_SPACING
        spacing[:] = opts.spacing
    elif opts.count is not None:
        # pass 1 measures each half-line's length; pass 2 resamples the whole line evenly
        emit = K.EMIT_SPACING
        _, _, s1, owner1, _si1 = setup.run(tseeds, dirs, K.EMIT_FINAL, spacing, phase, None)
        length = np.zeros(nt)
        length[owner1] = np.abs(s1)
        if both:
            lb, lf = length[0::2], length[1::2]
            total = lb + lf
            step = np.where(total > 0, total / (opts.count - 1), 1.0)
            # vertices at -lb + j * step: forward from the first j with -lb + j step >= 0
            jf = np.ceil(lb / step - 1e-12)
            phf = np.maximum(jf * step - lb, 0.0)
            spacing[0::2] = spacing[1::2] = step
            phase[1::2] = phf
            phase[0::2] = np.where(phf > 0, step - phf, step)
        else:
            spacing[:] = np.where(length > 0, length / (opts.count - 1), 1.0)

    pts, t, s, owner, si = setup.run(tseeds, dirs, emit, spacing, phase, opts.budget)
    if setup.bricks is not None and opts.attributes:
        setup.bricks.release()  # (the attributes read near the vertices within the budget)
    return _assemble(field, opts, seeds, id0, pts, t, s, owner, task_columns(si, opts.entry),
                     setup.point_data, setup.bricks is not None)


def task_columns(si, entry=None) -> dict:
    """The line_data columns of tasks from their int state: reason, step counts (of both
    steppers) and flags (int8): ``stiff``; a Rosenbrock entry adds ``stiff_steps`` (its steps
    with h ρ(J) > HLAMBDA_STIFF), a stiff switch (auto) a flag named after its stiff method
    (``ros34pw2``) on the lines that went on with it."""
    cols = {"reason": si[:, K.I_REASON].astype(np.int8),
            "n_accepted": si[:, K.I_NACC].astype(np.int32),
            "n_rejected": si[:, K.I_NREJ].astype(np.int32),
            "n_crossing": si[:, K.I_NCROSS].astype(np.int32),
            "stiff": ((si[:, K.I_STIFF] & STIFF_BIT) != 0).astype(np.int8)}
    if entry is not None and entry.kind == "rosenbrock":
        cols["stiff_steps"] = si[:, K.I_NSTIFF].astype(np.int32)
    elif entry is not None and entry.switch_to is not None:
        cols[entry.switch_to.name] = (si[:, K.I_ROS] != 0).astype(np.int8)
    return cols


def _assemble(field, opts: TraceOptions, seeds, id0, pts, t, s, owner, cols,
              point_data=None, bricked=False) -> Lines:
    """Lines from the vertices of the tasks (grouped by task, in order along each) and per-task
    line_data columns; direction both joins task 2i (backward) and 2i + 1 (forward) through the
    seed: reason is the forward half's (``reason_backward`` the other), flags (int8) either
    half's, counts summed."""
    n = seeds.shape[0]
    both = opts.direction == "both"
    nt = 2 * n if both else n
    counts = np.bincount(owner, minlength=nt)
    ld = {"seed_id": np.arange(id0, id0 + n, dtype=np.int64)}
    if both:
        line = owner // 2
        fwd = owner % 2
        keep = (fwd == 1) | (s != 0.0)  # the seed appears once, in the forward half
        if owner.size < 2 or np.all(owner[1:] >= owner[:-1]):
            # tasks in order (as the backends give them): each backward half reversed in place,
            # then the seed dropped from it -- the lexsort below without sorting
            end = np.cumsum(counts)
            pos = np.arange(owner.size)
            perm = np.where(fwd == 1, pos, (2 * end - counts - 1)[owner] - pos)
            idx = perm[keep[perm]]
        else:
            rank = np.arange(owner.size) - (np.cumsum(counts) - counts)[owner]
            order = np.lexsort((np.where(fwd == 1, rank, -rank)[keep], fwd[keep], line[keep]))
            idx = np.flatnonzero(keep)[order]
        line_of = line[idx]
        for name, c in cols.items():
            if name == "reason":
                ld.update(reason=c[1::2], reason_backward=c[0::2])
            elif c.dtype == np.int8:
                ld[name] = np.maximum(c[0::2], c[1::2])
            else:
                ld[name] = c[0::2] + c[1::2]
        pts, t, s = pts[idx], t[idx], s[idx]
        if point_data is not None:
            point_data = {k: v[idx] for k, v in point_data.items()}
        counts = np.bincount(line_of, minlength=n)
    else:
        line_of = owner
        ld.update(cols)
    offsets = np.zeros(n + 1, np.int64)
    np.cumsum(counts, out=offsets[1:])
    # computed by the backend (OpenCL: in its kernel) or by the block owners (those read from
    # the field); the rest here
    pd = point_data or {}
    rest = [n for n in opts.attributes if n not in pd]
    if rest:  # the seed of every vertex only for the attribute that uses it
        seed_of = seeds[line_of] if "distance_to_seed" in rest else None
        pd = {**pd, **_attributes.compute(field, rest, pts, t, s, seed_of, bricked)}
        pd = {n: pd[n] for n in opts.attributes}
    return Lines(pts, offsets, pd, ld)

