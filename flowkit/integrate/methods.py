"""Runge–Kutta methods as data: one registry that every backend generates its kernel from.

A method is its Butcher tableau plus what the kernels need to run it without special cases:

* ``c``, ``a``, ``b``: the tableau, extended so that stage ``fsal_stage`` evaluates f(y1)
  (``a[fsal_stage] == b``, ``c[fsal_stage] == 1``).  Its value is the next step's first stage
  (first same as last) and the end slope of the dense output.  Methods that lack such a stage
  (Cash–Karp, RK4, Euler) get one appended: it costs nothing on accepted steps.
* ``e``: embedded error weights, ``err = h * sum_i e[i] k[i]`` (zero for fixed-step methods);
  ``e2``, when given, is DOP853's second (3rd-order) estimate, combined as Hairer does.
* ``n_err``: stages computed before the error test; stages ``n_err..fsal_stage`` after
  acceptance; stages after ``fsal_stage`` only when the dense output is needed.
* ``p`` (s, q): dense output ``y(t0 + θh) = y0 + h Σ_i k_i Σ_j p[i, j] θ^(j+1)``.  Methods
  without their own continuous extension use the cubic Hermite interpolant of (y0, f0, y1, f1),
  written in the same form.
* ``order`` of the propagated solution, ``err_order`` of the error estimate; the step-size
  controller uses the exponent 1 / (min(order, err_order) + 1).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import schema


@dataclass(frozen=True, eq=False)
class Method:
    name: str
    order: int
    err_order: int  # 0: fixed step, no error estimate
    c: np.ndarray
    a: np.ndarray
    b: np.ndarray
    e: np.ndarray
    p: np.ndarray
    n_err: int
    fsal_stage: int
    e2: np.ndarray | None = None
    description: str = ""
    aliases: tuple[str, ...] = field(default=())

    @property
    def adaptive(self) -> bool:
        return self.err_order > 0

    @property
    def n_stages(self) -> int:
        return self.c.size

    @property
    def error_exponent_k(self) -> int:
        """q + 1 in the step-size rule h_new = h * (1 / err)^(1 / (q + 1))."""
        return min(self.order, self.err_order) + 1 if self.adaptive else self.order + 1

    def kernel_arrays(self):
        """(c, a, b, e, e2, p, ints) as contiguous float64/int64 arrays for the kernels; ints
        in the columns of ``schema.METHOD_INFO`` (stages, n_err, fsal stage, adaptive, exponent
        k, has e2)."""
        e2 = np.zeros(self.n_stages) if self.e2 is None else self.e2
        ints = np.zeros(schema.NMI, np.int64)
        ints[schema.M_STAGES] = self.n_stages
        ints[schema.M_NERR] = self.n_err
        ints[schema.M_FSAL] = self.fsal_stage
        ints[schema.M_ADAPTIVE] = self.adaptive
        ints[schema.M_KEXP] = self.error_exponent_k
        ints[schema.M_HASE2] = self.e2 is not None
        arrs = [np.ascontiguousarray(x, dtype=np.float64) for x in (self.c, self.a, self.b, self.e, e2, self.p)]
        return (*arrs, ints)

    def check(self, tol: float = 1e-12) -> None:
        """Consistency of the data: row sums, weights, FSAL stage, dense output at θ = 1."""
        s = self.n_stages
        if self.a.shape != (s, s) or self.b.shape != (s,) or self.e.shape != (s,) or self.p.shape[0] != s:
            raise ValueError(f"method {self.name}: inconsistent tableau shapes")
        if np.any(np.triu(self.a) != 0):
            raise ValueError(f"method {self.name}: tableau is not explicit")
        bad = np.abs(self.a.sum(axis=1) - self.c).max()
        if bad > tol:
            raise ValueError(f"method {self.name}: row sums of a differ from c by {bad:g}")
        if abs(self.b.sum() - 1) > tol or abs(self.e.sum()) > tol:
            raise ValueError(f"method {self.name}: weights b must sum to 1 and e to 0")
        f = self.fsal_stage
        if self.c[f] != 1 or np.abs(self.a[f] - self.b).max() > tol or np.any(self.b[f:] != 0):
            raise ValueError(f"method {self.name}: stage {f} must evaluate f(y1)")
        if np.abs(self.p.sum(axis=1) - self.b).max() > 1e-10:
            raise ValueError(f"method {self.name}: dense output at θ=1 differs from the solution")
        if np.any(self.e[self.n_err:] != 0) or np.any(self.b[self.n_err:] != 0):
            raise ValueError(f"method {self.name}: y1 and the error use only the first n_err stages")


def _extend(c, a, b):
    """Append the stage f(y1) to a tableau that has none; returns (c, a, b, fsal_stage)."""
    s = len(c)
    c2 = np.append(np.asarray(c, float), 1.0)
    a2 = np.zeros((s + 1, s + 1))
    a2[:s, :s] = a
    a2[s, :s] = b
    return c2, a2, np.append(np.asarray(b, float), 0.0), s


def _hermite(b, fsal):
    """Cubic Hermite dense output of (y0, f0 = k_0, y1 = y0 + h Σ b k, f1 = k_fsal), as p."""
    s = len(b)
    p = np.zeros((s, 3))
    d0 = np.eye(s)[0]
    d1 = np.eye(s)[fsal]
    # y(θ) - y0 = h [ (3θ² - 2θ³) Σ b k + (θ - 2θ² + θ³) k_0 + (θ³ - θ²) k_fsal ]
    p[:, 0] = d0
    p[:, 1] = 3 * b - 2 * d0 - d1
    p[:, 2] = -2 * b + d0 + d1
    return p


def _dopri5() -> Method:
    c = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1, 1])
    a = np.zeros((7, 7))
    a[1, :1] = [1 / 5]
    a[2, :2] = [3 / 40, 9 / 40]
    a[3, :3] = [44 / 45, -56 / 15, 32 / 9]
    a[4, :4] = [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]
    a[5, :5] = [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]
    b = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0])
    a[6] = b
    e = np.array([-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
    # Shampine's quartic continuous extension (as in scipy's RK45 and MATLAB's ode45)
    p = np.array([
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ])
    return Method("dopri5", 5, 4, c, a, b, e, p, n_err=7, fsal_stage=6,
                  description="Dormand–Prince 5(4), FSAL, quartic dense output",
                  aliases=("rk45", "dp5"))


def _cashkarp() -> Method:
    c = np.array([0, 1 / 5, 3 / 10, 3 / 5, 1, 7 / 8])
    a = np.zeros((6, 6))
    a[1, :1] = [1 / 5]
    a[2, :2] = [3 / 40, 9 / 40]
    a[3, :3] = [3 / 10, -9 / 10, 6 / 5]
    a[4, :4] = [-11 / 54, 5 / 2, -70 / 27, 35 / 27]
    a[5, :5] = [1631 / 55296, 175 / 512, 575 / 13824, 44275 / 110592, 253 / 4096]
    b5 = np.array([37 / 378, 0, 250 / 621, 125 / 594, 0, 512 / 1771])
    b4 = np.array([2825 / 27648, 0, 18575 / 48384, 13525 / 55296, 277 / 14336, 1 / 4])
    # VTK's vtkRungeKutta45 propagates the 5th-order solution (local extrapolation): so do we
    c, a, b, f = _extend(c, a, b5)
    e = np.append(b5 - b4, 0.0)
    return Method("cashkarp", 5, 4, c, a, b, e, _hermite(b, f), n_err=6, fsal_stage=f,
                  description="Cash–Karp 4(5) (VTK's RK45), Hermite dense output", aliases=("ck45",))


def _bs23() -> Method:
    c = np.array([0, 1 / 2, 3 / 4, 1])
    a = np.zeros((4, 4))
    a[1, :1] = [1 / 2]
    a[2, :2] = [0, 3 / 4]
    b = np.array([2 / 9, 1 / 3, 4 / 9, 0])
    a[3] = b
    e = np.array([5 / 72, -1 / 12, -1 / 9, 1 / 8])
    # its natural continuous extension is the cubic Hermite interpolant
    return Method("bs23", 3, 2, c, a, b, e, _hermite(b, 3), n_err=4, fsal_stage=3,
                  description="Bogacki–Shampine 3(2), FSAL, Hermite dense output", aliases=("rk23",))


def _rk4() -> Method:
    c0 = np.array([0, 1 / 2, 1 / 2, 1])
    a0 = np.zeros((4, 4))
    a0[1, 0] = 1 / 2
    a0[2, 1] = 1 / 2
    a0[3, 2] = 1
    c, a, b, f = _extend(c0, a0, [1 / 6, 1 / 3, 1 / 3, 1 / 6])
    return Method("rk4", 4, 0, c, a, b, np.zeros(5), _hermite(b, f), n_err=4, fsal_stage=f,
                  description="classic Runge–Kutta 4, fixed step, Hermite dense output")


def _euler() -> Method:
    c, a, b, f = _extend([0.0], np.zeros((1, 1)), [1.0])
    return Method("euler", 1, 0, c, a, b, np.zeros(2), _hermite(b, f), n_err=1, fsal_stage=f,
                  description="explicit Euler, fixed step, Hermite dense output")


def _dop853() -> Method:
    # Hairer's DOP853 coefficients as shipped with scipy (the same numbers as the Fortran code)
    from scipy.integrate._ivp import dop853_coefficients as dc

    s = dc.N_STAGES_EXTENDED
    c = np.array(dc.C, float)
    a = np.array(dc.A, float)
    b = np.zeros(s)
    b[:dc.N_STAGES] = dc.B
    e = np.zeros(s)
    e[:dc.E5.size] = dc.E5
    e2 = np.zeros(s)
    e2[:dc.E3.size] = dc.E3
    # Hairer's 7th-order continuous extension, rewritten as p: expand the nested form
    # y = y0 + ((((F6 θ + F5)(1-θ) + F4) θ + F3)(1-θ) + F2) θ ... with F_r linear in the stages.
    fs = dc.N_STAGES  # stage 12 = f(y1)
    F = np.zeros((dc.INTERPOLATOR_POWER, s))
    F[0] = b
    F[1] = -b
    F[1, 0] += 1
    F[2] = 2 * b
    F[2, 0] -= 1
    F[2, fs] -= 1
    F[3:] = dc.D
    poly = np.zeros((dc.INTERPOLATOR_POWER + 1, s))  # poly[j] multiplies θ^j
    for i, f in enumerate(F[::-1]):
        poly[0] += f
        shifted = np.zeros_like(poly)
        shifted[1:] = poly[:-1]
        poly = shifted if i % 2 == 0 else poly - shifted  # times θ or times (1 - θ)
    p = poly[1:].T.copy()
    return Method("dop853", 8, 7, c, a, b, e, p, n_err=fs + 1, fsal_stage=fs, e2=e2,
                  description="Dormand–Prince 8(5,3), 7th-order dense output (for references)")


METHODS: dict[str, Method] = {m.name: m for m in (_dopri5(), _cashkarp(), _bs23(), _rk4(), _euler(), _dop853())}
_ALIASES = {al: m.name for m in METHODS.values() for al in m.aliases}


def get_method(name: str | Method) -> Method:
    """Method by name (case-insensitive, aliases such as 'rk45' accepted)."""
    if isinstance(name, Method):
        return name
    key = str(name).lower()
    key = _ALIASES.get(key, key)
    try:
        return METHODS[key]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; choose one of: {', '.join(METHODS)}") from None
