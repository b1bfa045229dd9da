"""Evenly spaced streamlines in 3D, after Jobard and Lefer (1997), grown on the warm tracer.

Two distances: ``dsep``, the spacing wanted between lines, and ``dtest`` < ``dsep``, the
closest a line may come to another.  A line is grown from a candidate seed at least ``dsep``
from every line placed so far; walking out from its seed, it is cut at its first vertex closer
than ``dtest`` to another line, or to itself more than ``2 dsep`` of arc length away (a closed
or ergodic orbit), at the exact point of the segment where that distance reaches ``dtest``; that
half ends with reason ``too_close``.  Candidates come, first, from ``dsep`` beside every
accepted line (six directions around the tangent, about every ``dsep`` of arc length, oldest
line first), then, when none is left, from a lattice of spacing ``dsep / 2`` over the domain in
an order drawn from the random seed; this second source is what guarantees coverage: every
valid point of the field ends within about ``1.5 dsep`` of a line unless the flow is too slow to
carry one (see docs/seeding.md for the bounds and the tests that check them).

A generation of candidates, mutually ``dsep`` apart, grows together in rounds: each round
advances every live half-line further (for the tracing kernel's methods one pass of the kernel,
resumed where the last one stopped; growth.py), then walks the new vertices line after line, in
the generation's order, against every vertex placed so far, this round's included, and hashes
the ones that pass.  So no vertex is ever kept within ``dtest`` of another line's, and a line
cut early is traced at most one round past its cut.  A candidate is checked against the lines
(the hash) before the field is sampled there: most lie near a line, and the lines are only ever
added to, so a candidate near one is dropped for good.

Distances are found with a spatial hash (cells of size ``dsep``, minimum image on periodic
axes): a vertex is compared only with the vertices in the cells its ball reaches, so the cost
grows with the number of vertices, not its square.  Everything is deterministic for a given
random seed.
"""

from __future__ import annotations

import math
import sys
import warnings

import numpy as np
from numba import njit

from ..fields import Field
from ..integrate import attributes as _attributes
from ..integrate.options import OptionsError, TraceOptions
from ..integrate.reasons import Reason
from ..integrate.trace import line_attrs, resolve_options, stagnation_speed
from ..jit import helper, inline
from ..lines import Lines
from .growth import Resumed

DIRECTIONS = 6  # candidate seeds around the tangent of a line
MAX_BATCH = 1024
MIN_BATCH = 256
SELF_GAP = 2.0  # own vertices nearer than this many dsep of arc length never cut a line
LATTICE = 0.5  # lattice candidates every LATTICE * dsep
PROGRESS_DELAY = 1.0  # seconds before a count of the lines appears (progress None)
CHUNK = 4.0  # the first round grows each half-line by about this many dsep (growth.py)
TOO_CLOSE = int(Reason.TOO_CLOSE)
# typed constants: a literal 0, 1, 2 or False argument compiles one more copy of a helper per
# value (numba types it as that literal), about a second over the hash's helpers
NONE, NO, YES = np.int64(-1), np.bool_(False), np.bool_(True)
X, Y, Z = np.int64(0), np.int64(1), np.int64(2)  # axes
ALL = np.zeros(0, np.int8)  # _pick's ok for candidates that all are


# -- the spatial hash ---------------------------------------------------------------------------
# ``geo`` rows: the low corner, cells per unit length, cells, period (0: not periodic), per axis.
@inline
def _axis_cell(x, geo, a):
    d = x - geo[0, a]
    if geo[3, a] > 0.0:
        d = d % geo[3, a]
    return min(max(math.floor(d * geo[1, a]), 0), int(geo[2, a]) - 1)


@inline
def _cell(p, geo):
    return ((_axis_cell(p[0], geo, X) * int(geo[2, 1]) + _axis_cell(p[1], geo, Y))
            * int(geo[2, 2]) + _axis_cell(p[2], geo, Z))


@njit(cache=True)
def _insert(geo, head, nxt, pts, n0, n1):
    for v in range(n0, n1):
        c = _cell(pts[v], geo)
        nxt[v] = head[c]
        head[c] = v


@inline
def _span(x, r, geo, a):
    """The first cell and the number of cells along axis a that [x - r, x + r] reaches (a
    periodic axis wraps: callers take the index modulo the cell count), and where among them
    x's own cell lies."""
    n = int(geo[2, a])
    d = x - geo[0, a]
    if geo[3, a] > 0.0:
        d = d % geo[3, a]
        c0 = math.floor((d - r) * geo[1, a])
        m = min(math.floor((d + r) * geo[1, a]) - c0 + 1, n)
        return c0, m, (min(math.floor(d * geo[1, a]), n - 1) - c0) % m
    c0 = max(math.floor((d - r) * geo[1, a]), 0)
    m = min(math.floor((d + r) * geo[1, a]), n - 1) - c0 + 1
    return c0, m, min(max(math.floor(d * geo[1, a]) - c0, 0), max(m - 1, 0))


@inline
def _diff(p, q, geo, a):
    """p - q along axis a, the minimum image on a periodic axis."""
    d = p[a] - q[a]
    if geo[3, a] > 0.0:
        d -= geo[3, a] * np.round(d / geo[3, a])
    return d


@inline
def _entry(a, p, q, r2, geo):
    """The first u in [0, 1] where a + u (p - a) is within sqrt(r2) of q (-1: never)."""
    e0, e1, e2 = _diff(a, q, geo, X), _diff(a, q, geo, Y), _diff(a, q, geo, Z)
    f0, f1, f2 = p[0] - a[0], p[1] - a[1], p[2] - a[2]
    cc = e0 * e0 + e1 * e1 + e2 * e2 - r2
    if cc <= 0.0:
        return 0.0
    aa = f0 * f0 + f1 * f1 + f2 * f2
    bb = 2.0 * (f0 * e0 + f1 * e1 + f2 * e2)
    disc = bb * bb - 4.0 * aa * cc
    if aa <= 0.0 or disc < 0.0:
        return -1.0
    u = (-bb - math.sqrt(disc)) / (2.0 * aa)
    return u if 0.0 <= u <= 1.0 else -1.0


@inline
def _wrap(i, geo, a):
    """Cell index i of axis a, wrapped on a periodic axis (integer division only there)."""
    return i % int(geo[2, a]) if geo[3, a] > 0.0 else i


@inline
def _in_cell(c, geo, head, nxt, pts, owner, sarr, a, p, r2, line, s, gap, entry, best):
    """``_scan`` over the vertices of cell c: (the smallest entry u so far, 1 if not
    ``entry`` and one lies within r of p)."""
    v = head[c]
    while v >= 0:
        o = owner[v]
        if o >= 0 and (o != line or abs(sarr[v] - s) > gap):
            q = pts[v]
            d2 = 0.0
            for ax in range(3):
                d2 += _diff(p, q, geo, ax) ** 2
            if not entry:
                if d2 < r2:
                    return best, 1
            else:
                u = _entry(a, p, q, r2, geo)
                if u < 0.0 and d2 < r2:  # rounding: the root lies at the end
                    u = 1.0
                if u >= 0.0 and (best < 0.0 or u < best):
                    best = u
        v = nxt[v]
    return best, 0


@helper
def _scan(geo, head, nxt, pts, owner, sarr, a, p, r, line, s, gap, entry):
    """Over the hashed vertices that count (owner >= 0, and for the own ``line`` only those
    more than ``gap`` of arc length from ``s``): without ``entry``, 1 if one lies within ``r``
    of ``p``, else -1; with ``entry``, the smallest u in [0, 1] where the segment a + u (p - a)
    comes within ``r`` of one (-1: none does)."""
    r2 = r * r
    reach = r
    if entry:
        reach += math.sqrt(_diff(p, a, geo, X) ** 2 + _diff(p, a, geo, Y) ** 2
                           + _diff(p, a, geo, Z) ** 2)
    n1, n2 = int(geo[2, 1]), int(geo[2, 2])
    i0, ni, oi = _span(p[0], reach, geo, X)
    j0, nj, oj = _span(p[1], reach, geo, Y)
    k0, nk, ok = _span(p[2], reach, geo, Z)
    # p's own cell first (the likeliest to hold a hit, which ends the scan): each axis from
    # its offset o round to it
    best = -1.0
    for a0 in range(ni):
        di = oi + a0 - ni if oi + a0 >= ni else oi + a0
        ci = _wrap(i0 + di, geo, X) * n1
        for a1 in range(nj):
            dj = oj + a1 - nj if oj + a1 >= nj else oj + a1
            cj = (ci + _wrap(j0 + dj, geo, Y)) * n2
            for a2 in range(nk):
                dk = ok + a2 - nk if ok + a2 >= nk else ok + a2
                best, hit = _in_cell(cj + _wrap(k0 + dk, geo, Z), geo, head, nxt, pts, owner,
                                     sarr, a, p, r2, line, s, gap, entry, best)
                if hit:
                    return 1.0
    return best


@njit(cache=True)
def _pick(geo, head, nxt, pts, owner, sarr, cand, ok, at, limit, r, mutual, picked, ppts,
          phead, pnxt, pown, ps):
    """From ``cand[at:]``, in order, the candidates (where ``ok`` is not 0; an empty ``ok``:
    all) at least ``r`` from every hashed vertex and, where ``mutual``, from each other, until
    ``limit``: their indices into ``picked``; returns (how many, the next ``at``).  The picks
    are hashed in ``ppts``, ``phead`` (all -1, left so) and ``pnxt``, with ``pown`` and ``ps``
    zeros (the types of ``owner`` and ``sarr``: one compiled ``_scan``); all but ``phead``
    have a row for every pick there can be."""
    n = 0
    while at < cand.shape[0] and n < limit:
        p = cand[at]
        at += 1
        if ok.shape[0] > 0 and ok[at - 1] == 0:
            continue
        if _scan(geo, head, nxt, pts, owner, sarr, p, p, r, NONE, 0.0, 0.0, NO) > 0.0:
            continue
        if mutual:
            if _scan(geo, phead, pnxt, ppts, pown, ps, p, p, r, NONE, 0.0, 0.0, NO) > 0.0:
                continue
            # (row by row: numba's array setitem compiles a shape-mismatch message, seconds)
            ppts[n, 0], ppts[n, 1], ppts[n, 2] = p[0], p[1], p[2]
            c = _cell(p, geo)
            pnxt[n] = phead[c]
            phead[c] = n
        picked[n] = at - 1
        n += 1
    if mutual:
        for q in range(n):
            phead[_cell(ppts[q], geo)] = -1
    return n, at


@njit(cache=True)
def _walk(geo, head, nxt, pts, owner, sarr, tarr, cnt, tp, ts, tt, task, base, r, gap, dead,
          l0, out):
    """Walk the traced vertices of each task in order and hash those that pass.  A task row is
    (line, first, stop, step, prev): vertices ``tp[first:stop:step]`` of line ``line`` (its
    owner), after vertex ``prev`` (-1: the first is the seed); ``base`` adds (s, t) to the
    traced arc length and time.  A vertex within ``r`` of a vertex that counts (see ``_scan``)
    cuts the task where the segment from the previous vertex first comes within ``r``; at the
    seed it rejects the line (``dead``, indexed by line - ``l0``).  ``out`` per
    task: (store index of the last vertex kept or -1, 1 if cut); ``cnt[0]`` counts the store."""
    n = cnt[0]
    for k in range(task.shape[0]):
        line, j, stop, step, pj = task[k, 0], task[k, 1], task[k, 2], task[k, 3], task[k, 4]
        out[k, 0], out[k, 1] = -1, 0
        if dead[line - l0]:
            continue
        while j != stop:
            p = tp[j]
            sv, tv = ts[j] + base[k, 0], tt[j] + base[k, 1]
            if _scan(geo, head, nxt, pts, owner, sarr, p, p, r, line, sv, gap, NO) > 0.0:
                if pj < 0:
                    dead[line - l0] = 1
                    break
                a = tp[pj]
                u = _scan(geo, head, nxt, pts, owner, sarr, a, p, r, line, sv, gap, YES)
                out[k, 1] = 1
                if u <= 0.0:
                    break
                sa, ta = ts[pj] + base[k, 0], tt[pj] + base[k, 1]
                sv, tv = sa + u * (sv - sa), ta + u * (tv - ta)
                p = a + u * (p - a)
                stop = j  # keep the tip, then stop
            # (row by row: numba's array setitem compiles a shape-mismatch message, seconds)
            pts[n, 0], pts[n, 1], pts[n, 2] = p[0], p[1], p[2]
            owner[n], sarr[n], tarr[n] = line, sv, tv
            _insert(geo, head, nxt, pts, n, n + 1)
            out[k, 0] = n
            n += 1
            if j == stop:
                break
            pj = j
            j += step
    cnt[0] = n


class _Store:
    """Every vertex placed so far with its line (owner; -1: dropped), arc length and time,
    hashed on cells of size >= ``size``."""

    def __init__(self, bounds, period, size):
        extent = bounds[:, 1] - bounds[:, 0]
        ncell = np.maximum(1, np.floor(extent / size))
        self.geo = np.array([bounds[:, 0], ncell / np.where(extent > 0, extent, 1.0), ncell,
                             np.asarray(period, np.float64)])
        self.head = np.full(int(np.prod(ncell)), -1, np.int64)
        self.cnt = np.zeros(1, np.int64)
        self.pts, self.nxt = np.empty((0, 3)), np.empty(0, np.int64)
        self.owner, self.s, self.t = np.empty(0, np.int64), np.empty(0), np.empty(0)
        self.reserve(4096)

    @property
    def n(self) -> int:
        return int(self.cnt[0])

    def reserve(self, extra):
        cap, n = self.pts.shape[0], self.n
        if n + extra <= cap:
            return
        cap = max(2 * cap, n + extra)
        for name in ("pts", "nxt", "owner", "s", "t"):
            old = getattr(self, name)
            new = np.empty((cap, *old.shape[1:]), old.dtype)
            new[:n] = old[:n]
            setattr(self, name, new)

    def add(self, pts, owner, s):
        """Hash more vertices (time 0)."""
        n, m = self.n, len(pts)
        self.reserve(m)
        self.pts[n:n + m], self.owner[n:n + m], self.s[n:n + m], self.t[n:n + m] = pts, owner, s, 0
        _insert(self.geo, self.head, self.nxt, self.pts, n, n + m)
        self.cnt[0] = n + m

    @property
    def hashed(self):
        """What ``_scan`` reads: (geo, head, nxt, pts, owner, s)."""
        return self.geo, self.head, self.nxt, self.pts, self.owner, self.s


class _Lattice:
    """The lattice candidates, every LATTICE dsep over the domain, offered in an order drawn from
    the random seed.  The first pick, from an empty store, takes them in that order; a later
    one first queries every point still waiting, in the lattice's own order, drops for good
    those near a line (lines are only added), samples the field at the rest, and picks among
    the usable ones in the drawn order: the same seeds as picking in the drawn order
    throughout, but a million queries in random order had missed the cache at nearly every
    one."""

    def __init__(self, seeder, rng):
        lo, hi = seeder.bounds[:, 0], seeder.bounds[:, 1]
        n = np.maximum(1, np.ceil((hi - lo) / (LATTICE * seeder.dsep))).astype(int)
        h = (hi - lo) / n
        axes = [lo[a] + h[a] * (np.arange(n[a]) + 0.5) for a in range(3)]
        self.pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        self.order = rng.permutation(len(self.pts))  # drawn position -> point
        self.state = np.ones(len(self.pts), np.int8)  # 0 gone, 1 waiting, 2 waiting, usable
        self.seeder, self.first = seeder, 0  # (first picks) drawn positions below are gone

    def pick(self, limit):
        """Seeds from the lattice, as ``EvenSeeder._pick`` (none: the lattice is spent)."""
        sd = self.seeder
        if sd.store.n == 0:
            return self._pick_drawn(limit)
        far = sd._select(self.pts, 0, len(self.pts), False, self.state)[0]
        waiting = self.state[far]
        self.state[:] = 0
        self.state[far] = waiting
        unknown = far[waiting == 1]
        self.state[unknown] = np.where(sd._usable(self.pts[unknown]), 2, 0)
        far = far[self.state[far] == 2]
        rank = np.empty(len(self.pts), np.int64)  # (only where far: the drawn position)
        rank[self.order] = np.arange(len(self.order))
        far = far[np.argsort(rank[far], kind="stable")]
        idx, at = sd._select(self.pts[far], 0, limit, True)
        self.state[far[:at]] = 0
        return self.pts[far[idx]]

    def _pick_drawn(self, limit):
        """The first pick: in the drawn order, sampling the field at the picks only (picked
        again where one is not usable)."""
        sd, rest = self.seeder, self.order[self.first:]
        m = 8 * limit
        while True:
            ids = rest[:m]
            cand = self.pts[ids]
            idx, at = sd._select(cand, 0, limit, True, self.state[ids])
            bad = ~sd._usable(cand[idx])
            if bad.any():
                self.state[ids[idx[bad]]] = 0
            elif len(idx) == limit or m >= len(rest):
                self.state[ids[:at]] = 0
                self.first += at
                return cand[idx]
            else:
                m *= 4


class _Queue:
    """The candidates beside the lines, waiting in order: ``pts[at:end]`` of a buffer grown by
    doubling (appending by concatenation copied the whole queue every generation: gigabytes
    over a dense run)."""

    def __init__(self):
        self.pts, self.at, self.end = np.empty((1024, 3)), 0, 0

    @property
    def waiting(self):
        return self.pts[:self.end]

    def push(self, pts):
        live = self.end - self.at
        if self.end + len(pts) > len(self.pts):
            new = np.empty((max(len(self.pts), 2 * (live + len(pts))), 3))
            new[:live] = self.pts[self.at:self.end]
            self.pts, self.at, self.end = new, 0, live
        self.pts[self.end:self.end + len(pts)] = pts
        self.end += len(pts)


# -- the seeder ---------------------------------------------------------------------------------
def _warn_narrow(field: Field, bounds, dsep: float) -> None:
    """Warn where dsep is not smaller than the domain (``bounds``, (3, 2)) along an axis: lines
    about dsep apart then leave that axis one line wide (a fraction of the diagonal, ``1/30d``,
    does that on a tall thin domain)."""
    extent = bounds[:, 1] - bounds[:, 0]
    a = int(np.argmin(extent))
    if dsep >= extent[a]:
        diag = float(np.linalg.norm(extent))
        warnings.warn(f"{field.source}: evenly spaced seeding: dsep = {dsep:g} is not smaller "
                      f"than the domain along {'xyz'[a]} ({extent[a]:g}): lines about dsep "
                      f"apart leave it one line wide; a smaller dsep fills it (lengths in world "
                      f"units, or a fraction of the diagonal {diag:g} with the d suffix)",
                      stacklevel=3)


class EvenSeeder:
    """Grows evenly spaced lines through ``field``; ``run()`` returns them as Lines.
    ``chunk``: the arc length of a generation's first round (default 4 dsep; later rounds
    double it).  ``stats`` then holds the candidates traced and rejected, and the rounds of
    tracing (``trace_calls``: kernel passes, or trace calls), the vertices they returned and the
    seconds spent in them."""

    def __init__(self, field: Field, dsep: float, dtest: float | None = None,
                 options: TraceOptions | None = None, *, seed: int = 0, backend="numba",
                 max_lines: int | None = None, chunk: float | None = None):
        if not isinstance(field, Field):
            raise TypeError(f"evenly spaced seeding needs a gridded Field, got "
                            f"{type(field).__name__}")
        dtest = 0.5 * dsep if dtest is None else dtest
        if not (np.isfinite(dsep) and dsep > 0):
            raise OptionsError(f"evenly spaced seeding: dsep must be a positive length, got {dsep}")
        if not (np.isfinite(dtest) and 0 < dtest < dsep):
            raise OptionsError(f"evenly spaced seeding: dtest must lie in (0, dsep = {dsep:g}), "
                               f"got {dtest}")
        opts = options or TraceOptions()
        if opts.count is not None:
            raise OptionsError("evenly spaced seeding: option count (resample every line to n "
                               "vertices) cannot apply to lines that are cut; use spacing")
        if opts.spacing is None and opts.entry.resamples:
            opts = opts.replace(spacing=0.5 * dtest)  # vertices dense enough for the dtest bound
        self.field, self.dsep, self.dtest, self.opts = field, float(dsep), float(dtest), opts
        self.seed, self.backend, self.max_lines = int(seed), backend, max_lines
        g = field.grid
        self.bounds, self.period = g.bounds, np.array(g.period, np.float64)
        _warn_narrow(field, self.bounds, self.dsep)
        _attributes.check(field, opts.attributes)
        self.stag = stagnation_speed(field, opts)
        self.signs = {"forward": (1,), "backward": (-1,), "both": (-1, 1)}[opts.direction]
        self.store = _Store(self.bounds, self.period, self.dsep)
        self.lines: dict[str, list] = {}  # per generation, arrays of line data
        self.stats = {"traced": 0, "rejected": 0, "trace_calls": 0, "trace_vertices": 0,
                      "trace_seconds": 0.0}
        chunk = chunk or CHUNK * self.dsep
        self.source = Resumed(field, opts, backend, self.signs, chunk, self.store, self.stats)

    # -- candidates -----------------------------------------------------------------------------
    def _usable(self, pts):
        """Which points lie in valid cells where the flow is faster than the stagnation
        speed."""
        v, status = self.field.sample(pts)
        return (status == 0) & (np.einsum("ij,ij->i", v, v) > self.stag ** 2)

    def _fresh(self, cand):
        """The candidates, in order, that could still become seeds: at least dsep from every
        line placed so far (lines are only added, so the others never could) and usable (the
        field is sampled only at these few)."""
        cand = cand[self._select(cand, 0, len(cand), False)[0]]
        return cand[self._usable(cand)]

    def _beside(self, n0):
        """Candidates dsep beside the lines kept from store index ``n0`` on, line after line,
        about every dsep along each, in six directions around its tangent (central differences)
        in a frame fixed by the axis the tangent is least aligned with."""
        st = self.store
        idx = n0 + np.flatnonzero(st.owner[n0:st.n] >= 0)
        if not len(idx):
            return np.zeros((0, 3))
        idx = idx[np.lexsort((st.s[idx], st.owner[idx]))]
        own = st.owner[idx]
        start = np.flatnonzero(np.r_[True, own[1:] != own[:-1]])
        size = np.diff(np.r_[start, len(own)])
        h = self.opts.spacing  # None for the stiff methods: vertices at their steps
        if h is None:
            seg = np.linalg.norm(np.diff(st.pts[idx], axis=0), axis=1)[own[1:] == own[:-1]]
            h = float(seg.mean()) if len(seg) else self.dsep
        every = max(1, round(self.dsep / h)) if h > 0 else 1
        # every `every`-th vertex of each line of two vertices or more, from its first (indices
        # into idx, made per line: arrays as long as the vertices cost more than the rest)
        start, size = start[size > 1], size[size > 1]
        count = (size + every - 1) // every
        line = np.repeat(np.arange(len(start)), count)
        at = start[line] + every * (np.arange(len(line)) - np.repeat(np.cumsum(count) - count,
                                                                      count))
        first, last = start[line], start[line] + size[line] - 1
        t = st.pts[idx[np.minimum(at + 1, last)]] - st.pts[idx[np.maximum(at - 1, first)]]
        norm = np.linalg.norm(t, axis=1)
        at, t = at[norm > 0], t[norm > 0] / norm[norm > 0, None]
        ref = np.zeros_like(t)
        ref[np.arange(len(t)), np.argmin(np.abs(t), axis=1)] = 1.0
        n1 = np.cross(t, ref)
        n1 /= np.linalg.norm(n1, axis=1)[:, None]
        n2 = np.cross(t, n1)
        ang = 2.0 * np.pi * np.arange(DIRECTIONS) / DIRECTIONS
        ring = np.cos(ang)[None, :, None] * n1[:, None] + np.sin(ang)[None, :, None] * n2[:, None]
        return self._fresh((st.pts[idx[at]][:, None] + self.dsep * ring).reshape(-1, 3))

    def _select(self, cand, at, limit, mutual, ok=None):
        """``_pick``: the indices of the candidates picked from ``cand[at:]`` (where ``ok``),
        the next at."""
        k = max(0, min(limit, len(cand) - at))
        picked, rows = np.empty(k, np.int64), k if mutual else 0
        n, at = _pick(*self.store.hashed, cand, ALL if ok is None else ok, at, limit, self.dsep,
                      mutual, picked, np.empty((rows, 3)), self._phead, np.empty(rows, np.int64),
                      np.zeros(rows, np.int64), np.zeros(rows))
        return picked[:n], at

    def _pick(self, cand, at, limit):
        """Seeds from ``cand[at:]`` (fresh candidates), mutually dsep apart; the next at."""
        idx, at = self._select(cand, at, limit, True)
        return cand[idx], at

    # -- growing --------------------------------------------------------------------------------
    def _grow(self, seeds, l0):
        """Grow the lines ``l0, l0 + 1, ...`` from ``seeds`` round by round into the store;
        returns their line data (``dead``: rejected) and the store index they start at."""
        st, src = self.store, self.source
        nl, ns = len(seeds), len(self.signs)
        nh = nl * ns  # half j of line l is h = l * ns + j, direction signs[j]
        line = l0 + np.arange(nh) // ns
        dead = np.zeros(nl, np.int8)
        reason = np.zeros(nh, np.int8)
        alive = np.ones(nh, bool)
        last = np.full(nh, -1, np.int64)  # store index of each half's last vertex
        n0, gap = st.n, SELF_GAP * self.dsep
        src.start(seeds)
        while True:
            todo = np.flatnonzero(alive & (dead[line - l0] == 0))
            if not len(todo):
                break
            r = src.round(todo, last)
            hs = r.task[:, 0]
            task = r.task.copy()
            task[:, 0] = line[hs]
            st.reserve(len(r.pts) + len(task))
            out = np.empty((len(task), 2), np.int64)
            _walk(*st.hashed, st.t, st.cnt, r.pts, r.s, r.t, task, r.base, self.dtest, gap,
                  dead, l0, out)
            reason[hs] = r.reason
            reason[hs[out[:, 1] == 1]] = TOO_CLOSE
            moved = out[:, 0] >= 0
            last[hs[moved]] = out[moved, 0]
            alive[hs] = (out[:, 1] == 0) & moved & r.more
        # a line with fewer than two vertices is no line: drop what it left in the store
        own = st.owner[n0:st.n]
        short = np.bincount(own - l0, minlength=nl) < 2
        own[short[own - l0]] = -1
        dead |= short
        out = {"dead": dead.astype(bool), "seed": seeds,
               "reason": reason[ns - 1::ns], **src.line_data()}
        if ns == 2:
            out["reason_backward"] = reason[0::2]
        return out, n0

    def run(self) -> Lines:
        lattice = _Lattice(self, np.random.default_rng(self.seed))
        self._phead = np.full(self.store.head.shape, -1, np.int64)
        queue, nlines, l0 = _Queue(), 0, 0
        with self._progress() as bar:
            while self.max_lines is None or nlines < self.max_lines:
                limit = min(MAX_BATCH, max(MIN_BATCH, nlines))
                if self.max_lines is not None:
                    limit = min(limit, self.max_lines - nlines)
                seeds, queue.at = self._pick(queue.waiting, queue.at, limit)
                if not len(seeds):
                    seeds = lattice.pick(limit)
                if not len(seeds):
                    break
                self.stats["traced"] += len(seeds)
                data, n0 = self._grow(seeds, l0)
                l0 += len(seeds)
                for k, v in data.items():
                    self.lines.setdefault(k, []).append(v)
                self.stats["rejected"] += int(data["dead"].sum())
                placed = int((~data["dead"]).sum())
                nlines += placed
                bar.update(placed)
                bar.set_postfix_str(f"{self.store.n:,} vertices", refresh=False)
                queue.push(self._beside(n0))
        return self._lines()

    def _progress(self):
        """A running count of the lines placed, on stderr: with option progress None (the
        default) where stderr is a terminal and the run takes more than PROGRESS_DELAY seconds,
        with True at once, with False never (how many lines there will be is not known)."""
        from tqdm import tqdm

        show = self.opts.progress
        return tqdm(unit="line", desc="evenly spaced", smoothing=0.1,
                    disable=not (sys.stderr.isatty() if show is None else show),
                    delay=PROGRESS_DELAY if show is None else 0.0)

    # -- output ---------------------------------------------------------------------------------
    def _lines(self) -> Lines:
        opts, st = self.opts, self.store
        own = st.owner[:st.n]
        keep = np.flatnonzero(own >= 0)
        sign = -1.0 if opts.direction == "backward" else 1.0  # a line starts at its seed
        keep = keep[np.lexsort((sign * st.s[keep], own[keep]))]
        ids, counts = np.unique(own[keep], return_counts=True)
        n = len(ids)
        offsets = np.zeros(n + 1, np.int64)
        np.cumsum(counts, out=offsets[1:])
        both = opts.direction == "both"
        # (the counts and flags the method's lines carry: task_columns')
        dtypes = {"reason": np.int8, **({"reason_backward": np.int8} if both else {}),
                  **{k: (np.int8 if k in self.source.flags else np.int32)
                     for k in self.source.columns if k != "reason"}}
        cat = {k: np.concatenate(self.lines[k]) if self.lines else np.zeros(0)
               for k in [*dtypes, "seed"]}
        line_data = {"seed_id": np.arange(n, dtype=np.int64)}
        line_data.update({k: cat[k][ids].astype(dt) for k, dt in dtypes.items()})
        seeds = cat["seed"][ids].reshape(-1, 3)
        line_data["seed"] = seeds
        pts, t, s = st.pts[keep], st.t[keep], st.s[keep]
        seed_of = np.repeat(seeds, counts, axis=0)
        point_data = _attributes.compute(self.field, opts.attributes, pts, t, s, seed_of)
        attrs = line_attrs(self.field, opts, "; ".join(sorted(self.source.paths - {""})))
        attrs.update(seeding="even", dsep=self.dsep, dtest=self.dtest, seeding_seed=self.seed,
                     candidates_traced=self.stats["traced"],
                     candidates_rejected=self.stats["rejected"])
        return Lines(pts, offsets, point_data, line_data, attrs)


def evenly_spaced(field: Field, dsep: float, dtest: float | None = None,
                  options: TraceOptions | None = None, *, seed: int = 0, backend="numba",
                  max_lines: int | None = None, **kw) -> Lines:
    """Evenly spaced streamlines of ``field``: lines about ``dsep`` apart, none closer than
    ``dtest`` (default dsep / 2) to another; ``options`` / ``kw`` as for ``flowkit.trace``
    (spacing defaults to dtest / 2, except for the stiff methods, which place vertices at their
    steps; count is refused).  line_data ``seed`` holds each line's
    seed, ``reason`` (and ``reason_backward``) say ``too_close`` where a half was cut."""
    opts = resolve_options(options, kw)
    return EvenSeeder(field, dsep, dtest, opts, seed=seed, backend=backend,
                      max_lines=max_lines).run()
