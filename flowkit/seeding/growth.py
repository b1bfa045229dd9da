"""How the evenly spaced seeder advances a generation of half-lines, round after round.

Each round advances the half-lines still growing and hands back their new vertices as ``_walk``
tasks (even.py), which cuts or keeps them (``Resumed``): a round is one pass of the tracing
kernel over the live half-lines, their integration state kept from the pass before, so a
half-line is located and started once, and a cut one is simply left out of the next pass.  A
pass fills each half-line's buffer of vertices (16 at first: about 4 dsep at the default
spacing; each later pass twice as many), so a half-line is traced at most one pass past its
cut.

A round's tasks are rows (half, first, stop, step, prev) over its vertex arrays, in half order:
a first round's halves start at their seeds (direction both: the backward half walks from the
seed outward, the forward one on after it); a later round continues after the half's last kept
vertex, ``prev``.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from ..integrate import kernel as K
from ..integrate.reasons import Reason
from ..integrate.trace import MAX_BUDGET, Setup, task_columns

GROWTH = 2  # each round grows a half-line this many times further than the one before
MAX_LENGTH = int(Reason.MAX_LENGTH)


class Round(NamedTuple):
    """The vertices of one round (``pts`` with arc length ``s`` and time ``t``, plus ``base``
    (s, t) per task), the ``_walk`` tasks over them, each task's reason so far and whether its
    half-line has more to give."""

    task: np.ndarray
    base: np.ndarray
    pts: np.ndarray
    s: np.ndarray
    t: np.ndarray
    reason: np.ndarray
    more: np.ndarray


def _rows(half, a, b, first, both_forward, prev):
    """Tasks over the vertices [a, b) of each half: from the seed in a first round (a forward
    half of direction both after its copy of the seed, which its backward half walked),
    otherwise after ``prev``."""
    one = np.ones_like(a)
    if first:
        start = np.where(both_forward, np.minimum(a + 1, b), a)
        prev = np.where(both_forward & (b > a), a, -1)
        return np.stack([half, start, b, one, prev], 1)
    return np.stack([half, a, b, one, prev], 1)


class Resumed:
    """Half-lines advanced pass after pass in the tracing kernel (see the module's text)."""

    def __init__(self, field, opts, backend, signs, chunk, store, stats):
        self.setup = Setup(field, opts.replace(attributes=()), backend)
        self.entry = opts.entry
        # the line_data columns of the method's lines, and which of them are flags
        cols = task_columns(np.zeros((0, K.NI), np.int64), self.entry)
        self.columns = list(cols)
        self.flags = {k for k, v in cols.items() if v.dtype == np.int8 and k != "reason"}
        self.spacing = opts.spacing
        self.emit = K.EMIT_SPACING if opts.spacing is not None else K.EMIT_STEPS
        self.budget0 = max(2, round(chunk / opts.spacing)) if opts.spacing else 16
        self.signs, self.store, self.stats = np.array(signs, np.float64), store, stats

    @property
    def paths(self):
        return self.setup.paths

    def start(self, seeds):
        """A new generation: two halves per seed with direction both, else one."""
        ns = len(self.signs)
        self.seeds = np.repeat(seeds, ns, axis=0)
        self.dirs = np.tile(self.signs, len(seeds))
        n = len(self.dirs)
        self.both_forward = (np.arange(n) % ns == 1)  # the forward half of direction both
        self.io, self.sf, self.si = self.setup.tasks(n, self.emit)
        self.spacings = np.full(n, self.spacing or 0.0)
        self.phases = np.zeros(n)
        self.budget, self.first = self.budget0, True

    def round(self, todo, last):
        """Advance the halves ``todo`` one pass; ``last``: each half's last kept store index."""
        t0 = time.perf_counter()
        out = self.setup.buffers(len(todo), self.budget)
        (pts, t, s, _), _, more = self.setup.advance_pass(
            todo, self.seeds, self.dirs, self.spacings, self.phases, self.io, self.sf, self.si,
            out)
        self.budget = min(GROWTH * self.budget, MAX_BUDGET)
        b = np.cumsum(out[2][:len(todo)])
        a = b - out[2][:len(todo)]
        base = np.zeros((len(todo), 2))
        if self.first:
            task = _rows(todo, a, b, True, self.both_forward[todo], None)
        else:  # the previous vertex of each half: its last kept one, after this pass's
            st, prev = self.store, last[todo]
            task = _rows(todo, a, b, False, None, len(pts) + np.arange(len(todo)))
            pts, s, t = (np.concatenate([pts, st.pts[prev]]), np.concatenate([s, st.s[prev]]),
                         np.concatenate([t, st.t[prev]]))
        self.first = False
        self.stats["trace_calls"] += 1
        self.stats["trace_vertices"] += int(b[-1]) if len(b) else 0
        self.stats["trace_seconds"] += time.perf_counter() - t0
        return Round(task, base, pts, s, t, self.si[todo, K.I_REASON].astype(np.int8), more)

    def line_data(self):
        """Per line: the step counts of both halves summed, a flag if either half has it."""
        ns = len(self.signs)
        cols = task_columns(self.si, self.entry)
        return {k: (v.reshape(-1, ns).max(1) if k in self.flags else
                    v.reshape(-1, ns).sum(1).astype(np.int64))
                for k, v in cols.items() if k != "reason"}
