"""Grid, Field sampling and Lines: the contracts every other module builds on."""

import numpy as np
import pytest

from flowkit import Field, Grid, Lines
from flowkit.fields import GridError
from flowkit.fields.interp import INSIDE, NAN_CELL, OUTSIDE


def linear_field(grid):
    A = np.array([[0.3, -1.2, 0.5], [2.0, 0.1, -0.7], [0.4, 0.9, -1.1]])
    b = np.array([0.25, -0.5, 1.5])
    P = grid.node_points()
    return Field(grid, P @ A.T + b, {"s": P @ np.array([1.0, -2.0, 3.0]) + 4.0}), A, b


@pytest.mark.parametrize("kind", ["uniform", "rectilinear"])
def test_trilinear_exact_on_linear_fields(kind):
    if kind == "uniform":
        g = Grid.regular((-1.0, 0.5, 2.0), (0.1, 0.25, 0.2), (11, 7, 9))
    else:
        rng = np.random.default_rng(0)
        g = Grid.from_axes(*(np.sort(rng.uniform(-2, 2, n)) for n in (9, 6, 8)))
    assert g.uniform == (kind == "uniform")
    f, A, b = linear_field(g)
    lo, hi = g.bounds[:, 0], g.bounds[:, 1]
    pts = np.random.default_rng(1).uniform(lo, hi, (5000, 3))
    pts = np.vstack([pts, lo, hi, g.node_points().reshape(-1, 3)])
    v, st = f.sample(pts)
    assert np.all(st == INSIDE)
    np.testing.assert_allclose(v, pts @ A.T + b, rtol=0, atol=1e-12)
    s, st = f.sample_scalar("s", pts)
    np.testing.assert_allclose(s, pts @ [1.0, -2.0, 3.0] + 4.0, rtol=0, atol=1e-12)


def test_exact_at_nodes_for_any_data():
    g = Grid.regular(0, 0.3, (5, 4, 6))
    vec = np.random.default_rng(2).normal(size=g.shape + (3,))
    f = Field(g, vec)
    v, st = f.sample(g.node_points().reshape(-1, 3))
    assert np.all(st == INSIDE)
    np.testing.assert_array_equal(v, vec.reshape(-1, 3))


def test_outside_is_signalled_never_extrapolated():
    g = Grid.regular(0, 1.0, (4, 4, 4))
    f, _, _ = linear_field(g)
    pts = np.array([[-1e-12, 1, 1], [1, 3 + 1e-12, 1], [1, 1, np.nan], [3, 3, 3], [0, 0, 0]])
    v, st = f.sample(pts)
    assert list(st) == [OUTSIDE, OUTSIDE, OUTSIDE, INSIDE, INSIDE]
    assert np.all(np.isnan(v[:3]))


def test_periodic_wrap_matches_shifted_points():
    n = 16
    g = Grid.regular(0, 2 * np.pi / n, (n, n, n), periodic=(True, True, False))
    assert g.period[0] == pytest.approx(2 * np.pi)
    P = g.node_points()
    vec = np.stack([np.sin(P[..., 1]), np.cos(P[..., 0]), np.sin(P[..., 0] + P[..., 1])], -1)
    f = Field(g, vec)
    pts = np.random.default_rng(3).uniform(0, 2 * np.pi, (2000, 3))
    pts[:, 2] = np.clip(pts[:, 2], 0, g.z[-1])
    v0, s0 = f.sample(pts)
    shifted = pts + np.array([2 * np.pi * 3, -2 * np.pi * 2, 0])
    v1, s1 = f.sample(shifted)
    assert np.all(s0 == INSIDE) and np.all(s1 == INSIDE)
    np.testing.assert_allclose(v1, v0, atol=1e-12)
    # the wrap cell between the last node and x0 + L interpolates to node 0
    x_mid = g.x[-1] + 0.5 * (g.x[1] - g.x[0])
    v, _ = f.sample([[x_mid, 0.0, 0.0]])
    np.testing.assert_allclose(v[0], 0.5 * (vec[-1, 0, 0] + vec[0, 0, 0]), atol=1e-14)
    # z is bounded
    _, st = f.sample([[0, 0, g.z[-1] + 1e-9]])
    assert st[0] == OUTSIDE


def test_nan_cells_say_so():
    g = Grid.regular(0, 1.0, (5, 5, 5))
    vec = np.ones(g.shape + (3,))
    vec[2, 2, 2, 1] = np.nan
    f = Field(g, vec)
    _, st = f.sample([[1.5, 1.5, 1.5], [2.0, 2.0, 2.0], [0.5, 0.5, 0.5], [2.9, 2.9, 2.9]])
    assert list(st) == [NAN_CELL, NAN_CELL, INSIDE, NAN_CELL]


def test_a_point_on_the_face_of_a_nan_cell_samples_the_face():
    """On a face the trilinear interpolant is the face's bilinear one: the corners off the face
    carry weight 0 and a NaN there does not count (the cell itself is still a NaN cell)."""
    g = Grid.regular(0, 1.0, (5, 5, 5))
    vec = np.stack(np.meshgrid(g.x, g.y, g.z, indexing="ij"), axis=-1) * [1.0, 2.0, 3.0]
    T = vec[..., 0] + vec[..., 1]
    vec[3:] = np.nan
    T[3:] = np.nan
    f = Field(g, vec, scalars={"T": T})
    pts = [[2.0, 1.25, 0.5], [2.0, 3.0, 4.0], [2.0 + 1e-9, 1.25, 0.5]]
    v, st = f.sample(pts)
    assert list(st) == [INSIDE, INSIDE, NAN_CELL]
    np.testing.assert_allclose(v[:2], [[2.0, 2.5, 1.5], [2.0, 6.0, 12.0]], rtol=1e-15)
    t, st = f.sample_scalar("T", pts)
    assert list(st) == [INSIDE, INSIDE, NAN_CELL]
    np.testing.assert_allclose(t[:2], [4.5, 8.0], rtol=1e-15)  # x + 2 y


@pytest.mark.parametrize("bad", [[0, 1, 1, 2], [0, 2, 1], [0, np.nan, 1]])
def test_bad_coordinates_are_named(bad):
    with pytest.raises(GridError, match="coordinate 'y'"):
        Grid.from_axes([0, 1], bad, [0, 1])


def test_field_shape_errors_state_expected_shape():
    g = Grid.regular(0, 1, (3, 4, 5))
    with pytest.raises(ValueError, match=r"expected \(3, 4, 5, 3\)"):
        Field(g, np.zeros((3, 4, 5)))
    with pytest.raises(ValueError, match=r"scalar 'T'.*expected \(3, 4, 5\)"):
        Field(g, np.zeros((3, 4, 5, 3)), {"T": np.zeros((5, 4, 3))})


def test_lines_slice_iterate_concatenate():
    pts = np.arange(30, dtype=float).reshape(10, 3)
    L = Lines(pts, [0, 3, 3, 7, 10], {"t": np.arange(10.0)}, {"seed_id": np.array([5, 6, 7, 8])})
    assert len(L) == 4 and list(L.lengths) == [3, 0, 4, 3]
    sub = L[[2, 0]]
    assert list(sub.lengths) == [4, 3]
    np.testing.assert_array_equal(sub.point_data["t"], [3, 4, 5, 6, 0, 1, 2])
    np.testing.assert_array_equal(sub.line_data["seed_id"], [7, 5])
    assert [len(x.points) for x in L] == [3, 0, 4, 3]
    back = Lines.concatenate([L[:2], L[2:]])
    assert back.equals(L)
    assert L[-1].line_data["seed_id"][0] == 8
    with pytest.raises(ValueError):
        Lines(pts, [0, 3, 11])
