"""Order conditions of Runge–Kutta and Rosenbrock methods, checked on a method's coefficients.

Explicit Runge–Kutta (Butcher): weights w have order p when, for every rooted tree t with at most
p nodes, Σ_i w_i Φ_i(t) = 1 / γ(t), where Φ(leaf) = 1, Φ_i(t) = Π over t's subtrees u of
(A Φ(u))_i, and γ(t) = |t| Π γ(u).  Trees are canonical nested tuples (a node is the sorted
tuple of its subtrees), so each appears once: 1, 1, 2, 4, 9, 20, 48, 115 trees of orders 1..8.

Rosenbrock (Hairer & Wanner, Solving ODEs II, IV.7, Table 7.1), with β = α + Γ (Γ's diagonal
γ), α_i = Σ_j α_ij and β'_i = Σ_{j<i} β_ij: the conditions up to order 4, written out.
"""

from __future__ import annotations

from functools import cache

import numpy as np

MAX_RK_ORDER = 8
MAX_ROS_ORDER = 4


def _size(t) -> int:
    return 1 + sum(_size(u) for u in t)


@cache
def trees(n: int) -> tuple:
    """Every rooted tree with n nodes."""
    return ((),) if n == 1 else _forests(n - 1, None)


@cache
def _forests(m: int, bound) -> tuple:
    """Multisets of trees of m nodes in all, as tuples in non-increasing (size, tree) order,
    no member above ``bound``."""
    if m == 0:
        return ((),)
    out = []
    for k in range(1, m + 1):
        for t in trees(k):
            if bound is not None and (k, t) > bound:
                continue
            out += [(t, *rest) for rest in _forests(m - k, (k, t))]
    return tuple(out)


def _gamma(t) -> int:
    g = _size(t)
    for u in t:
        g *= _gamma(u)
    return g


def _phi(a: np.ndarray, t) -> np.ndarray:
    v = np.ones(a.shape[0])
    for u in t:
        v = v * (a @ _phi(a, u))
    return v


def _formula(t) -> str:
    """The condition's sum in the usual notation, e.g. Σ b·c², Σ b·(A c), Σ b·(A (A c))."""
    def factor(u):
        return "c" if u == () else f"(A {_inner(u)})"

    def _inner(u):
        parts = {}
        for v in u:
            parts[factor(v)] = parts.get(factor(v), 0) + 1
        return "·".join(f + ("" if n == 1 else "²³⁴⁵⁶⁷⁸⁹"[n - 2]) for f, n in parts.items())

    return "Σ b" if t == () else f"Σ b·{_inner(t)}"


def rk_failures(a, w, order: int, tol: float) -> list[str]:
    """The conditions of orders 1..order the weights w of tableau a miss, described."""
    bad = []
    for p in range(1, order + 1):
        for t in trees(p):
            got = float(w @ _phi(a, t))
            want = 1.0 / _gamma(t)
            if abs(got - want) > tol:
                bad.append(f"order {p}: {_formula(t)} = {got:.12g}, needs 1/{_gamma(t)}")
    return bad


def ros_failures(alpha, gamma_full, w, order: int, tol: float) -> list[str]:
    """Rosenbrock conditions of orders 1..order (at most 4) the weights w miss, described."""
    g = float(gamma_full[0, 0])
    beta = alpha + gamma_full
    al = alpha.sum(axis=1)
    bp = np.tril(beta, -1).sum(axis=1)  # β'_i = Σ_{j<i} β_ij
    B = np.tril(beta, -1)
    A = np.tril(alpha, -1)
    conds = [
        (1, "Σ b", w.sum(), 1.0),
        (2, "Σ b β'", w @ bp, 0.5 - g),
        (3, "Σ b α²", w @ al**2, 1 / 3),
        (3, "Σ b (β β')", w @ (B @ bp), 1 / 6 - g + g * g),
        (4, "Σ b α³", w @ al**3, 1 / 4),
        (4, "Σ b α (α β')", w @ (al * (A @ bp)), 1 / 8 - g / 3),
        (4, "Σ b (β α²)", w @ (B @ al**2), 1 / 12 - g / 3),
        (4, "Σ b (β β β')", w @ (B @ (B @ bp)), 1 / 24 - g / 2 + 1.5 * g * g - g**3),
    ]
    return [f"order {p}: {name} = {got:.12g}, needs {want:.12g}"
            for p, name, got, want in conds if p <= order and abs(got - want) > tol]
