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


def check(field: Field, names) -> None:
    """Raise a clear error for a name that is neither a known attribute nor a scalar field."""
    for n in names:
        if n not in ATTRIBUTES and n not in field.scalars:
            have = ", ".join(list(ATTRIBUTES) + sorted(field.scalars))
            raise KeyError(f"{field.source}: unknown attribute '{n}' (available: {have})")


def curl(field: Field) -> np.ndarray:
    """Curl of the node vector field, (nx, ny, nz, 3): second-order differences on the actual
    (possibly non-uniform) node coordinates, one-sided at bounded ends, wrapped on periodic axes."""
    g = field.grid
    v = field.vector
    d = [[_deriv(v[..., comp], g.axes[ax], g.period[ax], ax) for ax in range(3)] for comp in range(3)]
    # d[comp][axis] = ∂v_comp/∂x_axis
    return np.stack([d[2][1] - d[1][2], d[0][2] - d[2][0], d[1][0] - d[0][1]], axis=-1)


def _deriv(f: np.ndarray, c: np.ndarray, period: float, axis: int) -> np.ndarray:
    n = c.size
    if period > 0 and n >= 3:
        # wrap: neighbours across the period join the stencil
        wrap_cell = c[0] + period - c[-1] > 0
        lo_i, hi_i = (n - 1, 0) if wrap_cell else (n - 2, 1)
        lo_c = c[lo_i] - period
        hi_c = c[hi_i] + period
        ext_c = np.concatenate([[lo_c], c, [hi_c]])
        ext_f = np.concatenate([np.take(f, [lo_i], axis), f, np.take(f, [hi_i], axis)], axis=axis)
        return np.take(np.gradient(ext_f, ext_c, axis=axis, edge_order=2), np.arange(1, n + 1), axis)
    return np.gradient(f, c, axis=axis, edge_order=2 if n >= 3 else 1)


def compute(field: Field, names, points, t, s, seeds_per_vertex) -> dict[str, np.ndarray]:
    """Attributes ``names`` at the vertices ``points`` (N, 3)."""
    check(field, names)
    cache: dict[str, np.ndarray] = {}

    def velocity():
        if "velocity" not in cache:
            cache["velocity"] = field.sample(points)[0]
        return cache["velocity"]

    def vorticity():
        if "vorticity" not in cache:
            w = curl(field)
            out = np.empty((points.shape[0], 3))
            status = np.empty(points.shape[0], np.int8)
            interp.sample_vectors(*field.grid.kernel_args(), w, np.ascontiguousarray(points), out, status)
            cache["vorticity"] = out
        return cache["vorticity"]

    out = {}
    for n in names:
        if n == "time":
            out[n] = t
        elif n == "arc_length":
            out[n] = s
        elif n == "speed":
            out[n] = np.linalg.norm(velocity(), axis=1)
        elif n == "velocity":
            out[n] = velocity()
        elif n == "vorticity":
            out[n] = vorticity()
        elif n == "vorticity_magnitude":
            out[n] = np.linalg.norm(vorticity(), axis=1)
        elif n == "distance_to_seed":
            out[n] = np.linalg.norm(points - seeds_per_vertex, axis=1)
        else:
            out[n] = field.sample_scalar(n, points)[0]
    return out
