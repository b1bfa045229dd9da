"""Rounds of a trace through a field read brick by brick: which lines a pass runs, and which
bricks are loaded for them.

The step loop suspends a line where a step meets a brick that is not resident (``I_WAIT``) and
takes the same step again once it is.  Lines sparse in a large field wait for many different
bricks at once; loading what every line waits for, round after round, reads the pool's worth
per round while each brick serves a line or two, and a pool far smaller than the field thrashes.
So the bricks are grouped into blocks of at most half the pool, and each round serves the
block where the most lines wait: it loads only the bricks those lines need, and they run until
each ends or meets a brick that is not resident.  A line wandering within the block is served
by the next rounds; a line that leaves it waits with the others of its next block.  The pool
holds the last two blocks' bricks, so lines crossing back and forth between neighbouring blocks
are served without reading a brick again.  The order changes what is read, never the lines.

A line needs the brick it waits for, the bricks of the cell it stands in, and the bricks it
waited for since it last moved to another cell (a step's stages may meet several bricks, one at
a time: given only the last one, a line would lose the one before and wait for it again).
"""

from __future__ import annotations

import numpy as np

from . import schema as S

WANTED = 4  # bricks a line remembers having waited for since it last moved to another cell


def block_span(count: np.ndarray, slots: int) -> np.ndarray:
    """Bricks per block along each axis for a pool of ``slots``: every brick where the pool
    holds them all, else a cube of at most half the pool."""
    count = np.asarray(count, np.int64)
    if int(np.prod(count)) <= slots:
        return count.copy()
    side = max(1, int((slots // 2) ** (1.0 / 3.0) + 1e-9))
    return np.minimum(count, side)


def blocks_of(bricks: np.ndarray, count, span) -> np.ndarray:
    """The block (C order, ``span`` bricks along each axis) of each brick of a grid of
    ``count`` bricks."""
    ijk = np.unravel_index(bricks, tuple(count))
    blocks = -(-np.asarray(count) // np.asarray(span))
    return np.ravel_multi_index(tuple(i // s for i, s in zip(ijk, span)), tuple(blocks))


def running_cells(rows: np.ndarray, si: np.ndarray) -> np.ndarray:
    """The cell each of the tasks ``rows`` stands in, as the step loop keeps it in ``si``
    (-1 where it has none: a line not started)."""
    return np.where((si[rows, S.I_STATUS] == S.RUNNING)[:, None],
                    si[rows, S.I_CELL:S.I_CELL + 3], -1)


class Rounds:
    """The scheduler of a bricked trace of ``n`` tasks reading ``pool`` (a BrickPool), in
    blocks of ``span`` bricks (default ``block_span``); ``cells(rows, si)``: the cell each of
    the tasks ``rows`` stands in (default ``running_cells``)."""

    def __init__(self, pool, n: int, span=None, cells=running_cells):
        self.pool = pool
        self.wanted = np.full((n, WANTED), -1, np.int64)
        self.cell = np.full((n, 3), -1, np.int64)  # each line's cell when it last waited
        self.span = block_span(pool.count, pool.slots) if span is None else np.asarray(span)
        self.blocks = -(-pool.count // self.span)
        self.cells = cells

    def block_of(self, bricks: np.ndarray) -> np.ndarray:
        return blocks_of(bricks, self.pool.count, self.span)

    def ready(self, active: np.ndarray, si: np.ndarray, owned=None) -> np.ndarray:
        """The lines of ``active`` the next pass runs, their bricks loaded: every line that
        waits for no brick, and the waiting lines of the block where the most wait; with
        ``owned`` (a bool per block) only of a block owned, the others left waiting."""
        wait = si[active, S.I_WAIT] - 1
        waiting = wait >= 0
        if not waiting.any():
            return active
        rows, wait = active[waiting], wait[waiting]
        cells = self.cells(rows, si)
        moved = np.any(cells != self.cell[rows], axis=1)
        self.wanted[rows[moved]] = -1
        self.cell[rows] = cells
        hist = self.wanted[rows]
        fresh = ~np.any(hist == wait[:, None], axis=1)
        hist[fresh, 1:] = hist[fresh, :-1]  # (newest first)
        hist[fresh, 0] = wait[fresh]
        self.wanted[rows] = hist
        need = np.concatenate([hist, self.pool.corner_bricks(cells)], axis=1)

        block = self.block_of(wait)
        here = np.ones(block.size, bool) if owned is None else owned[block]
        if not here.any():
            return active[~waiting]
        pick = np.flatnonzero(here & (block == np.argmax(np.bincount(block[here]))))
        bricks = _within(need[pick], self.pool.slots)
        pick = pick[:bricks.shape[0]]
        self.pool.load(bricks[bricks >= 0])
        ok = np.all((need[pick] < 0) | self.pool.resident(np.maximum(need[pick], 0)), axis=1)
        return np.concatenate([active[~waiting], rows[pick[ok]]])


def serve(active: np.ndarray, si: np.ndarray, run, rounds: Rounds | None = None, owned=None):
    """Passes until every task of ``active`` is done: each pass runs ``run(ready)`` on the tasks
    ``rounds.ready`` gives (all of them without ``rounds``), which returns (what the pass gave,
    which of ``ready`` have more to do); with ``owned``, until every task left waits for a
    block served elsewhere.  Yields (what the pass gave, the number of tasks left, whether the
    pass was a round)."""
    while active.size:
        ready = active if rounds is None else rounds.ready(active, si, owned)
        if not ready.size:  # every task left waits for a block served elsewhere
            return
        got, busy = run(ready)
        active = active[busy] if ready is active else np.setdiff1d(active, ready[~busy])
        yield got, active.size, ready is not active


def _within(need: np.ndarray, slots: int) -> np.ndarray:
    """The leading rows of ``need`` (bricks per line, -1: none) whose bricks together fit
    ``slots`` (at least the first row)."""
    ids = np.unique(need[need >= 0])
    if ids.size <= slots:
        return need
    seen: set = set()
    for i, row in enumerate(need):
        seen.update(int(b) for b in row if b >= 0)
        if len(seen) > slots and i > 0:
            return need[:i]
    return need
