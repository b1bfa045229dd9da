"""Evenly spaced streamlines in 3D, after Jobard and Lefer (1997), grown on the warm tracer.

Two distances: ``dsep``, the spacing wanted between lines, and ``dtest`` < ``dsep``, the
closest a line may come to another.  A line is grown from a candidate seed at least ``dsep``
from every accepted line; walking out from its seed, it is cut at its first vertex closer than
``dtest`` to an accepted line, or to itself more than ``2 dsep`` of arc length away (a closed or
ergodic orbit), at the exact point of the segment where that distance reaches ``dtest``; that
half ends with reason ``too_close``.  Candidates come, first, from ``dsep`` beside every
accepted line (six directions around the tangent, about every ``dsep`` of arc length, oldest
line first), then, when none is left, from a lattice of spacing ``dsep / 2`` over the domain in
an order drawn from the random seed; this second source is what guarantees coverage: every
valid point of the field ends within about ``1.5 dsep`` of a line unless the flow is too slow to
carry one (see docs/seeding.md for the bounds and the tests that check them).

Distances are found with a spatial hash (cells of size ``dsep``, minimum image on periodic
axes): a vertex is compared only with the vertices in its 27 neighbouring cells, so the cost
grows with the number of vertices, not its square.  Candidates are traced in batches (one
``flowkit.trace`` call per direction for a batch, mutually ``dsep`` apart), each line of a
batch is then accepted in order against every line accepted before it, batch-mates included,
exactly as if they had been traced one by one.  Long lines grow in chunks of arc length so a
line that is cut early is not traced to its end first.  Everything is deterministic for a
given random seed.
"""

from __future__ import annotations

import math
import time

import numpy as np
from numba import njit

from ..fields import Field
from ..fields.interp import locate, trilinear_vector
from ..integrate import attributes as _attributes
from ..integrate import trace as _trace
from ..integrate.options import OptionsError, TraceOptions
from ..integrate.reasons import Reason
from ..lines import Lines

DIRECTIONS = 6  # candidate seeds around the tangent of a line
MAX_BATCH = 1024
MIN_BATCH = 64
SELF_GAP = 2.0  # own vertices nearer than this many dsep of arc length never cut a line
LATTICE = 0.5  # lattice candidates every LATTICE * dsep
TOO_CLOSE = int(Reason.TOO_CLOSE)
MAX_LENGTH = int(Reason.MAX_LENGTH)


# -- the spatial hash ---------------------------------------------------------------------------
@njit(cache=True)
def _cell_of(x, lo, inv, ncell, period, a):
    d = x - lo[a]
    if period[a] > 0.0:
        d = d % period[a]
    i = math.floor(d * inv[a])
    return min(max(i, 0), ncell[a] - 1)


@njit(cache=True)
def _reach(p, lo, inv, ncell, period, r, a):
    """The cell of p along axis a and the neighbours (-1, 0 or 1 each way) that a ball of
    radius r <= the cell width reaches: only the sides it crosses (8 cells, not 27, for r at
    most half a cell)."""
    d = p[a] - lo[a]
    if period[a] > 0.0:
        d = d % period[a]
    f = d * inv[a]
    c = min(max(math.floor(f), 0), ncell[a] - 1)
    below = -1 if (f - r * inv[a]) < c else 0
    above = 1 if (f + r * inv[a]) >= c + 1 else 0
    return c, below, above


@njit(cache=True)
def _cells_near(p, r, lo, inv, ncell, period, out):
    """The flat indices of the cells a ball of radius r around p reaches (into ``out``, 27
    long); returns how many."""
    ci, i0, i1 = _reach(p, lo, inv, ncell, period, r, 0)
    cj, j0, j1 = _reach(p, lo, inv, ncell, period, r, 1)
    ck, k0, k1 = _reach(p, lo, inv, ncell, period, r, 2)
    m = 0
    for di in range(i0, i1 + 1):
        i = _step(ci, di, ncell[0], period[0])
        for dj in range(j0, j1 + 1):
            j = _step(cj, dj, ncell[1], period[1])
            for dk in range(k0, k1 + 1):
                k = _step(ck, dk, ncell[2], period[2])
                if i >= 0 and j >= 0 and k >= 0:
                    out[m] = (i * ncell[1] + j) * ncell[2] + k
                    m += 1
    return m


@njit(cache=True)
def _step(c, d, n, period):
    """Cell c + d along an axis of n cells: wrapped when periodic, -1 past a bounded end."""
    c += d
    if period > 0.0:
        return c % n
    return c if 0 <= c < n else -1


@njit(cache=True)
def _insert(head, nxt, pts, n0, n1, lo, inv, ncell, period):
    for v in range(n0, n1):
        i = _cell_of(pts[v, 0], lo, inv, ncell, period, 0)
        j = _cell_of(pts[v, 1], lo, inv, ncell, period, 1)
        k = _cell_of(pts[v, 2], lo, inv, ncell, period, 2)
        c = (i * ncell[1] + j) * ncell[2] + k
        nxt[v] = head[c]
        head[c] = v


@njit(cache=True)
def _delta(p, q, period, a):
    d = p[a] - q[a]
    if period[a] > 0.0:
        d -= period[a] * np.round(d / period[a])
    return d


@njit(cache=True)
def _entry(a, p, q, r2, period):
    """The first u in [0, 1] where a + u (p - a) is within sqrt(r2) of q (-1: never)."""
    e0, e1, e2 = _delta(a, q, period, 0), _delta(a, q, period, 1), _delta(a, q, period, 2)
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


@njit(cache=True)
def _near(head, nxt, pts, owner, sarr, lo, inv, ncell, period, p, r, line, s, gap, a, out):
    """Vertices within ``r`` of ``p`` that count: any owner when ``line`` < 0, else only the
    vertices of ``line`` more than ``gap`` of arc length from ``s``.  Returns (whether one is
    within r of ``p``, u): ``out`` 0 stops at the first; 2 also finds u, the smallest in
    [0, 1] where the segment a + u (p - a) from the previous point ``a`` comes within r of one
    of them (-1 if it never does)."""
    cells = np.empty(27, np.int64)
    r2 = r * r
    best = -1.0
    hit = False
    for c in range(_cells_near(p, r, lo, inv, ncell, period, cells)):
        v = head[cells[c]]
        while v >= 0:
            q = pts[v]
            if line < 0 or (owner[v] == line and abs(sarr[v] - s) > gap):
                d2 = 0.0
                for ax in range(3):
                    d = _delta(p, q, period, ax)
                    d2 += d * d
                if d2 < r2:
                    if not out:
                        return True, 0.0
                    hit = True
                elif out == 2:  # the segment may still pass within r of q
                    u = _entry(a, p, q, r2, period)
                    if u >= 0.0 and (best < 0.0 or u < best):
                        best = u
                if d2 < r2 and out == 2:
                    u = _entry(a, p, q, r2, period)
                    if u < 0.0:  # rounding: the root lies at the end
                        u = 1.0
                    if best < 0.0 or u < best:
                        best = u
            v = nxt[v]
    return hit, best


@njit(cache=True)
def _usable(hp, lo, inv, ncell, period, grid, vec, stag, cand, r):
    """True for each candidate in a valid cell, faster than ``stag``, with no hashed vertex
    within ``r`` (serial: called often on few points, where a thread launch costs more)."""
    head, nxt, pts, owner, sarr = hp
    gx, gy, gz, gper, ginv = grid
    out = np.zeros(cand.shape[0], np.bool_)
    for c in range(cand.shape[0]):
        i, j, k, tx, ty, tz, ok = locate(gx, gy, gz, gper, ginv, cand[c, 0], cand[c, 1],
                                         cand[c, 2])
        if not ok:
            continue
        u, v, w, bad = trilinear_vector(vec, i, j, k, tx, ty, tz)
        if bad or not u * u + v * v + w * w > stag * stag:
            continue
        out[c] = not _near(head, nxt, pts, owner, sarr, lo, inv, ncell, period, cand[c], r, -1,
                           0.0, 0.0, cand[c], 0)[0]
    return out


@njit(cache=True)
def _pick(cand, picked, n, limit, r, period):
    """Append to ``picked[:n]`` the candidates at least ``r`` from every point already there,
    until ``limit``; returns the new count."""
    for c in range(cand.shape[0]):
        if n >= limit:
            break
        far = True
        for q in range(n):
            d2 = 0.0
            for a in range(3):
                d = _delta(cand[c], picked[q], period, a)
                d2 += d * d
            if d2 < r * r:
                far = False
                break
        if far:
            picked[n] = cand[c]
            n += 1
    return n


@njit(cache=True)
def _walk(hp, sp, S, lo, inv, ncell, period, pts, s, first, r, line, gap, add):
    """Walk a half-line's vertices from ``first``; returns (index of the first vertex too close,
    u on the segment before it) or (-1, 0).  ``hp`` holds the accepted lines, ``sp`` (when
    ``line`` >= 0) this batch's own vertices, which every vertex that passes joins (``add``;
    ``S[0]`` counts them)."""
    headA, nxtA, ptsA, ownA, sA = hp
    for v in range(first, pts.shape[0]):
        prev = pts[v - 1] if v > 0 else pts[v]
        hit = _near(headA, nxtA, ptsA, ownA, sA, lo, inv, ncell, period, pts[v], r, -1, 0.0,
                    0.0, prev, 0)[0]
        if line >= 0 and not hit:
            headS, nxtS, ptsS, ownS, sS = sp
            hit = _near(headS, nxtS, ptsS, ownS, sS, lo, inv, ncell, period, pts[v], r, line,
                        s[v], gap, prev, 0)[0]
        if hit:  # cut where the segment first comes within r of either set
            if v == 0:
                return v, 0.0
            u = _near(headA, nxtA, ptsA, ownA, sA, lo, inv, ncell, period, pts[v], r, -1, 0.0,
                      0.0, prev, 2)[1]
            if line >= 0:
                headS, nxtS, ptsS, ownS, sS = sp
                w = _near(headS, nxtS, ptsS, ownS, sS, lo, inv, ncell, period, pts[v], r, line,
                          s[v], gap, prev, 2)[1]
                if w >= 0.0 and (u < 0.0 or w < u):
                    u = w
            return v, max(u, 0.0)
        if add and line >= 0:
            headS, nxtS, ptsS, ownS, sS = sp
            n = S[0]
            ptsS[n] = pts[v]
            ownS[n] = line
            sS[n] = s[v]
            _insert(headS, nxtS, ptsS, n, n + 1, lo, inv, ncell, period)
            S[0] = n + 1
    return -1, 0.0


@njit(cache=True)
def _beside(p, every, dsep, ndir):
    """Points ``dsep`` from every ``every``-th vertex of polyline ``p``, in ``ndir`` directions
    around its tangent (central differences), in a frame fixed by the axis the tangent is least
    aligned with."""
    n = p.shape[0]
    out = np.empty((((n + every - 1) // every) * ndir if n > 1 else 0, 3))
    m = 0
    for v in range(0, n if n > 1 else 0, every):
        a, b = max(v - 1, 0), min(v + 1, n - 1)
        t = p[b] - p[a]
        norm = math.sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2])
        if norm == 0.0:
            continue
        t = t / norm
        ref = np.zeros(3)
        ref[np.argmin(np.abs(t))] = 1.0
        n1 = np.cross(t, ref)
        n1 /= math.sqrt(n1[0] * n1[0] + n1[1] * n1[1] + n1[2] * n1[2])
        n2 = np.cross(t, n1)
        for k in range(ndir):
            ang = 2.0 * math.pi * k / ndir
            out[m] = p[v] + dsep * (math.cos(ang) * n1 + math.sin(ang) * n2)
            m += 1
    return out[:m]


class _Hash:
    """Vertices with their line and arc length, hashed on cells of size >= ``size``."""

    def __init__(self, bounds, period, size):
        extent = bounds[:, 1] - bounds[:, 0]
        self.lo = bounds[:, 0].copy()
        self.period = np.asarray(period, np.float64)
        self.ncell = np.maximum(1, np.floor(extent / size)).astype(np.int64)
        self.inv = self.ncell / np.where(extent > 0, extent, 1.0)
        self.head = np.full(int(np.prod(self.ncell)), -1, np.int64)
        self.n = 0
        self._alloc(4096)

    def _alloc(self, cap):
        old = getattr(self, "pts", None)
        pts, nxt = np.empty((cap, 3)), np.empty(cap, np.int64)
        owner, s = np.empty(cap, np.int64), np.empty(cap)
        if old is not None:
            pts[:self.n], nxt[:self.n] = self.pts[:self.n], self.nxt[:self.n]
            owner[:self.n], s[:self.n] = self.owner[:self.n], self.s[:self.n]
        self.pts, self.nxt, self.owner, self.s = pts, nxt, owner, s

    def reserve(self, extra):
        if self.n + extra > self.pts.shape[0]:
            self._alloc(max(2 * self.pts.shape[0], self.n + extra))

    def add(self, pts, owner, s):
        m = len(pts)
        self.reserve(m)
        self.pts[self.n:self.n + m], self.owner[self.n:self.n + m] = pts, owner
        self.s[self.n:self.n + m] = s
        _insert(self.head, self.nxt, self.pts, self.n, self.n + m, self.lo, self.inv,
                self.ncell, self.period)
        self.n += m

    def clear(self):
        self.head[:] = -1
        self.n = 0

    @property
    def arrays(self):
        return self.head, self.nxt, self.pts, self.owner, self.s

    @property
    def grid(self):
        return self.lo, self.inv, self.ncell, self.period


# -- the seeder ---------------------------------------------------------------------------------
class _Half:
    """One direction of a line being grown: vertices (from the seed outward), t, s, counts."""

    def __init__(self, sign):
        self.sign = sign
        self.pts, self.t, self.s = np.zeros((0, 3)), np.zeros(0), np.zeros(0)
        self.reason, self.nacc, self.nrej, self.flags = 0, 0, 0, {}
        self.alive = True

    def extend(self, pts, t, s):
        if len(self.pts):  # a continuation starts on the last vertex
            pts, t, s = pts[1:], t[1:] + self.t[-1], s[1:] + self.s[-1]
        self.pts = np.concatenate([self.pts, pts])
        self.t, self.s = np.concatenate([self.t, t]), np.concatenate([self.s, s])

    def cut(self, v, u):
        """Keep vertices [0, v) and the point u along the segment to v; too_close."""
        keep = slice(0, v)
        if v > 0 and u > 0.0:
            a, b = v - 1, v
            tip = self.pts[a] + u * (self.pts[b] - self.pts[a])
            tt = self.t[a] + u * (self.t[b] - self.t[a])
            ss = self.s[a] + u * (self.s[b] - self.s[a])
            self.pts = np.concatenate([self.pts[keep], tip[None]])
            self.t, self.s = np.append(self.t[keep], tt), np.append(self.s[keep], ss)
        else:
            self.pts, self.t, self.s = self.pts[keep], self.t[keep], self.s[keep]
        self.reason, self.alive = TOO_CLOSE, False


class EvenSeeder:
    """Grows evenly spaced lines through ``field``; ``run()`` returns them as Lines."""

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
        # line_data column of the lines a StiffSwitch traced again (ros34pw2), if any
        retrace = opts.entry.retrace
        self.retraced = None if retrace is None else retrace.name
        self.seed, self.backend, self.max_lines = int(seed), backend, max_lines
        g = field.grid
        self.bounds, self.period = g.bounds, np.array(g.period, np.float64)
        diag = float(np.linalg.norm(self.bounds[:, 1] - self.bounds[:, 0]))
        _attributes.check(field, opts.attributes)
        self.chunk = chunk or max(diag, 8 * self.dsep)
        if math.isfinite(opts.max_time):  # time and length chunks cannot both add up: one go
            self.chunk = math.inf
        elif math.isfinite(opts.max_length):  # equal chunks that add up to max_length exactly
            self.chunk = opts.max_length / max(1, math.ceil(opts.max_length / self.chunk))
        vtyp = _trace._typical_speed(field)
        self.stag = opts.stagnation if opts.stagnation is not None else opts.stagnation_rel * vtyp
        self.signs = {"forward": (1,), "backward": (-1,), "both": (-1, 1)}[opts.direction]
        self.accepted = _Hash(self.bounds, self.period, self.dsep)
        self.own = _Hash(self.bounds, self.period, self.dsep)
        self.lines: list[list[_Half]] = []
        self.stats = {"traced": 0, "rejected": 0, "trace_seconds": 0.0}

    # -- candidates -----------------------------------------------------------------------------
    def _usable(self, cand):
        """Candidates inside valid cells, fast enough to move, dsep from accepted lines."""
        cand = np.ascontiguousarray(cand, np.float64)
        ok = _usable(self.accepted.arrays, *self.accepted.grid, self.field.grid.kernel_args(),
                     self.field.vector, self.stag, cand, self.dsep)
        return cand[ok]

    def _lattice(self, rng):
        lo, hi = self.bounds[:, 0], self.bounds[:, 1]
        n = np.maximum(1, np.ceil((hi - lo) / (LATTICE * self.dsep))).astype(int)
        h = (hi - lo) / n
        axes = [lo[a] + h[a] * (np.arange(n[a]) + 0.5) for a in range(3)]
        pts = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
        return pts[rng.permutation(len(pts))]

    def _beside(self, half_pts):
        """Candidates dsep beside a line, about every dsep along it, in six directions."""
        h = self.opts.spacing  # None for the stiff methods: vertices at their steps
        if h is None:
            seg = np.linalg.norm(np.diff(half_pts, axis=0), axis=1)
            h = float(seg.mean()) if len(seg) else self.dsep
        every = max(1, round(self.dsep / h)) if h > 0 else 1
        return _beside(np.ascontiguousarray(half_pts), every, self.dsep, DIRECTIONS)

    # -- growing --------------------------------------------------------------------------------
    def _trace(self, starts, sign, length):
        t0 = time.perf_counter()
        direction = {1: "forward", -1: "backward", 0: "both"}[sign]
        o = self.opts.replace(direction=direction, max_length=length,
                              attributes=("time", "arc_length"), progress=False)
        lines = _trace.trace(self.field, starts, o, backend=self.backend)
        self.stats["trace_seconds"] += time.perf_counter() - t0
        return lines

    def _grow(self, seeds):
        """Halves of the lines from ``seeds``, grown chunk by chunk and cut against the accepted
        lines and themselves."""
        self.own.clear()
        batch = [[_Half(sg) for sg in self.signs] for _ in seeds]
        gap = SELF_GAP * self.dsep
        grown = 0.0
        while True:
            todo = [(i, h) for i, hs in enumerate(batch) for h in hs if h.alive]
            if not todo:
                return batch
            length = min(self.chunk, self.opts.max_length - grown)
            grown += length
            # a chunk's max_length end continues while the whole line has length left
            total = self.opts.max_length
            more = math.isinf(total) or total - grown > 1e-12 * total
            fresh = all(not len(h.pts) for _, h in todo)
            if fresh and len(self.signs) == 2:  # one call for both halves of every line
                traced = self._trace(seeds, 0, length)
                self._take(traced, [(i, batch[i]) for i in range(len(seeds))], more, gap)
                continue
            for sign in self.signs:
                part = [(i, h) for i, h in todo if h.sign == sign]
                if part:
                    starts = np.array([h.pts[-1] if len(h.pts) else seeds[i] for i, h in part])
                    traced = self._trace(starts, sign, length)
                    self._take(traced, [(i, [h]) for i, h in part], more, gap)

    def _take(self, traced, tasks, more, gap):
        """Append each traced line to its half (or split it between both halves, seed first
        in each), then walk the new vertices: cut where too close, else end or continue."""
        for k, (i, halves) in enumerate(tasks):
            p, t = traced.line_points(k), traced.line_attribute("time", k)
            s = traced.line_attribute("arc_length", k)
            ld = {key: int(v[k]) for key, v in traced.line_data.items()}
            if len(halves) == 2:  # direction both: backward vertices (s < 0), seed, forward
                b = int(np.count_nonzero(s < 0))
                parts = [(p[:b + 1][::-1], t[:b + 1][::-1], s[:b + 1][::-1],
                          ld["reason_backward"]), (p[b:], t[b:], s[b:], ld["reason"])]
            else:
                parts = [(p, t, s, ld["reason"])]
            for j, (h, (pp, tt, ss, reason)) in enumerate(zip(halves, parts)):
                first = len(h.pts)
                h.extend(pp, tt, ss)
                h.reason = reason
                if j == len(halves) - 1:  # step counts of the call go to the last half
                    h.nacc += ld["n_accepted"]
                    h.nrej += ld["n_rejected"]
                for key in ("stiff", self.retraced):
                    if key in ld:
                        h.flags[key] = max(h.flags.get(key, 0), ld[key])
                self.own.reserve(len(h.pts))
                count = np.array([self.own.n], np.int64)
                v, u = _walk(self.accepted.arrays, self.own.arrays, count, *self.accepted.grid,
                             h.pts, h.s, first, self.dtest, i, gap, True)
                self.own.n = int(count[0])
                if v >= 0:
                    h.cut(v, u)
                elif not (h.reason == MAX_LENGTH and len(h.pts) > 1 and more
                          and h.nacc + h.nrej < self.opts.max_steps):
                    h.alive = False  # ended for its own reason (the kernel's)

    def _accept(self, halves) -> bool:
        """Cut the line against every accepted line; keep it (and hash it) if anything is left."""
        for h in halves:
            v, u = _walk(self.accepted.arrays, self.own.arrays, np.zeros(1, np.int64),
                         *self.accepted.grid, h.pts, h.s, 0, self.dtest, -1, 0.0, False)
            if v == 0:
                return False  # the seed itself is too close
            if v > 0:
                h.cut(v, u)
        if sum(len(h.pts) for h in halves) - (len(halves) - 1) < 2:
            return False
        line = len(self.lines)
        for h in halves:
            self.accepted.add(h.pts, line, h.s)
        self.lines.append(halves)
        return True

    def run(self) -> Lines:
        rng = np.random.default_rng(self.seed)
        lattice = self._lattice(rng)
        queue, at, lat = [], 0, 0  # candidates beside accepted lines, oldest line first
        while self.max_lines is None or len(self.lines) < self.max_lines:
            limit = min(MAX_BATCH, max(MIN_BATCH, len(self.lines)))
            if self.max_lines is not None:
                limit = min(limit, self.max_lines - len(self.lines))
            picked, n = np.empty((limit, 3)), 0
            while n < limit and at < len(queue):
                n = _pick(self._usable(queue[at]), picked, n, limit, self.dsep, self.period)
                queue[at] = None
                at += 1
            while not n and lat < len(lattice):
                block = lattice[lat:lat + 4 * limit]
                lat += len(block)
                n = _pick(self._usable(block), picked, n, limit, self.dsep, self.period)
            if not n:
                break
            seeds = picked[:n]
            self.stats["traced"] += len(seeds)
            for halves in self._grow(seeds):
                if self._accept(halves):
                    queue += [self._beside(h.pts) for h in halves]
                else:
                    self.stats["rejected"] += 1
        return self._lines()

    # -- output ---------------------------------------------------------------------------------
    def _lines(self) -> Lines:
        opts, both = self.opts, self.opts.direction == "both"
        pts, t, s, counts, seeds = [], [], [], [], []
        ld = {"reason": [], "n_accepted": [], "n_rejected": [], "stiff": []}
        if both:
            ld["reason_backward"] = []
        if self.retraced is not None:
            ld[self.retraced] = []
        for halves in self.lines:
            if both:
                b, f = halves
                parts = [(b.pts[::-1][:-1], b.t[::-1][:-1], b.s[::-1][:-1]), (f.pts, f.t, f.s)]
                ld["reason"].append(f.reason)
                ld["reason_backward"].append(b.reason)
            else:
                (h,) = halves
                parts = [(h.pts, h.t, h.s)]
                ld["reason"].append(h.reason)
            for p, tt, ss in parts:
                pts.append(p)
                t.append(tt)
                s.append(ss)
            counts.append(sum(len(p) for p, _, _ in parts))
            seeds.append(halves[-1].pts[0])
            ld["n_accepted"].append(sum(h.nacc for h in halves))
            ld["n_rejected"].append(sum(h.nrej for h in halves))
            ld["stiff"].append(max(h.flags.get("stiff", 0) for h in halves))
            if self.retraced is not None:
                ld[self.retraced].append(max(h.flags.get(self.retraced, 0) for h in halves))
        n = len(self.lines)
        pts = np.concatenate(pts) if pts else np.zeros((0, 3))
        t = np.concatenate(t) if t else np.zeros(0)
        s = np.concatenate(s) if s else np.zeros(0)
        offsets = np.zeros(n + 1, np.int64)
        np.cumsum(counts, out=offsets[1:])
        dtypes = {"reason": np.int8, "reason_backward": np.int8, "stiff": np.int8,
                  self.retraced: np.int8, "n_accepted": np.int32, "n_rejected": np.int32}
        line_data = {"seed_id": np.arange(n, dtype=np.int64)}
        line_data.update({k: np.array(v, dtypes[k]) for k, v in ld.items()})
        seeds = np.array(seeds).reshape(-1, 3)
        line_data["seed"] = seeds
        seed_of = np.repeat(seeds, np.diff(offsets), axis=0)
        point_data = _attributes.compute(self.field, opts.attributes, pts, t, s, seed_of)
        attrs = _trace._attrs(self.field, opts)
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
    opts = _trace._options(options, kw)
    return EvenSeeder(field, dsep, dtest, opts, seed=seed, backend=backend,
                      max_lines=max_lines).run()
