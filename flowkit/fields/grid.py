"""Uniform and rectilinear grids of nodes (point data), with optional periodic axes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

AXES = ("x", "y", "z")


class GridError(ValueError):
    """A grid definition that cannot be used (non-monotonic coordinates, bad shape...)."""


def _check_axis(name: str, c, where: str) -> np.ndarray:
    c = np.ascontiguousarray(c, dtype=np.float64)
    if c.ndim != 1 or c.size < 2:
        raise GridError(f"{where}: coordinate '{name}' must be 1-D with at least 2 nodes, got shape {c.shape}")
    if not np.all(np.isfinite(c)):
        bad = int(np.flatnonzero(~np.isfinite(c))[0])
        raise GridError(f"{where}: coordinate '{name}' has a non-finite value {float(c[bad])!r} at index {bad}")
    d = np.diff(c)
    if np.any(d <= 0):
        i = int(np.flatnonzero(d <= 0)[0])
        kind = "repeated" if d[i] == 0 else "decreasing"
        raise GridError(
            f"{where}: coordinate '{name}' must be strictly increasing; "
            f"{kind} at index {i + 1}: {float(c[i])!r} then {float(c[i + 1])!r}"
        )
    return c


@dataclass(frozen=True, eq=False)
class Grid:
    """Node coordinates per axis.  ``period[a]`` is 0 for a bounded axis, else the period length.

    A periodic axis with period L wraps the coordinate into [x0, x0 + L).  When L is larger than
    the node span, one extra "wrap cell" joins the last node to the first node's image at x0 + L
    (the ``endpoint=False`` convention); when L equals the span, the last node is the image of the
    first.
    """

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    period: tuple[float, float, float] = (0.0, 0.0, 0.0)
    uniform: bool = field(default=False)

    @classmethod
    def from_axes(cls, x, y, z, periodic=(False, False, False), period=None, where="grid") -> Grid:
        """Rectilinear grid from 1-D coordinates; detects uniform spacing (to 1e-9 relative)."""
        axes = [_check_axis(n, c, where) for n, c in zip(AXES, (x, y, z))]
        per = _periods(axes, periodic, period, where)
        uniform = all(_is_uniform(c) for c in axes)
        return cls(axes[0], axes[1], axes[2], per, uniform)

    @classmethod
    def regular(cls, origin, spacing, shape, periodic=(False, False, False), period=None) -> Grid:
        """Uniform grid.  For periodic axes the default period is ``shape * spacing``."""
        origin = np.broadcast_to(np.asarray(origin, float), (3,))
        spacing = np.broadcast_to(np.asarray(spacing, float), (3,))
        shape = tuple(int(n) for n in np.broadcast_to(np.asarray(shape), (3,)))
        if any(s <= 0 or not np.isfinite(s) for s in spacing):
            raise GridError(f"grid: spacing must be positive and finite, got {tuple(spacing)}")
        if any(n < 2 for n in shape):
            raise GridError(f"grid: every axis needs at least 2 nodes, got shape {shape}")
        axes = [o + h * np.arange(n) for o, h, n in zip(origin, spacing, shape)]
        if period is None:
            period = tuple(n * h if p else 0.0 for n, h, p in zip(shape, spacing, periodic))
        per = _periods(axes, periodic, period, "grid")
        return cls(axes[0], axes[1], axes[2], per, True)

    # -- derived properties -------------------------------------------------------------
    @property
    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (self.x, self.y, self.z)

    @property
    def shape(self) -> tuple[int, int, int]:
        return (self.x.size, self.y.size, self.z.size)

    @property
    def n_nodes(self) -> int:
        return int(np.prod(self.shape))

    @property
    def origin(self) -> np.ndarray:
        return np.array([c[0] for c in self.axes])

    @property
    def spacing(self) -> np.ndarray | None:
        """Node spacing per axis for a uniform grid, None for a rectilinear one."""
        if not self.uniform:
            return None
        return np.array([(c[-1] - c[0]) / (c.size - 1) for c in self.axes])

    @property
    def periodic(self) -> tuple[bool, bool, bool]:
        return tuple(p > 0 for p in self.period)

    @property
    def bounds(self) -> np.ndarray:
        """(3, 2) array of [min, max] per axis; a periodic axis spans its full period."""
        b = np.array([[c[0], c[-1]] for c in self.axes])
        for a, p in enumerate(self.period):
            if p > 0:
                b[a, 1] = b[a, 0] + p
        return b

    @property
    def kind(self) -> str:
        return "uniform" if self.uniform else "rectilinear"

    @property
    def min_cell_size(self) -> float:
        return float(min(np.diff(c).min() for c in self.axes))

    def kernel_args(self):
        """The tuple numba kernels take: (x, y, z, period(3,), inv_spacing(3,) or zeros)."""
        sp = self.spacing
        inv = np.zeros(3) if sp is None else 1.0 / sp
        return (self.x, self.y, self.z, np.array(self.period, dtype=np.float64), inv)

    def node_points(self) -> np.ndarray:
        """All node positions, (nx, ny, nz, 3), 'ij' order."""
        return np.stack(np.meshgrid(*self.axes, indexing="ij"), axis=-1)

    def __eq__(self, other) -> bool:
        return (
            isinstance(other, Grid)
            and self.period == other.period
            and all(a.shape == b.shape and np.array_equal(a, b) for a, b in zip(self.axes, other.axes))
        )

    def describe(self) -> str:
        lines = [f"grid: {self.kind}, shape {self.shape} ({self.n_nodes} nodes)"]
        for name, c, (lo, hi), p in zip(AXES, self.axes, self.bounds, self.period):
            d = np.diff(c)
            sp = f"spacing {d[0]:.6g}" if self.uniform else f"spacing {d.min():.6g}..{d.max():.6g}"
            per = f", periodic (period {p:.6g})" if p > 0 else ""
            lines.append(f"  {name}: [{lo:.6g}, {hi:.6g}], {sp}{per}")
        return "\n".join(lines)


def _is_uniform(c: np.ndarray) -> bool:
    d = np.diff(c)
    return bool(np.all(np.abs(d - d.mean()) <= 1e-9 * max(abs(d.mean()), 1e-300) + 1e-12 * np.abs(c).max()))


def _periods(axes, periodic, period, where) -> tuple[float, float, float]:
    periodic = tuple(bool(p) for p in np.broadcast_to(np.asarray(periodic), (3,)))
    out = []
    for a, (c, p) in enumerate(zip(axes, periodic)):
        if not p:
            out.append(0.0)
            continue
        L = float(period[a]) if period is not None else float(c[-1] - c[0] + (c[1] - c[0]))
        span = float(c[-1] - c[0])
        if not L >= span * (1 - 1e-12):
            raise GridError(f"{where}: period {L} of axis '{AXES[a]}' is shorter than its node span {span}")
        out.append(max(L, span))
    return tuple(out)
