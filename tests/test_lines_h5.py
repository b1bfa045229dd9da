"""Lines <-> HDF5: round trips, the two readers (xarray/CF and VTK/VTKHDF), sharing, atomicity,
errors. vtk (interop extra: CI installs it) and netCDF4 (no extra) are peers: their checks are skipped
(importorskip) where they are absent; xarray + h5netcdf (io extra) are required."""

import os
import tracemalloc

import h5py
import numpy as np
import pytest
import xarray as xr  # the "io" extra, installed by `make test`

from flowkit.cli.info import describe_lines
from flowkit.integrate.reasons import REASON_NAMES, Reason
from flowkit.io.atomic import atomic_path
from flowkit.io.lines_h5 import (
    FORMAT_VERSION,
    LinesFileError,
    LinesWriter,
    is_lines_file,
    read_lines,
    write_lines,
)
from flowkit.lines import Lines


def make_lines(lengths, seed=0, synth_seed_id=False):
    """Lines with the conventional attributes, scalar and vector, of the given vertex counts."""
    rng = np.random.default_rng(seed)
    lengths = np.asarray(lengths, np.int64)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    n, nl = int(offsets[-1]), len(lengths)
    line_data = {"reason": rng.integers(0, len(Reason), nl).astype(np.int8),
                 "n_accepted": rng.integers(0, 500, nl).astype(np.int32),
                 "n_rejected": rng.integers(0, 50, nl).astype(np.int32)}
    if not synth_seed_id:
        line_data["seed_id"] = rng.permutation(10 * nl)[:nl].astype(np.int64)
    return Lines(
        rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-3, 3, size=(n, 1)),
        offsets,
        {"time": rng.normal(size=n), "speed": rng.random(n).astype(np.float32),
         "velocity": rng.normal(size=(n, 3)), "vorticity": rng.normal(size=(n, 3)).astype(np.float32),
         "T": rng.random(n)},
        line_data,
        {"method": "dopri5", "rtol": 1e-8, "n_threads": 2, "cell_aware": True,
         "source": "heated room / U", "tolerances": [1e-6, 1e-9], "options": {"max_length": 10.0}},
    )


LENGTHS = [5, 0, 1, 17, 2, 0, 300, 3]


def assert_exact(a: Lines, b: Lines):
    assert a.equals(b)  # rtol = atol = 0
    for k in a.point_data:
        assert a.point_data[k].dtype == b.point_data[k].dtype, k
    for k in a.line_data:
        assert a.line_data[k].dtype == b.line_data[k].dtype, k


def test_round_trip_float64_is_exact_with_dtypes_and_metadata(tmp_path):
    lines = make_lines(LENGTHS)
    back = read_lines(write_lines(lines, tmp_path / "l.h5", position_dtype="float64"))
    assert back.points.dtype == np.float64
    assert_exact(back, lines)
    assert back.attrs == lines.attrs


def test_round_trip_float32_positions_round_once(tmp_path):
    lines = make_lines(LENGTHS)
    back = read_lines(write_lines(lines, tmp_path / "l.h5"))  # float32 is the default
    assert back.points.dtype == np.float32
    assert np.array_equal(back.points, lines.points.astype(np.float32))  # one rounding, no more
    assert not np.array_equal(back.points.astype(np.float64), lines.points)  # really float32
    rel = np.abs(back.points - lines.points) / np.abs(lines.points)
    assert rel.max() <= 2.0 ** -24
    assert back.equals(lines, rtol=2.0 ** -24, atol=0.0)
    for k, v in lines.point_data.items():  # attributes keep their own dtype, exactly
        assert np.array_equal(back.point_data[k], v) and back.point_data[k].dtype == v.dtype


@pytest.mark.parametrize("compression", ["gzip", "lzf", None])
def test_compression_is_applied_and_lossless(tmp_path, compression):
    lines = make_lines(LENGTHS)
    path = write_lines(lines, tmp_path / "l.h5", compression=compression, position_dtype="float64")
    assert_exact(read_lines(path), lines)
    with h5py.File(path) as f:
        for name in ("VTKHDF/Points", "time", "velocity", "seed_id", "VTKHDF/Lines/Connectivity"):
            assert f[name].compression == compression, name


@pytest.mark.parametrize("lengths", [[], [0], [0, 0, 0], [1], [1, 0, 1]])
def test_empty_and_degenerate_lines_round_trip(tmp_path, lengths):
    lines = make_lines(lengths)
    back = read_lines(write_lines(lines, tmp_path / "l.h5", position_dtype="float64"))
    assert len(back) == len(lengths) and back.n_points == sum(lengths)
    assert_exact(back, lines)


def test_bare_lines_without_seed_id_round_trip(tmp_path):
    """Lines.empty() and lines without seed_id: the file still has a trajectory_id variable
    (the line index, marked synthesized), and reading gives back exactly what was written."""
    for lines in (Lines.empty(), make_lines([3, 4], synth_seed_id=True)):
        path = write_lines(lines, tmp_path / "l.h5", position_dtype="float64")
        assert_exact(read_lines(path), lines)
        with h5py.File(path) as f:
            assert f["seed_id"].attrs["cf_role"] == "trajectory_id"
            assert np.array_equal(f["seed_id"][...], np.arange(len(lines)))


def test_streamed_chunks_equal_one_write(tmp_path):
    rng = np.random.default_rng(3)
    parts = [make_lines(rng.integers(0, 40, size=rng.integers(0, 30)), seed=i) for i in range(25)]
    parts.insert(7, make_lines([]))  # an empty chunk in the middle is fine
    whole = Lines.concatenate(parts)
    one = write_lines(whole, tmp_path / "one.h5")
    with LinesWriter.like(parts[0], tmp_path / "many.h5", chunk_points=64, chunk_lines=8) as w:
        for p in parts:
            w.append(p)
    many, single = read_lines(tmp_path / "many.h5"), read_lines(one)
    assert_exact(many, single)
    assert many.equals(whole, rtol=2.0 ** -24)
    with h5py.File(tmp_path / "many.h5") as f:  # the VTK topology is global, not per chunk
        assert np.array_equal(f["VTKHDF/Lines/Offsets"][...], whole.offsets)
        assert np.array_equal(f["VTKHDF/Lines/Connectivity"][...], np.arange(whole.n_points))
        assert f["VTKHDF/NumberOfPoints"][0] == whole.n_points
        assert f["VTKHDF/Lines/NumberOfCells"][0] == len(whole)


def test_gzip_chunks_compressed_in_parallel_are_what_hdf5_stores(tmp_path):
    """The writer deflates gzip chunks itself, on a thread pool, and stores them raw: every chunk
    holds, after inflating, exactly the shuffled bytes HDF5's own filter pipeline stores for the
    same rows (including the zero-padded last chunk), and plain h5py reads the file back."""
    import zlib

    rng = np.random.default_rng(5)
    parts = [make_lines(rng.integers(0, 50, size=rng.integers(1, 20)), seed=i) for i in range(12)]
    whole = Lines.concatenate(parts)
    with LinesWriter.like(parts[0], tmp_path / "ours.h5", chunk_points=100, chunk_lines=16) as w:
        for p in parts:
            w.append(p)
    with h5py.File(tmp_path / "ours.h5") as ours, h5py.File(tmp_path / "ref.h5", "w") as ref:
        names = ["VTKHDF/Points", "VTKHDF/PointData/velocity", "VTKHDF/Lines/Offsets",
                 "VTKHDF/Lines/Connectivity", "rowSize", "seed_id"]
        for name in names:
            ds = ours[name]
            assert ds.compression == "gzip" and ds.shuffle
            r = ref.create_dataset(name, data=ds[...], chunks=ds.chunks, compression="gzip",
                                   compression_opts=ds.compression_opts, shuffle=True)
            n_chunks = -(-ds.shape[0] // ds.chunks[0])
            assert n_chunks > 1 and ds.id.get_num_chunks() == n_chunks, name
            for k in range(n_chunks):
                at = (k * ds.chunks[0],) + (0,) * (ds.ndim - 1)
                (mask, a), (_, b) = ds.id.read_direct_chunk(at), r.id.read_direct_chunk(at)
                assert mask == 0 and zlib.decompress(a) == zlib.decompress(b), (name, k)
    assert read_lines(tmp_path / "ours.h5").equals(whole, rtol=2.0 ** -24)


def test_streaming_memory_stays_about_one_chunk(tmp_path):
    """40 chunks of 20 000 vertices (~1.3 MB of arrays each, 52 MB in all): the Python-side peak
    while streaming stays within a few chunks, not the total."""
    def chunk(i):
        return make_lines([2000] * 10, seed=i)
    one = chunk(0)
    chunk_bytes = one.points.nbytes + sum(v.nbytes for v in one.point_data.values())
    tracemalloc.start()
    try:
        with LinesWriter.like(one, tmp_path / "big.h5", compression=None) as w:
            for i in range(40):
                w.append(chunk(i))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 4 * chunk_bytes, (peak, chunk_bytes)
    assert read_lines(tmp_path / "big.h5", attributes=[]).n_points == 40 * 20000


def test_read_only_requested_attributes(tmp_path):
    lines = make_lines(LENGTHS)
    path = write_lines(lines, tmp_path / "l.h5")
    assert set(read_lines(path, attributes="time").point_data) == {"time"}  # one name as str
    some = read_lines(path, attributes=["speed", "velocity", "reason"])
    assert set(some.point_data) == {"speed", "velocity"} and set(some.line_data) == {"reason"}
    assert np.array_equal(some.point_data["velocity"], lines.point_data["velocity"])
    bare = read_lines(path, attributes=[])
    assert not bare.point_data and not bare.line_data
    assert np.array_equal(bare.offsets, lines.offsets)


def test_missing_attribute_lists_what_exists(tmp_path):
    path = write_lines(make_lines(LENGTHS), tmp_path / "l.h5")
    with pytest.raises(KeyError) as e:
        read_lines(path, attributes=["time", "pressure"])
    msg = e.value.args[0]
    assert "pressure" in msg and str(path) in msg
    for name in ("time", "speed", "velocity", "vorticity", "T", "seed_id", "reason"):
        assert f"'{name}'" in msg


@pytest.mark.parametrize("engine", ["h5netcdf", "netcdf4"])
def test_xarray_sees_cf_trajectories(tmp_path, engine):
    if engine == "netcdf4":  # netCDF4 is no flowkit dependency: an optional peer, like vtk
        pytest.importorskip("netCDF4")
    lines = make_lines(LENGTHS)
    path = write_lines(lines, tmp_path / "l.h5", position_dtype="float64")
    with xr.open_dataset(path, engine=engine) as ds:
        assert ds.attrs["featureType"] == "trajectory"
        assert ds.attrs["Conventions"].startswith("CF-1.")
        assert ds.attrs["flowkit_format"] == "lines"
        assert ds.attrs["flowkit_format_version"] == FORMAT_VERSION
        assert ds.attrs["method"] == "dopri5"
        assert ds.sizes["obs"] == lines.n_points and ds.sizes["trajectory"] == len(lines)
        for axis, name in enumerate("xyz"):
            assert ds[name].dims == ("obs",) and ds[name].attrs["axis"] == name.upper()
            assert "units" in ds[name].attrs
            assert np.array_equal(ds[name].values, lines.points[:, axis])
        assert ds.velocity.dims == ("obs", "component")
        assert np.array_equal(ds.velocity.values, lines.point_data["velocity"])
        assert ds.T.dims == ("obs",) and np.array_equal(ds.T.values, lines.point_data["T"])
        assert ds.rowSize.attrs["sample_dimension"] == "obs" and "long_name" in ds.rowSize.attrs
        assert np.array_equal(ds.rowSize.values, lines.lengths)
        roles = [v for v in ds.variables if ds[v].attrs.get("cf_role") == "trajectory_id"]
        assert roles == ["seed_id"] and ds.seed_id.dims == ("trajectory",)
        assert np.array_equal(ds.seed_id.values, lines.line_data["seed_id"])
        # reason codes: CF flags, and the names stored beside the codes
        assert ds.reason.dims == ("trajectory",)
        assert list(ds.reason.attrs["flag_values"]) == [r.value for r in Reason]
        assert ds.reason.attrs["flag_meanings"].split() == REASON_NAMES
        assert list(ds.reason_name.values) == REASON_NAMES
        names = ds.reason_name.sel(reason_code=ds.reason).values
        assert list(names) == [Reason(c).label for c in lines.line_data["reason"]]
        # the ragged representation: line i = rows offsets[i]:offsets[i+1]
        starts = np.concatenate([[0], np.cumsum(ds.rowSize.values)])
        i = int(np.argmax(lines.lengths))
        assert np.array_equal(ds.time.values[starts[i]:starts[i + 1]], lines.line_attribute("time", i))


def test_vtk_hdf_reader_opens_polydata(tmp_path, vtk):
    from vtk.util.numpy_support import vtk_to_numpy

    lines = make_lines(LENGTHS)
    path = write_lines(lines, tmp_path / "l.h5")
    reader = vtk.vtkHDFReader()
    assert reader.CanReadFile(str(path))
    reader.SetFileName(str(path))
    reader.Update()
    out = reader.GetOutput()
    assert out.IsA("vtkPolyData")
    assert out.GetNumberOfPoints() == lines.n_points
    assert out.GetNumberOfCells() == out.GetNumberOfLines() == len(lines)
    assert np.array_equal(vtk_to_numpy(out.GetPoints().GetData()),
                          lines.points.astype(np.float32))
    cells = out.GetLines()
    assert np.array_equal(vtk_to_numpy(cells.GetOffsetsArray()), lines.offsets)
    assert np.array_equal(vtk_to_numpy(cells.GetConnectivityArray()), np.arange(lines.n_points))
    pd, cd = out.GetPointData(), out.GetCellData()
    assert {pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays())} == set(lines.point_data)
    assert {cd.GetArrayName(i) for i in range(cd.GetNumberOfArrays())} == set(lines.line_data)
    assert pd.GetArray("velocity").GetNumberOfComponents() == 3
    assert np.array_equal(vtk_to_numpy(pd.GetArray("velocity")), lines.point_data["velocity"])
    assert np.array_equal(vtk_to_numpy(pd.GetArray("T")), lines.point_data["T"])
    for name in ("seed_id", "reason"):
        assert np.array_equal(vtk_to_numpy(cd.GetArray(name)), lines.line_data[name])


def test_vtkhdf_group_has_every_required_dataset(tmp_path):
    lines = make_lines(LENGTHS)
    with h5py.File(write_lines(lines, tmp_path / "l.h5")) as f:
        g = f["VTKHDF"]
        assert tuple(g.attrs["Version"]) == (2, 1)
        t = g.attrs.get_id("Type").get_type()
        assert not t.is_variable_str() and t.get_cset() == h5py.h5t.CSET_ASCII
        assert g.attrs["Type"] == b"PolyData"
        assert g.attrs["flowkit_format_version"] == FORMAT_VERSION
        assert g["NumberOfPoints"][...].tolist() == [lines.n_points]
        assert g["Points"].shape == (lines.n_points, 3)
        for topo in ("Vertices", "Polygons", "Strips"):
            assert g[f"{topo}/NumberOfCells"][...].tolist() == [0]
            assert g[f"{topo}/NumberOfConnectivityIds"][...].tolist() == [0]
            assert g[f"{topo}/Offsets"][...].tolist() == [0]
            assert g[f"{topo}/Connectivity"].shape == (0,)
        assert g["Lines/NumberOfCells"][...].tolist() == [len(lines)]
        assert g["Lines/NumberOfConnectivityIds"][...].tolist() == [lines.n_points]


def test_datasets_are_shared_not_copied(tmp_path):
    lines = make_lines([2000] * 20)
    path = write_lines(lines, tmp_path / "l.h5", compression=None)
    with h5py.File(path) as f:
        for name in lines.point_data:
            assert f[name].id == f[f"VTKHDF/PointData/{name}"].id, name  # one object, two names
        for name in lines.line_data:
            assert f[name].id == f[f"VTKHDF/CellData/{name}"].id, name
        assert f["time"].id != f["T"].id  # the comparison can fail
        for name in "xyz":  # positions: stored once, x/y/z are views of Points' columns
            assert f[name].is_virtual
            (src,) = f[name].virtual_sources()
            assert src.file_name == "." and src.dset_name == "/VTKHDF/Points"
    # stored once: the file is the raw data (with int64 offsets, row sizes and connectivity)
    # plus metadata; a copy of the point attributes would add 2.2 MB
    raw = (lines.points.astype(np.float32).nbytes + 8 * (lines.n_points + 2 * len(lines) + 1)
           + sum(v.nbytes for v in (*lines.point_data.values(), *lines.line_data.values())))
    assert raw < os.path.getsize(path) < raw + 100_000  # ~65 kB of HDF5 metadata


def test_failed_write_leaves_existing_file_untouched(tmp_path):
    target = tmp_path / "l.h5"
    write_lines(make_lines([4, 5]), target)
    before = target.read_bytes()
    with (pytest.raises(RuntimeError, match="tracer crashed"),
          LinesWriter.like(make_lines([3]), target) as w):
        w.append(make_lines([3, 3], seed=1))
        raise RuntimeError("tracer crashed")
    with (pytest.raises(ValueError, match="line attributes"),
          LinesWriter.like(make_lines([3]), target) as w):
        w.append(make_lines([3], synth_seed_id=True))  # wrong attribute set
    assert target.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["l.h5"]  # no temporary left behind
    write_lines(make_lines([7]), target)  # success replaces it
    assert len(read_lines(target)) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["l.h5"]


def test_atomic_path_helper(tmp_path):
    target = tmp_path / "out.png"
    target.write_bytes(b"old")
    with pytest.raises(OSError), atomic_path(target) as tmp:
        assert tmp.parent == tmp_path and tmp.suffix == ".png" and tmp != target
        tmp.write_bytes(b"half")
        raise OSError("disk full")
    assert target.read_bytes() == b"old" and not tmp.exists()
    with atomic_path(target) as tmp:
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new" and not tmp.exists()
    with pytest.raises(FileNotFoundError, match="does not exist"):
        atomic_path(tmp_path / "nowhere" / "x.h5")


def test_reason_codes_are_translated_by_name(tmp_path):
    """A file whose reason table numbers the reasons differently (an older or newer flowkit)
    reads back with today's codes: the names beside the codes decide."""
    lines = make_lines(LENGTHS)
    path = write_lines(lines, tmp_path / "l.h5")
    perm = np.random.default_rng(5).permutation(len(Reason))  # file code c means Reason(perm[c])
    with h5py.File(path, "r+") as f:
        f["reason_name"][...] = [Reason(int(p)).label for p in perm]
        inverse = np.argsort(perm)
        f["reason"][...] = inverse[lines.line_data["reason"]].astype(np.int8)
    assert np.array_equal(read_lines(path).line_data["reason"], lines.line_data["reason"])
    with h5py.File(path, "r+") as f:
        f["reason_name"][0] = "eaten_by_grue"
    with pytest.raises(LinesFileError, match="eaten_by_grue"):
        read_lines(path)


def test_summary_reports_counts_reasons_ranges_metadata(tmp_path):
    lines = make_lines(LENGTHS)
    lines.line_data["reason"][:] = [0, 0, 7, 1, 1, 7, 1, 3]
    text = describe_lines(write_lines(lines, tmp_path / "l.h5"))
    assert f"lines: {len(lines)}" in text and f"vertices: {lines.n_points}" in text
    assert f"min 0  median {np.median(lines.lengths):g}  max 300" in text
    assert "out_of_domain 2, max_length 3, max_steps 1, seed_outside 2" in text
    t = lines.point_data["time"]
    assert f"[{t.min():.6g}, {t.max():.6g}]" in text
    assert "velocity" in text and "float64 x3" in text
    assert "method = dopri5" in text and "rtol = 1e-08" in text
    assert describe_lines(write_lines(Lines.empty(), tmp_path / "e.h5")).count("lines: 0") == 1


def test_not_a_lines_file_errors(tmp_path):
    text = tmp_path / "notes.h5"
    text.write_text("not hdf5 at all\n")
    with pytest.raises(LinesFileError, match="not an HDF5 file"):
        read_lines(text)
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["data"] = np.arange(3)
    with pytest.raises(LinesFileError, match="not a flowkit lines file"):
        read_lines(plain)
    with h5py.File(plain, "a") as f:
        f.attrs["flowkit_format"] = "field"
    with pytest.raises(LinesFileError, match="'field' file"):
        describe_lines(plain)
    assert not is_lines_file(plain) and not is_lines_file(text)
    with pytest.raises(FileNotFoundError, match="missing.h5"):
        read_lines(tmp_path / "missing.h5")


def test_truncated_file_error(tmp_path):
    path = write_lines(make_lines([2000] * 20), tmp_path / "l.h5", compression=None)
    assert is_lines_file(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(LinesFileError, match=r"l\.h5.*truncated"):
        read_lines(path)


def test_future_format_version_error(tmp_path):
    path = write_lines(make_lines([3]), tmp_path / "l.h5")
    with h5py.File(path, "r+") as f:
        f.attrs["flowkit_format_version"] = FORMAT_VERSION + 1
    with pytest.raises(LinesFileError) as e:
        read_lines(path)
    assert f"version {FORMAT_VERSION + 1}" in str(e.value)
    assert f"reads lines format version {FORMAT_VERSION}" in str(e.value)


def test_writer_rejects_bad_schemas(tmp_path):
    path = tmp_path / "l.h5"
    with pytest.raises(ValueError, match="'x'"):
        LinesWriter(path, {"x": "float64"})
    with pytest.raises(ValueError, match="'label'.*dtype"):
        LinesWriter(path, {"label": "U5"})
    with pytest.raises(ValueError, match="clash"):
        LinesWriter(path, {"speed": "float64"}, {"speed": "float64"})
    with pytest.raises(ValueError, match="position_dtype"):
        LinesWriter(path, position_dtype="float16")
    with pytest.raises(ValueError, match="compression"):
        LinesWriter(path, compression="zstd")
    with pytest.raises(ValueError, match="reserved"):
        write_lines(make_lines([2]), path, attrs={"featureType": "point"})
    with pytest.raises(ValueError, match="metadata 'names'"):  # checked when the writer opens
        LinesWriter(path, attrs={"names": np.array(["a", "b"])})
    with pytest.raises(ValueError, match="metadata 'handle'"):
        LinesWriter(path, attrs={"handle": object()})
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match="'reason' must hold integer"):
        LinesWriter(path, line_attributes={"reason": "f4"})
    bad = make_lines([2, 2])
    bad.line_data["reason"][:] = [1, 42]
    with pytest.raises(ValueError, match=r"reason codes \[42\]"):
        write_lines(bad, path)
    with LinesWriter(path, {"speed": "float32"}) as w:
        with pytest.raises(ValueError, match="'speed'.*float32"):
            w.append(Lines(np.zeros((2, 3)), [0, 2], {"speed": np.zeros((2, 3))}))
        w.append(Lines(np.zeros((2, 3)), [0, 2], {"speed": np.ones(2)}))
    assert list(tmp_path.iterdir()) == [path]
    assert np.array_equal(read_lines(path).point_data["speed"], np.ones(2, np.float32))


def test_other_component_counts_get_their_own_dimension(tmp_path):
    lines = make_lines([3, 0, 4])
    lines.point_data["uv"] = np.arange(14.0).reshape(7, 2)
    lines.line_data["seed_point"] = np.arange(9.0).reshape(3, 3)
    path = write_lines(lines, tmp_path / "l.h5", position_dtype="float64")
    assert_exact(read_lines(path), lines)
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        assert ds.uv.dims == ("obs", "component_2")
        assert ds.seed_point.dims == ("trajectory", "component")
        assert np.array_equal(ds.seed_point.values, lines.line_data["seed_point"])
    with pytest.raises(ValueError, match="component_2"):
        LinesWriter(tmp_path / "x.h5", {"uv": ("f8", (2,)), "component_2": "f8"})


@pytest.mark.filterwarnings("error")
def test_summary_ranges_skip_nan_and_inf(tmp_path):
    lines = make_lines([2, 3])
    lines.point_data["T"][:] = [np.nan, 1.5, np.inf, -2.0, np.nan]
    lines.point_data["time"][:] = np.nan
    text = describe_lines(write_lines(lines, tmp_path / "l.h5"))
    assert "[-2, 1.5]" in text
    time_row = next(ln for ln in text.splitlines() if ln.strip().startswith("time "))
    assert time_row.endswith("[nan, nan]")
