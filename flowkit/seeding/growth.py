"""How the evenly spaced seeder advances a generation of half-lines, round after round.

Each round advances the half-lines still growing and hands back their new vertices as ``_walk``
tasks (even.py), which cuts or keeps them.  Two sources of rounds, one interface:

* ``Resumed``, for the methods the tracing kernel runs (every explicit method, on numba or
  OpenCL): a round is one pass of the kernel over the live half-lines, their integration state
  kept from the pass before, so a half-line is located and started once, and a cut one is
  simply left out of the next pass.  A pass fills each half-line's buffer of vertices (16 at
  first: about 4 dsep at the default spacing; each later pass twice as many), so a half-line
  is traced at most one pass past its cut.
* ``Restarted``, for the methods with a step loop of their own (Rosenbrock) and the stiff switch
  (whose stiff lines are traced again from their seeds): a round is one public
  ``flowkit.trace`` call per direction from each half-line's last kept vertex, a chunk of arc
  length further.

A round's tasks are rows (half, first, stop, step, prev) over its vertex arrays, in half order:
a first round's halves start at their seeds (direction both: the backward half walks from the
seed outward, the forward one on after it); a later round continues after the half's last kept
vertex, ``prev``.
"""

from __future__ import annotations

import math
import time
from typing import NamedTuple

import numpy as np

from ..integrate import kernel as K
from ..integrate.reasons import Reason
from ..integrate.trace import MAX_BUDGET, Setup, task_columns, trace

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
        """Per line: the step counts of both halves summed, stiff if either half was."""
        ns = len(self.signs)
        cols = task_columns(self.si)
        return {k: (v.reshape(-1, ns).max(1) if k == "stiff" else
                    v.reshape(-1, ns).sum(1).astype(np.int64))
                for k, v in cols.items() if k != "reason"}


class Restarted:
    """Half-lines traced again each round from their last kept vertex (see the module's text)."""

    def __init__(self, field, opts, backend, signs, chunk, store, stats, retraced):
        self.field, self.opts, self.backend = field, opts, backend
        self.signs, self.chunk0, self.store, self.stats = signs, chunk, store, stats
        self.retraced = retraced
        self.paths = set()
        if math.isfinite(opts.max_time):  # time and length rounds cannot both add up: one
            self.chunk0 = math.inf
        elif opts.spacing is not None:  # whole spacings: vertices stay regular across rounds
            self.chunk0 = max(1, round(chunk / opts.spacing)) * opts.spacing

    def start(self, seeds):
        ns, nl = len(self.signs), len(seeds)
        self.seeds, self.first, self.grown, self.chunk = seeds, True, 0.0, self.chunk0
        self.sign = np.tile(np.array(self.signs), nl)
        self.steps = np.zeros(nl * ns, np.int64)
        self.ld = {k: np.zeros(nl, np.int64) for k in ("n_accepted", "n_rejected", "n_crossing")}
        self.flags = {k: np.zeros(nl, np.int8) for k in ("stiff", self.retraced) if k is not None}

    def _trace(self, starts, direction, length):
        t0 = time.perf_counter()
        o = self.opts.replace(direction=direction, max_length=length,
                              attributes=("time", "arc_length"), progress=False)
        lines = trace(self.field, starts, o, backend=self.backend, empty="ignore")
        self.stats["trace_seconds"] += time.perf_counter() - t0
        self.stats["trace_calls"] += 1
        self.stats["trace_vertices"] += lines.n_points
        self.paths.update(lines.attrs.get("kernel_path", "").split("; "))
        return lines

    def round(self, todo, last):
        """Trace the halves ``todo`` a chunk further from their last kept vertices (``last``:
        store indices), or from their seeds in a generation's first round."""
        st, opts, ns = self.store, self.opts, len(self.signs)
        total = opts.max_length
        length = min(self.chunk, total - self.grown)
        self.chunk *= GROWTH
        self.grown += length
        further = math.isinf(total) or total - self.grown > 1e-12 * total
        calls = ([(opts.direction, todo, self.seeds)] if self.first else
                 [(d, todo[self.sign[todo] == sg], None) for d, sg in (("backward", -1),
                                                                      ("forward", 1))])
        tasks, bases, tp, ts, tt, reasons = [], [], [], [], [], []
        shift = 0
        for direction, hs, starts in calls:
            if not len(hs):
                continue
            if starts is None:
                starts = st.pts[last[hs]]
            tr = self._trace(starts, direction, length)
            off = tr.offsets
            a, b = off[:-1] + shift, off[1:] + shift
            if self.first and ns == 2:  # one line per seed: backward, seed, forward vertices
                sd = a + np.bincount(tr.line_index()[tr.point_data["arc_length"] < 0],
                                     minlength=len(a))
                task = np.stack([np.stack([hs[0::2], sd, a - 1, -np.ones_like(a),
                                           -np.ones_like(a)], 1),
                                 _rows(hs[1::2], sd, b, True, True, None)], 1).reshape(-1, 5)
                rs = np.stack([tr.line_data["reason_backward"], tr.line_data["reason"]], 1)
            elif self.first:
                task = _rows(hs, a, b, True, np.zeros(len(hs), bool), None)
                rs = tr.line_data["reason"]
            else:  # the first vertex is the last kept one
                task = _rows(hs, a + 1, b, False, None, a)
                rs = tr.line_data["reason"]
            tasks.append(task)
            reasons.append(rs.reshape(-1))
            base = np.zeros((len(hs), 2))
            if not self.first:
                base[:] = np.stack([st.s[last[hs]], st.t[last[hs]]], 1)
            bases.append(base)
            tp.append(tr.points)
            ts.append(tr.point_data["arc_length"])
            tt.append(tr.point_data["time"])
            shift += tr.n_points
            steps = tr.line_data["n_accepted"] + tr.line_data["n_rejected"]
            # a call's step counts go to a line's last half (direction both: both halves')
            self.steps[hs[ns - 1::ns] if self.first else hs] += steps
            li = hs[ns - 1::ns] // ns if self.first else hs // ns
            for k, v in self.ld.items():
                np.add.at(v, li, tr.line_data[k])
            for k, v in self.flags.items():
                if k in tr.line_data:
                    np.maximum.at(v, li, tr.line_data[k])
        self.first = False
        task = np.concatenate(tasks)
        order = np.argsort(task[:, 0], kind="stable")  # walk lines in the generation's order
        task = task[order]
        reason = np.concatenate(reasons)[order]
        more = ((reason == MAX_LENGTH) & further
                & (self.steps[task[:, 0]] < opts.max_steps))
        return Round(task, np.concatenate(bases)[order], np.concatenate(tp), np.concatenate(ts),
                     np.concatenate(tt), reason, more)

    def line_data(self):
        return {**self.ld, **self.flags}
