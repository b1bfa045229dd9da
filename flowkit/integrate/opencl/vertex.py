"""Per-vertex attributes computed in the OpenCL kernel, in the launch that writes the vertices.

A :class:`Plan` says what the kernel computes for the requested names (the template flags
``attrs``/``scalars``), which field data it needs on the device (the vector buffer, scalar
fields, the node curl grid of the vorticity) and how the per-attribute outputs, read back
into the columns of ``out_par`` after (t, s), become ``Lines.point_data``.  The formulas are
those of ``flowkit.integrate.attributes``: trilinear samples of the field and its scalars, the
curl of the node field (np.gradient's stencils, :func:`stencils`) trilinearly interpolated,
Euclidean norms; ``time`` and ``arc_length`` are the kernel's own t and s.  The node curl is
computed on the device once per field (kernel ``curl_nodes``) from the field buffer and the
stencil table of :func:`stencils`, so the vorticity uploads kilobytes, not a curl grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...fields import curl as _curl
from .. import attributes as _attributes

# attributes with code in the kernel, in the order of the template's outputs; components each
KERNEL_ATTRS = {"speed": 1, "velocity": 3, "vorticity": 3, "vorticity_magnitude": 1,
                "distance_to_seed": 1}
FROM_PARAMS = ("time", "arc_length")  # the kernel's t and s, always written


@dataclass(frozen=True)
class Plan:
    names: tuple  # requested, in the caller's order
    attrs: tuple  # KERNEL_ATTRS requested, in KERNEL_ATTRS order (template flag)
    scalars: tuple  # scalar field names requested, in order (their count is a template flag)

    @classmethod
    def of(cls, field, names) -> Plan:
        names = tuple(names)
        _attributes.check(field, names)
        attrs = tuple(a for a in KERNEL_ATTRS if a in names)
        scalars = tuple(dict.fromkeys(n for n in names if n not in KERNEL_ATTRS
                                      and n not in FROM_PARAMS))
        return cls(names, attrs, scalars)

    @property
    def needs_velocity(self) -> bool:
        return "speed" in self.attrs or "velocity" in self.attrs

    @property
    def needs_vector(self) -> bool:  # exact node values: the velocity, or the curl's stencils
        return self.needs_velocity or self.needs_stencils

    @property
    def needs_stencils(self) -> bool:
        return "vorticity" in self.attrs or "vorticity_magnitude" in self.attrs

    def outputs(self) -> list[tuple[str, int]]:
        """(name, components) of the kernel's attribute output buffers, in argument order."""
        return [(a, KERNEL_ATTRS[a]) for a in self.attrs] + [(s, 1) for s in self.scalars]

    @property
    def n_columns(self) -> int:
        return sum(c for _, c in self.outputs())

    def point_data(self, t, s, columns) -> dict[str, np.ndarray]:
        """``point_data`` from the vertices' t, s and attribute columns (N, n_columns)."""
        cols = {}
        at = 0
        for name, comps in self.outputs():
            cols[name] = columns[:, at] if comps == 1 else columns[:, at:at + comps]
            at += comps
        out = {}
        for n in self.names:
            v = {"time": t, "arc_length": s}[n] if n in FROM_PARAMS else cols[n]
            out[n] = np.ascontiguousarray(v, dtype=np.float64)
        return out


def stencils(grid, block: int = 256) -> tuple[np.ndarray, np.ndarray, int]:
    """The derivative stencil of every node on every axis, as ``fields.curl`` applies it.

    Returns (nodes (sum n, K) int32, weights (sum n, K) float64, K): row ``offset(axis) + i``
    lists the nodes (along that axis; -1 = unused) whose values enter d/dx_axis at node i, and
    their weights.  Taken from ``fields.curl.gradient`` itself, applied to unit vectors (the weights)
    and to NaN unit vectors (which nodes enter, also with weight 0, so that NaN data poisons the
    same derivatives as on the host).
    """
    rows_all, cols_all, w_all = [], [], []
    base = 0
    for ax in range(3):
        c = grid.axes[ax]
        n = c.size
        for lo in range(0, n, block):
            m = min(n, lo + block) - lo
            e = np.zeros((n, m))
            e[lo + np.arange(m), np.arange(m)] = 1.0
            w = _curl.gradient(e, c, float(grid.period[ax]), 0)
            hit = np.isnan(_curl.gradient(np.where(e > 0, np.nan, 0.0), c,
                                              float(grid.period[ax]), 0))
            r, q = np.nonzero(hit)
            rows_all.append(base + r)
            cols_all.append(lo + q)
            w_all.append(w[r, q])
        base += n
    rows, cols, w = (np.concatenate(a) for a in (rows_all, cols_all, w_all))
    order = np.lexsort((cols, rows))
    rows, cols, w = rows[order], cols[order], w[order]
    count = np.bincount(rows, minlength=base)
    k = int(count.max())
    slot = np.arange(rows.size) - (np.cumsum(count) - count)[rows]
    nodes = np.full((base, k), -1, np.int32)
    weights = np.zeros((base, k))
    nodes[rows, slot] = cols
    weights[rows, slot] = w
    return nodes, weights, k


def fallbacks(grid) -> tuple[np.ndarray, np.ndarray]:
    """``fields.curl.fallback_stencils`` of the three axes, rows as in :func:`stencils`:
    (nodes (sum n, 4, 3) int32, weights (sum n, 4, 3))."""
    parts = [_curl.fallback_stencils(grid.axes[ax], grid.period[ax]) for ax in range(3)]
    return (np.ascontiguousarray(np.concatenate([p[0] for p in parts])),
            np.ascontiguousarray(np.concatenate([p[1] for p in parts])))
