"""Fields larger than a memory budget, traced brick by brick: the same lines, attributes and
reasons as in memory, bit for bit, for every method, both directions, periodic axes,
NaN holes across brick faces, real data and lazily computed inputs; reads only where lines go,
each brick once when they fit; clear errors where a budget cannot hold a trace."""

import h5py
import numpy as np
import pytest
from test_stored_fields import _same  # (lines equal bit for bit, every array)

from flowkit import trace
from flowkit.cli import main
from flowkit.fields import Field, bricks, load_field, save_field
from flowkit.fields.analytic import ABCFlow
from flowkit.fields.grid import Grid
from flowkit.fields.stored import FieldMemoryError, Stored
from flowkit.integrate.pathlines import pathlines
from flowkit.io.lines_h5 import read_lines

L = 2 * np.pi
SEEDS = np.random.default_rng(5).random((40, 3)) * L


@pytest.fixture(autouse=True)
def _small_files_by_bricks(monkeypatch):
    """Files of any size read brick by brick (a file this small is read whole otherwise)."""
    monkeypatch.setattr(bricks, "WHOLE_BYTES", 0)


def _abc_file(path, n=24, chunk=8, periodic=False, hole=None, t=None):
    """ABC at n^3 nodes, float32, chunked (a brick per chunk); ``hole``: a box of NaN nodes;
    ``t``: a snapshot of an unsteady ABC flow (its coefficients and T change with t)."""
    flow = ABCFlow() if t is None else ABCFlow(A=np.sqrt(3) * (1 + 0.3 * np.sin(t)),
                                               B=np.sqrt(2) * (1 - 0.2 * t), C=1 + 0.1 * t)
    f = flow.to_field(n, bounds=[[0, L]] * 3, periodic=periodic)
    v = f.vector.astype(np.float32)
    t = (np.sin(f.grid.x)[:, None, None] * np.cos(f.grid.y)[None, :, None]
         + f.grid.z[None, None, :] + (t or 0.0)).astype(np.float32)
    if hole is not None:
        v[hole] = np.nan
    save_field(Field(f.grid, v, {"T": t}, source="abc"), path, compression=None)
    with h5py.File(path, "a") as h:  # rewritten chunked: the bricks follow the chunks
        for name, shape in (("vectors/U", (chunk,) * 3 + (3,)), ("scalars/T", (chunk,) * 3)):
            a = h[name][...]
            del h[name]
            h.create_dataset(name, data=a, chunks=shape)
    return path


def _stiff_file(path):
    """(the stiff linear field, float32 in chunks of 4^3 nodes, at ``path``; seeds in it whose
    lines all get flagged stiff)."""
    from flowkit.fields.analytic import LinearField

    f = LinearField.stiff().to_field((9, 9, 33), bounds=[[-1, 1], [-1, 1], [0, 8]])
    save_field(Field(f.grid, f.vector.astype(np.float32), source="stiff"), path, compression=None)
    with h5py.File(path, "a") as h:
        a = h["vectors/U"][...]
        del h["vectors/U"]
        h.create_dataset("vectors/U", data=a, chunks=(4, 4, 4, 3))
    return path, np.random.default_rng(2).uniform([-0.9, -0.9, 0.1], [0.9, 0.9, 1.0], (12, 3))


def _budgeted(path, seeds, budget="120kB", **kw):
    """(lines in memory, lines under ``budget``, the budgeted field: still unread)."""
    whole = trace(load_field(path), seeds, **kw)
    fld = load_field(path)
    lines = trace(fld, seeds, memory=budget, **kw)
    assert not fld.vector_in_memory()
    return whole, lines, fld


CASES = {
    "default": {"max_length": 8.0},
    "both, attributes": {"max_length": 6.0, "direction": "both",
                         "attributes": ["speed", "velocity", "vorticity", "T", "arc_length",
                                        "distance_to_seed"]},
    "plain dopri5": {"max_length": 6.0, "cell_aware": False},
    "rk4": {"max_length": 4.0, "method": "rk4", "cell_aware": False, "step": 0.05},
    "dop853, arc length": {"max_length": 6.0, "method": "dop853", "parameter": "arc_length"},
    "resampled": {"max_length": 6.0, "count": 30, "direction": "both"},
    "loose, crossing faces": {"max_length": 8.0, "rtol": 1e-3},
    "ros34pw2": {"max_length": 6.0, "method": "ros34pw2", "direction": "both"},
}


@pytest.mark.parametrize("case", CASES)
def test_budgeted_traces_equal_traces_in_memory(case, tmp_path):
    whole, lines, _ = _budgeted(_abc_file(tmp_path / "abc.h5"), SEEDS, **CASES[case])
    _same(whole, lines)
    assert lines.attrs["bricks_read"] > 0
    assert len(lines) == len(SEEDS) and lines.offsets[-1] > 5 * len(SEEDS)


def test_stiff_lines_switch_to_the_rosenbrock_stepper_under_a_budget(tmp_path):
    """auto's lines go on with the Rosenbrock stepper where they are flagged stiff, brick by
    brick as in memory."""
    path, seeds = _stiff_file(tmp_path / "stiff.h5")
    whole, lines, _ = _budgeted(path, seeds, "40kB", method="auto", rtol=1e-6, atol=1e-6,
                                max_time=5.0)
    _same(whole, lines)
    assert lines.line_data["ros34pw2"].sum() >= 6 and lines.attrs["bricks_read"] > 0


def test_a_periodic_field_under_a_budget(tmp_path):
    """Lines wrap around periodic axes across the bricks of both ends (the wrap cell's upper
    corners come from node 0); vorticity's stencils wrap too."""
    path = _abc_file(tmp_path / "abcp.h5", periodic=True)
    assert load_field(path).grid.periodic == (True, True, True)
    whole, lines, _ = _budgeted(path, SEEDS, max_length=15.0, attributes=["vorticity", "T"])
    _same(whole, lines)
    assert np.ptp(lines.points, axis=0).max() > L  # the lines did cross the seams


def test_a_nan_hole_across_a_brick_face(tmp_path):
    """NaN nodes on both sides of a brick face end lines there with the in-memory reason."""
    hole = (slice(6, 11), slice(6, 11), slice(None))  # nodes 6..10: across the face at node 8
    path = _abc_file(tmp_path / "hole.h5", hole=hole)
    whole, lines, _ = _budgeted(path, SEEDS, max_length=10.0, direction="both",
                                attributes=["speed"])
    _same(whole, lines)
    assert np.any(lines.line_data["reason"] == 6) or np.any(lines.line_data["reason_backward"] == 6)


def test_the_heated_room_under_a_budget(tmp_path):
    from flowkit.datasets import hotroom

    fld = hotroom()
    path = tmp_path / "room.h5"
    save_field(fld, path)
    b = fld.grid.bounds
    seeds = b[:, 0] + (b[:, 1] - b[:, 0]) * np.random.default_rng(2).random((30, 3))
    whole, lines, _lazy = _budgeted(path, seeds, budget="300kB", max_time=60.0,
                                   attributes=["speed", "T"])
    _same(whole, lines)


def test_a_field_that_fits_is_read_once_and_only_where_lines_go(tmp_path):
    """A large file (here: any) that fits the memory is still read brick by brick."""
    path = _abc_file(tmp_path / "abc.h5")
    n_bricks = 27  # 24 nodes per axis in bricks of 8
    corner = np.random.default_rng(1).random((20, 3)) * 1.0  # seeds near the origin
    fld = load_field(path)
    lines = trace(fld, corner, max_length=0.5)  # the machine's free memory: a slot per brick
    assert not fld.vector_in_memory()
    # each brick read at most once, only the few near the corner
    assert 1 <= lines.attrs["bricks_read"] <= 8 < n_bricks
    field_bytes = 24 ** 3 * 12
    assert lines.attrs["field_bytes_read"] < field_bytes / 4
    # lines that go everywhere: every brick, still once each
    lines = trace(load_field(path), SEEDS, max_length=20.0)
    assert 20 < lines.attrs["bricks_read"] <= n_bricks


def test_the_same_lines_from_a_zarr_store_and_a_dask_dataset_under_a_budget(tmp_path):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("dask")
    from flowkit.fields.readers import from_xarray

    f = ABCFlow().to_field(24, bounds=[[0, L]] * 3, periodic=False)
    v = f.vector.astype(np.float32)
    dims = ("x", "y", "z")
    ds = xr.Dataset({c: (dims, v[..., i]) for i, c in enumerate("uvw")},
                    coords={"x": f.grid.x, "y": f.grid.y, "z": f.grid.z}).chunk(8)
    whole = trace(Field(f.grid, v), SEEDS, max_length=8.0)
    fld = from_xarray(ds, source="dask")
    _same(whole, trace(fld, SEEDS, max_length=8.0, memory="120kB"))
    assert not fld.vector_in_memory()
    pytest.importorskip("zarr")
    ds.to_zarr(tmp_path / "f.zarr")
    fld = load_field(tmp_path / "f.zarr")
    _same(whole, trace(fld, SEEDS, max_length=8.0, memory="120kB"))
    assert not fld.vector_in_memory()


def test_a_budget_too_small_for_a_trace_is_a_named_error_and_leaves_no_file(tmp_path, capsys):
    path = _abc_file(tmp_path / "abc.h5")
    out = tmp_path / "lines.h5"
    rc = main(["trace", str(path), "-o", str(out), "--seeds", "random:10", "--max-length", "4",
               "--memory", "20kB"])
    err = capsys.readouterr().err
    assert rc == 2 and not out.exists() and "Traceback" not in err and err.count("\n") == 1
    assert str(path) in err and "20 kB" in err and "--memory 92.2 kB" in err
    with pytest.raises(FieldMemoryError, match="method auto without cell-aware stepping"):
        trace(load_field(path), SEEDS, memory="120kB", method="auto", cell_aware=False)
    # with a budget that holds a trace, the CLI writes the lines and what it read
    assert main(["trace", str(path), "-o", str(out), "--seeds", "random:10", "--max-length", "4",
                 "--memory", "100kB", "--quiet"]) == 0
    assert read_lines(out).attrs["bricks_read"] > 0


def test_a_brick_is_one_aligned_block_of_nodes():
    """A brick's slot holds its block of nodes (the file's chunk), NaN past the grid's end;
    the bricks of a cell's corners wrap to node 0 past the end of a periodic axis."""
    from flowkit.fields.stored import Stored

    g = Grid.regular(0.0, 1.0, (10, 7, 5), periodic=(True, False, False))
    v = np.arange(10 * 7 * 5 * 3, dtype=np.float64).reshape(10, 7, 5, 3)
    pool = bricks.BrickPool(Stored.of(v), g, 10 ** 6, size=(4, 4, 4))
    assert tuple(pool.count) == (3, 2, 2)
    brick = np.ravel_multi_index((2, 1, 0), (3, 2, 2))
    pool.load(np.array([brick]))
    s = pool.table[brick]
    nodes = pool.pool[s * 4:(s + 1) * 4]
    np.testing.assert_array_equal(nodes[:2, :3], v[8:10, 4:7, 0:4])
    assert np.isnan(nodes[2:]).all() and np.isnan(nodes[:, 3:]).all()  # past the ends
    # the wrap cell (9, 3, 3): x nodes 9 and 0, y 3 and 4, z 3 and 4
    corners = pool.corner_bricks(np.array([[9, 3, 3], [-1, 0, 0]]))
    assert sorted(set(corners[0])) == sorted(
        np.ravel_multi_index((bx, by, bz), (3, 2, 2)) for bx in (2, 0) for by in (0, 1)
        for bz in (0, 1))
    assert (corners[1] == -1).all()


def test_a_budget_far_below_the_field_serves_lines_block_by_block(tmp_path):
    """Lines everywhere in a field six times the pool: the rounds serve the lines of one block
    of bricks at a time, so a brick is read a few times, not once per round that wants it."""
    path = _abc_file(tmp_path / "abc.h5", n=48)  # 216 bricks of 8^3 nodes, 6 kB each
    seeds = np.random.default_rng(3).random((300, 3)) * L
    whole, lines, _ = _budgeted(path, seeds, budget="200kB", max_length=10.0)  # 26 slots
    _same(whole, lines)
    assert lines.attrs["field_bytes_read"] < 5 * 48 ** 3 * 12  # (loading every wanted brick
    # each round read it 20 times over)
    assert lines.attrs["brick_rounds"] > 1


def test_a_bricked_trace_shows_its_progress(tmp_path, capsys):
    path = _abc_file(tmp_path / "abc.h5")
    trace(load_field(path), SEEDS, max_length=4.0, memory="120kB", progress=True)
    err = capsys.readouterr().err
    assert "trace (bricks)" in err and "40/40" in err and "kB read" in err


def test_no_vertex_under_a_budget_gives_empty_attributes(tmp_path):
    """Every seed outside: the lines have no vertex, their attributes none either (they were
    sampled brick by brick from no point, over and over)."""
    fld = load_field(_abc_file(tmp_path / "abc.h5"))
    lines = trace(fld, np.full((3, 3), 50.0), memory="120kB", empty="ignore",
                  attributes=["speed", "vorticity", "T"])
    assert lines.n_points == 0 and lines.point_data["vorticity"].shape == (0, 3)
    assert lines.point_data["T"].shape == (0,)


def test_attributes_under_a_budget_read_no_scalar_they_do_not_use(tmp_path):
    """Vorticity sampled brick by brick leaves T in its file (reading every scalar of the field
    whole for each group cost 4.3 GB at 1024^3)."""
    fld = load_field(_abc_file(tmp_path / "abc.h5"))
    lines = trace(fld, SEEDS[:5], max_length=4.0, memory="120kB", attributes=["vorticity"])
    assert np.isfinite(lines.point_data["vorticity"]).any()
    assert not fld.scalars.in_memory("T") and not fld.vector_in_memory()


# -- pathlines: two snapshots' bricks ----------------------------------------------------------
TIMES = (0.0, 0.7, 1.5, 2.0)


def _series(tmp_path, **kw):
    """An unsteady ABC flow as a series of chunked files: [(time, path)]."""
    return [(t, _abc_file(tmp_path / f"abc_{i}.h5", t=t, **kw)) for i, t in enumerate(TIMES)]


def _in_memory(series):
    """The snapshots read whole, as Fields in memory."""
    out = []
    for t, path in series:
        f = load_field(path)
        _ = f.vector, f.scalars["T"]
        out.append((t, f))
    return out


ATTRIBUTES = ["speed", "velocity", "vorticity", "vorticity_magnitude", "T", "arc_length",
              "distance_to_seed"]
RELEASE = np.random.default_rng(6).uniform(0.0, 2.0, len(SEEDS))  # inside the intervals
PATH_CASES = {
    "forward": {"max_time": 1.5},
    "backward": {"max_time": 1.5, "direction": "backward"},
    "released inside intervals, attributes": {"max_time": 1.0, "attributes": ATTRIBUTES,
                                              "release": RELEASE},
    "backward, released inside intervals, attributes": {
        "max_time": 1.0, "attributes": ATTRIBUTES, "release": RELEASE, "direction": "backward"},
    "dop853, periodic": {"max_time": 2.0, "method": "dop853", "rtol": 1e-8,
                         "attributes": ["vorticity"], "periodic": True},
    "rk4 at fixed steps": {"max_time": 1.5, "method": "rk4", "step": 0.05, "release": RELEASE},
}


@pytest.mark.parametrize("case", PATH_CASES)
def test_budgeted_pathlines_equal_pathlines_in_memory(case, tmp_path):
    kw = dict(PATH_CASES[case])
    release = kw.pop("release", None)
    series = _series(tmp_path, periodic=kw.pop("periodic", False))
    whole = pathlines(_in_memory(series), SEEDS, release, **kw)
    lines = pathlines(series, SEEDS, release, memory="185kB", **kw)  # 12 of 27 bricks, twice
    _same(whole, lines)
    assert lines.attrs["bricks_read"] > 0 and lines.attrs["brick_rounds"] > 1
    assert lines.offsets[-1] > 5 * len(SEEDS)


def test_budgeted_pathlines_through_a_nan_hole_across_a_brick_face(tmp_path):
    hole = (slice(6, 11), slice(6, 11), slice(None))  # nodes 6..10: across the face at node 8
    series = _series(tmp_path, hole=hole)
    whole = pathlines(_in_memory(series), SEEDS, RELEASE, max_length=8.0, attributes=["speed"])
    lines = pathlines(series, SEEDS, RELEASE, max_length=8.0, attributes=["speed"],
                      memory="185kB")
    _same(whole, lines)
    assert np.any(lines.line_data["reason"] == 6)  # nan_field


def test_budgeted_pathlines_hold_two_snapshots_bricks_and_read_none_whole(tmp_path, monkeypatch):
    """The pool holds two time levels under one table; a snapshot is read only while it is one
    of the interval's two, never whole (nor by the attributes), and where the pool holds every
    brick, the snapshot two intervals share is not read again: each brick of each snapshot
    once."""
    series = _series(tmp_path)
    where = {str(path): i for i, (_, path) in enumerate(series)}

    def whole(self, progress=None):
        raise AssertionError(f"{self.where} read whole")

    monkeypatch.setattr(Stored, "read", whole)
    reads = []  # (snapshot, brick, the snapshots of the pool's levels)
    read = bricks.BrickPool._read

    def counting(self, brick, slot):
        if len(self.sources) > 1:  # (the trace's pool; the attributes' have one level each)
            levels = [where[s.where.rsplit(":", 1)[0]] for s in self.sources]
            reads.extend((levels[i], brick, tuple(levels))
                         for i in np.flatnonzero(~self.valid[:, slot]))
        read(self, brick, slot)

    monkeypatch.setattr(bricks.BrickPool, "_read", counting)
    corner = np.random.default_rng(1).random((20, 3)) * 2.0
    lines = pathlines(series, corner, max_time=2.0, memory="185kB", attributes=["vorticity"])
    assert np.isfinite(lines.point_data["vorticity"]).all()
    pairs = [r[2] for r in reads]
    assert set(pairs) == {(0, 1), (1, 2), (2, 3)}
    assert pairs == sorted(pairs)  # each pair's reads before the next pair's
    assert all(snap in pair for snap, _, pair in reads)
    pool_bytes = lines.attrs["brick_pool_bytes"]
    assert pool_bytes <= bricks.POOL_SHARE * 185e3 and pool_bytes == 2 * 12 * 8 ** 3 * 12
    # a budget that holds every brick: each (snapshot, brick) read once, the lines the same
    reads.clear()
    again = pathlines(series, corner, max_time=2.0, memory="10MB")
    assert len(reads) == len({r[:2] for r in reads})
    assert np.array_equal(again.points, lines.points)
