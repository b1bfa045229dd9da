"""Shared pieces of the benchmarks: the ABC grid, seeds, the tight reference, errors at a fixed
arc length, timing, machine description and table output.

The error measure: every tool traces the same seeds through the same trilinear
interpolant of ABC flow; its point at arc length ``length`` is compared with the point a tight
DOP853 (scipy, rtol = atol = 1e-12) reaches on that same interpolant, integrated in arc length
(dx/ds = v/|v|).  So the error is integration error only; interpolation error (grid against the
analytic field) does not enter.
"""

from __future__ import annotations

import csv
import hashlib
import json
import multiprocessing as mp
import os
import platform
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy
from numba import njit
from scipy.integrate import solve_ivp

# timed runs are the lanes' (compiled in the first call), never the scalar kernel's while the
# lock-step compiles in the background
os.environ.setdefault("FLOWKIT_LOCKSTEP_WAIT", "1")

from flowkit.fields import Field, interp
from flowkit.fields.analytic import ABCFlow
from flowkit.fields.grid import Grid
from flowkit.io.atomic import atomic_path

RESULTS = Path(__file__).resolve().parent / "results"
TWO_PI = 2.0 * np.pi


# -- the problem ------------------------------------------------------------------------
@dataclass(frozen=True)
class Problem:
    """ABC flow (A=sqrt3, B=sqrt2, C=1) on [0, periods*2pi]^3, ``nodes_per_period`` cells per
    period (a bounded box: the last node is included, so n = periods * nodes_per_period + 1 per
    axis), ``n_seeds`` seeds drawn with ``rng_seed``, lines of arc length ``length``."""

    nodes_per_period: int = 128
    periods: int = 3
    n_seeds: int = 2000
    length: float = 10.0
    rng_seed: int = 20261122
    ref_rtol: float = 1e-12
    ref_atol: float = 1e-12
    stretch: float = 1.0  # > 1: a rectilinear x axis, its widest cell this many times its narrowest

    @property
    def n_nodes(self) -> int:
        return self.periods * self.nodes_per_period + 1

    @property
    def span(self) -> float:
        return self.periods * TWO_PI

    @property
    def spacing(self) -> float:
        return TWO_PI / self.nodes_per_period

    def key(self) -> str:
        """Cache key of the seeds and the reference: every parameter they depend on."""
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        if d["stretch"] == 1.0:  # (the uniform problem's key as before the stretched one existed)
            del d["stretch"]
        d["scipy"] = scipy.__version__
        return hashlib.sha1(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]


def abc_field(problem: Problem) -> Field:
    """ABC sampled exactly at the nodes of the bounded box (float64, (n, n, n, 3)); with
    ``stretch`` > 1 the x nodes are graded (cell widths growing geometrically from x = 0, the
    last ``stretch`` times the first: a stretched mesh as blockMesh grades one), the same count."""
    n = problem.n_nodes
    if problem.stretch == 1.0:
        return ABCFlow().to_field(n, bounds=[[0.0, problem.span]] * 3, periodic=False)
    w = problem.stretch ** (np.arange(n - 1) / (n - 2))
    x = np.concatenate([[0.0], np.cumsum(w)]) * (problem.span / w.sum())
    x[-1] = problem.span
    u = np.linspace(0.0, problem.span, n)
    return ABCFlow().to_field(grid=Grid.from_axes(x, u, u))


def make_seeds(problem: Problem, margin: float = 1.0) -> np.ndarray:
    """``n_seeds`` seeds from a fixed RNG in the central period, kept only when the analytic ABC
    line of arc length ``length`` from them stays ``margin`` inside the box (the trilinear line
    is close to it, so the tools never meet the boundary: all of them do the same work)."""
    rng = np.random.default_rng(problem.rng_seed)
    lo, hi = problem.span / 2 - np.pi, problem.span / 2 + np.pi
    kept, have = [], 0
    while have < problem.n_seeds:
        cand = lo + (hi - lo) * rng.random((2 * problem.n_seeds, 3))
        ok = _stays_inside(cand, problem.length, margin, problem.span - margin)
        kept.append(cand[ok])
        have += int(ok.sum())
    return np.ascontiguousarray(np.concatenate(kept)[: problem.n_seeds])


def _stays_inside(p, length, lo, hi, h=0.01):
    """Classic RK4 in arc length on the analytic field, all seeds at once (a coarse screen)."""
    abc = ABCFlow()

    def f(x):
        v = abc.velocity(x)
        return v / np.linalg.norm(v, axis=1, keepdims=True)

    ok = np.ones(len(p), bool)
    x = p.copy()
    for _ in range(round(length / h)):
        k1 = f(x)
        k2 = f(x + 0.5 * h * k1)
        k3 = f(x + 0.5 * h * k2)
        k4 = f(x + h * k3)
        x += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        ok &= np.all((x > lo) & (x < hi), axis=1)
    return ok


# -- the reference ----------------------------------------------------------------------
@njit(cache=True)
def unit_velocity(gx, gy, gz, period, inv, vec, y):
    """v/|v| of the trilinear interpolant at y (NaN outside the grid or at zero speed)."""
    out = np.full(3, np.nan)
    i, j, k, tx, ty, tz, ok = interp.locate(gx, gy, gz, period, inv, y[0], y[1], y[2])
    if not ok:
        return out
    u, v, w, bad = interp.trilinear_vector(vec, i, j, k, tx, ty, tz)
    s = np.sqrt(u * u + v * v + w * w)
    if bad or s == 0.0:
        return out
    out[0] = u / s
    out[1] = v / s
    out[2] = w / s
    return out


@njit(cache=True)
def cell_unit_velocity(gx, gy, gz, vec, i, j, k, y):
    """v/|v| of the trilinear polynomial of cell (i, j, k), extended beyond the cell's faces:
    smooth, so DOP853 meets no kink; the caller switches cells at the faces."""
    tx = (y[0] - gx[i]) / (gx[i + 1] - gx[i])
    ty = (y[1] - gy[j]) / (gy[j + 1] - gy[j])
    tz = (y[2] - gz[k]) / (gz[k + 1] - gz[k])
    u, v, w, _ = interp.trilinear_vector(vec, i, j, k, tx, ty, tz)
    s = np.sqrt(u * u + v * v + w * w)
    return np.array([u / s, v / s, w / s])


def reference_line(field: Field, seed, length: float, rtol=1e-12, atol=1e-12, max_step_cells=0.5):
    """Point at arc length ``length`` from ``seed``: scipy DOP853 (dx/ds = v/|v|) on the
    trilinear interpolant, cell by cell.  The interpolant is only C0 across cell faces, where a
    plain adaptive step sees a kink (at 1e-12 plain DOP853 ends 1e-8..1e-7 from this, and
    rejects most steps); here each solve stops at the face it reaches (a terminal event) and
    the next starts in the neighbouring cell.  Returns (point, RHS evaluations)."""
    g = field.grid
    axes = g.axes
    # events are tested at step ends only: short steps keep a line from grazing a face (out
    # and back within one step) unnoticed
    max_step = max_step_cells * g.min_cell_size
    y = np.array(seed, dtype=np.float64)
    v0 = unit_velocity(*g.kernel_args(), field.vector, y)
    if not np.all(np.isfinite(v0)):
        raise RuntimeError(f"reference: seed {y.tolist()} is outside the grid or at zero speed")
    cell = [_cell_of(axes[a], y[a], v0[a]) for a in range(3)]
    s, nfev = 0.0, 0
    entered = None  # (axis, face value) of the face the line last came in through
    skip = None  # that face, when the line runs along it (an event there at once, no progress)
    stalls = 0
    while s < length:
        i, j, k = cell
        lo = [axes[a][cell[a]] for a in range(3)]
        hi = [axes[a][cell[a] + 1] for a in range(3)]
        faces = [(a, face, sign) for a in range(3) for face, sign in ((lo[a], -1), (hi[a], 1))
                 if (a, face) != skip]

        def rhs(t, yy, i=i, j=j, k=k):
            return cell_unit_velocity(*axes, field.vector, i, j, k, yy)

        sol = solve_ivp(rhs, (s, length), y, method="DOP853", rtol=rtol, atol=atol,
                        events=[_face_event(*f) for f in faces], max_step=max_step)
        nfev += sol.nfev
        if sol.status == 1:  # reached a face: continue in the neighbouring cell
            hit = next(n for n, te in enumerate(sol.t_events) if te.size)
            a, face, sign = faces[hit]
            t_hit = float(sol.t_events[hit][0])
            if t_hit <= s + 1e-14 * length:
                stalls += 1
                if stalls > 10:
                    raise RuntimeError(f"reference: no progress from seed {list(seed)} at s={s:g}")
                if (a, face) == entered:  # running along the face it came through: ignore it
                    skip = (a, face)
                    continue
            else:
                stalls, skip = 0, None
            s, y = t_hit, sol.y_events[hit][0].copy()
            y[a] = face  # exactly on the face
            cell[a] += sign
            entered = (a, face)
            if not 0 <= cell[a] < axes[a].size - 1:
                raise RuntimeError(f"reference: line from {list(seed)} left the grid at s={s:g}")
        elif sol.status == 0:
            s, y = length, sol.y[:, -1]
        else:
            raise RuntimeError(f"reference failed from seed {list(seed)}: {sol.message}")
    return y, nfev


def _face_event(a, face, sign):
    """Terminal event: coordinate ``a`` crosses ``face`` moving in direction ``sign``."""

    def ev(t, y):
        return y[a] - face

    ev.terminal, ev.direction = True, sign
    return ev


def _cell_of(c, x, v):
    """Cell index of x on axis c; on a node, the cell the line moves into."""
    i = int(np.clip(np.searchsorted(c, x, side="right") - 1, 0, c.size - 2))
    if x == c[i] and v < 0 and i > 0:
        i -= 1
    return i


_WORK: dict = {}  # the field of the reference workers (inherited by fork, never pickled)


def _ref_one(args):
    seed, length, rtol, atol = args
    return reference_line(_WORK["field"], seed, length, rtol, atol)


def reference_points(field: Field, seeds: np.ndarray, length: float, rtol=1e-12, atol=1e-12,
                     processes: int = 2, progress: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Points at arc length ``length`` by scipy DOP853 on the trilinear interpolant of
    ``field``, and the RHS evaluations per seed.  Seeds are shared out over ``processes`` forked
    workers (the field is inherited, not copied)."""
    _WORK["field"] = field
    jobs = [(s, float(length), rtol, atol) for s in seeds]
    try:
        if processes > 1 and len(jobs) > 1 and "fork" in mp.get_all_start_methods():
            with mp.get_context("fork").Pool(processes) as pool:
                res = []
                for r in pool.imap(_ref_one, jobs, chunksize=4):
                    res.append(r)
                    _progress(progress, len(res), len(jobs))
        else:
            res = []
            for j in jobs:
                res.append(_ref_one(j))
                _progress(progress, len(res), len(jobs))
    finally:
        _WORK.clear()
    return np.array([r[0] for r in res]).reshape(-1, 3), np.array([r[1] for r in res])


def _progress(on, done, total):
    if on and (done % 100 == 0 or done == total):
        print(f"  reference: {done}/{total} seeds", flush=True)


def cached_reference(problem: Problem, field: Field, seeds: np.ndarray, processes: int = 2):
    """The reference of ``problem``, computed once and kept in benchmarks/results/."""
    path = RESULTS / f"reference_{problem.key()}.npz"
    if path.exists():
        with np.load(path, allow_pickle=False) as z:
            if np.array_equal(z["seeds"], seeds):
                return z["points"], z["nfev"], float(z["seconds"]), True
    t0 = time.perf_counter()
    pts, nfev = reference_points(field, seeds, problem.length, problem.ref_rtol, problem.ref_atol,
                                 processes)
    sec = time.perf_counter() - t0
    RESULTS.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "wb") as fh:
        np.savez(fh, seeds=seeds, points=pts, nfev=nfev, seconds=sec)
    return pts, nfev, sec, False


# -- errors -----------------------------------------------------------------------------
def point_at_arc_length(points: np.ndarray, offsets: np.ndarray, s: float) -> np.ndarray:
    """Per polyline, the point at cumulative chord length ``s`` (linear between vertices; NaN
    for a line shorter than ``s``).  For tools that give no exact end point: the chord sum
    underestimates the arc length by about kappa^2 h^3 / 24 per step of length h."""
    out = np.full((offsets.size - 1, 3), np.nan)
    for i in range(offsets.size - 1):
        p = points[offsets[i]:offsets[i + 1]]
        if len(p) < 2:
            continue
        cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        if cum[-1] < s * (1 - 1e-12):
            continue
        j = min(int(np.searchsorted(cum, s, side="right")) - 1, len(p) - 2)
        t = (s - cum[j]) / (cum[j + 1] - cum[j])
        out[i] = p[j] + t * (p[j + 1] - p[j])
    return out


def errors(points: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Distance of each tool point from its reference point (inf where the tool gave none)."""
    d = np.linalg.norm(np.asarray(points, float) - reference, axis=1)
    return np.where(np.isfinite(d), d, np.inf)


# -- runs and timing --------------------------------------------------------------------
@dataclass
class Run:
    """One tool at one setting: its points at arc length ``length`` and what it cost."""

    tool: str
    setting: str
    end_points: np.ndarray
    n_vertices: int
    wall: float
    cpu: float
    n_seeds: int
    scale: float = 1.0  # wall time per seed is multiplied by this to give the full-set time
    notes: list[str] = field(default_factory=list)
    err: np.ndarray | None = None

    @property
    def threads_used(self) -> float:
        """Process CPU time over wall time during the timed call: the cores it really used."""
        return self.cpu / self.wall if self.wall > 0 else 0.0

    @property
    def full_wall(self) -> float:
        return self.wall * self.scale

    def stats(self) -> dict:
        e = self.err
        finite = e[np.isfinite(e)]
        return {
            "tool": self.tool,
            "setting": self.setting,
            "seeds": self.n_seeds,
            "median_err": float(np.median(e)),
            "p90_err": float(np.percentile(e, 90)),
            "failed": int((~np.isfinite(e)).sum()),
            "max_err": float(finite.max()) if finite.size else float("inf"),
            "wall_s": self.full_wall,
            "measured_s": self.wall,
            "vertices": self.n_vertices,
            "vertices_per_s": self.n_vertices / self.wall if self.wall > 0 else 0.0,
            "threads_used": self.threads_used,
        }


class Timer:
    """Wall and process CPU time of a block (CPU/wall shows how many cores were busy)."""

    def __enter__(self):
        self.w0, self.c0 = time.perf_counter(), time.process_time()
        return self

    def __exit__(self, *exc):
        self.wall = time.perf_counter() - self.w0
        self.cpu = time.process_time() - self.c0


def machine() -> str:
    load = os.getloadavg()
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return (f"{cpu}; {os.cpu_count()} logical cores (affinity: {len(os.sched_getaffinity(0))}); "
            f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; "
            f"Python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}")


# -- tables -----------------------------------------------------------------------------
COLUMNS = [("tool", "{}"), ("setting", "{}"), ("seeds", "{}"), ("median_err", "{:.2e}"),
           ("p90_err", "{:.2e}"), ("failed", "{}"), ("wall_s", "{:.3f}"),
           ("vertices_per_s", "{:.3g}"), ("threads_used", "{:.2f}")]


def markdown_table(rows: list[dict], columns=COLUMNS) -> str:
    head = "| " + " | ".join(c for c, _ in columns) + " |"
    sep = "|" + "|".join("---" for _ in columns) + "|"
    body = ["| " + " | ".join(fmt.format(r[c]) for c, fmt in columns) + " |" for r in rows]
    return "\n".join([head, sep] + body)


def write_csv(path: Path, rows: list[dict]) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return path


def fastest_at(rows: list[dict], tool: str, level: float) -> dict | None:
    """The fastest run of ``tool`` whose median error is at most ``level``."""
    ok = [r for r in rows if r["tool"] == tool and r["median_err"] <= level]
    return min(ok, key=lambda r: r["wall_s"]) if ok else None
