"""Analytic velocity fields with exact velocity gradients and, where known, exact trajectories.

They are the references of the project: tests compare traced lines with ``trajectory``,
benchmarks sample them onto grids with ``to_field``, the renderer's demos draw them.

API (every field is an ``AnalyticField``; all arrays float64, points are (n, 3)):

- ``name``, ``params()`` (dict), ``describe()`` -> ``"abc(A=1.73205, B=1.41421, C=1)"``
- ``velocity(points, t=0.0)`` -> (n, 3).  Steady fields ignore ``t``; the unsteady one
  (``UnsteadyRotation``, ``unsteady = True``) takes ``t`` as a scalar or one time per point (n,).
- ``jacobian(points, t=0.0)`` -> (n, 3, 3) with ``J[:, i, j] = d u_i / d x_j`` (analytic).
- ``vorticity(points, t=0.0)`` (curl, from the jacobian), ``divergence(points, t=0.0)``.
- ``scalars(points, t=0.0)`` -> ``{name: (n,)}``: named scalar fields, empty unless listed below.
- ``default_bounds`` (3, 2) [min, max] per axis; ``period`` (3 floats, 0 = not periodic) and
  ``periodic`` (3 bools).
- ``has_exact``; ``trajectory(p0, t, t0=0.0)``: position at time ``t`` of the particle that is at
  ``p0`` (n, 3) at time ``t0``; ``t`` scalar -> (n, 3), ``t`` of shape (m,) -> (m, n, 3);
  negative ``t - t0`` runs backwards.  Raises ``NoExactSolution`` when ``has_exact`` is False.
- ``to_field(shape=64, bounds=None, grid=None, periodic=None, t=0.0)`` -> ``Field`` with the exact
  values at the nodes (vector ``U`` plus the scalars).  Periodic axes: see ``to_field``.
- ``to_series(times, ...)`` -> ``[(time, Field), ...]`` snapshots (for the unsteady field).

Fields (``make(name, **params)`` builds one by name; ``FIELDS`` lists the names):

=====================  =========================================================  exact  div-free
``UniformFlow``        u = U; scalar ``T`` = g . x (linear: trilinear-exact)       yes    yes
``SolidBodyRotation``  u = omega k x (x - c); scalar ``p`` = |u|^2 / 2            yes    yes
``LinearField``        u = A (x - x0) + b; by matrix exponential; ``sink``,        yes    if tr A=0
                       ``source``, ``saddle``, ``centre``, ``spiral``, ``stiff``
``ABCFlow``            Arnold-Beltrami-Childress, period 2 pi; ``p`` = -|u|^2 / 2  no     yes
``TaylorGreen``        steady 3-D Taylor-Green cells, period 2 pi; pressure ``p``  no     yes
``HillVortex``         Hill's spherical vortex in its own frame; Stokes ``psi``    no     yes
``BurgersVortex``      steady Burgers vortex (circulation, strain, viscosity)     yes    yes
``Lorenz``             the Lorenz system read as a velocity field (chaotic)       no     no
``UnsteadyRotation``   rotation at rate omega0 + omega1 t (the unsteady field)    yes    yes
=====================  =========================================================  =====  ========

The ``p`` scalars are the pressures (unit density) that balance the steady Euler equations
(rotation, ABC: grad p = -(u . grad) u) or the pressure Poisson equation (Taylor-Green:
lap p = -tr(J J)); Hill's ``psi`` is constant along streamlines; tests check those identities.

Example, the benchmark's grid (three periods of ABC at 128 nodes per period, periodic):
``ABCFlow().to_field(384, bounds=[[0, 6 * np.pi]] * 3)``; pass ``periodic=False`` for a bounded
box whose lines leave the domain.  A field's ``source`` is ``"analytic " + describe()``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np
from scipy import linalg, special

from .field import Field, _points
from .grid import Grid

TWO_PI = 2.0 * np.pi
_CHUNK = 1 << 20  # nodes sampled per call in to_field: bounds the temporaries of large grids


class NoExactSolution(ValueError):
    """``trajectory`` was asked of a field with no exact solution (``has_exact`` is False)."""


def _vec3(value, what: str) -> np.ndarray:
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{what} must be 3 finite numbers, got {value!r}")
    return v


def _fmt(v) -> str:
    if isinstance(v, str):
        return v
    a = np.asarray(v, dtype=float)
    if a.ndim == 0:
        return f"{float(a) + 0.0:.6g}"  # + 0.0 prints -0.0 as 0
    return "[" + ", ".join(_fmt(x) for x in a) + "]"


def _skew(w: np.ndarray) -> np.ndarray:
    """Matrix K with K v = w x v (w of shape (..., 3) -> (..., 3, 3))."""
    K = np.zeros(w.shape[:-1] + (3, 3))
    K[..., 0, 1], K[..., 0, 2] = -w[..., 2], w[..., 1]
    K[..., 1, 0], K[..., 1, 2] = w[..., 2], -w[..., 0]
    K[..., 2, 0], K[..., 2, 1] = -w[..., 1], w[..., 0]
    return K


def _rotate(r: np.ndarray, k: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues: rotate vectors r (n, 3) about unit axis k by angle (broadcast (m, n) or (n,))."""
    c = np.cos(angle)[..., None]
    s = np.sin(angle)[..., None]
    kr = (r @ k)[:, None] * k
    return r * c + np.cross(k, r) * s + kr * (1.0 - c)


class AnalyticField:
    """Base of the analytic fields; subclasses define ``_velocity`` and ``_jacobian``.

    Subclasses are dataclasses whose fields are the parameters (used by ``describe``); they may
    override ``_scalars`` (named scalar fields), ``_trajectory`` (setting ``has_exact``) and
    ``default_bounds``/``period``.
    """

    name = "analytic"
    has_exact = False
    unsteady = False
    period = (0.0, 0.0, 0.0)

    # -- description --------------------------------------------------------------------
    def params(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self) if f.repr}

    def describe(self) -> str:
        return f"{self.name}(" + ", ".join(f"{k}={_fmt(v)}" for k, v in self.params().items()) + ")"

    def __repr__(self) -> str:
        return self.describe()

    @property
    def default_bounds(self) -> np.ndarray:
        return np.array([[-1.0, 1.0]] * 3)

    @property
    def periodic(self) -> tuple[bool, bool, bool]:
        return tuple(p > 0 for p in self.period)

    # -- evaluation ---------------------------------------------------------------------
    def velocity(self, points, t=0.0) -> np.ndarray:
        """Velocity (n, 3) at points (n, 3) (a single (3,) point gives (1, 3))."""
        p = _points(points)
        return self._velocity(p, self._time(t, p.shape[0]))

    def jacobian(self, points, t=0.0) -> np.ndarray:
        """Exact velocity gradient (n, 3, 3): ``J[:, i, j] = d u_i / d x_j``."""
        p = _points(points)
        return self._jacobian(p, self._time(t, p.shape[0]))

    def vorticity(self, points, t=0.0) -> np.ndarray:
        """Curl of the velocity (n, 3), from the exact jacobian."""
        J = self.jacobian(points, t)
        return np.stack([J[:, 2, 1] - J[:, 1, 2], J[:, 0, 2] - J[:, 2, 0], J[:, 1, 0] - J[:, 0, 1]], -1)

    def divergence(self, points, t=0.0) -> np.ndarray:
        return np.trace(self.jacobian(points, t), axis1=1, axis2=2)

    def scalars(self, points, t=0.0) -> dict[str, np.ndarray]:
        """Named scalar fields at points: ``{name: (n,)}`` (empty for most fields)."""
        p = _points(points)
        return self._scalars(p, self._time(t, p.shape[0]))

    def trajectory(self, p0, t, t0=0.0) -> np.ndarray:
        """Exact position at time(s) ``t`` of the particles at ``p0`` (n, 3) at time ``t0``.

        ``t`` scalar -> (n, 3); ``t`` 1-D (m,) -> (m, n, 3).
        """
        if not self.has_exact:
            raise NoExactSolution(
                f"{self.describe()} has no exact trajectory (has_exact is False); "
                "use a tightly integrated reference instead"
            )
        p0 = _points(p0)
        tt = np.asarray(t, dtype=np.float64)
        if tt.ndim > 1 or not np.all(np.isfinite(tt)) or not np.isfinite(t0):
            raise ValueError(f"trajectory: t must be a finite scalar or 1-D array, got shape {tt.shape}")
        out = self._trajectory(p0, np.atleast_1d(tt), float(t0))
        return out[0] if tt.ndim == 0 else out

    # -- sampling onto grids ------------------------------------------------------------
    def to_field(self, shape=None, bounds=None, grid=None, periodic=None, t=0.0) -> Field:
        """Sample onto a grid: the exact velocity (and scalars) at every node.

        Either ``grid`` (any Grid, e.g. rectilinear) or ``shape`` (int or (nx, ny, nz), default
        64) with ``bounds`` ((3, 2), default ``default_bounds``) for a uniform grid.  On a uniform
        grid an axis is periodic when the field is periodic along it and the bounds span a whole
        number of periods (``periodic=None``, the default) or when ``periodic`` says so (bool or 3
        bools; asking for a period the field does not have is an error).  A periodic axis has
        ``n`` nodes ``lo + i * span / n`` (the last node is not repeated); a bounded one has
        ``n`` nodes from ``lo`` to ``hi`` inclusive.
        """
        if grid is not None:
            if shape is not None or bounds is not None or periodic is not None:
                raise ValueError("to_field: give either grid or shape/bounds/periodic, not both")
            for a, L in enumerate(grid.period):
                if L > 0 and not self._is_period(a, L):
                    raise ValueError(
                        f"to_field: grid axis {'xyz'[a]} is periodic with period {L:g}, "
                        f"but {self.describe()} is not (its periods: {_fmt(self.period)})"
                    )
        else:
            grid = self._grid(64 if shape is None else shape, bounds, periodic)
        t = self._time(t)
        vec = np.empty(grid.shape + (3,))
        names = list(self._scalars(np.zeros((1, 3)), t))
        sca = {k: np.empty(grid.shape) for k in names}
        nx, ny, nz = grid.shape
        step = max(1, _CHUNK // (ny * nz))
        for i in range(0, nx, step):
            x = grid.x[i : i + step]
            pts = np.stack(np.meshgrid(x, grid.y, grid.z, indexing="ij"), -1).reshape(-1, 3)
            vec[i : i + step] = self._velocity(pts, t).reshape(x.size, ny, nz, 3)
            for k, v in self._scalars(pts, t).items():
                sca[k][i : i + step] = v.reshape(x.size, ny, nz)
        src = f"analytic {self.describe()}" + (f" at t={t:g}" if self.unsteady else "")
        return Field(
            grid, vec, sca, vector_name="U", source=src,
            time=float(t) if self.unsteady else None,
            notes=["exact analytic values at the nodes"],
        )

    def to_series(self, times, **kwargs) -> list[tuple[float, Field]]:
        """Snapshots ``[(t, to_field(t=t, **kwargs)), ...]``, e.g. for pathlines."""
        return [(float(t), self.to_field(t=float(t), **kwargs)) for t in np.atleast_1d(times)]

    def _is_period(self, axis: int, L: float) -> bool:
        p = self.period[axis]
        if p <= 0:
            return False
        k = round(L / p)
        return k >= 1 and abs(L - k * p) <= 1e-9 * L

    def _grid(self, shape, bounds, periodic) -> Grid:
        shape = np.broadcast_to(np.asarray(shape), (3,))
        if not np.issubdtype(shape.dtype, np.integer) or np.any(shape < 2):
            raise ValueError(f"to_field: shape must be integers >= 2, got {shape.tolist()}")
        b = self.default_bounds if bounds is None else np.asarray(bounds, dtype=np.float64)
        if b.shape != (3, 2) or not np.all(np.isfinite(b)) or np.any(b[:, 1] <= b[:, 0]):
            raise ValueError(f"to_field: bounds must be (3, 2) finite [min, max] rows, got {b.tolist()}")
        span = b[:, 1] - b[:, 0]
        if periodic is None:
            per = [self._is_period(a, span[a]) for a in range(3)]
        else:
            per = [bool(p) for p in np.broadcast_to(np.asarray(periodic), (3,))]
            for a in range(3):
                if per[a] and not self._is_period(a, span[a]):
                    raise ValueError(
                        f"to_field: axis {'xyz'[a]} cannot be periodic over span {span[a]:g}; "
                        f"{self.describe()} has periods {_fmt(self.period)} (0 = none)"
                    )
        n = shape.astype(int)
        spacing = np.where(per, span / n, span / (n - 1))
        return Grid.regular(b[:, 0], spacing, n, periodic=per, period=np.where(per, span, 0.0))

    # -- subclass hooks -----------------------------------------------------------------
    def _time(self, t, n=None):
        """The time argument: ignored (0.0) by steady fields; a scalar, or (n,) per point."""
        if not self.unsteady:
            return 0.0
        tt = np.asarray(t, dtype=np.float64)
        if tt.ndim == 0:
            return float(tt)
        if n is None or tt.shape != (n,):
            raise ValueError(f"{self.name}: t must be a scalar or one time per point ({n},), "
                             f"got shape {tt.shape}")
        return tt

    def _scalars(self, p, t) -> dict[str, np.ndarray]:
        return {}

    def _velocity(self, p, t):  # pragma: no cover - every subclass defines it
        raise TypeError(f"{type(self).__name__} defines no velocity")

    def _jacobian(self, p, t):  # pragma: no cover - every subclass defines it
        raise TypeError(f"{type(self).__name__} defines no jacobian")


# ---------------------------------------------------------------------------------------
@dataclass(eq=False, repr=False)
class UniformFlow(AnalyticField):
    """u = U everywhere.  Scalar ``T`` = T_gradient . x is linear, so trilinear sampling of it is
    exact and a line's ``T`` attribute has the exact reference ``T(p0 + U t)``."""

    U: tuple = (1.0, 0.0, 0.0)
    T_gradient: tuple = (1.0, 0.5, 0.25)
    name = "uniform"
    has_exact = True

    def __post_init__(self):
        self.U = _vec3(self.U, "uniform: U")
        self.T_gradient = _vec3(self.T_gradient, "uniform: T_gradient")

    @property
    def default_bounds(self):
        return np.array([[0.0, 1.0]] * 3)

    def _velocity(self, p, t):
        return np.broadcast_to(self.U, p.shape).copy()

    def _jacobian(self, p, t):
        return np.zeros((p.shape[0], 3, 3))

    def _scalars(self, p, t):
        return {"T": p @ self.T_gradient}

    def _trajectory(self, p0, t, t0):
        return p0[None] + (t - t0)[:, None, None] * self.U


class _Rotation(AnalyticField):
    """Rotation about the unit ``axis`` through ``centre`` at rate ``_rate(t)``."""

    has_exact = True

    def __post_init__(self):
        a = _vec3(self.axis, f"{self.name}: axis")
        if not np.linalg.norm(a) > 0:
            raise ValueError(f"{self.name}: axis must be a nonzero vector, got {self.axis!r}")
        self.axis = a / np.linalg.norm(a)
        self.centre = _vec3(self.centre, f"{self.name}: centre")

    def _velocity(self, p, t):
        return np.asarray(self._rate(t))[..., None] * np.cross(self.axis, p - self.centre)

    def _jacobian(self, p, t):
        w = np.asarray(self._rate(t))[..., None] * self.axis
        return np.broadcast_to(_skew(w), (p.shape[0], 3, 3)).copy()

    def _trajectory(self, p0, t, t0):
        angle = np.broadcast_to(self._angle(t, t0)[:, None], (t.size, p0.shape[0]))
        return self.centre + _rotate(p0 - self.centre, self.axis, angle)


@dataclass(eq=False, repr=False)
class SolidBodyRotation(_Rotation):
    """u = omega * k x (x - centre), k the unit ``axis``: circles at angular speed omega.
    Scalar ``p`` = |u|^2 / 2 (the centrifugal pressure)."""

    omega: float = 1.0
    axis: tuple = (0.0, 0.0, 1.0)
    centre: tuple = (0.0, 0.0, 0.0)
    name = "rotation"

    def _rate(self, t):
        return self.omega

    def _angle(self, t, t0):
        return self.omega * (t - t0)

    def _scalars(self, p, t):
        u = self._velocity(p, t)
        return {"p": 0.5 * np.einsum("ij,ij->i", u, u)}


@dataclass(eq=False, repr=False)
class UnsteadyRotation(_Rotation):
    """THE unsteady field (``unsteady = True``): rotation whose rate changes linearly in time,
    u(x, t) = (omega0 + omega1 t) k x (x - centre).  Exact: the angle turned from t0 to t is
    omega0 (t - t0) + omega1 (t^2 - t0^2) / 2.  ``velocity``/``jacobian`` take ``t`` (a scalar or
    one time per point); ``to_field(t=...)`` samples one snapshot, ``to_series`` several."""

    omega0: float = 1.0
    omega1: float = 0.5
    axis: tuple = (0.0, 0.0, 1.0)
    centre: tuple = (0.0, 0.0, 0.0)
    name = "unsteady_rotation"
    unsteady = True

    def _rate(self, t):
        return self.omega0 + self.omega1 * np.asarray(t)

    def _angle(self, t, t0):
        return self.omega0 * (t - t0) + 0.5 * self.omega1 * (t * t - t0 * t0)


@dataclass(eq=False, repr=False)
class LinearField(AnalyticField):
    """u = A (x - x0) + drift.  Exact by the matrix exponential of the augmented system
    d/dt [x; 1] = [[A, drift - A x0], [0, 0]] [x; 1] (also for singular A).

    Named constructors: ``sink``, ``source``, ``saddle``, ``centre``,
    ``spiral`` and ``stiff`` (see each).
    """

    A: np.ndarray = field(default_factory=lambda: -np.eye(3))
    x0: tuple = (0.0, 0.0, 0.0)
    drift: tuple = (0.0, 0.0, 0.0)
    kind: str = "linear"
    bounds: np.ndarray | None = field(default=None, repr=False)
    name = "linear"
    has_exact = True

    def __post_init__(self):
        A = np.asarray(self.A, dtype=np.float64)
        if A.shape != (3, 3) or not np.all(np.isfinite(A)):
            raise ValueError(f"linear: A must be a finite 3x3 matrix, got {np.asarray(self.A).tolist()}")
        self.A = A
        self.x0 = _vec3(self.x0, "linear: x0")
        self.drift = _vec3(self.drift, "linear: drift")
        M = np.zeros((4, 4))
        M[:3, :3] = A
        M[:3, 3] = self.drift - A @ self.x0
        self._M = M

    def params(self):
        return {"kind": self.kind, "A": self.A, "x0": self.x0, "drift": self.drift}

    @property
    def default_bounds(self):
        return np.array([[-1.0, 1.0]] * 3) if self.bounds is None else np.asarray(self.bounds, float)

    def _velocity(self, p, t):
        return (p - self.x0) @ self.A.T + self.drift

    def _jacobian(self, p, t):
        return np.broadcast_to(self.A, (p.shape[0], 3, 3)).copy()

    def _trajectory(self, p0, t, t0):
        out = np.empty((t.size,) + p0.shape)
        for m, tm in enumerate(t):
            E = linalg.expm(self._M * (tm - t0))
            out[m] = p0 @ E[:3, :3].T + E[:3, 3]
        return out

    # -- named constructors -------------------------------------------------------------
    @classmethod
    def sink(cls, rate=1.0, centre=(0, 0, 0)):
        """u = -rate (x - c): straight lines into the centre, eigenvalue -rate (triple)."""
        return cls(-abs(rate) * np.eye(3), centre, kind="sink")

    @classmethod
    def source(cls, rate=1.0, centre=(0, 0, 0)):
        """u = rate (x - c): straight lines out of the centre."""
        return cls(abs(rate) * np.eye(3), centre, kind="source")

    @classmethod
    def saddle(cls, rate=1.0, centre=(0, 0, 0)):
        """Planar saddle: u = rate * (x, -y, 0) about c; z is neutral.  Divergence-free."""
        return cls(np.diag([rate, -rate, 0.0]), centre, kind="saddle")

    @classmethod
    def centre(cls, omega=1.0, centre=(0, 0, 0)):
        """Centre: circles in planes z = const at angular speed omega (eigenvalues +-i omega, 0)."""
        return cls(_skew(np.array([0.0, 0.0, omega])), centre, kind="centre")

    @classmethod
    def spiral(cls, omega=1.0, rate=-0.1, axial=0.0, centre=(0, 0, 0)):
        """Spiral in z = const planes: eigenvalues rate +- i omega, and ``axial`` along z.
        rate < 0: spiral sink; rate > 0: spiral source."""
        A = _skew(np.array([0.0, 0.0, omega])) + np.diag([rate, rate, axial])
        return cls(A, centre, kind="spiral_sink" if rate < 0 else "spiral_source")

    @classmethod
    def stiff(cls, slow=-1.0, fast=-1.0e4, drift=1.0):
        """Stiff test field: in the xy-plane eigenvalues ``slow`` and ``fast`` along the
        diagonals (1, 1, 0)/sqrt2 and (1, -1, 0)/sqrt2 (so both coordinates carry both modes);
        z is neutral (eigenvalue 0) with a constant ``drift`` so that lines keep moving after the
        xy-part has decayed onto the z-axis.  Stiffness ratio fast/slow = 1e4 by default.
        Default bounds x, y in [-1, 1], z in [0, 10].  Backwards in time the fast mode grows
        like e^(1e4 |t|): exact trajectories overflow beyond |t| of about 0.07."""
        s, f = float(slow), float(fast)
        A = np.array([[(s + f) / 2, (s - f) / 2, 0.0], [(s - f) / 2, (s + f) / 2, 0.0], [0, 0, 0]])
        b = np.array([[-1.0, 1.0], [-1.0, 1.0], [0.0, 10.0]])
        return cls(A, (0.0, 0.0, 0.0), (0.0, 0.0, drift), kind="stiff", bounds=b)


@dataclass(eq=False, repr=False)
class ABCFlow(AnalyticField):
    """Arnold-Beltrami-Childress flow, periodic with period 2 pi on every axis:
    u = (A sin z + C cos y, B sin x + A cos z, C sin y + B cos x); curl u = u (Beltrami).
    Scalar ``p`` = -|u|^2 / 2 (Bernoulli).  Chaotic streamlines: no exact trajectory."""

    A: float = float(np.sqrt(3.0))
    B: float = float(np.sqrt(2.0))
    C: float = 1.0
    name = "abc"
    period = (TWO_PI, TWO_PI, TWO_PI)

    @property
    def default_bounds(self):
        return np.array([[0.0, TWO_PI]] * 3)

    def _velocity(self, p, t):
        x, y, z = p.T
        A, B, C = self.A, self.B, self.C
        return np.stack([A * np.sin(z) + C * np.cos(y), B * np.sin(x) + A * np.cos(z),
                         C * np.sin(y) + B * np.cos(x)], -1)

    def _jacobian(self, p, t):
        x, y, z = p.T
        A, B, C = self.A, self.B, self.C
        J = np.zeros((p.shape[0], 3, 3))
        J[:, 0, 1], J[:, 0, 2] = -C * np.sin(y), A * np.cos(z)
        J[:, 1, 0], J[:, 1, 2] = B * np.cos(x), -A * np.sin(z)
        J[:, 2, 0], J[:, 2, 1] = -B * np.sin(x), C * np.cos(y)
        return J

    def _scalars(self, p, t):
        u = self._velocity(p, t)
        return {"p": -0.5 * np.einsum("ij,ij->i", u, u)}


@dataclass(eq=False, repr=False)
class TaylorGreen(AnalyticField):
    """Steady 3-D Taylor-Green cells (the classic vortex at t = 0), period 2 pi:
    u = U0 (sin x cos y cos z, -cos x sin y cos z, 0).  Scalar ``p`` =
    U0^2/16 (cos 2x + cos 2y)(cos 2z + 2), the pressure that solves lap p = -tr(J J)."""

    U0: float = 1.0
    name = "taylor_green"
    period = (TWO_PI, TWO_PI, TWO_PI)

    @property
    def default_bounds(self):
        return np.array([[0.0, TWO_PI]] * 3)

    def _velocity(self, p, t):
        sx, sy = np.sin(p[:, 0]), np.sin(p[:, 1])
        cx, cy, cz = np.cos(p).T
        return self.U0 * np.stack([sx * cy * cz, -cx * sy * cz, np.zeros_like(sx)], -1)

    def _jacobian(self, p, t):
        sx, sy, sz = np.sin(p).T
        cx, cy, cz = np.cos(p).T
        J = np.zeros((p.shape[0], 3, 3))
        J[:, 0] = np.stack([cx * cy * cz, -sx * sy * cz, -sx * cy * sz], -1)
        J[:, 1] = np.stack([sx * sy * cz, -cx * cy * cz, cx * sy * sz], -1)
        return self.U0 * J

    def _scalars(self, p, t):
        c2 = np.cos(2.0 * p)
        return {"p": self.U0**2 / 16.0 * (c2[:, 0] + c2[:, 1]) * (c2[:, 2] + 2.0)}


@dataclass(eq=False, repr=False)
class HillVortex(AnalyticField):
    """Hill's spherical vortex of radius ``a`` moving at speed ``U`` along +z, seen in its own
    frame (steady): far field -U e_z.  Inside (R <= a), with k = 3U / (2 a^2):
    u = (k x z, k y z, 3U/2 (1 - (2 (x^2 + y^2) + z^2) / a^2)), vorticity 15 U rho / (2 a^2);
    outside a uniform stream plus a dipole, irrotational.  Velocity and the Stokes stream function
    ``psi`` are continuous across R = a (the jacobian is not).  Closed streamlines inside, no
    elementary trajectory."""

    a: float = 1.0
    U: float = 1.0
    centre: tuple = (0.0, 0.0, 0.0)
    name = "hill"

    def __post_init__(self):
        if not self.a > 0:
            raise ValueError(f"hill: radius a must be > 0, got {self.a!r}")
        self.centre = _vec3(self.centre, "hill: centre")

    @property
    def default_bounds(self):
        return self.centre[:, None] + 2.0 * self.a * np.array([-1.0, 1.0])

    def _split(self, p):
        r = p - self.centre
        R2 = np.einsum("ij,ij->i", r, r)
        return r, R2, R2 <= self.a**2

    def _velocity(self, p, t):
        r, R2, inside = self._split(p)
        a, U = self.a, self.U
        x, y, z = r.T
        k = 1.5 * U / a**2
        ui = np.stack([k * x * z, k * y * z, 1.5 * U - k * (2 * (x * x + y * y) + z * z)], -1)
        Ro = np.where(inside, a, np.sqrt(R2))  # outside formula only used where R > a
        m = 0.5 * U * a**3
        uo = m * 3.0 * z[:, None] * r / Ro[:, None] ** 5
        uo[:, 2] -= U + m / Ro**3
        return np.where(inside[:, None], ui, uo)

    def _jacobian(self, p, t):
        r, R2, inside = self._split(p)
        a, U = self.a, self.U
        x, y, z = r.T
        k = 1.5 * U / a**2
        Ji = np.zeros((p.shape[0], 3, 3))
        Ji[:, 0] = np.stack([k * z, 0 * z, k * x], -1)
        Ji[:, 1] = np.stack([0 * z, k * z, k * y], -1)
        Ji[:, 2] = np.stack([-4 * k * x, -4 * k * y, -2 * k * z], -1)
        # outside: u = -U e_z - m grad(z / R^3); J = -m Hessian(z / R^3)
        R = np.where(inside, a, np.sqrt(R2))
        m = 0.5 * U * a**3
        ez = np.array([0.0, 0.0, 1.0])
        H = 15.0 * (z / R**7)[:, None, None] * r[:, :, None] * r[:, None, :]
        cross = r[:, :, None] * ez + ez[:, None] * r[:, None, :]
        H -= 3.0 * (cross + z[:, None, None] * np.eye(3)) / R[:, None, None] ** 5
        return np.where(inside[:, None, None], Ji, -m * H)

    def _scalars(self, p, t):
        r, R2, inside = self._split(p)
        a, U = self.a, self.U
        rho2 = r[:, 0] ** 2 + r[:, 1] ** 2
        R = np.maximum(np.sqrt(R2), a)
        psi = np.where(inside, 0.75 * U * rho2 * (1 - R2 / a**2), -0.5 * U * rho2 * (1 - (a / R) ** 3))
        return {"psi": psi}


def _swirl(sig):
    """h(s) = (1 - e^-s) / s and h'(s), stable at s -> 0 (series below 1e-2)."""
    small = sig < 1e-2
    s = np.where(small, 1.0, sig)
    h = -np.expm1(-s) / s
    dh = (np.exp(-s) - h) / s
    # series: h = sum (-s)^n / (n+1)!, h' = sum_{n>=1} (-1)^n n s^(n-1) / (n+1)!
    hs = np.zeros_like(sig)
    dhs = np.zeros_like(sig)
    for n in range(7, -1, -1):
        hs = hs * -sig + 1.0 / math.factorial(n + 1)
    for n in range(7, 0, -1):
        dhs = dhs * sig + (-1) ** n * n / math.factorial(n + 1)
    return np.where(small, hs, h), np.where(small, dhs, dh)


@dataclass(eq=False, repr=False)
class BurgersVortex(AnalyticField):
    """Steady Burgers vortex about the z-axis through ``centre``: axial strain ``alpha``,
    circulation ``gamma``, viscosity ``nu``; core radius delta = sqrt(4 nu / alpha).
    u_r = -alpha r / 2, u_z = alpha z, u_theta = gamma / (2 pi r) (1 - exp(-r^2 / delta^2));
    smooth on the axis (evaluated through a series there).  Vorticity gamma / (pi delta^2)
    exp(-r^2 / delta^2) e_z.  Exact trajectory: z = z0 e^(alpha t), r = r0 e^(-alpha t / 2),
    theta from the exponential integral E1."""

    gamma: float = 1.0
    alpha: float = 1.0
    nu: float = 0.25
    centre: tuple = (0.0, 0.0, 0.0)
    name = "burgers"
    has_exact = True

    def __post_init__(self):
        if not (self.alpha > 0 and self.nu > 0):
            raise ValueError(f"burgers: alpha and nu must be > 0, got alpha={self.alpha!r}, nu={self.nu!r}")
        self.centre = _vec3(self.centre, "burgers: centre")

    @property
    def delta(self) -> float:
        return float(np.sqrt(4.0 * self.nu / self.alpha))

    @property
    def default_bounds(self):
        return self.centre[:, None] + 3.0 * self.delta * np.array([-1.0, 1.0])

    def _velocity(self, p, t):
        r = p - self.centre
        d2 = self.delta**2
        h, _ = _swirl((r[:, 0] ** 2 + r[:, 1] ** 2) / d2)
        w = self.gamma / (2 * np.pi * d2) * h  # angular velocity u_theta / r
        return np.stack([-0.5 * self.alpha * r[:, 0] - w * r[:, 1],
                         -0.5 * self.alpha * r[:, 1] + w * r[:, 0], self.alpha * r[:, 2]], -1)

    def _jacobian(self, p, t):
        r = p - self.centre
        x, y = r[:, 0], r[:, 1]
        d2 = self.delta**2
        h, dh = _swirl((x * x + y * y) / d2)
        k = self.gamma / (2 * np.pi)
        g, dg = k * h / d2, 2.0 * k * dh / d2**2  # w and dw/d(r^2) times 2
        J = np.zeros((p.shape[0], 3, 3))
        J[:, 0, 0] = -0.5 * self.alpha - dg * x * y
        J[:, 0, 1] = -g - dg * y * y
        J[:, 1, 0] = g + dg * x * x
        J[:, 1, 1] = -0.5 * self.alpha + dg * x * y
        J[:, 2, 2] = self.alpha
        return J

    def _trajectory(self, p0, t, t0):
        r = p0 - self.centre
        dt = (t - t0)[:, None]
        a, d2 = self.alpha, self.delta**2
        rho0 = np.hypot(r[:, 0], r[:, 1])
        u0 = rho0**2 / d2
        u = u0 * np.exp(-a * dt)
        on_axis = u0 == 0

        def G(v):  # antiderivative of (1 - e^-v) / v^2
            v = np.where(on_axis, 1.0, v)
            return np.expm1(-v) / v - special.exp1(v)

        theta = np.arctan2(r[:, 1], r[:, 0]) + self.gamma / (2 * np.pi * a * d2) * (G(u0) - G(u))
        rho = rho0 * np.exp(-0.5 * a * dt)
        out = np.empty((t.size,) + p0.shape)
        out[..., 0] = rho * np.cos(theta)
        out[..., 1] = rho * np.sin(theta)
        out[..., 2] = r[:, 2] * np.exp(a * dt)
        return out + self.centre


@dataclass(eq=False, repr=False)
class Lorenz(AnalyticField):
    """The Lorenz system read as a steady velocity field: u = (sigma (y - x), x (rho - z) - y,
    x y - beta z).  Chaotic (no exact trajectory), divergence -(sigma + 1 + beta)."""

    sigma: float = 10.0
    rho: float = 28.0
    beta: float = 8.0 / 3.0
    name = "lorenz"

    @property
    def default_bounds(self):
        return np.array([[-30.0, 30.0], [-30.0, 30.0], [-10.0, 60.0]])

    def _velocity(self, p, t):
        x, y, z = p.T
        return np.stack([self.sigma * (y - x), x * (self.rho - z) - y, x * y - self.beta * z], -1)

    def _jacobian(self, p, t):
        x, y, z = p.T
        J = np.zeros((p.shape[0], 3, 3))
        J[:, 0, 0], J[:, 0, 1] = -self.sigma, self.sigma
        J[:, 1, 0], J[:, 1, 1], J[:, 1, 2] = self.rho - z, -1.0, -x
        J[:, 2, 0], J[:, 2, 1], J[:, 2, 2] = y, x, -self.beta
        return J


FIELDS = {
    "uniform": UniformFlow,
    "rotation": SolidBodyRotation,
    "unsteady_rotation": UnsteadyRotation,
    "linear": LinearField,
    "sink": LinearField.sink,
    "source": LinearField.source,
    "saddle": LinearField.saddle,
    "centre": LinearField.centre,
    "spiral": LinearField.spiral,
    "stiff": LinearField.stiff,
    "abc": ABCFlow,
    "taylor_green": TaylorGreen,
    "hill": HillVortex,
    "burgers": BurgersVortex,
    "lorenz": Lorenz,
}


def make(name: str, **params) -> AnalyticField:
    """Build an analytic field by name (see ``FIELDS``), e.g. ``make("abc", A=1.0)``."""
    try:
        ctor = FIELDS[name]
    except KeyError:
        raise ValueError(f"unknown analytic field '{name}'; known: {', '.join(FIELDS)}") from None
    return ctor(**params)
