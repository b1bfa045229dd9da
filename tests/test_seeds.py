"""Seed generation: shapes, exact positions, reproducible randomness, files and the CLI spec."""

import numpy as np
import pytest

from flowkit.fields import Field, Grid
from flowkit.fields.analytic import ABCFlow
from flowkit.integrate import seeds
from flowkit.integrate.seeds import SeedError


def check(p, n):
    assert p.shape == (n, 3) and p.dtype == np.float64 and p.flags.c_contiguous


# -- explicit points and files ---------------------------------------------------------------
def test_points():
    check(seeds.points([1, 2, 3]), 1)
    p = seeds.points(np.arange(12).reshape(4, 3))
    check(p, 4)
    np.testing.assert_array_equal(p[2], [6, 7, 8])
    check(seeds.points(np.zeros((0, 3))), 0)
    with pytest.raises(SeedError, match=r"expected shape \(n, 3\).*\(4, 2\)"):
        seeds.points(np.zeros((4, 2)))
    with pytest.raises(SeedError, match=r"point 1 is not finite.*nan.*\(2 such\)"):
        seeds.points([[0, 0, 0], [0, np.nan, 0], [np.inf, 0, 0]])
    with pytest.raises(SeedError, match="not an array of numbers"):
        seeds.points([["a", "b", "c"]])


def test_from_npy(tmp_path):
    ref = np.random.default_rng(0).normal(size=(7, 3))
    np.save(tmp_path / "s.npy", ref)
    np.testing.assert_array_equal(seeds.from_file(tmp_path / "s.npy"), ref)
    np.save(tmp_path / "i.npy", np.arange(6).reshape(2, 3))
    np.testing.assert_array_equal(seeds.from_file(tmp_path / "i.npy"), [[0, 1, 2], [3, 4, 5]])


def test_from_npy_bad(tmp_path):
    obj = np.empty(2, dtype=object)
    obj[:] = [{"a": 1}, [1, 2]]
    np.save(tmp_path / "pickled.npy", obj, allow_pickle=True)
    with pytest.raises(SeedError, match=r"pickled.npy: holds pickled Python objects; refused"):
        seeds.from_file(tmp_path / "pickled.npy")
    np.save(tmp_path / "shape.npy", np.zeros((5, 4)))
    with pytest.raises(SeedError, match=r"shape.npy: expected shape \(n, 3\).*\(5, 4\)"):
        seeds.from_file(tmp_path / "shape.npy")
    np.save(tmp_path / "full.npy", np.zeros((100, 3)))
    (tmp_path / "trunc.npy").write_bytes((tmp_path / "full.npy").read_bytes()[:300])
    with pytest.raises(SeedError, match=r"trunc.npy: not a readable .npy array"):
        seeds.from_file(tmp_path / "trunc.npy")
    np.save(tmp_path / "str.npy", np.array([["a", "b", "c"]]))
    with pytest.raises(SeedError, match=r"str.npy: array of dtype <U1, expected numbers"):
        seeds.from_file(tmp_path / "str.npy")
    np.save(tmp_path / "empty.npy", np.zeros((0, 3)))
    with pytest.raises(SeedError, match=r"empty.npy: holds no seed points"):
        seeds.from_file(tmp_path / "empty.npy")


def test_from_text(tmp_path):
    f = tmp_path / "s.csv"
    f.write_text("x,y,z\n# a comment\n1,2,3\n\n 4.5 , -6e-1, 7  # trailing\n")
    np.testing.assert_array_equal(seeds.from_file(f), [[1, 2, 3], [4.5, -0.6, 7]])
    g = tmp_path / "s.txt"
    g.write_text("1 2 3\n4\t5\t6\n")
    np.testing.assert_array_equal(seeds.from_file(g), [[1, 2, 3], [4, 5, 6]])


@pytest.mark.parametrize("text, msg", [
    ("x,y,z\n1,2,3\n4,5\n", r"bad.csv line 3: expected 3 columns \(x, y, z\), got 2: '4,5'"),
    ("1,2,3\n1,2,3,4\n", r"bad.csv line 2: expected 3 columns \(x, y, z\), got 4"),
    ("x,y,z\n1,2,3\n1,two,3\n", r"bad.csv line 3: not numbers: '1,two,3'"),
    ("1,2,3\n1,nan,3\n", r"bad.csv line 2: non-finite coordinate"),
    ("x,y,z\n# nothing\n", r"bad.csv: holds no seed points"),
])
def test_from_text_bad(tmp_path, text, msg):
    f = tmp_path / "bad.csv"
    f.write_text(text)
    with pytest.raises(SeedError, match=msg):
        seeds.from_file(f)


def test_from_file_missing_and_unknown(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.npy: seed file not found"):
        seeds.from_file(tmp_path / "nope.npy")
    with pytest.raises(SeedError, match=r"s.vtk: unknown seed file type '.vtk'; use one of .npy"):
        seeds.from_file(tmp_path / "s.vtk")


# -- generators ------------------------------------------------------------------------------
def test_line():
    p = seeds.line([0, 0, 0], [1, 2, -2], 4)
    check(p, 4)
    np.testing.assert_array_equal(p[0], [0, 0, 0])
    np.testing.assert_array_equal(p[-1], [1, 2, -2])
    np.testing.assert_allclose(np.linalg.norm(np.diff(p, axis=0), axis=1), 1.0, rtol=1e-15)
    np.testing.assert_array_equal(seeds.line([1, 1, 1], [2, 2, 2], 1), [[1, 1, 1]])
    with pytest.raises(SeedError, match="line: n must be a positive integer, got 0"):
        seeds.line([0, 0, 0], [1, 1, 1], 0)


def test_plane():
    o, u, v = np.array([1.0, 0, 0]), np.array([0, 2.0, 0]), np.array([0, 1.0, 1.0])
    p = seeds.plane(o, u, v, 3, 2)
    check(p, 6)
    # point i + nu * j is o + i/(nu-1) u + j/(nv-1) v
    for j in range(2):
        for i in range(3):
            np.testing.assert_allclose(p[i + 3 * j], o + i / 2 * u + j * v, atol=1e-15)
    normal = np.cross(u, v)
    np.testing.assert_allclose((p - o) @ normal, 0.0, atol=1e-14)
    check(seeds.plane(o, u, v, 1, 5), 5)
    with pytest.raises(SeedError, match="not parallel"):
        seeds.plane(o, u, 3 * u, 2, 2)
    with pytest.raises(SeedError, match="not parallel"):
        seeds.plane(o, [0, 0, 0], v, 2, 2)


def test_box_lattice():
    p = seeds.box([0, -1, 2], [1, 1, 3], 3)
    check(p, 27)
    g = Grid.regular([0, -1, 2], [0.5, 1.0, 0.5], (3, 3, 3))
    np.testing.assert_allclose(p, g.node_points().reshape(-1, 3), atol=1e-15)  # same order
    q = seeds.box([0, 0, 0], [1, 2, 3], (2, 3, 4))
    check(q, 24)
    np.testing.assert_array_equal(q.min(0), [0, 0, 0])
    np.testing.assert_array_equal(q.max(0), [1, 2, 3])
    flat = seeds.box([0, 0, 0.5], [1, 1, 0.5], 4)  # a flat axis gets one node
    check(flat, 16)
    assert np.all(flat[:, 2] == 0.5)
    with pytest.raises(SeedError, match=r"box: lo \[0.0, 2.0, 0.0\] must not exceed hi"):
        seeds.box([0, 2, 0], [1, 1, 1], 3)
    with pytest.raises(SeedError, match="box: nz must be a positive integer"):
        seeds.box([0, 0, 0], [1, 1, 1], (2, 2, 0))


def test_box_random_is_reproducible_and_uniform():
    lo, hi = np.array([0.0, -1, 2]), np.array([1.0, 1, 3])
    p = seeds.box(lo, hi, 20000, random=True, seed=5)
    check(p, 20000)
    assert np.all((p >= lo) & (p <= hi))
    np.testing.assert_array_equal(p, seeds.box(lo, hi, 20000, random=True, seed=5))
    assert not np.array_equal(p, seeds.box(lo, hi, 20000, random=True, seed=6))
    # uniform: the mean is within 4 standard errors of the centre on each axis
    se = (hi - lo) / np.sqrt(12 * 20000)
    assert np.all(np.abs(p.mean(0) - (lo + hi) / 2) < 4 * se)
    check(seeds.box(lo, hi, (2, 3, 4), random=True), 24)


def test_random_in_bounds_grid_and_analytic():
    b = np.array([[0.0, 1], [2, 3], [-1, 1]])
    p = seeds.random_in(b, 500, seed=1)
    check(p, 500)
    assert np.all((p >= b[:, 0]) & (p <= b[:, 1]))
    # same draw as a random box over the same bounds
    np.testing.assert_array_equal(p, seeds.box(b[:, 0], b[:, 1], 500, random=True, seed=1))
    g = Grid.regular(0, 0.5, (3, 5, 2))
    q = seeds.random_in(g, 100)
    assert np.all((q >= g.bounds[:, 0]) & (q <= g.bounds[:, 1]))
    abc = seeds.random_in(ABCFlow(), 100)
    assert np.all((abc >= 0) & (abc <= 2 * np.pi))
    with pytest.raises(SeedError, match=r"random: domain bounds must be \(3, 2\)"):
        seeds.random_in([[0, 1], [0, 1]], 10)


def test_random_in_field_rejects_nan_cells():
    g = Grid.regular(0, 1.0, (5, 5, 5))
    vec = np.ones(g.shape + (3,))
    vec[:2] = np.nan  # every cell with x < 2 touches a NaN node
    f = Field(g, vec, source="holey.npz")
    p = seeds.random_in(f, 300, seed=3)
    check(p, 300)
    assert p[:, 0].min() >= 2.0 - 1e-12
    np.testing.assert_array_equal(p, seeds.random_in(f, 300, seed=3))
    assert np.all(f.sample(p)[1] == 0)
    dead = Field(g, np.full(g.shape + (3,), np.nan), source="dead.npz")
    with pytest.raises(SeedError, match=r"dead.npz: only 0 of 10 random seeds fell in valid"):
        seeds.random_in(dead, 10)


# -- the --seeds spec ------------------------------------------------------------------------
def test_parse_spec_forms(tmp_path):
    P = seeds.parse_seed_spec
    np.testing.assert_array_equal(P("line:0,0,0:1,2,3:5"), seeds.line([0, 0, 0], [1, 2, 3], 5))
    np.testing.assert_array_equal(P("plane:0,0,0:1,0,0:0,1,0:3,4"),
                                  seeds.plane([0, 0, 0], [1, 0, 0], [0, 1, 0], 3, 4))
    np.testing.assert_array_equal(P("box:0,0,0:1,1,1:3"), seeds.box([0, 0, 0], [1, 1, 1], 3))
    np.testing.assert_array_equal(P("box:0,0,0:1,1,1:2,3,4"), seeds.box([0, 0, 0], [1, 1, 1], (2, 3, 4)))
    np.testing.assert_array_equal(P("BOX:0,0,0:1,1,1:50:random:7"),
                                  seeds.box([0, 0, 0], [1, 1, 1], 50, random=True, seed=7))
    np.testing.assert_array_equal(P("box:0,0,0:1,1,1:50:random"),
                                  seeds.box([0, 0, 0], [1, 1, 1], 50, random=True, seed=0))
    f = ABCFlow().to_field(8)
    np.testing.assert_array_equal(P("random:40:2", f), seeds.random_in(f, 40, seed=2))
    np.testing.assert_array_equal(P("random:40", f), seeds.random_in(f, 40, seed=0))
    np.testing.assert_array_equal(P("points:1,2,3:-4,5e-1,6"), [[1, 2, 3], [-4, 0.5, 6]])
    np.save(tmp_path / "s.npy", np.eye(3))
    np.testing.assert_array_equal(P(str(tmp_path / "s.npy")), np.eye(3))
    (tmp_path / "s.csv").write_text("x,y,z\n1,2,3\n")
    np.testing.assert_array_equal(P(str(tmp_path / "s.csv")), [[1, 2, 3]])


@pytest.mark.parametrize("spec, msg", [
    ("lines:0,0,0:1,1,1:3", r"'lines:0,0,0:1,1,1:3': not a seed file nor a known form; allowed: .*line:"),
    ("seeds.dat", r"'seeds.dat': not a seed file nor a known form"),
    ("line:0,0,0:1,1:10", r"part 2 '1,1' must be a point x,y,z.*form: line:x0,y0,z0:x1,y1,z1:n"),
    ("line:0,0,0:1,1,1", r"'line' takes 3 parts after 'line:', got 2"),
    ("line:0,0,0:1,1,x:4", r"part 2 '1,1,x' must be a point"),
    ("line:0,0,0:1,1,inf:4", r"part 2 '1,1,inf' must be a point x,y,z \(3 comma-separated finite"),
    ("line:0,0,0:1,1,1:0", r"part 3 '0' must be n, an integer >= 1"),
    ("line:0,0,0:1,1,1:2.5", r"part 3 '2.5' must be n, an integer >= 1"),
    ("plane:0,0,0:1,0,0:0,1,0:3", r"part 4 '3' must be nu,nv, 2 comma-separated"),
    ("plane:0,0,0:1,0,0:2,0,0:3,3", r"plane: u .* not parallel; form: plane:"),
    ("box:0,0,0:1,1,1:3:rand", r"part 4 'rand' must be the word 'random'"),
    ("box:0,0,0:1,1,1:3:random:-1", r"part 5 '-1' must be seed, an integer >= 0"),
    ("box:1,0,0:0,1,1:3", r"box: lo .* must not exceed hi"),
    ("box:0,0,0:1,1,1:2,2", r"part 3 '2,2' must be n, an integer >= 1"),
    ("box:0,0,0:1,1,1:3:random:1:2", r"'box' takes 3 to 5 parts"),
    ("random:100", r"'random' draws in the field's domain, but no field was given"),
    ("points:1,2", r"part 1 '1,2' must be a point"),
])
def test_parse_spec_errors(spec, msg):
    with pytest.raises(SeedError, match=msg) as e:
        seeds.parse_seed_spec(spec)
    assert f"seed spec '{spec}'" in str(e.value)


def test_parse_spec_missing_file():
    with pytest.raises(FileNotFoundError, match="missing.csv: seed file not found"):
        seeds.parse_seed_spec("missing.csv")
