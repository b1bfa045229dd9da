"""The method registry: every integration method as data, with what the backends need to run it.

An entry is one of three kinds, each with its capabilities (``backends``, ``adaptive``,
``lockstep``, ``stiffness_stage``, ``resamples``) so that no caller keys anything on a name:

* ``Method``: an explicit Runge–Kutta tableau.  The numba kernel reads its ``kernel_arrays()``
  and the OpenCL code generator unrolls the same arrays, so a user's tableau runs on both.
* ``RosenbrockMethod``: a linearly implicit method's coefficients (α, Γ, b, b̂), which the
  step loop's Rosenbrock stepper runs (``rosenbrock.py``).
* ``StiffSwitch``: an explicit method whose lines go on with a Rosenbrock method from the step
  its stiffness test flags them (``auto``).

``register_method`` validates an entry with its ``check()`` (consistency and order conditions,
the errors name the coefficient or the condition) and makes it known by name to ``flowkit.trace``,
``TraceOptions`` and the CLI; ``TraceOptions(method=entry)`` also takes an unregistered entry.

A tableau (``Method``) holds what the kernels need to run it without special cases:

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
* ``stiffness_stage``: the stage evaluated at c = 1 before the error test that Hairer &
  Wanner's stiffness test pairs with f(y1) (dopri5: stage 5, with f(y1) in row 6); None: no
  test.  The method must be stable on the negative real axis beyond the test's threshold
  (``stiffness.HLAMBDA_STIFF``), or its steps could never be flagged.

``Method.from_butcher`` builds one from a plain Butcher tableau and an optional embedded pair.
"""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import order_conditions as oc
from . import schema
from .stiffness import HLAMBDA_STIFF

BACKENDS = ("numba", "opencl")
LOCKSTEP_STAGES = 13  # stages the lock-step path holds, up to f(y1) (dop853 has the most)


def real_stability_reach(a, b) -> float:
    """Where an explicit tableau's stability interval on the negative real axis ends (to 0.01
    below): the last x before |R(-x)| > 1, R(z) = 1 + z b·(I − z a)⁻¹ 1 (inf beyond 20)."""
    one, eye = np.ones(len(b)), np.eye(len(b))
    for x in np.arange(0.01, 20.0, 0.01):
        if abs(1.0 - x * (b @ np.linalg.solve(eye + x * a, one))) > 1.0 + 1e-12:
            return float(x) - 0.01
    return np.inf


class MethodError(ValueError):
    """A method whose data cannot be run; the message names the method and the coefficient."""


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
    stiffness_stage: int | None = None
    backends: tuple[str, ...] = BACKENDS

    kind = "explicit"
    resamples = True  # dense output: vertices at any spacing or count
    switch_to = None

    @classmethod
    def from_butcher(cls, name, c, a, b, b_hat=None, *, order, err_order=None, p=None,
                     description="", aliases=(), stiffness_stage=None, backends=BACKENDS):
        """A method from its Butcher tableau (c, a, b) and embedded weights ``b_hat`` (None:
        fixed step).  A tableau whose last stage is not f(y1) gets that stage appended;
        dense output ``p`` (rows per stage of the extended tableau) defaults to cubic Hermite.
        ``err_order`` defaults to order - 1."""
        c, a, b = (np.asarray(x, float) for x in (c, a, b))
        s = c.size
        fsal = s > 1 and c[-1] == 1 and b[-1] == 0 and np.array_equal(a[-1], b)
        if fsal:
            f = s - 1
            n_err = s
        else:
            c, a, b, f = _extend(c, a, b)
            n_err = f
        if b_hat is None:
            e = np.zeros(c.size)
            err_order = 0
        else:
            bh = np.zeros(c.size)
            bh[:len(b_hat)] = b_hat
            e = b - bh
            err_order = order - 1 if err_order is None else err_order
        p = _hermite(b, f) if p is None else np.asarray(p, float)
        return cls(name, order, err_order, c, a, b, e, p, n_err=n_err, fsal_stage=f,
                   description=description, aliases=tuple(aliases),
                   stiffness_stage=stiffness_stage, backends=tuple(backends))

    @property
    def adaptive(self) -> bool:
        return self.err_order > 0

    @property
    def explicit(self) -> Method:
        """The tableau the explicit kernel runs."""
        return self

    @property
    def lockstep(self) -> bool:
        """The lock-step path (``lanes.py``) can run it on plain (not cell-aware) traces."""
        return lockstep_tableau(self.kernel_arrays()[-1])

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
        """Raise MethodError unless the data can run: shapes, explicitness, row sums, the f(y1)
        stage, the order conditions of b (``order``) and of the embedded weights b − e
        (``err_order``; with a second estimate e2 each pair is checked for consistency), the
        dense output at θ = 1, the stiffness stage and the backends."""
        from .kernel import QMAX

        name = self.name
        s = self.n_stages
        _common(self, "explicit Runge–Kutta")
        shapes = {"c": (self.c.shape, (s,)), "a": (self.a.shape, (s, s)), "b": (self.b.shape, (s,)),
                  "e": (self.e.shape, (s,))}
        if self.e2 is not None:
            shapes["e2"] = (np.shape(self.e2), (s,))
        for key, (got, want) in shapes.items():
            if got != want:
                raise MethodError(f"method {name}: {key} has shape {got}, {want} for {s} stages")
        if self.p.ndim != 2 or self.p.shape[0] != s or not 1 <= self.p.shape[1] <= QMAX:
            raise MethodError(f"method {name}: dense output p has shape {self.p.shape}, needs "
                              f"({s}, q) with 1 <= q <= {QMAX}")
        for key in ("c", "a", "b", "e", "e2", "p"):
            v = getattr(self, key)
            if v is not None and not np.all(np.isfinite(v)):
                idx = tuple(int(i) for i in np.argwhere(~np.isfinite(v))[0])
                raise MethodError(f"method {name}: {key}{list(idx)} = {v[idx]!r} is not finite")
        upper = np.argwhere(np.triu(self.a) != 0)
        if upper.size:
            i, j = upper[0]
            raise MethodError(f"method {name}: a[{i}, {j}] = {self.a[i, j]:g} is on or above the "
                              "diagonal: the tableau must be explicit")
        for i in range(s):
            if abs(self.a[i].sum() - self.c[i]) > tol:
                raise MethodError(f"method {name}: row a[{i}, :] sums to {self.a[i].sum():.12g}, "
                                  f"c[{i}] = {self.c[i]:.12g}")
        if not (0 < self.n_err <= s and self.n_err - 1 <= self.fsal_stage < s):
            raise MethodError(f"method {name}: n_err = {self.n_err} and fsal_stage = "
                              f"{self.fsal_stage} must satisfy 0 < n_err <= fsal_stage + 1 <= {s}")
        f = self.fsal_stage
        if self.c[f] != 1:
            raise MethodError(f"method {name}: c[{f}] = {self.c[f]:g}, the f(y1) stage "
                              f"(fsal_stage {f}) needs c = 1")
        for j in range(s):
            if abs(self.a[f, j] - self.b[j]) > tol:
                raise MethodError(f"method {name}: a[{f}, {j}] = {self.a[f, j]:.12g} differs from "
                                  f"b[{j}] = {self.b[j]:.12g}: stage {f} must evaluate f(y1)")
        for key in ("b", "e", "e2"):
            w = getattr(self, key)
            late = [] if w is None else np.flatnonzero(w[self.n_err:] != 0)
            if len(late):
                j = self.n_err + int(late[0])
                raise MethodError(f"method {name}: {key}[{j}] = {w[j]:g}, y1 and the error use "
                                  f"the first n_err = {self.n_err} stages only")
        if not 1 <= self.order <= oc.MAX_RK_ORDER:
            raise MethodError(f"method {name}: order {self.order}; check() covers orders "
                              f"1..{oc.MAX_RK_ORDER}")
        if not 0 <= self.err_order <= oc.MAX_RK_ORDER:
            raise MethodError(f"method {name}: err_order {self.err_order} out of 0..{oc.MAX_RK_ORDER}")
        _conditions(name, "b", oc.rk_failures(self.a, self.b, self.order, 1e-10))
        if self.adaptive:
            if abs(self.e.sum()) > tol:
                raise MethodError(f"method {name}: the error weights e sum to {self.e.sum():.3g}, "
                                  "must be 0 (b and the embedded weights b − e both sum to 1)")
            if self.e2 is None:
                _conditions(name, "the embedded weights b − e",
                            oc.rk_failures(self.a, self.b - self.e, self.err_order, 1e-10))
            elif abs(self.e2.sum()) > tol:
                raise MethodError(f"method {name}: the error weights e2 sum to "
                                  f"{self.e2.sum():.3g}, must be 0")
        elif np.any(self.e != 0):
            raise MethodError(f"method {name}: err_order 0 (fixed step) with non-zero error "
                              "weights e; give err_order")
        rows = self.p.sum(axis=1)
        for i in range(s):
            if abs(rows[i] - self.b[i]) > 1e-10:
                raise MethodError(f"method {name}: dense output row p[{i}, :] sums to "
                                  f"{rows[i]:.12g}, b[{i}] = {self.b[i]:.12g} (y(θ = 1) must be y1)")
        cols = self.p.sum(axis=0)
        want = np.eye(self.p.shape[1])[0]
        for j in range(self.p.shape[1]):
            if abs(cols[j] - want[j]) > 1e-10:
                raise MethodError(f"method {name}: dense output column p[:, {j}] sums to "
                                  f"{cols[j]:.12g}, needs {want[j]:g} (y(θ) consistent: "
                                  "Σ_i p[i, :] = (1, 0, ...))")
        st = self.stiffness_stage
        if st is not None:
            if not (1 <= st < self.n_err and self.c[st] == 1):
                raise MethodError(f"method {name}: stiffness_stage {st} must be a stage before "
                                  f"the error test (1..{self.n_err - 1}) with c = 1")
            if st == f:
                raise MethodError(f"method {name}: stiffness_stage {st} is f(y1) itself; the "
                                  "test compares f(y1) with another evaluation at c = 1")
            reach = real_stability_reach(self.a[:f, :f], self.b[:f])
            if reach < HLAMBDA_STIFF:
                raise MethodError(
                    f"method {name}: stable only up to h|λ| = {reach:.2f} on the negative real "
                    f"axis, below the stiffness test's threshold {HLAMBDA_STIFF}: its steps "
                    "never reach it; give stiffness_stage=None")


@dataclass(frozen=True, eq=False)
class RosenbrockMethod:
    """A Rosenbrock(-W) method: W k_i = h f(y0 + Σ α_ij k_j) + h J Σ_{j<i} γ_ij k_j with
    W = I − hγJ, y1 = y0 + Σ b_i k_i, error Σ (b_i − b̂_i) k_i.  ``gammas`` is Γ off its
    diagonal (strictly lower); the diagonal is ``gamma``."""

    name: str
    order: int
    err_order: int
    gamma: float
    alpha: np.ndarray
    gammas: np.ndarray
    b: np.ndarray
    bhat: np.ndarray
    description: str = ""
    aliases: tuple[str, ...] = field(default=())

    kind = "rosenbrock"
    backends = ("numba",)
    adaptive = True
    lockstep = False
    resamples = False  # vertices at its accepted steps
    stiffness_stage = None
    explicit = None
    switch_to = None

    def check(self, tol: float = 1e-12) -> None:
        """Raise MethodError unless the coefficients can run: shapes, strictly lower α and Γ,
        γ > 0, the order conditions of b (``order``) and b̂ (``err_order``), at most order 4."""
        name = self.name
        _common(self, "Rosenbrock")
        s = np.size(self.b)
        for key, want in (("alpha", (s, s)), ("gammas", (s, s)), ("b", (s,)), ("bhat", (s,))):
            v = np.asarray(getattr(self, key))
            if v.shape != want:
                raise MethodError(f"method {name}: {key} has shape {v.shape}, {want} for {s} stages")
            if not np.all(np.isfinite(v)):
                raise MethodError(f"method {name}: {key} has a non-finite coefficient")
        for key in ("alpha", "gammas"):
            upper = np.argwhere(np.triu(getattr(self, key)) != 0)
            if upper.size:
                i, j = upper[0]
                raise MethodError(f"method {name}: {key}[{i}, {j}] = {getattr(self, key)[i, j]:g} "
                                  "on or above the diagonal: must be strictly lower triangular")
        if not (np.isfinite(self.gamma) and self.gamma > 0):
            raise MethodError(f"method {name}: gamma = {self.gamma!r} must be positive")
        for key, p in (("order", self.order), ("err_order", self.err_order)):
            if not 1 <= p <= oc.MAX_ROS_ORDER:
                raise MethodError(f"method {name}: {key} {p}; check() covers Rosenbrock orders "
                                  f"1..{oc.MAX_ROS_ORDER}")
        G = self.gammas + self.gamma * np.eye(s)
        _conditions(name, "b", oc.ros_failures(self.alpha, G, self.b, self.order, 1e-10))
        _conditions(name, "bhat", oc.ros_failures(self.alpha, G, self.bhat, self.err_order, 1e-10))


@dataclass(frozen=True, eq=False)
class StiffSwitch:
    """Trace with the explicit method ``first``; a line its stiffness test flags goes on with
    the Rosenbrock method ``stiff`` from that step (a line_data flag named after it marks
    those lines)."""

    name: str
    first: str
    stiff: str
    description: str = ""
    aliases: tuple[str, ...] = field(default=())

    kind = "switch"
    adaptive = True
    resamples = False  # the lines that switch have vertices at their steps

    @property
    def explicit(self) -> Method:
        return get_method(self.first)

    @property
    def lockstep(self) -> bool:
        return self.explicit.lockstep  # its first pass is the explicit method's

    @property
    def switch_to(self):
        return get_method(self.stiff)

    @property
    def stiffness_stage(self) -> int | None:
        return self.explicit.stiffness_stage

    @property
    def backends(self) -> tuple[str, ...]:
        # (a line switches inside the step loop: both steppers on one backend)
        return tuple(b for b in self.explicit.backends if b in self.switch_to.backends)

    def check(self, tol: float = 1e-12) -> None:
        _common(self, "switch")
        first = get_method(self.first)
        if first.kind != "explicit" or first.stiffness_stage is None:
            raise MethodError(f"method {self.name}: first = {self.first!r} must be an explicit "
                              "method with a stiffness_stage (one that flags stiff lines)")
        if get_method(self.stiff).kind != "rosenbrock":
            raise MethodError(f"method {self.name}: stiff = {self.stiff!r} must be a Rosenbrock "
                              "method")


def _common(m, kind: str) -> None:
    if not (isinstance(m.name, str) and m.name and m.name == m.name.lower()
            and m.name.replace("_", "").replace("-", "").isalnum()):
        raise MethodError(f"{kind} method name {m.name!r} must be a lower-case word "
                          "(letters, digits, - and _)")
    bad = set(m.backends) - set(BACKENDS)
    if bad or not m.backends:
        raise MethodError(f"method {m.name}: backends {tuple(m.backends)!r}; choose from {BACKENDS}")


def _conditions(name: str, what: str, failures: list[str]) -> None:
    if failures:
        more = f" (and {len(failures) - 1} more)" if len(failures) > 1 else ""
        raise MethodError(f"method {name}: {what} miss the order condition {failures[0]}{more}")


def lockstep_tableau(ints) -> bool:
    """The method part of ``lanes.eligible``: an explicit method whose stages up to f(y1) fit in
    the LOCKSTEP_STAGES the lock-step holds (the stages after it feed only the dense output,
    which the lock-step leaves to the scalar kernel)."""
    return int(ints[schema.M_FSAL]) + 1 <= LOCKSTEP_STAGES


REGISTRY: dict = {}  # every entry by name, in registration order
METHODS: dict[str, Method] = {}  # the explicit tableaux among them
_ALIASES: dict[str, str] = {}


def register_method(m, *, replace: bool = False):
    """Validate ``m`` (a Method, RosenbrockMethod or StiffSwitch) with its ``check()`` and make it
    known by its name and aliases; ``replace`` lets it take over an entry of the same name.
    Returns ``m``."""
    if not isinstance(m, (Method, RosenbrockMethod, StiffSwitch)):
        raise TypeError(f"register_method takes a Method, RosenbrockMethod or StiffSwitch, got "
                        f"{type(m).__name__}")
    m.check()
    old = REGISTRY.get(m.name)
    if old is not None and old is not m and not replace:
        raise MethodError(f"method name {m.name!r} is registered already ({old.description}); "
                          "choose another name or pass replace=True")
    for al in m.aliases:
        owner = _ALIASES.get(al, al if al in REGISTRY else None)
        if owner is not None and owner != m.name:
            raise MethodError(f"method {m.name}: alias {al!r} names method {owner} already")
    if old is not None:
        for al in old.aliases:
            _ALIASES.pop(al, None)
        METHODS.pop(m.name, None)
    REGISTRY[m.name] = m
    if m.kind == "explicit":
        METHODS[m.name] = m
    _ALIASES.update({al: m.name for al in m.aliases})
    return m


def get_method(name):
    """Registry entry by name (case-insensitive, aliases such as 'rk45' accepted); an entry
    object is returned as it is."""
    if isinstance(name, (Method, RosenbrockMethod, StiffSwitch)):
        return name
    key = str(name).lower()
    key = _ALIASES.get(key, key)
    try:
        return REGISTRY[key]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; choose one of: {', '.join(REGISTRY)}") from None


def is_registered(m) -> bool:
    return REGISTRY.get(m.name) is m


def names(where=None) -> list[str]:
    """Registered names, in registration order; ``where(entry)`` filters."""
    return [n for n, m in REGISTRY.items() if where is None or where(m)]


def describe(m) -> str:
    """One line: the description and the capabilities (for option docs and ``--help``)."""
    caps = ["adaptive" if m.adaptive else "fixed step", "+".join(m.backends)]
    if m.lockstep:
        caps.append("lanes")  # (argparse would break the line at a hyphen)
    if m.stiffness_stage is not None:
        caps.append("flags stiff lines")
    if not m.resamples:
        caps.append("vertices at its steps")
    return f"{m.description} ({', '.join(caps)})"


def catalogue(indent: str = "") -> str:
    """Every registered method, one per line: name, description, capabilities."""
    w = max(len(n) for n in REGISTRY)
    return "\n".join(f"{indent}{n:<{w}}  {describe(m)}" for n, m in REGISTRY.items())


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
                  aliases=("rk45", "dp5"), stiffness_stage=5)


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
    return Method.from_butcher("cashkarp", c, a, b5, b4, order=5, err_order=4, aliases=("ck45",),
                               description="Cash–Karp 4(5) (VTK's RK45), Hermite dense output")


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
    return Method.from_butcher("rk4", c0, a0, [1 / 6, 1 / 3, 1 / 3, 1 / 6], order=4,
                               description="classic Runge–Kutta 4, Hermite dense output")


def _euler() -> Method:
    return Method.from_butcher("euler", [0.0], np.zeros((1, 1)), [1.0], order=1,
                               description="explicit Euler, Hermite dense output")


def _dop853_coefficients():
    """Hairer's DOP853 coefficients as shipped with scipy (the same numbers as the Fortran code;
    a module of numpy arrays), read without importing scipy.integrate, whose package import
    would add ~0.4 s to every start of flowkit (the registry is built at import)."""
    spec = importlib.util.find_spec("scipy")  # (finds the package without importing it)
    path = Path(spec.origin).parent / "integrate" / "_ivp" / "dop853_coefficients.py"
    if not path.is_file():  # another layout: the import, at its cost
        from scipy.integrate._ivp import dop853_coefficients

        return dop853_coefficients
    loader = importlib.util.spec_from_file_location("flowkit._dop853_coefficients", path)
    module = importlib.util.module_from_spec(loader)
    loader.loader.exec_module(module)
    return module


def _dop853() -> Method:
    dc = _dop853_coefficients()
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
                  description="Dormand–Prince 8(5,3), 7th-order dense output (references)")


def _ros34pw2() -> RosenbrockMethod:
    # Rang & Angermann, BIT 45 (2005): L-stable, W-method of order 3, embedded order 2
    alpha = np.array([
        [0.0, 0.0, 0.0, 0.0],
        [8.7173304301691801e-01, 0.0, 0.0, 0.0],
        [8.4457060015369423e-01, -1.1299064236484185e-01, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ])
    gammas = np.array([  # off-diagonal γ_ij
        [0.0, 0.0, 0.0, 0.0],
        [-8.7173304301691801e-01, 0.0, 0.0, 0.0],
        [-9.0338057013044082e-01, 5.4180672388095326e-02, 0.0, 0.0],
        [2.4212380706095346e-01, -1.2232505839045147e+00, 5.4526025533510214e-01, 0.0],
    ])
    b = np.array([2.4212380706095346e-01, -1.2232505839045147e+00, 1.5452602553351020e+00,
                  4.3586652150845900e-01])
    bhat = np.array([3.7810903145819369e-01, -9.6042292212423178e-02, 5.0e-01,
                     2.1793326075422950e-01])
    return RosenbrockMethod("ros34pw2", 3, 2, 4.3586652150845900e-01, alpha, gammas, b, bhat,
                            description="Rosenbrock-W 3(2), L-stable, for stiff fields, exact "
                                        "cell Jacobian")


for _m in (_dopri5(), _cashkarp(), _bs23(), _rk4(), _euler(), _dop853(), _ros34pw2(),
           StiffSwitch("auto", "dopri5", "ros34pw2",
                       description="dopri5; the lines it flags stiff are traced again with "
                                   "ros34pw2")):
    register_method(_m)
del _m
