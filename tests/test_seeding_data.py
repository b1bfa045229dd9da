"""Seeds from the data (density, where), the expression grammar, similarity pruning and the
spec strings a rake produces."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chisquare

from flowkit import Lines
from flowkit.fields import Field, Grid
from flowkit.fields.analytic import ABCFlow
from flowkit.integrate import seeds
from flowkit.integrate.seeds import CHECK_ONLY, SeedError, parse_seed_spec
from flowkit.seeding.expr import Expression, ExpressionError
from flowkit.seeding.prune import prune


def small_field():
    """4 x 3 x 3 nodes on a rectilinear grid: 3 x 2 x 2 = 12 cells of unequal size, a scalar
    'w' with very unequal cell weights, a temperature-like 'T' rising along x."""
    g = Grid.from_axes([0.0, 1.0, 1.5, 3.0], [0.0, 0.5, 2.0], [0.0, 1.0, 1.2])
    rng = np.random.default_rng(0)
    w = rng.random(g.shape) ** 3
    w[0] = 0.0  # the first layer of cells weighs almost nothing
    x = g.node_points()[..., 0]
    vec = np.stack([np.ones(g.shape), 0.1 * x, np.zeros(g.shape)], -1)
    return Field(g, vec, {"w": w, "T": 300.0 + x}, source="small.npz")


def cell_of(g, p):
    idx = [np.clip(np.searchsorted(c, p[:, a], side="right") - 1, 0, c.size - 2)
           for a, c in enumerate(g.axes)]
    return np.ravel_multi_index(idx, tuple(c.size - 1 for c in g.axes))


def cell_weights(f, name):
    """The integral of the trilinear interpolant over each cell: corner mean x volume."""
    a = f.scalars[name]
    mean = sum(a[i:a.shape[0] - 1 + i, j:a.shape[1] - 1 + j, k:a.shape[2] - 1 + k]
               for i in (0, 1) for j in (0, 1) for k in (0, 1)) / 8
    vol = np.einsum("i,j,k->ijk", *(np.diff(c) for c in f.grid.axes))
    return (mean * vol).ravel()


def test_density_matches_the_cell_weights_chi_square():
    f = small_field()
    n = 20_000
    p = parse_seed_spec(f"density:{n}:w:7", f)
    assert p.shape == (n, 3)
    counts = np.bincount(cell_of(f.grid, p), minlength=12)
    w = cell_weights(f, "w")
    expected = n * w / w.sum()
    pval = chisquare(counts, expected)[1]
    assert pval > 0.01, (counts, expected.round(1))
    # the test has power: the same seeds against volume weights (uniform seeding) fail it
    vol = np.einsum("i,j,k->ijk", *(np.diff(c) for c in f.grid.axes)).ravel()
    assert chisquare(counts, n * vol / vol.sum())[1] < 1e-12
    np.testing.assert_array_equal(p, parse_seed_spec(f"density:{n}:w:7", f))  # fixed seed


def test_density_within_a_cell_follows_the_interpolant():
    # one cell, weight rising linearly in x from 0 to 1: the x of the seeds has density 2x
    g = Grid.regular(0.0, 1.0, (2, 2, 2))
    w = np.zeros(g.shape)
    w[1] = 1.0
    f = Field(g, np.ones(g.shape + (3,)), {"w": w})
    x = seeds.parse_seed_spec("density:20000:w", f)[:, 0]
    counts = np.histogram(x, bins=10, range=(0, 1))[0]
    expected = 20000 * np.diff(np.linspace(0, 1, 11) ** 2)
    assert chisquare(counts, expected)[1] > 0.01


def test_density_attributes():
    f = ABCFlow().to_field(12)
    for attr in ("speed", "vorticity_magnitude", "vorticity"):
        p = parse_seed_spec(f"density:200:{attr}", f)
        assert p.shape == (200, 3) and np.all(f.sample(p)[1] == 0)
    g = small_field()
    assert parse_seed_spec("density:50:grad(T)", g).shape == (50, 3)
    with pytest.raises(SeedError, match=r"no attribute 'q' to seed from \(available: speed, "
                                        r"vorticity_magnitude, T, w, grad\(T\), grad\(w\)\)"):
        parse_seed_spec("density:10:q", g)
    h = small_field()
    h.scalars["w"][1, 2, 0] = -0.5
    with pytest.raises(SeedError, match=r"non-negative; 'w' is -0.5 at node \(1, 2, 0\)"):
        parse_seed_spec("density:10:w", h)
    with pytest.raises(SeedError, match="'density' weighs the field's data, but no field"):
        parse_seed_spec("density:10:w")


def test_where_draws_only_where_the_expression_holds():
    f = small_field()
    p = parse_seed_spec("where:T > 301.2 and T<=302.5:3000:3", f)
    x = p[:, 0]
    assert x.min() > 1.2 and x.max() <= 2.5
    # uniform in the slab: the mean and spread of x are those of U(1.2, 2.5)
    assert abs(x.mean() - 1.85) < 0.03
    assert p.shape == (3000, 3)
    chain = parse_seed_spec("where:301.2 < T <= 302.5:3000:3", f)
    assert np.all((chain[:, 0] > 1.2) & (chain[:, 0] <= 2.5))
    q = parse_seed_spec("where:not (T < 302) | speed > 1e9:500", f)
    assert q[:, 0].min() >= 2.0
    with pytest.raises(SeedError, match=r"'T > 400' holds in no valid cell \(T in \[300, 303\]\)"):
        parse_seed_spec("where:T > 400:10", f)


@pytest.mark.parametrize("expr, token", [
    ("T + 1 > 300", "'+'"),
    ("T > 300; import os", "';'"),
    ("__import__('os') > 0", "\"'\""),
    ("T.real > 1", "'.'"),
    ("abs(T) > 1", "'abs'"),
    ("T > 'a'", "\"'\""),
    ("T ** 2 > 1", "'*'"),
    ("T > 300 and", None),
    ("T > -x", "'x'"),
    ("(T > 300", None),
    ("T > 300)", "')'"),
    ("Tx > 300", "'Tx'"),
])
def test_expression_refuses_anything_else(expr, token):
    f = small_field()
    with pytest.raises(SeedError) as e:
        parse_seed_spec(f"where:{expr}:10", f)
    msg = str(e.value)
    assert "token" in msg or "ends too early" in msg or "missing" in msg
    if token is not None:
        assert f"token {token}" in msg, msg


def test_expression_grammar_without_a_field():
    e = Expression("T >= 1 and (p < 2 or not q == 3)")
    assert e.names == {"T", "p", "q"}
    v = {"T": np.array([0.0, 1.0, 2.0]), "p": np.array([0.0, 5.0, 5.0]),
         "q": np.array([3.0, 3.0, 4.0])}
    np.testing.assert_array_equal(e.evaluate(v), [False, False, True])
    with pytest.raises(ExpressionError, match="token 'x' at position 4 is not a scalar field"):
        Expression("T > x", allowed_names=["T"])
    with pytest.raises(SeedError, match=r"token '\+'"):
        parse_seed_spec("where:T+1>0:10", CHECK_ONLY)  # scenes check the grammar early
    assert parse_seed_spec("where:T>0:10", CHECK_ONLY) is None


def test_interval_test_is_conservative():
    # every point where the expression holds lies in a cell the interval test calls "maybe"
    e = Expression("T > 0.3 and not (T >= 0.6) or T == 0.9")
    rng = np.random.default_rng(1)
    lo = rng.random(2000)
    hi = lo + rng.random(2000) * 0.3
    x = lo + rng.random(2000) * (hi - lo)
    surely, maybe = e.evaluate_interval({"T": lo}, {"T": hi})
    holds = e.evaluate({"T": x})
    assert not np.any(holds & ~maybe)
    assert not np.any(surely & ~holds)


# -- pruning ------------------------------------------------------------------------------------
def straight(y, x1, n):
    return np.stack([np.linspace(0, x1, n), np.full(n, y), np.zeros(n)], 1)


def test_prune_drops_a_line_beside_a_longer_one():
    parts = [straight(0.0, 10.0, 101), straight(0.1, 6.0, 61), straight(1.0, 6.0, 61),
             np.concatenate([straight(0.1, 2.0, 21), straight(0.8, 6.0, 61)[21:]])]
    pts = np.concatenate(parts)
    offsets = np.cumsum([0] + [len(p) for p in parts])
    lines = Lines(pts, offsets, line_data={"seed_id": np.array([10, 11, 12, 13])})
    out = prune(lines, 0.2, 0.8)
    assert out.line_data["seed_id"].tolist() == [10, 12, 13]  # 13 runs beside 10 for 1/3 only
    assert out.attrs["pruned_seed_id"].tolist() == [11]
    assert out.attrs["pruned_by"].tolist() == [10]
    assert out.attrs["pruned_covered"].tolist() == [1.0]
    assert sorted(prune(lines, 0.2, 0.3).attrs["pruned_seed_id"].tolist()) == [11, 13]
    with pytest.raises(ValueError, match="fraction must lie in"):
        prune(lines, 0.2, 1.5)


# -- spec strings for a rake --------------------------------------------------------------------
def test_rake_specs_round_trip():
    rng = np.random.default_rng(4)
    for _ in range(20):
        a, b, c = rng.normal(size=(3, 3)) * 10 ** rng.uniform(-8, 8)
        n, m = (int(k) for k in rng.integers(1, 40, 2))
        np.testing.assert_array_equal(parse_seed_spec(seeds.line_spec(a, b, n)),
                                      seeds.line(a, b, n))
        np.testing.assert_array_equal(parse_seed_spec(seeds.plane_spec(a, b, c, n, m)),
                                      seeds.plane(a, b, c, n, m))
        pts = rng.normal(size=(n, 3))
        np.testing.assert_array_equal(parse_seed_spec(seeds.points_spec(pts)), pts)
    assert seeds.line_spec([0, 0, 0], [1, 2.5, 1 / 3], 4) == (
        "line:0.0,0.0,0.0:1.0,2.5,0.3333333333333333:4")
    with pytest.raises(SeedError, match="line: n must be a positive integer"):
        seeds.line_spec([0, 0, 0], [1, 1, 1], 0)
