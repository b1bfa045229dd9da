"""Fields read brick by brick: the pool and table the step loop reads (``kernel._gather``).

A brick is a block of nodes, the file's chunk where it has one (else ``BRICK_NODES`` along each
axis), so that a brick is one aligned read: a read that takes part of a chunk costs the whole
chunk, so a brick never reaches into the next one.  A cell's corners lie in one brick, or, for
the cells on a brick's upper faces, in up to eight: the step loop looks each corner's brick up.
A bricked field keeps some bricks in memory, in a pool of slots; the table maps every brick to
its slot (-1: not resident).  Layout of the int64 table array ``bk``: ``bk[B_SIZE:B_SIZE + 3]``
nodes per brick along each axis, ``bk[B_COUNT:B_COUNT + 3]`` bricks along each axis,
``bk[B_NODES:B_NODES + 3]`` the grid's nodes along each axis, ``bk[B_TABLE:]`` the slot of each
brick, C order.  The pool is one array of shape (slots * s0, s1, s2, 3), slot after slot.  An
empty table (``NO_BRICKS``) means the vector array is the whole field.
"""

from __future__ import annotations

import contextlib
import itertools
import mmap

import numpy as np

B_SIZE, B_COUNT, B_NODES, B_TABLE = 0, 3, 6, 9
NO_BRICKS = np.zeros(0, np.int64)

MIN_SLOTS = 12  # what one line may need at once: its cell's 8 corner bricks and the 4 it last
# waited for (integrate/rounds.py), so that a round always runs a line
POOL_SHARE = 0.8  # of a memory budget for the bricks; the rest for lines, buffers, the runtime
WHOLE_BYTES = 64 << 20  # an array in a file this small is read whole: bricks would not pay
GROUP_BYTES = 256 << 20  # of pages ``by_bricks`` fills before it computes and gives them back
BRICK_NODES = 64  # along each axis, where the file is not chunked


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
    nodes per brick along each axis (default ``brick_nodes``)."""

    def __init__(self, stored, grid, budget: int, size=None):
        from .stored import FieldMemoryError, fmt_bytes

        self.stored, self.grid = stored, grid
        self.size = np.array(size if size is not None else brick_nodes(stored, grid), np.int64)
        self.count = -(-np.array(grid.shape, np.int64) // self.size)
        n_bricks = int(np.prod(self.count))
        self.tail = tuple(stored.shape[3:])  # (3,) for a vector, () for a scalar
        self.slot_bytes = int(np.prod(self.size)) * int(np.prod(self.tail)) * stored.dtype.itemsize
        slots = min(n_bricks, int(POOL_SHARE * budget // self.slot_bytes))
        least = min(MIN_SLOTS, n_bricks)
        if slots < least:
            raise FieldMemoryError(
                f"{stored.where}: a memory budget of {fmt_bytes(budget)} holds {slots} bricks "
                f"of {tuple(self.size.tolist())} nodes, a trace needs {least}: give --memory "
                f"{fmt_bytes(least * self.slot_bytes / POOL_SHARE)} or more")
        s0, s1, s2 = (int(v) for v in self.size)
        # in pages of its own, so that ``release`` can give them back
        self._map = _anonymous(slots * self.slot_bytes)
        self.pool = np.frombuffer(self._map, stored.dtype).reshape(slots * s0, s1, s2, *self.tail)
        self.bk = np.full(B_TABLE + n_bricks, -1, np.int64)
        self.bk[B_SIZE:B_SIZE + 3] = self.size
        self.bk[B_COUNT:B_COUNT + 3] = self.count
        self.bk[B_NODES:B_NODES + 3] = grid.shape
        self.table = self.bk[B_TABLE:]
        self.held = np.full(slots, -1, np.int64)  # the brick in each slot
        self.used = np.zeros(slots, np.int64)  # when each slot was last asked for
        self.clock = 0
        self.bytes_read = 0
        self.loads = 0

    @property
    def slots(self) -> int:
        return self.held.size

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
        keep = np.zeros(self.slots, bool)
        keep[here[here >= 0]] = True
        free = np.flatnonzero(~keep)
        free = free[np.argsort(self.used[free], kind="stable")][:missing.size]
        with self.stored.source.held():
            for brick, slot in zip(missing, free):
                old = self.held[slot]
                if old >= 0:
                    self.table[old] = -1
                self._read(int(brick), int(slot))
                self.held[slot] = brick
                self.table[brick] = slot
                self.used[slot] = self.clock

    def _read(self, brick: int, slot: int) -> None:
        """Brick ``brick`` into ``slot``: one aligned read (NaN past the grid's ends)."""
        b = np.unravel_index(brick, tuple(self.count))
        s0 = int(self.size[0])
        dst = self.pool[slot * s0:(slot + 1) * s0]
        box = tuple(slice(int(b[a] * self.size[a]), int(min((b[a] + 1) * self.size[a], n)))
                    for a, n in enumerate(self.grid.shape))
        shape = tuple(x.stop - x.start for x in box)
        if shape == dst.shape[:3]:
            self.stored.source.fill_box(dst, box)
        else:  # the last brick of an axis: part of a slot
            dst[...] = np.nan
            tmp = np.empty((*shape, *self.tail), dst.dtype)
            self.stored.source.fill_box(tmp, box)
            dst[:shape[0], :shape[1], :shape[2]] = tmp
        self.bytes_read += int(np.prod(shape)) * int(np.prod(self.tail)) * dst.itemsize
        self.loads += 1

    def release(self) -> None:
        """Every brick evicted and the pool's pages given back (while attributes are sampled
        from the file, say); the bricks are read again when next wanted."""
        self._map.madvise(mmap.MADV_DONTNEED)
        self.table[:] = -1
        self.held[:] = -1

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
