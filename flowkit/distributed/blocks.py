"""Block mode: the field's bricks in blocks owned by workers, lines handed between them in rounds.

For a field no worker can hold.  The bricks (``fields.bricks``: the file's chunks) are grouped
in boxes (blocks), each owned by one worker; the blocks of a worker are a contiguous run of
them in C order.  A worker keeps one pool of bricks per job (``_SETUPS``: its Setup, kept
between rounds) and reads only the bricks its lines need: those of its own blocks, and the few
outside that a line at a block face needs at once (``rounds.Rounds``' need set).

Each round the client sends every unfinished line, as its whole state (the kernel's rows of
``sf`` and ``si``, its seed, direction, spacing, phase, and the bricks it waited for since it
last changed cell), to the owner of the block of the brick it waits for.  The worker runs the
trace's own passes (``Setup.passes``) on them until each line has ended or waits for a brick
of a block it does not own, and sends back the states, the vertices they emitted and (in
``si``) the bricks they wait for.  The kernel suspends a line that meets a brick not resident
at the start of its step and takes the same step again once it is there, so the lines are those
of one process, bit for bit, wherever they ran.  The worker also samples the attributes read
from the field (velocity, vorticity, scalars) at the vertices it emitted, by the trace's own
``attributes.compute`` through its pool (a vertex's curl may reach into another worker's block:
those few bricks are read too), and sends them with the vertices: the client never reads the
field for them.  The client keeps the vertices; the lines are assembled in seed order by the
trace's own code (``trace_to_file``, through the atomic writer), with time, arc length and the
distance to the seed, which need no field.

Load balance, as Viskores does it: where one worker holds most of a round's lines (a plume, a
vortex: seeds all in one block; a worker whose blocks hold more of the field), its most crowded
block gets a second owner, the worker with the
fewest lines that round, which reads that block's bricks too; from then on the block's lines
are split between its two owners so as to level their loads.  Where a line runs never changes
it, so the lines stay those of one process.

A task's result is a function of its inputs up to where each line stops (a brick another
line's step read may already be resident); the lines are the same either way, so a task
retried after its worker was lost gives the same lines, and the client takes one result per
task: none is lost or duplicated.
"""

from __future__ import annotations

import os
import threading
import time
from dataclasses import dataclass

import numpy as np

from ..fields.bricks import (
    GROUP_BYTES,
    MIN_SLOTS,
    POOL_SHARE,
    BrickPool,
    brick_nodes,
    bricks_of,
    cell_nodes,
)
from ..fields.stored import fmt_bytes
from ..integrate import schema as S
from ..integrate.attributes import check, compute, from_field
from ..integrate.options import TraceOptions
from ..integrate.rounds import WANTED, Rounds, block_span, blocks_of
from ..integrate.trace import pass_budget, trace_to_file, typical_speed, unfinished
from .tasks import JobError, numba_threads, open_field

WORKER_SHARE = 0.5  # of a worker's memory limit for its pool: dask pauses a worker at 80 %
BATCH_LINES = 1 << 16  # seeds per run of rounds: the client holds their vertices
# A worker with more than CROWDED times the mean lines of a round gets its most crowded block
# shared with the least loaded worker, where the stepping that moves off it outlasts the second
# owner's read of the block: a line ~150 steps at ~0.5 M steps/s, bricks read at ~0.4 GB/s
# (docs/scale-out.md, "Cost model").
CROWDED = 1.2
LINE_SECONDS = 3e-4
READ_BYTES_PER_S = 4e8
MODES = ("auto", "seeds", "blocks")


class BlockError(JobError):
    """A block task failed: the message names the worker, the block and the file."""


# -- the choice of mode ------------------------------------------------------------------------
def choose(distribute: str, field, client, n_snapshots: int,
           per_snapshot: bool = False) -> tuple[str, str]:
    """("seeds" or "blocks", why): blocks where a worker cannot hold the field's vector
    (``POOL_SHARE`` of its memory limit; a series': its first snapshot's), seeds where it can
    (or is given no limit).  Block mode traces a series snapshot by snapshot into one file
    each (``per_snapshot``): where it would have to write one file, a ValueError says so."""
    if distribute not in MODES:
        raise ValueError(f"distribute = {distribute!r}: expected one of {', '.join(MODES)}")
    one_file = n_snapshots > 1 and not per_snapshot
    if distribute == "blocks" and one_file:
        raise ValueError(f"distribute='blocks' traces the {n_snapshots} snapshots one after the "
                         f"other into one file each: give per_snapshot=True (--per-snapshot), "
                         f"or distribute='seeds' for one file")
    if distribute != "auto":
        return distribute, "asked for"
    limit = worker_memory(client)
    if limit is None:
        return "seeds", "the workers have no memory limit"
    size = field.stored_vector().nbytes
    fits = size <= POOL_SHARE * limit
    what = "the field's vector" if n_snapshots == 1 else "a snapshot's vector"
    why = (f"{what} ({fmt_bytes(size)}) {'fits' if fits else 'does not fit'} "
           f"{POOL_SHARE:.0%} of a worker's memory limit ({fmt_bytes(limit)})")
    if not fits and one_file:
        raise ValueError(f"{field.source}: {why}, and block mode writes one file per snapshot: "
                         f"give per_snapshot=True (--per-snapshot)")
    return ("seeds" if fits else "blocks"), why


def worker_memory(client) -> int | None:
    """The smallest memory limit of the cluster's workers (None: none has one)."""
    limits = [w.get("memory_limit") or 0 for w in client.scheduler_info()["workers"].values()]
    return min(limits) if limits and min(limits) > 0 else None


# -- the blocks ---------------------------------------------------------------------------------
class Layout:
    """The bricks of ``field`` in blocks for ``n_workers`` workers of ``budget`` bytes each
    (None: as much as a worker's share of the field takes): a block is at most half a
    worker's pool, as ``rounds.block_span`` makes it, and there are at least as many blocks as
    workers, so that every worker owns some."""

    def __init__(self, field, n_workers: int, budget: int | None):
        stored, grid = field.stored_vector(), field.grid
        self.grid = grid
        self.size = brick_nodes(stored, grid)
        self.count = -(-np.array(grid.shape, np.int64) // self.size)
        n_bricks = int(np.prod(self.count))
        self.slot = slot = int(np.prod(self.size)) * 3 * stored.dtype.itemsize
        # (a pool of twice a worker's share of the bricks: its blocks and their neighbours)
        need = max(MIN_SLOTS, 2 * -(-n_bricks // n_workers)) * slot / POOL_SHARE
        self.budget = int(need if budget is None else min(budget, need))
        slots = min(n_bricks, int(POOL_SHARE * self.budget // slot))
        span = block_span(self.count, slots)
        while int(np.prod(-(-self.count // span))) < n_workers and span.max() > 1:
            a = int(np.argmax(span))
            span[a] = -(-span[a] // 2)
        self.span = span
        self.n_blocks = int(np.prod(-(-self.count // span)))
        # each worker a contiguous run of blocks (C order: slabs along x) holding about its share
        # of the bricks: the last block along an axis may be smaller (8 bricks in blocks of 6:
        # blocks of 216 and 8 bricks; equal counts of blocks gave one of 2 workers 3/4 of the
        # bricks); as many blocks each where that leaves a worker none
        edge = [np.minimum(s, c - np.arange(-(-c // s)) * s) for c, s in zip(self.count, span)]
        bricks = np.einsum("i,j,k->ijk", *edge).ravel()
        mid = np.cumsum(bricks) - bricks / 2
        self.owner = (mid * n_workers // bricks.sum()).astype(np.int64)
        if np.unique(self.owner).size < n_workers:
            self.owner = np.arange(self.n_blocks) * n_workers // self.n_blocks

    def release(self) -> None:
        """(As ``BrickPool.release``: the pools are the workers', so nothing is held here.)"""

    def blocks_of_points(self, points) -> np.ndarray:
        return blocks_of(bricks_of(cell_nodes(self.grid, points), self.size, self.count),
                         self.count, self.span)

    def blocks_of_bricks(self, bricks) -> np.ndarray:
        return blocks_of(bricks, self.count, self.span)


# -- on a worker ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Job:
    """What every block task of one trace shares."""

    key: str
    source: object  # path or SnapshotRef
    vector: str | None
    options: TraceOptions
    size: tuple  # nodes per brick (the file's chunks: a field a worker read whole has none)
    span: tuple
    budget: int  # bytes of a worker's pool
    speed: float  # the field's typical speed (sampled on the client: on a small field, all of it)
    load: dict  # load_field's keywords (a mesh's resample=, ...): each worker resamples its own
    points: str = "float64"  # the dtype the vertices travel back in: the output's, where exact


@dataclass
class Batch:
    """Lines in flight: their numbers in the trace and their whole state."""

    rows: np.ndarray
    seeds: np.ndarray
    dirs: np.ndarray
    spacing: np.ndarray
    phase: np.ndarray
    sf: np.ndarray
    si: np.ndarray
    wanted: np.ndarray  # the bricks each waited for since it last changed cell (Rounds)
    cell: np.ndarray


class _Pool(BrickPool):
    """A worker's pool: it knows the brick it is reading, for the message if that fails."""

    reading = -1

    def _read(self, brick: int, slot: int) -> None:
        self.reading = brick
        super()._read(brick, slot)
        self.reading = -1


_SETUPS: dict = {}  # job key -> (Setup, lock): the worker's pool, kept between rounds
_SETUPS_LOCK = threading.Lock()


def _setup(job: Job):
    """(Setup, lock, field) of the job on this worker."""
    from ..integrate.trace import Setup

    with _SETUPS_LOCK:
        got = _SETUPS.get(job.key)
        if got is None:
            _SETUPS.clear()  # one job per worker: the last one's pool goes
            field = open_field(job.source, job.vector, job.load)
            pool = _Pool(field.stored_vector(), field.grid, job.budget, job.size)
            got = _SETUPS[job.key] = (Setup(field, job.options, "numba", pool, job.speed),
                                      threading.Lock(), field)
    return got


def _worker_name() -> str:
    try:
        from distributed import get_worker

        return get_worker().address
    except ValueError:  # (not in a worker: called directly)
        return f"pid {os.getpid()}"


def advance(job: Job, owned: np.ndarray, emit: int, batch: Batch) -> dict:
    """Run the lines of ``batch`` on this worker until each has ended or waits for a brick of a
    block not ``owned`` (a bool per block); their states, vertices and counts back."""
    t0, cpu0 = time.perf_counter(), time.thread_time()
    where = str(getattr(job.source, "path", job.source))
    worker = _worker_name()
    mine = np.flatnonzero(owned)
    try:
        setup, lock, field = _setup(job)
    except Exception as e:  # noqa: BLE001 (whatever opening raised, named in one line)
        raise BlockError(f"worker {worker}: blocks {_ranges(mine)} of {where}: cannot open the "
                         f"field: {_one_line(e)}") from None
    n = batch.rows.size
    sf, si = batch.sf.copy(), batch.si.copy()
    with lock, numba_threads(1):
        pool = setup.bricks
        loads, read = pool.loads, pool.bytes_read
        rounds = Rounds(pool, n, np.asarray(job.span))
        rounds.wanted[:], rounds.cell[:] = batch.wanted, batch.cell
        io = setup.tasks(0, emit)[0]
        out = setup.buffers(n, pass_budget(n, emit, job.options.budget))
        parts, point_data, sampling = [], {}, False
        names = from_field(job.options.attributes) if emit != S.EMIT_FINAL else []
        try:
            for part, _, _ in setup.passes(np.arange(n, dtype=np.int64), batch.seeds,
                                           batch.dirs, batch.spacing, batch.phase, io, sf, si,
                                           out, rounds, owned):
                parts.append(part)
            pts, t, s, owner = (np.concatenate(c) for c in zip(*parts)) if parts else (
                np.zeros((0, 3)), np.zeros(0), np.zeros(0), np.zeros(0, np.int64))
            t1, sampling = time.perf_counter(), True
            if names and pts.shape[0]:
                # the attributes read from the field, here: the client never reads it; through
                # this worker's pool, whose bricks are those near most of these vertices
                point_data = compute(field, names, pts, None, None, None, bricked=True,
                                     pool=pool, budget=_attribute_budget(job.budget))
        except Exception as e:
            brick, pool.reading = pool.reading, -1
            if brick >= 0:
                block = int(blocks_of(np.array([brick]), pool.count, job.span)[0])
                raise BlockError(f"worker {worker}: block {block} (brick {brick}) of {where} "
                                 f"failed to load: {_one_line(e)}") from None
            if not sampling:
                raise
            raise BlockError(f"worker {worker}: blocks {_ranges(mine)} of {where}: attributes "
                             f"{', '.join(names)} failed: {_one_line(e)}") from None
        loads, read = pool.loads - loads, pool.bytes_read - read
        paths = sorted(setup.paths)
    # back to the client only what it uses: the positions in the output's dtype where rounding
    # here gives the same bits, t and s where attributes or joining halves read them, and each
    # run of vertices of one line as (line, count): 12 bytes a vertex instead of 48
    opts = job.options
    runs, lengths = _runs(batch.rows[owner])
    return {"rows": batch.rows, "sf": sf, "si": si, "wanted": rounds.wanted, "cell": rounds.cell,
            "left": unfinished(si), "points": pts.astype(job.points, copy=False),
            "t": t if "time" in opts.attributes else None,
            "s": s if (opts.direction == "both" or emit == S.EMIT_FINAL
                       or "arc_length" in opts.attributes) else None,
            "runs": runs, "lengths": lengths,
            "point_data": point_data, "worker": worker, "seconds": time.perf_counter() - t0,
            "attribute_s": time.perf_counter() - t1, "cpu_s": time.thread_time() - cpu0,
            "loads": loads, "bytes_read": read, "paths": paths}


def _runs(owner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The runs of equal values of ``owner``: (value, length) of each, in order."""
    if not owner.size:
        return owner, owner
    starts = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    return owner[starts], np.diff(np.r_[starts, owner.size])


def _attribute_budget(pool_budget: int) -> int:
    """Bytes of the nodes ``by_bricks`` copies at once on a worker: a quarter of its pool's
    budget (the pool stays for the next round, beside them), at most ``GROUP_BYTES``."""
    return max(1 << 20, min(GROUP_BYTES, pool_budget // 4))


def _one_line(e: Exception) -> str:
    return f"{type(e).__name__}: {' '.join(str(e).split())}"


def _ranges(ids) -> str:
    ids = [int(i) for i in ids]
    return f"{ids[0]}-{ids[-1]}" if len(ids) > 1 else str(ids[0]) if ids else "none"


# -- on the client ---------------------------------------------------------------------------------
class BlockRun:
    """What ``trace_to_file`` runs the passes of a batch with (in place of a Setup): rounds of
    block tasks on the cluster.  ``reads()`` gives the job's counts for the lines' attrs."""

    point_data = None  # the last run's attributes read from the field, sampled by the workers

    def __init__(self, client, field, source, vector, opts: TraceOptions, why: str,
                 retries: int = 2, budget: int | None = None, load=None,
                 balance: bool = True, attrs: dict | None = None, position_dtype="float64"):
        entry = opts.entry
        if entry.switch_to is not None and not opts.cell_aware:
            # (as a field read brick by brick anywhere: a switching plain line locates its cell
            # afresh, where no brick need be resident)
            raise ValueError(f"method {entry.name}: block mode runs it cell-aware only")
        check(field, opts.attributes)  # (here, not on every worker)
        self.client, self.retries, self.why = client, retries, why
        self.addrs = sorted(client.scheduler_info()["workers"])
        if not self.addrs:
            raise RuntimeError("the dask cluster has no workers")
        if budget is None and opts.memory is None:
            limit = worker_memory(client)
            budget = None if limit is None else int(WORKER_SHARE * limit)
        self.bricks = self.layout = Layout(field, len(self.addrs), opts.memory or budget)
        self.balance = balance
        self.attrs = dict(attrs or {})
        self.second = np.full(self.layout.n_blocks, -1, np.int64)  # a block's second owner
        self.job = Job(f"{os.getpid()}-{id(self)}-{time.time_ns()}", source, vector, opts,
                       tuple(int(v) for v in self.layout.size),
                       tuple(int(v) for v in self.layout.span), self.layout.budget,
                       typical_speed(field), dict(load or {}),
                       # (rounded on the workers to the writer's float32: the same bits; not
                       # where the client computes the distance to the seed from them)
                       "float32" if np.dtype(position_dtype) == np.float32
                       and "distance_to_seed" not in opts.attributes else "float64")
        self.paths: set = set()
        self.stats = {"rounds": 0, "sends": 0, "lines": 0, "busy": 0.0, "slots": 0.0,
                      "loads": 0, "bytes_read": 0}
        self.per_round: list[dict] = []

    def run(self, seeds, dirs, emit, spacing, phase, budget):
        """Setup.run's result ((points, t, s, owner, si), vertices grouped by task in order
        along each) from rounds on the workers."""
        n = seeds.shape[0]
        sf, si = np.zeros((n, S.NF)), np.zeros((n, S.NI), np.int64)
        wanted, cell = np.full((n, WANTED), -1, np.int64), np.full((n, 3), -1, np.int64)
        block = self.layout.blocks_of_points(seeds)
        live = np.arange(n, dtype=np.int64)
        got = []
        self.stats["lines"] += n
        state = Batch(np.arange(n, dtype=np.int64), seeds, dirs, spacing, phase, sf, si, wanted,
                      cell)
        while live.size:
            for r in self._round(live, block[live], emit, state):
                rows = r["rows"]
                sf[rows], si[rows], wanted[rows], cell[rows] = r["sf"], r["si"], r["wanted"], r["cell"]
                got.append(r)
            live = live[unfinished(si[live])]
            block[live] = self.layout.blocks_of_bricks(si[live, S.I_WAIT] - 1)
            if np.any(si[live, S.I_WAIT] <= 0):  # (a worker returns a line only when it waits)
                raise RuntimeError("a block task returned a line that waits for no brick")
        return (*self._assemble(got), si)

    def _assemble(self, got: list[dict]):
        """(points, t, s, owner) of the tasks' results ``got`` grouped by line, each line's
        runs in the order of the rounds (each its vertices in order), and ``point_data`` the
        same way: each result's vertices scattered straight to their places."""
        runs = np.concatenate([r["runs"] for r in got])
        lengths = np.concatenate([r["lengths"] for r in got])
        order = np.argsort(runs, kind="stable")  # (runs, not vertices: a few per line)
        start = np.empty_like(lengths)  # where each run goes
        start[order] = np.cumsum(lengths[order]) - lengths[order]
        total = int(lengths.sum())
        # (t and s stay zeros where the workers did not send them: nothing reads them then)
        out = {"points": np.empty((total, 3), got[0]["points"].dtype),
               "t": np.zeros(total), "s": np.zeros(total)}
        # (a task that emitted no vertex sampled nothing)
        sampled = next((r["point_data"] for r in got if r["point_data"]), {})
        out.update({k: np.empty((total, *v.shape[1:]), v.dtype) for k, v in sampled.items()})
        at = 0
        for r in got:
            k = r["runs"].size
            if not k:
                continue
            ln = lengths[at:at + k]
            dest = np.repeat(start[at:at + k] - (np.cumsum(ln) - ln), ln) + np.arange(ln.sum())
            at += k
            for key, v in (("points", r["points"]), ("t", r["t"]), ("s", r["s"]),
                           *r["point_data"].items()):
                if v is not None:
                    out[key][dest] = v
        self.point_data = {k: out[k] for k in sampled} or None
        return out["points"], out["t"], out["s"], np.repeat(runs[order], lengths[order])

    def _round(self, rows, block, emit, batch: Batch) -> list[dict]:
        """One task per worker that owns blocks where the lines ``rows`` of ``batch`` (every
        line's state) wait; their results."""
        self._replace_lost_workers()
        t0 = time.perf_counter()
        who = self._assign(block)
        futures, ws = [], np.unique(who)
        for w in ws:
            pick = rows[who == w]  # (the whole state indexed once)
            part = Batch(*(getattr(batch, f)[pick] for f in Batch.__dataclass_fields__))
            owned = (self.layout.owner == w) | (self.second == w)
            futures.append(self.client.submit(
                advance, self.job, owned, emit, part,
                workers=[self.addrs[w]], allow_other_workers=True, retries=self.retries,
                pure=False, key=f"flowkit-blocks-{self.job.key}-r{self.stats['rounds']}-w{w}"))
        results = []
        try:
            for f in futures:
                try:
                    results.append(f.result())
                except BlockError as e:
                    raise BlockError(str(e)) from None  # (without the worker's traceback)
                except Exception as e:
                    raise JobError(f"block task {f.key} failed after {self.retries} retries: "
                                   f"{_one_line(e)}") from e
        except BaseException:
            for f in futures:
                f.cancel()
            raise
        wall = time.perf_counter() - t0
        busy = sum(r["seconds"] for r in results)
        st = self.stats
        st["rounds"] += 1
        st["sends"] += rows.size
        st["busy"] += busy
        st["slots"] += wall * len(self.addrs)
        st["loads"] += sum(r["loads"] for r in results)
        st["bytes_read"] += sum(r["bytes_read"] for r in results)
        for r in results:
            self.paths.update(r["paths"])
        # each worker's time in its task (one task each), and the CPU it got in it
        seconds, cpu, sampling = np.zeros((3, len(self.addrs)))
        vertices = np.zeros(len(self.addrs), np.int64)
        seconds[ws], cpu[ws] = [r["seconds"] for r in results], [r["cpu_s"] for r in results]
        sampling[ws] = [r["attribute_s"] for r in results]
        vertices[ws] = [r["points"].shape[0] for r in results]
        back = sum(v.nbytes for r in results for v in (r["points"], r["t"], r["s"], r["runs"],
                                                        r["lengths"], *r["point_data"].values())
                   if v is not None)
        self.per_round.append({"lines": int(rows.size), "tasks": len(results), "wall_s": wall,
                               "idle_share": max(0.0, 1.0 - busy / (wall * len(self.addrs))),
                               "worker_lines": np.bincount(who, minlength=len(self.addrs)).tolist(),
                               "worker_s": seconds.tolist(), "worker_cpu_s": cpu.tolist(),
                               "worker_vertices": vertices.tolist(),
                               "worker_attribute_s": sampling.tolist(),
                               "vertex_bytes": int(back),
                               "shared_blocks": int(np.count_nonzero(self.second >= 0))})
        return results

    def _assign(self, block: np.ndarray) -> np.ndarray:
        """The worker of each line of a round (its block's owner; a block with two owners split
        between them), after sharing crowded blocks where ``balance``."""
        n_w = len(self.addrs)
        who = self._split(block)
        for _ in range(n_w if self.balance and n_w > 1 else 0):
            load = np.bincount(who, minlength=n_w)
            busy, idle = int(np.argmax(load)), int(np.argmin(load))
            if load[busy] <= CROWDED * load.mean():
                break
            # the busiest worker's most crowded block not yet shared
            mine = (self.layout.owner[block] == busy) & (self.second[block] < 0)
            counts = np.bincount(block[mine], minlength=self.layout.n_blocks)
            b = int(np.argmax(counts))
            moved = min(counts[b], (load[busy] - load[idle]) // 2)
            read = np.prod(self.layout.span) * self.layout.slot / READ_BYTES_PER_S
            if moved * LINE_SECONDS < read:
                break
            self.second[b] = idle
            who = self._split(block)
        return who

    def _split(self, block: np.ndarray) -> np.ndarray:
        """Each line to its block's owner; the lines of a block with a second owner split so
        that the two owners' loads come out as level as they can (largest blocks first)."""
        first, second = self.layout.owner[block], self.second[block]
        who = first.copy()
        load = np.bincount(first[second < 0], minlength=len(self.addrs))
        shared = np.bincount(block[second >= 0], minlength=self.layout.n_blocks)
        for b in np.argsort(-shared, kind="stable")[:np.count_nonzero(shared)]:
            rows = np.flatnonzero(block == b)
            a, c, k = self.layout.owner[b], self.second[b], rows.size
            to_c = int(np.clip((k + load[a] - load[c]) // 2, 0, k))
            who[rows[k - to_c:]] = c
            load[a] += k - to_c
            load[c] += to_c
        return who

    def _replace_lost_workers(self):
        """A worker gone (the nanny starts a new one under a new address): its blocks go to a
        worker that owns none, else to the first."""
        live = sorted(self.client.scheduler_info()["workers"])
        spare = [a for a in live if a not in self.addrs]
        for i, a in enumerate(self.addrs):
            if a not in live and live:
                self.addrs[i] = spare.pop(0) if spare else live[0]

    def reads(self) -> dict:
        """The Lines.attrs of the job: mode and why, blocks, rounds, handoffs, idle, reads,
        and the ``attrs`` given (a series' snapshot time and index)."""
        st, lay = self.stats, self.layout
        return {"distribute": "blocks", "distribute_why": self.why, "blocks": lay.n_blocks,
                "block_bricks": " ".join(str(int(v)) for v in lay.span),
                "block_workers": len(self.addrs), "block_rounds": st["rounds"],
                "shared_blocks": int(np.count_nonzero(self.second >= 0)),
                "handoffs_per_line": (st["sends"] - st["lines"]) / max(1, st["lines"]),
                "idle_share": 1.0 - st["busy"] / st["slots"] if st["slots"] else 0.0,
                "bricks_read": st["loads"], "field_bytes_read": st["bytes_read"], **self.attrs}

    @property
    def path(self) -> str:
        return "; ".join(sorted(self.paths))


def trace_blocks(client, source, vector, seeds, out, opts: TraceOptions, why: str, *,
                 position_dtype="float32", retries: int = 2, timings: dict | None = None,
                 field=None, load=None, balance: bool = True, attrs: dict | None = None):
    """Lines of ``seeds`` through the snapshot ``source`` in block mode, written to ``out``
    as ``trace_to_file`` writes them (all or nothing).  Returns ``out``.  ``balance``: share
    crowded blocks with a second owner (False: each block on its one owner, to compare);
    ``attrs``: root attributes the file gets besides the trace's."""
    field = open_field(source, vector, load) if field is None else field
    run = BlockRun(client, field, source, vector, opts, why, retries, load=load, balance=balance,
                   attrs=attrs, position_dtype=position_dtype)
    t0 = time.perf_counter()
    # (written while the next batch's rounds run: the client mostly waits for the workers)
    path = trace_to_file(field, seeds, out, opts, setup=run, batch_seeds=BATCH_LINES,
                         position_dtype=position_dtype, empty="ignore", write_behind=True)
    if timings is not None:
        timings.update(tasks=time.perf_counter() - t0, rounds=run.per_round, **run.reads())
    return path
