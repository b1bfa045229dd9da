"""Per-vertex attributes, computed only when requested.

Each attribute names the intermediate results it needs ("params": time/arc length from the
kernel; "velocity": the field sampled at the vertices; "curl": the vorticity grid, the only
expensive one; "seed": the seed of each vertex).  :func:`compute` builds each intermediate at
most once, and only for the attributes asked for; any other name is a scalar field of the Field.
"""

from __future__ import annotations

import numpy as np

from ..fields import Field, interp

# name -> intermediates it needs
ATTRIBUTES = {
    "time": ("params",),
    "arc_length": ("params",),
    "speed": ("velocity",),
    "velocity": ("velocity",),
    "vorticity": ("curl",),
    "vorticity_magnitude": ("curl",),
    "distance_to_seed": ("seed",),
}


def units(field: Field, names) -> dict[str, str]:
    """CF units of the attributes ``names`` traced in ``field``, where the field's units give
    them: time in s (when the vector is a length per second in the grid's length), arc length and
    distance to the seed in the grid's length unit, speed and velocity in the vector's unit,
    vorticity in the vector's unit per length ("1/s" for m/s on a grid in m), scalars as the
    file states.  Attributes whose units are not known are left out."""
    vec, length = field.units.get(field.vector_name), field.length_units
    per = _per_second(vec)
    if per is not None and length is not None and per != length:
        per = None  # a velocity in another length unit than the grid's: time is not in s
    derived = {"time": "s" if per is not None else None,
               "arc_length": length, "distance_to_seed": length,
               "speed": vec, "velocity": vec,
               "vorticity": _per_length(vec, length), "vorticity_magnitude": _per_length(vec, length)}
    out = {}
    for n in names:
        u = derived.get(n) if n in ATTRIBUTES else field.units.get(n)
        if u:
            out[n] = u
    return out


def metadata(field: Field, names) -> dict:
    """Lines.attrs entries that carry units and time: ``units`` (JSON of ``units``; the lines
    file writes them as CF ``units`` on each attribute), ``length_units`` (positions) and
    ``snapshot_time`` (the field's time, when known)."""
    import json

    out = {}
    u = units(field, names)
    if u:
        out["units"] = json.dumps(u)
    if field.length_units:
        out["length_units"] = field.length_units
    if field.time is not None:
        out["snapshot_time"] = float(field.time)
    return out


def _per_second(u: str | None) -> str | None:
    """The length unit of a velocity unit ("m/s", "m s-1", "m.s^-1" -> "m"), else None."""
    if not u:
        return None
    t = u.replace("^", "").replace(".", " ").strip()
    for tail in ("/s", " s-1", "/ s"):
        if t.endswith(tail) and t[: -len(tail)].strip():
            return t[: -len(tail)].strip()
    return None


def _per_length(vec: str | None, length: str | None) -> str | None:
    if not vec or not length:
        return None
    if _per_second(vec) == length:
        return "1/s"
    return f"({vec})/{length}"


def check(field: Field, names) -> None:
    """Raise a clear error for a name that is neither a known attribute nor a scalar field."""
    for n in names:
        if n not in ATTRIBUTES and n not in field.scalars:
            have = ", ".join(list(ATTRIBUTES) + sorted(field.scalars))
            raise KeyError(f"{field.source}: unknown attribute '{n}' (available: {have})")


def curl(field: Field) -> np.ndarray:
    """Curl of the node vector field, (nx, ny, nz, 3): second-order differences on the actual
    (possibly non-uniform) node coordinates, one-sided at bounded ends, wrapped on periodic axes;
    next to non-finite data (NaN holes) the one-sided differences of :func:`fallback_stencils`,
    so that only the non-finite nodes themselves get a NaN curl."""
    g = field.grid
    v = field.vector
    d = []  # d[comp][axis] = ∂v_comp/∂x_axis
    for comp in range(3):
        f = v[..., comp]
        finite = np.isfinite(f)
        finite = None if finite.all() else finite
        d.append([_deriv(f, g.axes[ax], g.period[ax], ax, finite) for ax in range(3)])
    return np.stack([d[2][1] - d[1][2], d[0][2] - d[2][0], d[1][0] - d[0][1]], axis=-1)


def _deriv(f: np.ndarray, c: np.ndarray, period: float, axis: int,
           finite: np.ndarray | None = None) -> np.ndarray:
    """∂f/∂x along ``axis``: :func:`gradient`; where its stencil meets a non-finite value, the
    first stencil of :func:`fallback_stencils` whose values are all finite (else NaN).
    ``finite``: np.isfinite(f), or None when all of f is finite."""
    d = gradient(f, c, period, axis)
    if finite is None:
        return d
    # nodes whose standard stencil meets non-finite data: the gradient of the mask is NaN there
    hit = np.moveaxis(np.isnan(gradient(np.where(finite, 0.0, np.nan), c, period, axis)), axis, 0)
    idx = np.nonzero(hit)  # (node along the axis, then the other two indices)
    if idx[0].size == 0:
        return d
    fm = np.moveaxis(f, axis, 0)
    nodes, weights = fallback_stencils(c, period)
    best = np.full(idx[0].size, np.nan)
    todo = np.ones(idx[0].size, bool)
    for cand in range(nodes.shape[1]):
        q = nodes[idx[0], cand]  # (m, 3) nodes, -1 unused
        w = weights[idx[0], cand]
        usable = todo & (q[:, 0] >= 0)
        acc = np.zeros(idx[0].size)
        for slot in range(q.shape[1]):
            qs = q[:, slot]
            val = np.where(qs >= 0, fm[(np.maximum(qs, 0),) + idx[1:]], 0.0)
            usable &= np.isfinite(val)
            acc += w[:, slot] * val
        best[usable] = acc[usable]
        todo &= ~usable
    out = np.moveaxis(d, axis, 0).copy()
    out[idx] = best
    return np.moveaxis(out, 0, axis)


def fallback_stencils(c: np.ndarray, period: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The one-sided differences tried, in order, at a node whose standard stencil (:func:
    `gradient`) meets non-finite data: 3-point forward, 3-point backward (second order on the
    node coordinates), 2-point forward, 2-point backward.  Returns (nodes (n, 4, 3) int32, -1
    unused or unavailable; weights (n, 4, 3)) for the node coordinates ``c``.  On a periodic
    axis (``period`` > 0) the stencils wrap across the seam with :func:`gradient`'s neighbours
    (a last node that repeats the first is skipped); on a bounded one they stay inside.  The
    OpenCL kernel applies the same table (opencl/vertex.py)."""
    n = c.size
    if period > 0 and n >= 3:
        lo, hi = _seam(c, period)  # two neighbours beyond each end (gradient's wrap takes one)
        ext = np.r_[lo - 1, lo, np.arange(n), hi, hi + 1]
        ext_c = np.r_[c[[lo - 1, lo]] - period, c, c[[hi, hi + 1]] + period]
        nodes, w = _one_sided(ext_c)
        nodes, w = nodes[2:n + 2], w[2:n + 2]
        return np.where(nodes >= 0, ext[np.maximum(nodes, 0)], -1).astype(np.int32), w
    return _one_sided(c)


def _one_sided(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = c.size
    nodes = np.full((n, 4, 3), -1, np.int32)
    w = np.zeros((n, 4, 3))
    i = np.arange(n)
    # 3-point forward at i from i, i+1, i+2 (derivative of the quadratic through them)
    f3 = i[: max(n - 2, 0)]
    h1, h2 = c[f3 + 1] - c[f3], c[f3 + 2] - c[f3 + 1]
    nodes[f3, 0] = np.stack([f3, f3 + 1, f3 + 2], axis=1)
    w[f3, 0] = np.stack([-(2 * h1 + h2) / (h1 * (h1 + h2)), (h1 + h2) / (h1 * h2),
                         -h1 / (h2 * (h1 + h2))], axis=1)
    # 3-point backward at i from i, i-1, i-2
    b3 = i[2:]
    h1, h2 = c[b3] - c[b3 - 1], c[b3 - 1] - c[b3 - 2]
    nodes[b3, 1] = np.stack([b3, b3 - 1, b3 - 2], axis=1)
    w[b3, 1] = np.stack([(2 * h1 + h2) / (h1 * (h1 + h2)), -(h1 + h2) / (h1 * h2),
                         h1 / (h2 * (h1 + h2))], axis=1)
    f2 = i[: max(n - 1, 0)]
    h = c[f2 + 1] - c[f2]
    nodes[f2, 2, :2] = np.stack([f2, f2 + 1], axis=1)
    w[f2, 2, :2] = np.stack([-1.0 / h, 1.0 / h], axis=1)
    b2 = i[1:]
    h = c[b2] - c[b2 - 1]
    nodes[b2, 3, :2] = np.stack([b2, b2 - 1], axis=1)
    w[b2, 3, :2] = np.stack([1.0 / h, -1.0 / h], axis=1)
    return nodes, w


def _seam(c: np.ndarray, period: float) -> tuple[int, int]:
    """The nodes beside the seam of a periodic axis: (the one below node 0, the one above the
    last), skipping a last node that repeats the first."""
    n = c.size
    return (n - 1, 0) if c[0] + period - c[-1] > 0 else (n - 2, 1)


def gradient(f: np.ndarray, c: np.ndarray, period: float, axis: int) -> np.ndarray:
    """np.gradient along ``axis`` on the node coordinates ``c``: second order, one-sided at
    bounded ends, wrapped on a periodic axis (NaN wherever its stencil meets NaN)."""
    n = c.size
    if period > 0 and n >= 3:
        # wrap: neighbours across the period join the stencil
        lo_i, hi_i = _seam(c, period)
        lo_c = c[lo_i] - period
        hi_c = c[hi_i] + period
        ext_c = np.concatenate([[lo_c], c, [hi_c]])
        ext_f = np.concatenate([np.take(f, [lo_i], axis), f, np.take(f, [hi_i], axis)], axis=axis)
        return np.take(np.gradient(ext_f, ext_c, axis=axis, edge_order=2), np.arange(1, n + 1), axis)
    return np.gradient(f, c, axis=axis, edge_order=2 if n >= 3 else 1)


def sample_grid_vectors(field: Field, w: np.ndarray, points) -> np.ndarray:
    """Node vectors ``w`` (nx, ny, nz, 3) on the field's grid, sampled trilinearly at ``points``
    as the field itself is (NaN outside)."""
    out = np.empty((points.shape[0], 3))
    status = np.empty(points.shape[0], np.int8)
    interp.sample_vectors(*field.grid.kernel_args(), w, np.ascontiguousarray(points), out, status)
    return out


def norm(v: np.ndarray) -> np.ndarray:
    """Length of each row of ``v`` (n, 3): ``np.linalg.norm(v, axis=1)`` to the bit (the same
    sum of squares in the same order), a sixth of its time (numpy reduces a 3-long axis
    slowly: ~1 ms on the viewer's 59k vertices)."""
    x, y, z = np.asarray(v).T
    return np.sqrt((x * x + y * y) + z * z)


def compute(field: Field, names, points, t, s, seeds_per_vertex) -> dict[str, np.ndarray]:
    """Attributes ``names`` at the vertices ``points`` (N, 3)."""
    check(field, names)
    cache: dict[str, np.ndarray] = {}
    scalars: dict[str, np.ndarray] = {}  # scalar fields sampled with the velocity
    first = next((n for n in names if n not in ATTRIBUTES), None)
    if first is not None and any(ATTRIBUTES.get(n) == ("velocity",) for n in names):
        # both in one pass: each vertex located once
        cache["velocity"], scalars[first], _ = field.sample_with(first, points)

    def velocity():
        if "velocity" not in cache:
            cache["velocity"] = field.sample(points)[0]
        return cache["velocity"]

    def vorticity():
        if "vorticity" not in cache:
            cache["vorticity"] = sample_grid_vectors(field, curl(field), points)
        return cache["vorticity"]

    out = {}
    for n in names:
        if n == "time":
            out[n] = t
        elif n == "arc_length":
            out[n] = s
        elif n == "speed":
            out[n] = norm(velocity())
        elif n == "velocity":
            out[n] = velocity()
        elif n == "vorticity":
            out[n] = vorticity()
        elif n == "vorticity_magnitude":
            out[n] = norm(vorticity())
        elif n == "distance_to_seed":
            out[n] = norm(points - seeds_per_vertex)
        else:
            out[n] = scalars[n] if n in scalars else field.sample_scalar(n, points)[0]
    return out
