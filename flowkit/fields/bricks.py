"""Fields read brick by brick: the pool and table the step loop reads (``kernel._gather``).

A brick is a block of nodes, the file's chunk where it has one (else ``BRICK_NODES`` along each
axis), so that a brick is one aligned read: a read that takes part of a chunk costs the whole
chunk, so a brick never reaches into the next one.  A cell's corners lie in one brick, or, for
the cells on a brick's upper faces, in up to eight: the step loop looks each corner's brick up.
A bricked field keeps some bricks in memory, in a pool of slots; the table maps every brick to
its slot (-1: not resident).  Layout of the int64 table array ``bk``: ``bk[B_SIZE:B_SIZE + 3]``
nodes per brick along each axis, ``bk[B_COUNT:B_COUNT + 3]`` bricks along each axis,
``bk[B_NODES:B_NODES + 3]`` the grid's nodes along each axis, ``bk[B_TABLE:]`` the slot of each
brick, C order.  The pool is one array of shape (slots * s0, s1, s2, 3), slot after slot; for
pathlines, two snapshots' pools share one table (``unsteady.velocity`` reads both).  An empty
table (``NO_BRICKS``) means the vector array is the whole field.
"""

from __future__ import annotations

import contextlib
import itertools
import mmap

import numpy as np

from ..jit import inline

B_SIZE, B_COUNT, B_NODES, B_TABLE = 0, 3, 6, 9
NO_BRICKS = np.zeros(0, np.int64)

MIN_SLOTS = 12  # what one line may need at once: its cell's 8 corner bricks and the 4 it last
# waited for (integrate/rounds.py), so that a round always runs a line
POOL_SHARE = 0.8  # of a memory budget for the bricks; the rest for lines, buffers, the runtime
WHOLE_BYTES = 64 << 20  # an array in a file this small is read whole: bricks would not pay
GROUP_BYTES = 256 << 20  # of pages ``by_bricks`` fills before it computes and gives them back
BRICK_NODES = 64  # along each axis, where the file is not chunked


# -- the table as the step loops read it (inlined into them) --------------------------------
@inline
def axis_bricks(size, n, i):
    """Along an axis of n nodes in bricks of ``size``: (brick, index in it) of node i and of
    node i + 1 (node 0 after the last on a wrapped axis)."""
    b0 = i // size
    l0 = i - b0 * size
    if l0 + 1 < size and i + 1 < n:
        return b0, l0, b0, l0 + 1
    up = i + 1 if i + 1 < n else 0
    b1 = up // size
    return b0, l0, b1, up - b1 * size


@inline
def slot_of(bk, bx, by, bz):
    return bk[B_TABLE + (bx * bk[B_COUNT + 1] + by) * bk[B_COUNT + 2] + bz]


@inline
def missing_brick(bk, i, j, k):
    """A brick holding a corner of cell (i, j, k) of a bricked field that is not resident (the
    first found), else -1."""
    bx0, _, bx1, _ = axis_bricks(bk[B_SIZE], bk[B_NODES], i)
    by0, _, by1, _ = axis_bricks(bk[B_SIZE + 1], bk[B_NODES + 1], j)
    bz0, _, bz1, _ = axis_bricks(bk[B_SIZE + 2], bk[B_NODES + 2], k)
    for d in range(8):
        bx = bx1 if d & 1 else bx0
        by = by1 if d & 2 else by0
        bz = bz1 if d & 4 else bz0
        if slot_of(bk, bx, by, bz) < 0:
            return (bx * bk[B_COUNT + 1] + by) * bk[B_COUNT + 2] + bz
    return -1


def brick_nodes(stored, grid) -> np.ndarray:
    """Nodes per brick along each axis: the file's chunks where it has them, else
    ``BRICK_NODES`` (at most the axis)."""
    chunks = stored.chunks[:3] if stored.chunks else (BRICK_NODES,) * 3
    return np.array([max(2, min(ch, n)) for ch, n in zip(chunks, grid.shape)], np.int64)


def bricks_of(nodes: np.ndarray, size: np.ndarray, count: np.ndarray) -> np.ndarray:
    """The brick of each node (rows of node indices, in the grid)."""
    return np.ravel_multi_index(tuple((np.asarray(nodes) // size).T), tuple(count))


class BrickPool:
    """The vector of a field as bricks in a memory budget (``POOL_SHARE`` of ``budget`` bytes,
    at most what every brick takes): ``pool`` and ``bk`` for the step loop, ``load`` to make
    bricks resident, the least recently used ones evicted for them.

    ``stored``: the vector (a ``stored.Stored``, read a box at a time), on ``grid``; ``size``:
    nodes per brick along each axis (default ``brick_nodes``).  ``more``: arrays of the same
    shape read alongside (the next snapshot's vector, for pathlines), each into a pool of its
    own (``pools``, ``pool`` the first) under the one table: a brick is resident in every pool
    or in none, in the same slot, and the budget holds them all.  ``dtype``: the pools' type
    (default ``stored``'s; one that holds every source's values exactly)."""

    def __init__(self, stored, grid, budget: int, size=None, more=(), dtype=None):
        from .stored import FieldMemoryError, fmt_bytes

        self.sources, self.grid = [stored, *more], grid
        self.dtype = np.dtype(stored.dtype if dtype is None else dtype)
        self.size = np.array(size if size is not None else brick_nodes(stored, grid), np.int64)
        self.count = -(-np.array(grid.shape, np.int64) // self.size)
        n_bricks = int(np.prod(self.count))
        self.tail = tuple(stored.shape[3:])  # (3,) for a vector, () for a scalar
        # (a slot in every pool)
        self.slot_bytes = (len(self.sources) * int(np.prod(self.size))
                           * int(np.prod(self.tail)) * self.dtype.itemsize)
        slots = min(n_bricks, int(POOL_SHARE * budget // self.slot_bytes))
        least = min(MIN_SLOTS, n_bricks)
        if slots < least:
            raise FieldMemoryError(
                f"{stored.where}: a memory budget of {fmt_bytes(budget)} holds {slots} bricks "
                f"of {tuple(self.size.tolist())} nodes{self._times()}, a trace needs {least}: "
                f"give --memory {fmt_bytes(least * self.slot_bytes / POOL_SHARE)} or more")
        s0, s1, s2 = (int(v) for v in self.size)
        # in pages of their own, so that ``release`` can give them back
        self._maps = [_anonymous(slots * self.slot_bytes // len(self.sources))
                      for _ in self.sources]
        self.pools = [np.frombuffer(m, self.dtype).reshape(slots * s0, s1, s2, *self.tail)
                      for m in self._maps]
        self.bk = np.full(B_TABLE + n_bricks, -1, np.int64)
        self.bk[B_SIZE:B_SIZE + 3] = self.size
        self.bk[B_COUNT:B_COUNT + 3] = self.count
        self.bk[B_NODES:B_NODES + 3] = grid.shape
        self.table = self.bk[B_TABLE:]  # (resident: read in every pool)
        self.held = np.full(slots, -1, np.int64)  # the brick in each slot
        self.valid = np.zeros((len(self.sources), slots), bool)  # which pools hold it yet
        self.used = np.zeros(slots, np.int64)  # when each slot was last asked for
        self.clock = 0
        self.bytes_read = 0
        self.loads = 0

    def _times(self) -> str:
        n = len(self.sources)
        return "" if n == 1 else f" in each of {n} snapshots"

    @property
    def pool(self) -> np.ndarray:
        return self.pools[0]

    @property
    def slots(self) -> int:
        return self.held.size

    @property
    def nbytes(self) -> int:
        return sum(p.nbytes for p in self.pools)

    def attrs(self, rounds: int) -> dict:
        """Lines.attrs entries of a trace read through the pool in ``rounds`` rounds: what was
        read, and the pool."""
        return {"bricks_read": self.loads, "field_bytes_read": self.bytes_read,
                "brick_rounds": rounds, "brick_pool_bytes": self.nbytes}

    def holds(self, sources) -> bool:
        """Whether the pools can read ``sources`` (one per pool) from now on: their shape, and
        values the pools' type holds exactly."""
        return len(sources) == len(self.sources) and all(
            s.shape == self.sources[0].shape and np.can_cast(s.dtype, self.dtype, "safe")
            for s in sources)

    def follow(self, sources) -> None:
        """Read ``sources`` (one per pool, ``holds``) from now on.  A source one of the pools
        reads already keeps its bricks (that pool moves to the source's place); the others are
        read, for each brick held, when it is next wanted: from one snapshot interval to the
        next, the snapshot both share is not read again."""
        was = [next((i for i, o in enumerate(self.sources) if o is s), None) for s in sources]
        spare = [i for i in range(len(self.sources)) if i not in was]
        take = [i if i is not None else spare.pop() for i in was]
        self._maps = [self._maps[i] for i in take]
        self.pools = [self.pools[i] for i in take]
        self.valid = self.valid[take]
        self.valid[[i is None for i in was]] = False
        self.sources = list(sources)
        self.table[:] = -1
        full = np.flatnonzero((self.held >= 0) & self.valid.all(axis=0))
        self.table[self.held[full]] = full

    def corner_bricks(self, cells: np.ndarray) -> np.ndarray:
        """The bricks holding the corners of each cell (rows of cell indices): (n, 8), -1 in
        rows with a negative index (no cell)."""
        cells = np.asarray(cells, np.int64)
        ok = np.all(cells >= 0, axis=1)
        n = np.array(self.grid.shape)
        out = np.empty((cells.shape[0], 8), np.int64)
        for d in range(8):
            corner = np.maximum(cells, 0) + [(d >> a) & 1 for a in range(3)]
            corner = np.where(corner >= n, 0, corner)  # (node 0 after the last: a wrap cell)
            out[:, d] = bricks_of(corner, self.size, self.count)
        return np.where(ok[:, None], out, -1)

    def resident(self, bricks: np.ndarray) -> np.ndarray:
        return self.table[bricks] >= 0

    def load(self, wanted: np.ndarray) -> None:
        """Make the bricks ``wanted`` (numbers, repeated once per line that waits for each)
        resident, the most wanted first, as many as the pool holds; a slot goes to a new brick
        only when it is free or its brick is wanted by no line and was used longest ago."""
        self.clock += 1
        ids, n = np.unique(wanted, return_counts=True)
        ids = ids[np.argsort(-n, kind="stable")][:self.slots]
        here = self.table[ids]
        self.used[here[here >= 0]] = self.clock
        missing = ids[here < 0]
        if not missing.size:
            return
        # bricks held but not yet read from a source that ``follow`` brought: read in place
        part = np.flatnonzero((self.held >= 0) & ~self.valid.all(axis=0))
        part = part[np.isin(self.held[part], missing)]
        missing = missing[~np.isin(missing, self.held[part])]
        keep = np.zeros(self.slots, bool)
        keep[here[here >= 0]] = True
        keep[part] = True
        free = np.flatnonzero(~keep)
        free = free[np.argsort(self.used[free], kind="stable")][:missing.size]
        # (a run of reads shares each file it opens: opening costs as much as a brick)
        read = range(len(self.sources)) if missing.size else \
            np.flatnonzero(~self.valid[:, part].all(axis=1))
        with contextlib.ExitStack() as files:
            for i in read:
                files.enter_context(self.sources[i].source.held())
            for brick, slot in [*zip(self.held[part], part), *zip(missing, free)]:
                old = self.held[slot]
                if old != brick:
                    if old >= 0:
                        self.table[old] = -1
                    self.valid[:, slot] = False
                self._read(int(brick), int(slot))
                self.held[slot] = brick
                self.table[brick] = slot
                self.used[slot] = self.clock

    def _read(self, brick: int, slot: int) -> None:
        """Brick ``brick`` into ``slot`` of each pool that does not hold it yet: one aligned read
        each (NaN past the grid's ends)."""
        b = np.unravel_index(brick, tuple(self.count))
        s0 = int(self.size[0])
        box = tuple(slice(int(b[a] * self.size[a]), int(min((b[a] + 1) * self.size[a], n)))
                    for a, n in enumerate(self.grid.shape))
        shape = tuple(x.stop - x.start for x in box)
        for i in np.flatnonzero(~self.valid[:, slot]):
            dst = self.pools[i][slot * s0:(slot + 1) * s0]
            source = self.sources[i].source
            if shape == dst.shape[:3] and self.sources[i].dtype == self.dtype:
                source.fill_box(dst, box)
            else:  # the last brick of an axis: part of a slot (or a source of a narrower type)
                dst[...] = np.nan
                tmp = np.empty((*shape, *self.tail), self.sources[i].dtype)
                source.fill_box(tmp, box)
                dst[:shape[0], :shape[1], :shape[2]] = tmp
            self.bytes_read += (int(np.prod(shape)) * int(np.prod(self.tail))
                                * self.sources[i].dtype.itemsize)
            self.loads += 1
        self.valid[:, slot] = True

    def release(self) -> None:
        """Every brick evicted and the pools' pages given back (while attributes are sampled
        from the file, say); the bricks are read again when next wanted."""
        for m in self._maps:
            m.madvise(mmap.MADV_DONTNEED)
        self.table[:] = -1
        self.held[:] = -1
        self.valid[:] = False

    def copy_box(self, out: np.ndarray, box: tuple) -> None:
        """out[box] = the nodes of ``box`` (slices along x, y, z, inside the grid), from the
        bricks holding them, loaded first (the pool must hold them all)."""
        axes = [range(b.start // n, (b.stop - 1) // n + 1) for b, n in zip(box, self.size)]
        blocks = list(itertools.product(*axes))
        ids = np.ravel_multi_index(tuple(np.array(blocks).T), tuple(self.count))
        self.load(ids)
        s0 = int(self.size[0])
        for blk, brick in zip(blocks, ids):
            cut = [slice(max(b.start, q * n), min(b.stop, (q + 1) * n))
                   for b, q, n in zip(box, blk, self.size)]
            lo = [c.start - q * n for c, q, n in zip(cut, blk, self.size)]
            row = int(self.table[brick]) * s0 + lo[0]
            out[tuple(cut)] = self.pool[row:row + cut[0].stop - cut[0].start,
                                        lo[1]:lo[1] + cut[1].stop - cut[1].start,
                                        lo[2]:lo[2] + cut[2].stop - cut[2].start]


def read_whole(field, scalar: str | None = None) -> bool:
    """Whether a sampler reads ``field``'s vector (or ``scalar``) whole: it is in memory, or its
    file's array is small; else ``by_bricks`` reads only near the points."""
    if scalar is None:
        return field.vector_in_memory() or field.stored_vector().nbytes <= WHOLE_BYTES
    return field.scalars.in_memory(scalar) or field.scalars.meta(scalar).nbytes <= WHOLE_BYTES


def brick_budget(fields, memory: int | None = None) -> float | None:
    """The memory budget (bytes) within which a trace reads the vectors of ``fields`` (a field,
    or the two snapshots of a pathline interval) brick by brick, only where its lines go:
    ``memory``, else the memory free now; None where they are read whole: each in memory
    already, or small (``read_whole``) with all of them fitting the budget."""
    from .stored import available_memory

    if all(f.vector_in_memory() for f in fields):
        return None
    nbytes = sum(f.stored_vector().nbytes for f in fields)
    budget = memory if memory is not None else available_memory()
    if budget is None:  # (nothing says what is free: a slot for every brick)
        budget = nbytes / POOL_SHARE
    if nbytes <= POOL_SHARE * budget and all(read_whole(f) for f in fields):
        return None
    return budget


def cell_nodes(grid, points: np.ndarray) -> np.ndarray:
    """The lower corner node of each point's cell (wrapped on a periodic axis, clipped to the
    grid outside it)."""
    nodes = np.empty((points.shape[0], 3), np.int64)
    for a, (c, p) in enumerate(zip(grid.axes, grid.period)):
        x = points[:, a]
        if p > 0.0:
            x = c[0] + (x - c[0]) % p
        nodes[:, a] = np.clip(np.searchsorted(c, x, "right") - 1, 0, c.size - 1)
    return nodes


def by_bricks(field, points: np.ndarray, compute, scalars=(), halo: int = 0,
              budget: int = GROUP_BYTES, pool: BrickPool | None = None) -> dict:
    """``compute(field, points)`` (a dict of per-point arrays), on a copy of ``field`` that holds
    only the nodes near ``points`` (each brick holding their cells, ``brick_nodes``, with its
    upper corners and ``halo`` nodes more on every side), a group of bricks at a time within
    ``budget`` bytes: the same values, read from the same nodes, as on the whole field.  The
    copy's arrays are virtual memory of the field's size (pages are taken only where nodes are
    written, and given back after each group).  The file is read through a pool of bricks
    (``BrickPool``) and the groups go through the bricks block by block, so that a brick a
    neighbouring group needs again is read once; ``scalars``: the scalar arrays ``compute``
    reads.  ``pool``: a pool of the vector's bricks to read them through (a trace's, whose
    resident bricks are then not read again), where its bricks are these and it holds a
    block's boxes (or every brick)."""
    from dataclasses import replace

    g = field.grid
    shape = np.array(g.shape, np.int64)
    points = np.ascontiguousarray(points, np.float64)
    arrays = {None: field.stored_vector()}
    # (a scalar not in memory is held as its Stored handle)
    arrays.update({n: field.scalars.meta(n) for n in scalars if not field.scalars.in_memory(n)})
    size = brick_nodes(arrays[None], g)
    count = -(-shape // size)
    ijk = cell_nodes(g, points) // size
    brick = np.ravel_multi_index(tuple(ijk.T), tuple(count))
    # blocks of 2^3 bricks, one after the other: the halos of a group's bricks overlap, and the
    # pool holds a block's bricks with the layer around them
    order = np.lexsort((brick, np.ravel_multi_index(tuple((ijk // 2).T), tuple(-(-count // 2)))))
    cut = np.flatnonzero(np.diff(brick[order])) + 1
    groups = np.split(order, cut)
    ids = brick[order][np.concatenate([[0], cut])] if order.size else brick[:0]

    reach = 1 + halo  # nodes read beyond a brick: its cells' upper corners, and the halo
    most = int(np.prod(-(-(size + 2 * reach) // size) + 2))  # bricks a block's boxes span
    maps, copies, pools = [], {}, {}
    if pool is not None and (not np.array_equal(pool.size, size)
                             or pool.slots < min(most, int(np.prod(count)))):
        pool = None
    for name, st in arrays.items():
        nbytes = int(np.prod(st.shape)) * st.dtype.itemsize
        maps.append(_anonymous(nbytes))
        copies[name] = np.frombuffer(maps[-1], st.dtype, nbytes // st.dtype.itemsize).reshape(st.shape)
        one = int(np.prod(size)) * int(np.prod(st.shape[3:])) * st.dtype.itemsize
        pools[name] = pool if name is None and pool is not None else BrickPool(
            st, g, max(budget // 2, most * one) / POOL_SHARE, size)
    # (the other scalars as they are: in memory, or still in their file, unread)
    kept = {n: field.scalars.meta(n) for n in field.scalars}
    sub = replace(field, vector=copies[None],
                  scalars={**kept, **{n: a for n, a in copies.items() if n is not None}})
    out: dict = {}
    todo: list[int] = []
    held = 0
    with contextlib.ExitStack() as files:
        for st in arrays.values():
            files.enter_context(st.source.held())
        for n, brick_id in enumerate(ids):
            b = np.unravel_index(brick_id, tuple(count))
            spans = [_wrapped(int(b[a] * size[a]) - reach, int((b[a] + 1) * size[a]) + reach,
                              int(shape[a]), g.periodic[a]) for a in range(3)]
            for box in itertools.product(*spans):
                for name, pool in pools.items():
                    pool.copy_box(copies[name], box)
                    held += _pages(copies[name], *box)
            todo.append(n)
            if held >= budget or n == ids.size - 1:
                idx = np.concatenate([groups[m] for m in todo])
                for key, v in compute(sub, points[idx]).items():
                    if key not in out:
                        out[key] = np.empty((points.shape[0], *v.shape[1:]), v.dtype)
                    out[key][idx] = v
                for mm in maps:
                    mm.madvise(mmap.MADV_DONTNEED)  # the pages back, zero again
                todo, held = [], 0
    return out


def _anonymous(nbytes: int):
    """Zeroed virtual memory of its own (pages taken when written), which madvise can give
    back."""
    flags = mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | getattr(mmap, "MAP_NORESERVE", 0)
    return mmap.mmap(-1, max(nbytes, 1), flags=flags)


def zeroed(n: int, dtype) -> np.ndarray:
    """np.zeros(n, dtype) in pages of its own, of the base size: numpy advises huge pages for a
    large array, and an array written at scattered places would then take 2 MiB per write."""
    dtype = np.dtype(dtype)
    return np.frombuffer(_anonymous(n * dtype.itemsize), dtype, n)


def _wrapped(lo: int, hi: int, n: int, periodic: bool) -> list:
    """The node range lo..hi-1 of an axis of n nodes as slices inside it: clipped at a bounded
    axis' ends, on a periodic one wrapped (node n is node 0)."""
    if not periodic:
        return [slice(max(lo, 0), min(hi, n))]
    if hi - lo >= n:
        return [slice(0, n)]
    lo, hi = lo % n, (hi - 1) % n + 1
    return [slice(lo, hi)] if lo < hi else [slice(lo, n), slice(0, hi)]


def _pages(a: np.ndarray, sx: slice, sy: slice, sz: slice, page: int = 4096) -> int:
    """Bytes of the pages a write of a[sx, sy, sz] touches (C order: a page per row at least)."""
    row = (sz.stop - sz.start) * int(np.prod(a.shape[3:], dtype=np.int64)) * a.itemsize
    return (sx.stop - sx.start) * (sy.stop - sy.start) * (row // page + 2) * page
