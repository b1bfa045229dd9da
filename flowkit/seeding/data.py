"""Seeds drawn from the data: ``density`` (probability proportional to a non-negative field) and
``where`` (uniform where an expression of scalar fields holds).

Both work cell by cell on the field's own trilinear interpolant, so the draw is exact, not a
histogram: ``density`` draws points under an envelope (each cell's largest corner weight times its
volume) and keeps each with probability interpolated weight / largest corner weight, which
gives the point density of the interpolant itself: a cell gets seeds in proportion to the
integral of the interpolated weight over it (the mean of its 8 corners times its volume).  ``where`` keeps only the cells whose corner ranges can satisfy the
expression (an interval test, see flowkit.seeding.expr), picks among them by volume and keeps the
points where the interpolated values satisfy it.  Cells touching a non-finite vector or weight
never get seeds.  Results depend only on the random seed.
"""

from __future__ import annotations

import numpy as np

from ..fields import curl as _curl
from ..fields.field import Field
from .errors import SeedError
from .expr import Expression, ExpressionError

DERIVED = ("speed", "vorticity_magnitude")  # scalars computed from the vector field
MAX_DRAWS = 200  # rejection draws per requested seed before giving up


def node_values(field: Field, name: str) -> np.ndarray:
    """Node array of ``name``: a scalar field, speed, vorticity_magnitude (or vorticity), or
    grad(SCALAR) (the magnitude of its gradient, second-order differences)."""
    if name == "speed":
        return field.speed()
    if name in ("vorticity_magnitude", "vorticity"):
        return np.linalg.norm(_curl.curl(field), axis=-1)
    if name.startswith("grad(") and name.endswith(")"):
        s = field.scalar(_known(field, name[5:-1].strip()))
        g = field.grid
        parts = [_curl.gradient(s, g.axes[a], g.period[a], a) for a in range(3)]
        return np.sqrt(sum(p * p for p in parts))
    return field.scalar(_known(field, name))


def _known(field: Field, name: str) -> str:
    if name not in field.scalars:
        have = ", ".join([*DERIVED, *sorted(field.scalars),
                          *(f"grad({s})" for s in sorted(field.scalars))])
        raise SeedError(f"{field.source}: no attribute '{name}' to seed from (available: {have})")
    return name


# -- cells ------------------------------------------------------------------------------------
class _Cells:
    """Per axis, the cells of a grid: their corner node indices, lower coordinate and width (a
    periodic axis whose last node does not repeat the first has a wrap-around cell)."""

    def __init__(self, grid):
        self.i0, self.i1, self.lo, self.w = [], [], [], []
        for c, period in zip(grid.axes, grid.period):
            n = c.size
            if period > 0 and c[0] + period - c[-1] > 0:
                i0 = np.arange(n)
                ends = np.append(c, c[0] + period)
            else:
                i0 = np.arange(n - 1)
                ends = c
            self.i0.append(i0)
            self.i1.append((i0 + 1) % n)
            self.lo.append(ends[:-1])
            self.w.append(np.diff(ends))
        self.shape = tuple(a.size for a in self.i0)

    def reduce(self, a: np.ndarray, op) -> np.ndarray:
        """op over each cell's 8 corner values, (cx, cy, cz) (separable: axis by axis)."""
        for ax in range(3):
            a = op(np.take(a, self.i0[ax], ax), np.take(a, self.i1[ax], ax))
        return a

    def volume(self) -> np.ndarray:
        return self.w[0][:, None, None] * self.w[1][None, :, None] * self.w[2][None, None, :]

    def valid(self, field: Field) -> np.ndarray:
        """Cells whose 8 corner vectors are finite (where a line can be traced)."""
        ok = np.all(np.isfinite(field.vector), axis=-1)
        return self.reduce(ok, np.logical_and)

    def draw(self, cells: np.ndarray, rng) -> tuple[np.ndarray, np.ndarray]:
        """A uniform point in each flat cell index: (points (m, 3), local coordinates (m, 3))."""
        idx = np.unravel_index(cells, self.shape)
        u = rng.random((cells.size, 3))
        p = np.stack([self.lo[a][idx[a]] + u[:, a] * self.w[a][idx[a]] for a in range(3)], 1)
        return p, u

    def interpolate(self, a: np.ndarray, cells: np.ndarray, u: np.ndarray) -> np.ndarray:
        """Trilinear value of node array ``a`` at local coordinates ``u`` in flat ``cells``."""
        idx = np.unravel_index(cells, self.shape)
        out = np.zeros(cells.size)
        for bx in (0, 1):
            ix = (self.i1 if bx else self.i0)[0][idx[0]]
            wx = u[:, 0] if bx else 1.0 - u[:, 0]
            for by in (0, 1):
                iy = (self.i1 if by else self.i0)[1][idx[1]]
                wy = u[:, 1] if by else 1.0 - u[:, 1]
                for bz in (0, 1):
                    iz = (self.i1 if bz else self.i0)[2][idx[2]]
                    wz = u[:, 2] if bz else 1.0 - u[:, 2]
                    out += wx * wy * wz * a[ix, iy, iz]
        return out


def _need(field: Field, n: int) -> None:
    if not isinstance(field, Field):
        raise SeedError(f"seeds from the data need a gridded Field, got {type(field).__name__}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise SeedError(f"number of seeds must be a positive integer, got {n!r}")


# -- density ----------------------------------------------------------------------------------
def density(field: Field, n: int, attribute: str, seed: int = 0) -> np.ndarray:
    """n seeds with probability density proportional to the interpolated ``attribute``."""
    _need(field, n)
    w = node_values(field, attribute)
    finite = np.isfinite(w)
    if np.any(w[finite] < 0):
        k = np.unravel_index(np.flatnonzero(finite & (w < 0))[0], w.shape)
        raise SeedError(f"{field.source}: density weights must be non-negative; '{attribute}' is "
                        f"{w[k]:.6g} at node {tuple(int(i) for i in k)} (min {w[finite].min():.6g})")
    cells = _Cells(field.grid)
    good = cells.valid(field) & cells.reduce(finite, np.logical_and)
    wz = np.where(finite, w, 0.0)
    peak = np.where(good, cells.reduce(wz, np.maximum), 0.0).ravel()
    # rejection sampling under the envelope peak x volume: a cell is drawn with probability
    # proportional to its envelope and its point kept with probability f / peak, so a kept
    # point lies in a cell with probability proportional to its integral of f
    envelope = peak * cells.volume().ravel()
    total = envelope.sum()
    if not total > 0:
        raise SeedError(f"{field.source}: '{attribute}' is zero (or not finite) in every valid "
                        "cell: nothing to weigh seeds by")
    rng = np.random.default_rng(seed)
    prob = envelope / total
    kept, have = [], 0
    for _ in range(MAX_DRAWS):
        m = 2 * (n - have) + 16
        c = rng.choice(prob.size, size=m, p=prob)
        p, u = cells.draw(c, rng)
        ok = rng.random(m) * peak[c] < cells.interpolate(wz, c, u)
        kept.append(p[ok])
        have += int(ok.sum())
        if have >= n:
            break
    if have < n:  # cannot happen unless the weights are degenerate: say so rather than return less
        raise SeedError(f"{field.source}: only {have} of {n} density seeds accepted")
    return np.ascontiguousarray(np.concatenate(kept)[:n])


# -- where ------------------------------------------------------------------------------------
def where(field: Field, text: str, n: int, seed: int = 0) -> np.ndarray:
    """n seeds uniform in the part of the domain where the expression ``text`` holds."""
    _need(field, n)
    try:
        expr = Expression(text, allowed_names=[*field.scalars, *DERIVED])
    except ExpressionError as e:
        raise SeedError(f"{field.source}: {e}") from None
    values = {name: node_values(field, name) for name in sorted(expr.names)}
    cells = _Cells(field.grid)
    lo = {k: cells.reduce(v, np.fmin) for k, v in values.items()}
    hi = {k: cells.reduce(v, np.fmax) for k, v in values.items()}
    finite = {k: cells.reduce(np.isfinite(v), np.logical_and) for k, v in values.items()}
    _, maybe = expr.evaluate_interval(lo, hi)
    good = cells.valid(field) & np.asarray(maybe, bool)
    for f in finite.values():
        good &= f
    vol = np.where(good, cells.volume(), 0.0).ravel()
    if not vol.sum() > 0:
        ranges = "; ".join(f"{k} in [{np.nanmin(v):.6g}, {np.nanmax(v):.6g}]"
                           for k, v in values.items())
        raise SeedError(f"{field.source}: '{text}' holds in no valid cell ({ranges or 'constant'})")
    rng = np.random.default_rng(seed)
    prob = vol / vol.sum()
    kept, have, drawn = [], 0, 0
    while have < n and drawn < MAX_DRAWS * n + 10_000:
        m = 2 * (n - have) + 16
        c = rng.choice(prob.size, size=m, p=prob)
        p, u = cells.draw(c, rng)
        ok = expr.evaluate({k: cells.interpolate(v, c, u) for k, v in values.items()})
        kept.append(p[ok])
        have += int(ok.sum())
        drawn += m
    if have < n:
        raise SeedError(f"{field.source}: only {have} of {n} points satisfied '{text}' after "
                        f"{drawn} draws in the cells where it can hold")
    return np.ascontiguousarray(np.concatenate(kept)[:n])
