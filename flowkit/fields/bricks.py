"""Fields read brick by brick: the table the step loop reads (``kernel._gather``).

A bricked field keeps only some bricks of its vector array in memory, in a pool of slots; the
table maps every brick to its slot (-1: not resident).  Layout of the int64 table array ``bk``:
``bk[B_CELLS:B_CELLS + 3]`` cells per brick along each axis, ``bk[B_COUNT:B_COUNT + 3]`` bricks
along each axis, ``bk[B_TABLE:]`` the slot of each brick, C order.  The pool is one array of
shape (slots * (b0 + 1), b1 + 1, b2 + 1, 3): each slot holds a brick's cells and the one layer of
nodes above them (the upper corners of its last cells), so a cell is read from one slot.  An
empty table (``NO_BRICKS``) means the vector array is the whole field.
"""

from __future__ import annotations

import numpy as np

B_CELLS, B_COUNT, B_TABLE = 0, 3, 6
NO_BRICKS = np.zeros(0, np.int64)

MIN_SLOTS = 8  # a step may read a few bricks at once; fewer slots would make lines take turns
POOL_SHARE = 0.8  # of a memory budget for the bricks; the rest for lines, buffers, the runtime
WHOLE_BYTES = 64 << 20  # an array in a file this small is read whole: bricks would not pay
GROUP_BYTES = 256 << 20  # of pages ``by_bricks`` fills before it computes and gives them back
BRICK_CELLS = 64  # along each axis, where the file is not chunked


def n_cells(c: np.ndarray, period: float) -> int:
    """Cells along an axis of nodes ``c``: a periodic axis has the wrap cell (``kernel._n_cells``)."""
    return c.size if period > 0.0 and c[0] + period - c[-1] > 0.0 else c.size - 1


def brick_cells(stored, grid) -> tuple[int, int, int]:
    """Cells per brick along each axis: the file's chunks where it has them (a brick is then
    read from one chunk and the first layer of the next), else ``BRICK_CELLS``."""
    chunks = stored.chunks[:3] if stored.chunks else (BRICK_CELLS,) * 3
    return tuple(int(max(1, min(ch, n_cells(c, p))))
                 for ch, c, p in zip(chunks, grid.axes, grid.period))


class BrickPool:
    """The vector of a field as bricks in a memory budget (``POOL_SHARE`` of ``budget`` bytes,
    at most what every brick takes): ``pool`` and ``bk`` for the step loop, ``load`` to make
    bricks resident, the least recently used ones evicted for them.

    ``stored``: the vector (a ``stored.Stored``, read a box at a time), on ``grid``; ``cells``:
    cells per brick along each axis (default ``brick_cells``)."""

    def __init__(self, stored, grid, budget: int, cells=None):
        from .stored import FieldMemoryError, fmt_bytes

        self.stored, self.grid = stored, grid
        self.cells = np.array(cells or brick_cells(stored, grid), np.int64)
        ncell = np.array([n_cells(c, p) for c, p in zip(grid.axes, grid.period)], np.int64)
        self.count = -(-ncell // self.cells)
        n_bricks = int(np.prod(self.count))
        nodes = tuple(int(b) + 1 for b in self.cells)
        self.slot_bytes = int(np.prod(nodes)) * 3 * stored.dtype.itemsize
        slots = min(n_bricks, int(POOL_SHARE * budget // self.slot_bytes))
        least = min(MIN_SLOTS, n_bricks)
        if slots < least:
            raise FieldMemoryError(
                f"{stored.where}: a memory budget of {fmt_bytes(budget)} holds {slots} bricks "
                f"of {nodes} nodes, a trace needs {least}: give --memory "
                f"{fmt_bytes(least * self.slot_bytes / POOL_SHARE)} or more")
        self.pool = np.empty((slots * nodes[0], nodes[1], nodes[2], 3), stored.dtype)
        self.bk = np.full(B_TABLE + n_bricks, -1, np.int64)
        self.bk[B_CELLS:B_CELLS + 3] = self.cells
        self.bk[B_COUNT:B_COUNT + 3] = self.count
        self.table = self.bk[B_TABLE:]
        self.held = np.full(slots, -1, np.int64)  # the brick in each slot
        self.used = np.zeros(slots, np.int64)  # when each slot was last asked for
        self.clock = 0
        self.bytes_read = 0
        self.loads = 0

    @property
    def slots(self) -> int:
        return self.held.size

    def brick_of(self, cells: np.ndarray) -> np.ndarray:
        """The brick of each cell (rows of cell indices; -1 where one is negative)."""
        cells = np.asarray(cells, np.int64)
        ok = np.all(cells >= 0, axis=1)
        b = np.ravel_multi_index(tuple((np.maximum(cells, 0) // self.cells).T), tuple(self.count),
                                 mode="clip")
        return np.where(ok, b, -1)

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
        for brick, slot in zip(missing, free):
            old = self.held[slot]
            if old >= 0:
                self.table[old] = -1
            self._read(int(brick), int(slot))
            self.held[slot] = brick
            self.table[brick] = slot
            self.used[slot] = self.clock

    def _read(self, brick: int, slot: int) -> None:
        """Brick ``brick`` into ``slot``: its cells' nodes and the layer above them, the nodes
        past the last on a periodic axis from its start (NaN past a bounded axis's end)."""
        b = np.unravel_index(brick, tuple(self.count))
        nodes = self.cells + 1
        dst = self.pool[slot * nodes[0]:(slot + 1) * nodes[0]]
        pieces = [wrapped_pieces(int(b[a] * self.cells[a]), int((b[a] + 1) * self.cells[a]) + 1,
                                 self.grid.shape[a], self.grid.periodic[a]) for a in range(3)]
        if np.prod([sum(d.stop - d.start for d, _ in p) for p in pieces]) < np.prod(nodes):
            dst[...] = np.nan  # (the nodes past a bounded axis's end, read by no cell)
        for dx, sx in pieces[0]:
            for dy, sy in pieces[1]:
                for dz, sz in pieces[2]:
                    out = dst[dx, dy, dz]
                    if out.flags.c_contiguous:
                        self.stored.source.fill_box(out, (sx, sy, sz))
                    else:
                        tmp = np.empty(out.shape, out.dtype)
                        self.stored.source.fill_box(tmp, (sx, sy, sz))
                        out[...] = tmp
                    self.bytes_read += out.nbytes
        self.loads += 1


def wrapped_pieces(lo: int, hi: int, n: int, periodic: bool) -> list[tuple[slice, slice]]:
    """Nodes lo:hi of an axis of n nodes as (offset from lo, nodes) slice pairs: past the ends
    from the other end on a periodic axis, left out on a bounded one."""
    if not periodic:
        a, b = max(lo, 0), min(hi, n)
        return [(slice(a - lo, b - lo), slice(a, b))] if a < b else []
    out = []
    for start in range(lo - lo % n, hi, n):  # each period the range meets
        a, b = max(lo, start), min(hi, start + n)
        out.append((slice(a - lo, b - lo), slice(a - start, b - start)))
    return out


def read_whole(field, scalar: str | None = None) -> bool:
    """Whether a sampler reads ``field``'s vector (or ``scalar``) whole: it is in memory, or its
    file's array is small; else ``by_bricks`` reads only near the points."""
    arrays = field.scalars if scalar is not None else None
    if scalar is None:
        return field.vector_in_memory() or field.stored_vector().nbytes <= WHOLE_BYTES
    return arrays.in_memory(scalar) or arrays.meta(scalar).nbytes <= WHOLE_BYTES


def by_bricks(field, points: np.ndarray, compute, scalars=(), halo: int = 0,
              budget: int = GROUP_BYTES) -> dict:
    """``compute(field, points)`` (a dict of per-point arrays), on a copy of ``field`` that holds
    only the bricks (``brick_cells``) holding ``points``, with ``halo`` nodes more around them,
    a few bricks at a time within ``budget`` bytes: the same values, read from the same nodes,
    as on the whole field.  The copy's arrays are virtual memory of the field's size (pages are
    taken only where a brick is written, and given back after each group); ``scalars``: the
    scalar arrays ``compute`` reads."""
    import mmap
    from dataclasses import replace

    g = field.grid
    points = np.ascontiguousarray(points, np.float64)
    size = np.array(brick_cells(field.stored_vector(), g), np.int64)
    count = -(-np.array([n_cells(c, p) for c, p in zip(g.axes, g.period)]) // size)
    cells = np.empty((points.shape[0], 3), np.int64)
    for a, (c, p) in enumerate(zip(g.axes, g.period)):
        x = points[:, a]
        if p > 0.0:
            x = c[0] + (x - c[0]) % p
        cells[:, a] = np.clip(np.searchsorted(c, x, "right") - 1, 0, n_cells(c, p) - 1)
    brick = np.ravel_multi_index(tuple((cells // size).T), tuple(count))
    order = np.argsort(brick, kind="stable")
    ids, first = np.unique(brick[order], return_index=True)
    groups = np.split(order, first[1:])

    arrays = {None: field.stored_vector()}
    arrays.update({n: _stored_scalar(field, n) for n in scalars if not field.scalars.in_memory(n)})
    maps, copies = [], {}
    for name, st in arrays.items():
        nbytes = int(np.prod(st.shape)) * st.dtype.itemsize
        flags = mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS | getattr(mmap, "MAP_NORESERVE", 0)
        maps.append(mmap.mmap(-1, max(nbytes, 1), flags=flags))
        copies[name] = np.frombuffer(maps[-1], st.dtype, nbytes // st.dtype.itemsize).reshape(st.shape)
    sub = replace(field, vector=copies[None],
                  scalars={**field.scalars, **{n: a for n, a in copies.items() if n is not None}})
    reach = 1 + halo  # nodes read below a brick's first cell and above its last upper corner
    out: dict = {}
    todo: list[int] = []
    held = 0
    for n, brick_id in enumerate(ids):
        b = np.unravel_index(brick_id, tuple(count))
        box = [wrapped_pieces(int(b[a] * size[a]) - reach, int((b[a] + 1) * size[a]) + 1 + reach,
                              g.shape[a], g.periodic[a]) for a in range(3)]
        for name, st in arrays.items():
            for _, sx in box[0]:
                for _, sy in box[1]:
                    for _, sz in box[2]:
                        copies[name][sx, sy, sz] = st.read_box((sx, sy, sz))
                        held += _pages(copies[name], sx, sy, sz)
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


def _stored_scalar(field, name):
    from .stored import Stored

    meta = field.scalars.meta(name)
    return meta if isinstance(meta, Stored) else Stored.of(field.scalars[name])


def _pages(a: np.ndarray, sx: slice, sy: slice, sz: slice, page: int = 4096) -> int:
    """Bytes of the pages a write of a[sx, sy, sz] touches (C order: a page per row at least)."""
    row = (sz.stop - sz.start) * int(np.prod(a.shape[3:], dtype=np.int64)) * a.itemsize
    return (sx.stop - sx.start) * (sy.stop - sy.start) * (row // page + 2) * page
