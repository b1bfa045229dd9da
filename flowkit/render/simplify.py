"""Per-frame level of detail: draw only the vertices that change the picture.

Streamlines are traced with many more vertices than a frame can show (the benchmark scene has
0.7-pixel segments at 1920x1080), and on a software rasterizer every tiny triangle costs a full
setup.  Once per renderer, every vertex gets a Douglas-Peucker importance: the distance (world
units) from the vertex to the chord that replaces it when the DP recursion picks it, capped by its
parent's importance so that importance only falls down the hierarchy; ``importance > tol`` then
selects exactly the vertices DP keeps at tolerance ``tol``.  An attribute's deviation is
the deviation from what the fragment shader draws between two kept vertices, a cubic Hermite
interpolant along the arc length through their values and slopes (``slopes``: monotone, PCHIP,
so nothing overshoots between the traced vertices; a straight line of values stays straight).
Attributes that only place shapes and patterns along the line get a displacement importance
instead (world units, like the geometry's): how far along the arc the interpolant puts the
vertex's value -- a pattern feature -- from where it belongs, to first order the value error
over the slope; 0 wherever the interpolant is exact (arc_length itself needs no vertices of its
own) and inf at a local extremum the interpolant misses.  A style's importance is one DP
hierarchy (``lod_importance``) whose deviation at a vertex is the largest of its criteria: the
geometric deviation, each placed attribute's displacement, and each attribute mapped to colour,
width or a transfer function: its displacement where its value error exceeds half that
attribute's tolerance (else 0).  Per frame a vertex is kept when its importance exceeds half
the pixel tolerance (converted to world units at the vertex's depth): a dropped vertex moves
the line and the shapes and patterns on it by less than that, and either changes a mapped
value by less than half its tolerance or moves the mapped picture along the line by less than
that; the ends of every run are always kept.  One hierarchy, so that a vertex the geometry
keeps serves the attributes too (a union of one DP set per criterion kept 44% more vertices on
the benchmark scene); the halves are a margin kept from when the kept set was such a union,
which at most doubles each set's error.

Runs are the pieces of a line with consecutive finite points (>= 2 of them); the renderer draws
one triangle strip per run.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..lines import Lines, finite_rows
from ..threads import run_ranges
from .style.model import ColorMap, Style, WidthMap

RESTART = 0xFFFFFFFF  # moderngl enables primitive restart with this index
VALUE, DISPLACEMENT, MAPPED = 1, 2, 3  # kinds of attribute deviation
OUTSIDE = 1e200  # displacement at an extremum: overflows to inf in the float32 importance
MAX_SPAN = 4096  # longer pieces are split at their middle (which shares its parent's importance)
# unscanned, so the DP cost stays O(n log n + n * MAX_SPAN) whatever the curve


def runs(lines: Lines) -> tuple[np.ndarray, np.ndarray]:
    """(starts, stops) int64 of the runs of >= 2 consecutive finite points of each line."""
    finite = finite_rows(lines.points)
    line_of = lines.line_index()
    i = np.flatnonzero(finite)
    if i.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    # a run breaks where the index jumps (a non-finite point) or the line changes
    brk = np.flatnonzero((np.diff(i) != 1) | (np.diff(line_of[i]) != 0)) + 1
    first, last = np.r_[0, brk], np.r_[brk, i.size] - 1
    keep = last > first
    return i[first[keep]].astype(np.int64), i[last[keep]].astype(np.int64) + 1


def arc_parameter(points: np.ndarray, starts: np.ndarray, stops: np.ndarray) -> np.ndarray:
    """Cumulative chord length from each run's start (0 outside runs)."""
    return _arc(np.ascontiguousarray(points, np.float64), starts, stops)


def geometry_importance(points, starts, stops) -> np.ndarray:
    """float32 DP importance (world units) of every point; inf at run ends, 0 outside runs."""
    return lod_importance(points, np.zeros(0), starts, stops)


def slopes(values, arc, starts, stops) -> np.ndarray:
    """d(value)/d(arc) at every point for the Hermite interpolant the shaders draw: PCHIP's
    (Fritsch-Carlson: the weighted harmonic mean of the two adjacent secants, 0 where they
    differ in sign, so the interpolant is monotone between consecutive points; at run ends the
    limited three-point formula, as scipy's PchipInterpolator); 0 outside runs and where a
    neighbour is not finite."""
    return _slopes(np.ascontiguousarray(values, np.float64), arc, starts, stops)


def linear_along_arc(values, arc, starts, stops, rtol: float = 1e-6) -> bool:
    """Whether ``values`` change linearly with the arc parameter along every run (within
    ``rtol`` of their largest magnitude, below what float32 shaders resolve): then the
    shaders interpolate them linearly, which is exact, and skip the cubic."""
    v = np.asarray(values, np.float64)
    if not starts.size:
        return True
    n = stops - starts
    first, last = np.repeat(starts, n), np.repeat(stops - 1, n)
    i = np.arange(n.sum()) + np.repeat(starts - np.r_[0, np.cumsum(n)[:-1]], n)
    L = arc[last] - arc[first]
    t = np.divide(arc[i] - arc[first], L, out=np.zeros_like(L), where=L > 0)
    err = np.abs(v[i] - v[first] - t * (v[last] - v[first]))
    scale = np.max(np.abs(v[i])) if i.size else 0.0
    return bool(np.all(np.isfinite(err)) and err.max(initial=0.0) <= rtol * scale)


def hermite(values, slopes_, arc, i, j, at) -> np.ndarray:
    """The interpolant between points i and j (what a fragment gets) at arc parameters ``at``:
    the cubic through their values with their slopes, limited so that it is monotone between
    them (``_end_terms``)."""
    L = arc[j] - arc[i]
    u = np.clip((np.asarray(at, np.float64) - arc[i]) / L, 0.0, 1.0) if L > 0 else 0.0 * at
    d = values[j] - values[i]
    a, b = _end_terms(d, slopes_[i] * L, slopes_[j] * L)
    return values[i] + u * (d + (1.0 - u) * ((1.0 - u) * a + u * b))


def attribute_importance(values, slopes_, arc, starts, stops) -> np.ndarray:
    """float32 DP importance (attribute units) of a scalar attribute along the arc parameter,
    against the Hermite interpolant of ``slopes``; inf where a value is not finite."""
    return _attribute_importance(values, slopes_, arc, starts, stops, VALUE)


def displacement_importance(values, slopes_, arc, starts, stops) -> np.ndarray:
    """float32 DP importance (world units along the arc) of an attribute that places shapes or
    patterns: how far from the vertex the Hermite interpolant reaches the vertex's value (the
    value error over the slope there); inf at local extrema it misses and where a value is not
    finite."""
    return _attribute_importance(values, slopes_, arc, starts, stops, DISPLACEMENT)


def mapped_importance(values, slopes_, arc, starts, stops, value_tol: float) -> np.ndarray:
    """float32 DP importance (world units) of an attribute mapped to colour, width or a transfer
    function: its displacement where its value error exceeds ``value_tol``, else 0 -- one
    hierarchy, so that the kept points satisfy both conditions on the same chords.
    ``value_tol`` <= 0: inf wherever the interpolant is not exact."""
    return _attribute_importance(values, slopes_, arc, starts, stops, MAPPED, value_tol)


def _attribute_importance(values, slopes_, arc, starts, stops, kind, vtol=0.0) -> np.ndarray:
    v = np.ascontiguousarray(values, np.float64)[None]
    m = np.ascontiguousarray(slopes_, np.float64)[None]
    return _importance(np.zeros((0, 3)), v, m, np.asarray(arc, np.float64),
                       np.array([kind], np.int64), np.array([vtol], np.float64), starts, stops)


def lod_importance(points, arc, starts, stops, placed=(), mapped=()) -> np.ndarray:
    """float32 DP importance (world units) of every point for a style: one hierarchy whose
    deviation at a point is the largest of its geometric deviation, the displacement of each
    attribute in ``placed`` ((values, slopes) pairs: attributes that place shapes and
    patterns) and that of each attribute in ``mapped`` ((values, slopes, value tolerance):
    colour, width, transfer; see ``mapped_importance``).  So the points DP keeps at a tolerance
    bound every one of these errors by it, and a point that the geometry keeps anyway serves
    the attributes too: on the benchmark scene of bench_styles.py a union of one hierarchy per
    criterion drew 522k points where this draws 362k (geometry alone: 361k)."""
    p = np.ascontiguousarray(points, np.float64)
    crit = [(v, m, DISPLACEMENT, 0.0) for v, m in placed] + [(v, m, MAPPED, t) for v, m, t in mapped]
    n = p.shape[0]
    V = np.zeros((len(crit), n))
    DV = np.zeros((len(crit), n))
    for q, (v, m, _, _) in enumerate(crit):
        V[q], DV[q] = v, m
    kinds = np.array([c[2] for c in crit], np.int64)
    vtols = np.array([c[3] for c in crit], np.float64)
    return _importance(p, V, DV, np.asarray(arc, np.float64), kinds, vtols, starts, stops)


@numba.njit(cache=True)
def _arc(p, starts, stops):
    s = np.zeros(p.shape[0])
    for r in range(starts.size):
        for i in range(starts[r] + 1, stops[r]):
            d0, d1, d2 = p[i, 0] - p[i - 1, 0], p[i, 1] - p[i - 1, 1], p[i, 2] - p[i - 1, 2]
            s[i] = s[i - 1] + math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)  # (no temporary array)
    return s


@numba.njit(cache=True)
def _slopes(v, s, starts, stops):
    m = np.zeros(v.size)
    for r in range(starts.size):
        a, b = starts[r], stops[r] - 1
        for i in range(a, b + 1):
            if b - a == 1:  # two points: the secant
                g = (v[b] - v[a]) / (s[b] - s[a]) if s[b] > s[a] else 0.0
            elif i == a or i == b:  # three-point one-sided, limited as PCHIP's ends are
                k = 1 if i == a else -1
                h0, h1 = abs(s[i + k] - s[i]), abs(s[i + 2 * k] - s[i + k])
                d0 = (v[i + k] - v[i]) / (s[i + k] - s[i]) if h0 > 0.0 else 0.0
                d1 = (v[i + 2 * k] - v[i + k]) / (s[i + 2 * k] - s[i + k]) if h1 > 0.0 else 0.0
                g = ((2.0 * h0 + h1) * d0 - h0 * d1) / (h0 + h1) if h0 + h1 > 0.0 else 0.0
                if np.sign(g) != np.sign(d0):
                    g = 0.0
                elif np.sign(d0) != np.sign(d1) and abs(g) > 3.0 * abs(d0):
                    g = 3.0 * d0
            else:
                h0, h1 = s[i] - s[i - 1], s[i + 1] - s[i]
                d0 = (v[i] - v[i - 1]) / h0 if h0 > 0.0 else 0.0
                d1 = (v[i + 1] - v[i]) / h1 if h1 > 0.0 else 0.0
                g = 0.0
                if d0 * d1 > 0.0:  # weighted harmonic mean; 0 at an extremum
                    w0, w1 = 2.0 * h1 + h0, h1 + 2.0 * h0
                    g = (w0 + w1) / (w0 / d0 + w1 / d1)
            m[i] = g if math.isfinite(g) else 0.0
    return m


@numba.njit(cache=True)
def _end_terms(d, ga, gb):
    """The cubic's end terms on a segment whose values change by d, with end slopes times its
    length ga, gb, after Fritsch-Carlson's limits (slopes against the change's sign become 0,
    their ratios to the secant are scaled into the circle of radius 3), so that the cubic is
    monotone on the segment and never leaves its end values.  strip.glsl (hermite_terms) does
    the same."""
    if d == 0.0:
        return 0.0, 0.0
    al, be = max(ga / d, 0.0), max(gb / d, 0.0)
    r = al * al + be * be
    if r > 9.0:
        t = 3.0 / math.sqrt(r)
        al, be = al * t, be * t
    return (al - 1.0) * d, (1.0 - be) * d


@numba.njit(cache=True)
def _chord(v, dv, s, i, j):
    """The interpolant from i to j (see ``hermite``): arc length, change, the cubic's terms."""
    L = s[j] - s[i]
    d = v[j] - v[i]
    a, b = _end_terms(d, dv[i] * L, dv[j] * L)
    return L, d, a, b


@numba.njit(cache=True)
def _distance(p, i, j, m):
    """Distance from point m to the segment i-j (the geometric deviation)."""
    dx, dy, dz = p[j, 0] - p[i, 0], p[j, 1] - p[i, 1], p[j, 2] - p[i, 2]
    mx, my, mz = p[m, 0] - p[i, 0], p[m, 1] - p[i, 1], p[m, 2] - p[i, 2]
    dd = dx * dx + dy * dy + dz * dz
    t = 0.0 if dd == 0.0 else min(max((mx * dx + my * dy + mz * dz) / dd, 0.0), 1.0)
    ex, ey, ez = mx - t * dx, my - t * dy, mz - t * dz
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@numba.njit(cache=True)
def _deviation(v, dv, s, i, j, m, kind, vtol, L, d, a, b):
    """An attribute's deviation at m from its interpolant on the chord i-j (``_chord``)."""
    if not abs(d) <= 1e300:
        # a non-finite end value: the fragments get no value over the whole chord, the traced
        # line only on the segments next to that end, so split next to it (then the points
        # around a NaN are kept, and no others for it)
        return OUTSIDE * (1.0 + (m - i if not abs(v[j]) <= 1e300 else j - m))
    u = (s[m] - s[i]) / L if L > 0.0 else (m - i) / (j - i)
    h = v[i] + u * (d + (1.0 - u) * ((1.0 - u) * a + u * b))
    err = abs(v[m] - h)
    if kind == VALUE:
        return err
    if kind == MAPPED and vtol <= 0.0:  # no tolerance known: exact or kept
        return OUTSIDE if err != 0.0 else 0.0
    if kind == MAPPED and err <= vtol:  # (NaN: kept, below)
        return 0.0
    # displacement: the value error over the slope.  Where the slope is 0 (an extremum) and the
    # value is missed, beyond every finite importance (inf once stored as float32), ordered by
    # the error so that DP splits at the extremum itself and keeps only the extrema
    if err == 0.0:
        return 0.0
    if dv[m] == 0.0:
        return OUTSIDE * (1.0 + min(err, 1e50))
    return err / abs(dv[m])


# The per-run loops run on threads over ranges of runs (threads.py), as the tracing
# kernel does, not in prange loops: numba builds and optimises a parallel gufunc around each
# prange loop, seconds of compilation on every fresh machine for work that is the same either
# way (runs are independent, and each range writes only its own runs' entries).
def _importance(p, V, DV, s, kinds, vtols, starts, stops):
    """DP importances with the deviation at a point the largest of the criteria: the geometric
    one when ``p`` has points, and per row q of V (values) and DV (slopes) that of kinds[q] at
    value tolerance vtols[q]."""
    imp = np.zeros(p.shape[0] if p.shape[0] > 0 else V.shape[1], np.float32)
    run_ranges(_importance_range, starts.size, p, V, DV, s, kinds, vtols, starts, stops, imp)
    return imp


@numba.njit(cache=True, nogil=True)
def _importance_range(start, stop, p, V, DV, s, kinds, vtols, starts, stops, imp):
    geometry = p.shape[0] > 0
    for r in range(start, stop):
        a, b = starts[r], stops[r] - 1
        imp[a] = np.inf
        imp[b] = np.inf
        si = np.empty(b - a + 1, np.int64)  # stack of (first, last, parent importance)
        sj = np.empty(b - a + 1, np.int64)
        sc = np.empty(b - a + 1)
        chord = np.empty((kinds.size, 4))  # per criterion: the interpolant on the chord
        si[0], sj[0], sc[0] = a, b, np.inf
        top = 1
        while top > 0:
            top -= 1
            i, j, cap = si[top], sj[top], sc[top]
            if j - i < 2:
                continue
            if j - i > MAX_SPAN:
                k, e = (i + j) // 2, cap
            else:
                for q in range(kinds.size):
                    L, dd, ca, cb = _chord(V[q], DV[q], s, i, j)
                    chord[q, 0], chord[q, 1], chord[q, 2], chord[q, 3] = L, dd, ca, cb
                best, k = -1.0, i + 1
                for m in range(i + 1, j):
                    d = _distance(p, i, j, m) if geometry else 0.0
                    for q in range(kinds.size):
                        dq = _deviation(V[q], DV[q], s, i, j, m, kinds[q], vtols[q],
                                        chord[q, 0], chord[q, 1], chord[q, 2], chord[q, 3])
                        if not dq <= 1e300:  # NaN or inf (non-finite attribute): always keep
                            dq = np.inf
                        d = max(d, dq)
                    if d > best:
                        best, k = d, m
                e = min(best, cap)
            imp[k] = e
            si[top], sj[top], sc[top] = i, k, e
            si[top + 1], sj[top + 1], sc[top + 1] = k, j, e
            top += 2


def _select(points, imp, zrow, px, tol, extra, starts, stops):
    """Kept point ids as the strip buffer and the element indices.

    ids: the kept points of each run with -1 between runs (and at both ends), every entry twice,
    so strip vertex e = 2k + side reads prev/cur/next at ids[e], ids[e + 2], ids[e + 4].
    Runs are independent: the first pass marks and counts each run's kept points, the second
    writes them where the counts before it put them (both on threads over ranges of runs).
    """
    n_runs = starts.size
    n = 0 if n_runs == 0 else int(stops.max())
    keep = np.zeros(max(n, 1), np.uint8)
    kept = np.zeros(n_runs + 1, np.int64)  # kept points per run, then summed: before each run
    run_ranges(_mark_range, n_runs, points, imp, zrow, px, tol, extra, starts, stops, keep, kept)
    np.cumsum(kept, out=kept)
    nk = int(kept[n_runs]) + n_runs + 1  # kept entries and a -1 before, between and after runs
    ids = np.empty(2 * nk + 4, np.int32)
    idx = np.empty(2 * int(kept[n_runs]) + n_runs, np.uint32)
    ids[:2] = -1
    ids[2 * nk:] = -1
    run_ranges(_write_range, n_runs, starts, stops, keep, kept, ids, idx)
    return ids, idx


@numba.njit(cache=True, nogil=True)
def _mark_range(start, stop, points, imp, zrow, px, tol, extra, starts, stops, keep, kept):
    half = 0.5 * tol
    for r in range(start, stop):
        a, b = starts[r], stops[r]
        c = 0
        for i in range(a, b):
            k = tol <= 0.0 or i == a or i == b - 1
            if not k and extra.size:
                k = extra[i]
            if not k:
                z = zrow[0] * points[i, 0] + zrow[1] * points[i, 1] + zrow[2] * points[i, 2] + zrow[3]
                k = imp[i] > half * (px[0] * (-z) + px[1])
            keep[i] = k
            c += k
        kept[r + 1] = c


@numba.njit(cache=True, nogil=True)
def _write_range(start, stop, starts, stops, keep, kept, ids, idx):
    for r in range(start, stop):
        m = kept[r] + r + 1  # entry of the run's first kept point
        j = 2 * kept[r] + r  # its first strip index
        for i in range(starts[r], stops[r]):
            if keep[i]:
                ids[2 * m] = ids[2 * m + 1] = i
                idx[j] = 2 * (m - 1)
                idx[j + 1] = 2 * (m - 1) + 1
                m += 1
                j += 2
        ids[2 * m] = ids[2 * m + 1] = -1
        idx[j] = RESTART


def select(points, imp, view, px, tol, extra, starts, stops) -> tuple[np.ndarray, np.ndarray]:
    """(ids int32, indices uint32) of the strips to draw this frame (see ``_select``).
    ``extra``: bool per point, kept whatever its geometry (attributes), or an empty array."""
    zrow = np.ascontiguousarray(view[2], np.float64)
    return _select(points, imp, zrow, np.asarray(px, np.float64), float(tol), extra, starts, stops)


@numba.njit(cache=True)
def _split(idx, ids, values, lo, hi, n_groups):
    """Strip indices regrouped: segment m -> m+1 goes to range r when the transfer values of both
    ends lie in [lo[r], hi[r]) (then every value between them does), else to group n_groups
    (mixed, NaN).  Consecutive segments of one group form one strip piece; the pieces keep their
    element numbers, so neighbours stay those of the whole run.  A group's pieces form one strip,
    joined by repeating the last index of a piece and the first of the next (four zero-area
    triangles) rather than by primitive restarts: a draw module splits an indexed draw at every
    restart into a draw of its own, and the pieces of a transfer range can be a few points long.
    The first pass finds each segment's group and sizes the groups, the second appends each
    segment to its group's strip."""
    seg = np.full(idx.size, -1, np.int32)  # group of the segment ending at idx[k]; -1: none
    first = np.zeros(idx.size, np.uint32)  # even element of that segment's first point
    new = np.zeros(idx.size, np.int8)  # 1: the segment starts a piece
    counts = np.zeros(n_groups + 1, np.int64)
    prev, last = -1, -1  # even element of the previous kept point of the run; its segment's group
    for k in range(idx.size):
        e = idx[k]
        if e == RESTART:
            prev, last = -1, -1
            continue
        if e % 2:
            continue
        if prev >= 0:
            va, vb = values[ids[prev + 2]], values[ids[e + 2]]
            g = n_groups
            for r in range(n_groups):
                if lo[r] <= va < hi[r] and lo[r] <= vb < hi[r]:
                    g = r
                    break
            seg[k], first[k] = g, prev
            if g != last:  # a new piece: its first point, and a join after an earlier piece
                new[k] = 1
                counts[g] += 4 if counts[g] else 2
            counts[g] += 2
            last = g
        prev = e
    start = np.zeros(n_groups + 1, np.int64)  # each group's first position
    for g in range(1, n_groups + 1):
        start[g] = start[g - 1] + counts[g - 1]
    cur = start.copy()  # each group's write position
    out = np.empty(start[n_groups] + counts[n_groups], np.uint32)
    for k in range(idx.size):
        g = seg[k]
        if g < 0:
            continue
        c = cur[g]
        if new[k]:
            if c > start[g]:  # joined to the group's previous piece
                out[c], out[c + 1] = out[c - 1], first[k]
                c += 2
            out[c], out[c + 1] = first[k], first[k] + 1
            c += 2
        out[c], out[c + 1] = idx[k], idx[k] + 1
        cur[g] = c + 2
    return out, counts


def split_by_range(idx, ids, values, lo, hi) -> tuple[np.ndarray, np.ndarray]:
    """(indices, counts): the strips of ``select`` regrouped by transfer range (see ``_split``);
    group r < len(lo) holds the segments wholly inside [lo[r], hi[r]), the last group the rest."""
    return _split(idx, ids, np.asarray(values, np.float32), np.asarray(lo, np.float64),
                  np.asarray(hi, np.float64), len(lo))


def adjacency(idx: np.ndarray) -> np.ndarray:
    """lines_adjacency indices (uint32, 4 per segment) of the strips ``idx`` (from ``select`` or
    ``split_by_range``), for the geometry-shader path, which reads point ids at ids[j]: kept
    entry m (strip vertices
    2(m-1), 2(m-1)+1) is vertex 2m, and a segment m -> m+1 of a run is (2m-2, 2m, 2m+2, 2m+4);
    the neighbours outside the run read the -1 that ``select`` puts between runs."""
    pos = np.flatnonzero((idx != RESTART) & (idx % 2 == 0))
    ev = idx[pos].astype(np.int64)  # 2(m-1) per kept entry m
    # segments: the next kept entry follows in the same strip (no restart or join between)
    first = ev[:-1][(np.diff(ev) == 2) & (np.diff(pos) == 2)]
    return (first[:, None] + np.arange(0, 8, 2)).astype(np.uint32).reshape(-1)


def attribute_tolerances(style: Style, tol_px: float, ranges: dict[str, float],
                         unit: float = 1.0) -> dict[str, float]:
    """Per attribute the error the picture tolerates, for a pixel tolerance ``tol_px``: half a
    colormap step per 0.25 px, widths off by ``tol_px`` pixels (``unit``: style width units per
    pixel), transfer switches by 1/1024 of the data range per 0.25 px.  ``ranges``: each
    attribute's data range (max - min).  Attributes that only place shapes and patterns are left
    out (``placed_attributes``); others with no known use get 0 (every vertex where they are not
    linear is kept)."""
    f = tol_px / 0.25
    tol = {name: 0.0 for name in style.attributes()}
    need: dict[str, float] = {}

    def add(name, t):
        need[name] = min(need.get(name, math.inf), abs(t))

    for n in style.used_styles():
        for b in style.styles[n].bands:
            colors = [b.color] + ([b.pattern.color] if b.pattern is not None else [])
            for c in colors:
                if isinstance(c, ColorMap):
                    add(c.attribute, (c.range[1] - c.range[0]) * f / 512)
            if isinstance(b.width, WidthMap):
                w = b.width
                dw = abs(w.max - w.min) * style.scale
                add(w.attribute, (w.range[1] - w.range[0]) * tol_px * unit / dw if dw > 0 else math.inf)
    if style.transfer is not None:
        a = style.transfer.attribute
        add(a, ranges.get(a, 0.0) * f / 1024)
    tol.update({k: v for k, v in need.items() if k in tol})
    for name in placed_attributes(style):  # placement only: displacement importance instead
        if name not in need:
            del tol[name]
    return tol


def placed_attributes(style: Style) -> list[str]:
    """Attributes that place shapes and patterns along the drawn lines.  Their interpolation
    error shows as a shift along the line, so they are kept by displacement importance at the
    geometry's pixel tolerance (see the module docstring)."""
    out = []
    for n in style.used_styles():
        for b in style.styles[n].bands:
            for sp in (b.shape, b.pattern):
                if sp is not None and sp.attribute not in out:
                    out.append(sp.attribute)
    return out
