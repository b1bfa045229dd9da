"""Every reader on real files: VTK-written .vti/.vtr/.vtu (tests/data, made by
tests/data/make_vtk_files.py), the OpenFOAM heated room (.vtu from ../shared/datasets), npz, HDF5
(flowkit layout and by dataset path), netCDF/xarray and series; plus every bad-input case."""

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

import flowkit.fields
from flowkit import Grid
from flowkit.fields.readers import (
    KNOWN_EXTENSIONS,
    ReaderError,
    SnapshotRef,
    find_lattice,
    from_xarray,
    load_field,
    load_series,
)

DATA = Path(__file__).parent / "data"
SHARED = Path(__file__).parents[1] / ".." / "shared" / "datasets" / "hotroom"
needs_shared = pytest.mark.skipif(
    not SHARED.is_dir(), reason=f"{SHARED} absent (the shared OpenFOAM data sits beside the clone)"
)

# the linear fields make_vtk_files.py wrote
A = np.array([[0.3, -1.2, 0.5], [2.0, 0.1, -0.7], [0.4, 0.9, -1.1]])
B = np.array([0.25, -0.5, 1.5])
C = np.array([1.0, -2.0, 3.0])
IMAGE_AXES = [
    o + h * np.arange(n) for o, h, n in zip((-1.0, 0.5, 2.0), (0.5, 0.25, 0.2), (4, 3, 5))
]
RECT_AXES = [[0.0, 0.1, 0.35, 0.9], [-1.0, 0.0, 2.0], [0.0, 1.0, 1.5, 2.5, 4.0]]
VARIANTS = [
    "ascii", "binary", "binary_zlib_u64", "binary_lzma", "appended_raw_u64", "appended_raw_zlib",
    "appended_b64", "appended_b64_zlib_u64", "bigendian_zlib", "pieces",
]  # fmt: skip


def check_linear(f, axes, time=1.5):
    for got, want in zip(f.grid.axes, axes):
        np.testing.assert_array_equal(got, want)
    P = f.grid.node_points()
    np.testing.assert_allclose(f.vector, P @ A.T + B, rtol=0, atol=1e-14)
    # T was stored as Float32: exact to float32 rounding of the exact value
    np.testing.assert_array_equal(f.scalars["T"], (P @ C + 4.0).astype(np.float32))
    assert f.time == time


# -- VTK XML -----------------------------------------------------------------------------------
@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("kind", ["image", "rect"])
def test_vtk_xml_every_encoding(kind, variant):
    path = DATA / f"{kind}_{variant}.{'vti' if kind == 'image' else 'vtr'}"
    f = load_field(path)
    check_linear(f, IMAGE_AXES if kind == "image" else RECT_AXES)
    assert f.grid.uniform == (kind == "image")
    assert set(f.scalars) == {"T"}
    assert any("cell data not loaded" in n and "rho" in n for n in f.notes)


@pytest.mark.parametrize("path", ["image_appended_raw_zlib.vti", "rect_pieces.vtr"])
def test_vtk_xml_cell_data_when_asked(path):
    f = load_field(DATA / path, vector="U_cell", data="cell")
    axes = IMAGE_AXES if path.endswith("vti") else RECT_AXES
    centres = [0.5 * (np.add(a[1:], a[:-1])) for a in axes]
    for got, want in zip(f.grid.axes, centres):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)
    P = f.grid.node_points()
    np.testing.assert_allclose(f.vector, P @ A.T + B, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(f.scalars["rho"], P[..., 0])
    assert any("cell centre" in n for n in f.notes)


def test_cell_data_where_point_data_is_needed():
    path = DATA / "image_cellonly.vti"
    with pytest.raises(ReaderError, match=r"image_cellonly\.vti.*'U' is cell data.*data='cell'"):
        load_field(path)
    f = load_field(path, data="cell")  # asked for: fine
    assert f.grid.shape == (3, 2, 4)


@pytest.mark.parametrize("name", ["image_appended_raw_zlib.vti", "image_binary.vti"])
@pytest.mark.parametrize("keep", [0.5, 0.9])
def test_truncated_vtk_file(tmp_path, name, keep):
    raw = (DATA / name).read_bytes()
    bad = tmp_path / name
    bad.write_bytes(raw[: int(len(raw) * keep)])
    with pytest.raises(ReaderError, match=rf"{name}: VTK file is truncated or corrupt"):
        load_field(bad)


def test_corrupt_compressed_block(tmp_path):
    raw = bytearray((DATA / "image_appended_raw_zlib.vti").read_bytes())
    at = raw.index(b"_", raw.index(b"<AppendedData")) + 200
    raw[at : at + 20] = b"\x00" * 20
    (tmp_path / "z.vti").write_bytes(bytes(raw))
    with pytest.raises(ReaderError, match=r"z\.vti: VTK file is truncated or corrupt \(array '"):
        load_field(tmp_path / "z.vti")


# -- .vtu -------------------------------------------------------------------------------------------
def test_vtu_lattice_rebuilt_from_shuffled_nodes():
    f = load_field(DATA / "lattice_shuffled.vtu")
    check_linear(f, RECT_AXES)
    assert (
        "lattice rebuilt exactly" in f.notes[0] and "offset from its lattice line 0" in f.notes[0]
    )
    c = load_field(DATA / "lattice_shuffled.vtu", vector="U_cell", data="cell")
    P = c.grid.node_points()
    assert c.grid.shape == (3, 2, 4)
    np.testing.assert_allclose(c.vector, P @ A.T + B, rtol=0, atol=1e-13)


def test_vtu_scattered_resamples_by_cell_location_linear_exactly():
    path = DATA / "scattered_tets.vtu"
    auto = load_field(path)  # no lattice: a grid chosen from the cells' sizes
    assert "10th percentile of the cells' sizes" in auto.notes[0]
    f = load_field(path, shape=(5, 6, 7))
    assert f.grid.shape == (5, 6, 7) and np.allclose(f.grid.bounds, [[0, 1]] * 3)
    P = f.grid.node_points()
    # vtkDelaunay3D left slivers of the cube uncovered (its tetrahedra fill 95% of it, the x = 0
    # and x = 1 faces not at all): the
    # nodes there are NaN, each other node holds the linear field exactly
    nan = np.isnan(f.vector[..., 0])
    np.testing.assert_array_equal(nan, ~_in_some_tet(path, P))
    assert 0 < nan.sum() < nan.size // 2
    np.testing.assert_allclose(f.vector[~nan], P[~nan] @ A.T + B, rtol=0, atol=1e-12)
    assert "cell containing it" in f.notes[0]
    assert f"{nan.sum()} of 210 nodes lie in no cell" in f.notes[0]
    g = load_field(path, resample=(4, 4, 4), bounds=((-0.5, 1), (0, 1), (0, 1)))
    assert np.isnan(g.vector[0]).all()  # x = -0.5 lies outside the mesh: NaN, counted
    n = int(np.isnan(g.vector[..., 0]).sum())
    assert f"{n} of 64 nodes lie in no cell" in g.notes[0] and n >= 16


def _in_some_tet(path, P, tol=1e-9):
    """Whether each point lies in one of the file's tetrahedra (barycentric coordinates, by
    brute force: the reference for the cell location)."""
    import meshio

    m = meshio.read(path)
    q = P.reshape(-1, 3)
    inside = np.zeros(len(q), bool)
    for c in m.cells_dict["tetra"]:
        v = m.points[c]
        lam = np.linalg.solve((v[1:] - v[0]).T, (q - v[0]).T).T
        inside |= (lam.min(1) >= -tol) & (lam.sum(1) <= 1 + tol)
    return inside.reshape(P.shape[:-1])


def test_find_lattice_rejects_a_moved_node():
    x, y, z = np.meshgrid([0.0, 1.0, 2.0], [0.0, 1.0], [0.0, 1.0, 3.0], indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], 1)
    axes, ijk = find_lattice(pts)
    assert [a.tolist() for a in axes] == [[0, 1, 2], [0, 1], [0, 1, 3]]
    assert np.array_equal(pts, np.stack([axes[a][ijk[:, a]] for a in range(3)], 1))
    dup = pts.copy()
    dup[5] = dup[4]  # one position twice, another empty
    assert "holds 2 points" in find_lattice(dup)
    moved = pts.copy()
    moved[0, 0] = 0.5
    assert "distinct coordinates" in find_lattice(moved)


def test_vtu_needs_no_meshio(monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "meshio", None)
    assert load_field(DATA / "lattice_shuffled.vtu").grid.shape == (4, 3, 5)


def test_truncated_vtu(tmp_path):
    raw = (DATA / "lattice_shuffled.vtu").read_bytes()
    (tmp_path / "t.vtu").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(ReaderError, match=r"t\.vtu: VTK file is truncated or corrupt"):
        load_field(tmp_path / "t.vtu")


@needs_shared
def test_real_hotroom_vtu_point_and_cell_data():
    import meshio

    path = SHARED / "hotroom_t0800.vtu"
    f = load_field(path)
    assert f.grid.shape == (41, 21, 41) and f.grid.uniform and f.time == 800
    np.testing.assert_allclose(f.grid.bounds, [[0, 10], [0, 5], [0, 10]])
    np.testing.assert_allclose(f.grid.spacing, 0.25)
    # every node value lands at its own position: compare against meshio's raw arrays
    m = meshio.read(path)
    ijk = np.rint(m.points / 0.25).astype(int)
    np.testing.assert_array_equal(f.vector[ijk[:, 0], ijk[:, 1], ijk[:, 2]], m.point_data["U"])
    np.testing.assert_array_equal(
        f.scalars["T"][ijk[:, 0], ijk[:, 1], ijk[:, 2]], m.point_data["T"]
    )
    assert 300 <= f.scalars["T"].min() and f.scalars["T"].max() <= 600
    c = load_field(path, data="cell")
    assert c.grid.shape == (40, 20, 40)
    np.testing.assert_allclose(c.grid.x, 0.125 + 0.25 * np.arange(40), atol=1e-12)


@needs_shared
def test_real_hotroom_series():
    s = load_series(SHARED / "hotroom.vtu.series")
    assert [t for t, _ in s] == [400, 800, 1200, 1600, 2000]
    assert all(p.exists() for _, p in s)
    assert load_series(str(SHARED / "hotroom_t*.vtu")) == s  # glob: times from the names
    f = load_field(SHARED / "hotroom.vtu.series", time=1600)
    assert f.time == 1600 and f.source.endswith("hotroom_t1600.vtu")
    with pytest.raises(ReaderError, match=r"no snapshot at time 1700.*400, 800"):
        load_field(SHARED / "hotroom.vtu.series", time=1700)


# -- npz / npy ---------------------------------------------------------------------------------
def rect_grid():
    return [np.array(a, float) for a in RECT_AXES]


def linear_arrays(axes):
    P = np.stack(np.meshgrid(*axes, indexing="ij"), -1)
    return P @ A.T + B, P @ C + 4.0


def test_npz_vector_as_one_array_or_three_components(tmp_path):
    x, y, z = rect_grid()
    U, T = linear_arrays((x, y, z))
    np.savez(tmp_path / "a.npz", x=x, y=y, z=z, U=U, T=T)
    f = load_field(tmp_path / "a.npz")
    np.testing.assert_array_equal(f.vector, U)
    np.testing.assert_array_equal(f.scalars["T"], T)
    comps = {f"W_{c}": U[..., i] for i, c in enumerate("xyz")}
    with pytest.raises(
        ReaderError, match=r"a2\.npz: array 'note' has shape \(3,\), expected \(4, 3, 5\)"
    ):
        np.savez(tmp_path / "a2.npz", x=x, y=y, z=z, note=np.arange(3), **comps)
        load_field(tmp_path / "a2.npz", vector="W")
    np.savez(tmp_path / "b.npz", x=x, y=y, z=z, T=T, time=np.float64(7.0), **comps)
    g = load_field(tmp_path / "b.npz", vector="W")
    np.testing.assert_array_equal(g.vector, U)
    assert g.vector_name == "W" and list(g.scalars) == ["T"] and g.time == 7.0


def test_npy_single_vector_array(tmp_path):
    U, _ = linear_arrays(rect_grid())
    np.save(tmp_path / "u.npy", U.astype(np.float32))
    f = load_field(tmp_path / "u.npy")
    assert f.grid.shape == (4, 3, 5) and np.array_equal(f.grid.x, [0, 1, 2, 3])
    assert any("origin" in n for n in f.notes)
    # float32 stays float32 (read when used, from the memory-mapped file), with no note
    assert not f.vector_in_memory() and f.dtype == np.float32
    assert f.vector.dtype == np.float32 and not any("float32" in n for n in f.notes)
    np.testing.assert_array_equal(f.vector, U.astype(np.float32))
    g = load_field(tmp_path / "u.npy", x=RECT_AXES[0], y=RECT_AXES[1], z=RECT_AXES[2])
    np.testing.assert_array_equal(g.grid.z, RECT_AXES[2])


def test_npz_with_pickled_objects_is_refused_never_unpickled(tmp_path):
    x, y, z = rect_grid()
    path = tmp_path / "evil.npz"
    np.savez(path, x=x, y=y, z=z, U=np.array([{"a": 1}], dtype=object))
    with pytest.raises(ReaderError, match=r"evil\.npz: array 'U' holds pickled objects; refused"):
        load_field(path)
    np.save(tmp_path / "evil.npy", np.array([None, 1], dtype=object))
    with pytest.raises(ReaderError, match=r"evil\.npy: holds a pickled object array; refused"):
        load_field(tmp_path / "evil.npy")


def test_wrong_shapes_state_the_expected_shape(tmp_path):
    x, y, z = rect_grid()
    U, T = linear_arrays((x, y, z))
    np.savez(tmp_path / "s.npz", x=x, y=y, z=z, U=U, T=T[:, :, :-1])
    with pytest.raises(
        ReaderError, match=r"s\.npz: array 'T' has shape \(4, 3, 4\), expected \(4, 3, 5\)"
    ):
        load_field(tmp_path / "s.npz")
    np.savez(tmp_path / "v.npz", x=x, y=y, z=z, U=U[..., :2])
    with pytest.raises(
        ReaderError, match=r"v\.npz: array 'U' has shape \(4, 3, 5, 2\).*\(4, 3, 5, 3\)"
    ):
        load_field(tmp_path / "v.npz")
    np.savez(tmp_path / "c.npz", x=x[:, None], y=y, z=z, U=U)
    with pytest.raises(
        ReaderError, match=r"c\.npz: coordinate array 'x' has shape \(4, 1\), expected 1-D"
    ):
        load_field(tmp_path / "c.npz")
    np.savez(tmp_path / "m.npz", y=y, z=z, U=U)
    with pytest.raises(ReaderError, match=r"m\.npz: missing coordinate array\(s\) x"):
        load_field(tmp_path / "m.npz")


@pytest.mark.parametrize(
    ("bad", "what"),
    [([0.0, 0.5, 0.5, 1.0], "repeated at index 2"), ([0.0, 0.5, 0.4, 1.0], "decreasing")],
)
def test_non_monotonic_or_repeated_coordinates(tmp_path, bad, what):
    _, y, z = rect_grid()
    U = np.zeros((4, 3, 5, 3))
    np.savez(tmp_path / "n.npz", x=bad, y=y, z=z, U=U)
    with pytest.raises(
        ReaderError, match=rf"n\.npz: coordinate 'x' must be strictly increasing; {what}"
    ):
        load_field(tmp_path / "n.npz")


def test_decreasing_axes_are_reversed_with_their_data(tmp_path):
    """Latitudes from north to south, depths downwards: an axis whose nodes all decrease is
    reversed, the arrays with it (the same field as the increasing file, bit for bit), and a
    note says so; the vector's components keep their directions."""
    x, y, z = rect_grid()
    U, T = linear_arrays((x, y, z))
    np.savez(tmp_path / "up.npz", x=x, y=y, z=z, U=U, T=T)
    np.savez(tmp_path / "down.npz", x=x, y=y[::-1], z=z[::-1], U=U[:, ::-1, ::-1],
             T=T[:, ::-1, ::-1])
    up, down = load_field(tmp_path / "up.npz"), load_field(tmp_path / "down.npz")
    for a in "xyz":
        np.testing.assert_array_equal(getattr(down.grid, a), getattr(up.grid, a))
    np.testing.assert_array_equal(down.vector, up.vector)
    np.testing.assert_array_equal(down.scalars["T"], up.scalars["T"])
    assert any("decreasing along y, z" in n for n in down.notes)
    assert not any("decreasing" in n for n in up.notes)


def test_nan_and_inf_are_allowed_counted_and_reported(tmp_path):
    x, y, z = rect_grid()
    U, T = linear_arrays((x, y, z))
    U[1, 1, 1] = np.nan
    T[0, 0, 0] = np.inf
    T[2, 2, 2] = np.nan
    np.savez(tmp_path / "nan.npz", x=x, y=y, z=z, U=U, T=T)
    f = load_field(tmp_path / "nan.npz")
    s = f.summary()
    assert "U: vector (3)" in s and "3 NaN" in s  # one node, three components
    assert "T: scalar, float64" in s and "range [" in s and "1 NaN, 1 inf" in s


def test_vector_name_not_in_file_lists_the_names(tmp_path):
    x, y, z = rect_grid()
    U, T = linear_arrays((x, y, z))
    np.savez(tmp_path / "q.npz", x=x, y=y, z=z, U=U, T=T, V_x=T, V_y=T, V_z=T)
    with pytest.raises(ReaderError, match=r"q\.npz: no vector 'vel'.*vectors in the file: U, V"):
        load_field(tmp_path / "q.npz", vector="vel")
    with pytest.raises(
        ReaderError, match=r"q\.npz: 'T' is a scalar array.*vectors in the file: U, V"
    ):
        load_field(tmp_path / "q.npz", vector="T")
    with pytest.raises(
        ReaderError, match=r"image_binary\.vti: no vector 'vel'.*vectors in the file: U"
    ):
        load_field(DATA / "image_binary.vti", vector="vel")


# -- missing file, unknown extension, truncated HDF5 ---------------------------------------
def test_missing_file(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nothere\.vti: no such file"):
        load_field(tmp_path / "nothere.vti")


def test_unknown_extension_lists_the_known(tmp_path):
    (tmp_path / "f.xyz").write_text("1 2 3")
    with pytest.raises(
        ReaderError, match=r"f\.xyz: unknown extension '\.xyz'; known: .*\.npz.*\.vtr"
    ):
        load_field(tmp_path / "f.xyz")
    assert {".npz", ".npy", ".h5", ".vti", ".vtr", ".vtu", ".nc", ".series"} <= set(
        KNOWN_EXTENSIONS
    )


def test_option_the_reader_does_not_take():
    with pytest.raises(ReaderError, match=r"image_binary\.vti: option 'shape' is not one"):
        load_field(DATA / "image_binary.vti", shape=(3, 3, 3))


# -- HDF5 ------------------------------------------------------------------------------------
def write_flowkit_h5(path, snapshots):
    x, y, z = rect_grid()
    with h5py.File(path, "w") as h:
        h.attrs["flowkit_format"] = "field"
        h.attrs["flowkit_format_version"] = 1
        for c, a in zip("xyz", (x, y, z)):
            h[c] = a
        for i, (t, U, T) in enumerate(snapshots):
            g = h.create_group(f"snapshots/{i:04d}")
            g.attrs["time"] = t
            g["vectors/U"] = U
            g["scalars/T"] = T.astype(np.float32)


def test_flowkit_h5_snapshots_by_index_and_time(tmp_path):
    U, T = linear_arrays(rect_grid())
    write_flowkit_h5(tmp_path / "s.h5", [(0.5, U, T), (1.0, 2 * U, T + 1), (2.0, 3 * U, T + 2)])
    f = load_field(tmp_path / "s.h5")  # first by default
    assert f.time == 0.5 and np.array_equal(f.vector, U)
    assert np.array_equal(load_field(tmp_path / "s.h5", snapshot=-1).vector, 3 * U)
    g = load_field(tmp_path / "s.h5", time=1.0)
    assert np.array_equal(g.vector, 2 * U) and np.array_equal(
        g.scalars["T"], (T + 1).astype(np.float32)
    )
    s = load_series(tmp_path / "s.h5")
    assert s == [(0.5, SnapshotRef(tmp_path / "s.h5", 0)), (1.0, SnapshotRef(tmp_path / "s.h5", 1)),
                 (2.0, SnapshotRef(tmp_path / "s.h5", 2))]  # fmt: skip
    assert np.array_equal(load_field(s[2][1]).vector, 3 * U)
    with pytest.raises(ReaderError, match=r"s\.h5: snapshot 3 out of range; the file holds 3"):
        load_field(tmp_path / "s.h5", snapshot=3)


def test_any_hdf5_by_dataset_paths(tmp_path):
    x, y, z = rect_grid()
    U, T = linear_arrays((x, y, z))
    with h5py.File(tmp_path / "g.h5", "w") as h:
        h["grid/x"], h["grid/y"], h["grid/z"] = x, y, z
        for i, c in enumerate("uvw"):
            h[f"vel/{c}"] = U[..., i].transpose(2, 1, 0)  # stored [k, j, i] as C codes do
        h["Uvec"] = U
        h["temp"] = T.transpose(2, 1, 0)
    grid = {"x": "/grid/x", "y": "/grid/y", "z": "/grid/z"}
    f = load_field(tmp_path / "g.h5", **grid, u="/vel/u", v="/vel/v", w="/vel/w",
                   scalars={"T": "/temp"}, order="zyx")  # fmt: skip
    np.testing.assert_array_equal(f.vector, U)
    np.testing.assert_array_equal(f.scalars["T"], T)
    g = load_field(tmp_path / "g.h5", **grid, vector="/Uvec")
    assert g.vector_name == "Uvec" and np.array_equal(g.vector, U)
    with pytest.raises(ReaderError, match=r"g\.h5: no dataset '/vel/q' \(given for w\).*/grid/x"):
        load_field(tmp_path / "g.h5", **grid, u="/vel/u", v="/vel/v", w="/vel/q")
    with pytest.raises(
        ReaderError, match=r"g\.h5: not a flowkit field file.*Datasets in the file: "
    ):
        load_field(tmp_path / "g.h5")


def test_truncated_hdf5(tmp_path):
    U, T = linear_arrays(rect_grid())
    write_flowkit_h5(tmp_path / "full.h5", [(0.0, U, T)])
    raw = (tmp_path / "full.h5").read_bytes()
    (tmp_path / "cut.h5").write_bytes(raw[: len(raw) // 2])
    with pytest.raises(ReaderError, match=r"cut\.h5: .*HDF5.*\(truncated or corrupt\)"):
        load_field(tmp_path / "cut.h5")


def test_lines_file_is_not_a_field(tmp_path):
    with h5py.File(tmp_path / "l.h5", "w") as h:
        h.attrs["flowkit_format"] = "lines"
    with pytest.raises(ReaderError, match=r"l\.h5: flowkit_format is 'lines', not a field file"):
        load_field(tmp_path / "l.h5")


# -- netCDF / xarray ---------------------------------------------------------------------------
def hot_dataset(with_time):
    import xarray as xr

    x, y, z = rect_grid()
    U, T = linear_arrays((x, y, z))
    dims = ("z", "y", "x")
    data = {n: (dims, a.transpose(2, 1, 0)) for n, a in zip("uvw", np.moveaxis(U, -1, 0))}
    data["T"] = (dims, T.transpose(2, 1, 0))
    ds = xr.Dataset(data, coords={"x": x, "y": y, "z": z})
    if with_time:
        ds = xr.concat([ds, ds * 2], dim=xr.DataArray([10.0, 20.0], dims="time", name="time"))
    return ds, U, T


def test_from_xarray_and_netcdf(tmp_path):
    ds, U, T = hot_dataset(with_time=False)
    f = from_xarray(ds, u="u", v="v", w="w")
    np.testing.assert_array_equal(f.vector, U)
    np.testing.assert_array_equal(f.scalars["T"], T)
    dst, _, _ = hot_dataset(with_time=True)
    dst.to_netcdf(tmp_path / "h.nc", engine="h5netcdf")
    g = load_field(tmp_path / "h.nc", time=20.0)
    assert g.time == 20.0 and g.time_origin is None  # numbers: seconds, no date
    np.testing.assert_array_equal(g.vector, 2 * U)
    np.testing.assert_array_equal(g.scalars["T"], 2 * T)
    with pytest.raises(
        ReaderError, match=r"h\.nc: no variable 'q' \(given for v\); variables: u, v, w, T"
    ):
        load_field(tmp_path / "h.nc", u="u", v="q", w="w")


def test_netcdf_dates_a_series_and_a_single_step_agree_in_seconds(tmp_path):
    """CF dates become seconds since 1970-01-01, the same in every file: a netCDF file with a
    time dimension is a series (one snapshot per time, read lazily), a single step cut from it
    (``isel``: a scalar time coordinate, which xarray writes with itself as the reference date)
    has the same time, and pathlines through the series step in seconds."""
    import pandas as pd
    import xarray as xr

    from flowkit.integrate.pathlines import pathlines

    ds, U, _ = hot_dataset(with_time=False)
    dates = pd.date_range("2024-03-01 12:00", periods=3, freq="30s")
    dst = xr.concat([ds * (1 + k) for k in range(3)],
                    dim=xr.DataArray(dates, dims="time", name="time"))
    dst.to_netcdf(tmp_path / "t.nc", engine="h5netcdf",
                  encoding={"time": {"units": "seconds since 2000-01-01"}})
    dst.isel(time=1).to_netcdf(tmp_path / "one.nc", engine="h5netcdf")
    noon = (np.datetime64("2024-03-01T12:00") - np.datetime64("1970-01-01")) / np.timedelta64(1, "s")
    series = load_series(tmp_path / "t.nc")
    assert [t for t, _ in series] == [noon, noon + 30, noon + 60]
    assert all(isinstance(r, SnapshotRef) for _, r in series)
    second = load_field(series[1][1])
    np.testing.assert_array_equal(second.vector, 2 * U)
    one = load_field(tmp_path / "one.nc")
    assert one.time == second.time == noon + 30
    assert one.time_origin == second.time_origin == "1970-01-01T00:00:00"
    assert any("1970-01-01" in n for n in one.notes)
    lines = pathlines(series, [[0.3, 0.4, 0.5]], max_time=45.0, attributes=["time"])
    t = lines.point_data["time"]
    assert t[0] == noon and 0 < t[-1] - noon <= 45.0
    # the date travels: the lines' metadata, a flowkit HDF5 copy of the field, the picture's label
    from flowkit import trace
    from flowkit.fields.writers import save_series
    from flowkit.render.legend import time_label

    attrs = trace(one, [[0.3, 0.4, 0.5]], max_length=0.2).attrs
    assert attrs["snapshot_time"] == noon + 30 and attrs["time_origin"] == one.time_origin
    assert lines.attrs["time_origin"] == one.time_origin
    save_series([one], tmp_path / "one.h5", single=True)
    assert load_field(tmp_path / "one.h5").time_origin == one.time_origin
    assert time_label(noon + 30, one.time_origin) == "t = 2024-03-01 12:00:30"
    assert time_label(noon + 30.25, one.time_origin) == "t = 2024-03-01 12:00:30.250"
    assert time_label(2000.0) == "t = 2000 s"
    assert "s since 1970-01-01T00:00:00 = 2024-03-01 12:00:30" in one.summary()  # flowkit info


def test_field_module_does_not_import_the_readers():
    """The readers build Fields; field.py and grid.py know nothing of them (no import cycle)."""
    import ast

    for name in ("field.py", "grid.py"):
        tree = ast.parse((Path(flowkit.fields.__file__).parent / name).read_text())
        mods = {n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
        mods |= {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
        assert not any("readers" in m for m in mods), (name, mods)


# -- series ------------------------------------------------------------------------------------
def test_series_json_and_glob_rules(tmp_path):
    for n in ("b_7.vti", "a_12.vti", "c_3.5.vti"):
        (tmp_path / n).write_bytes((DATA / "image_binary.vti").read_bytes())
    s = load_series(str(tmp_path / "*.vti"))
    assert [(t, p.name) for t, p in s] == [(3.5, "c_3.5.vti"), (7.0, "b_7.vti"), (12.0, "a_12.vti")]
    (tmp_path / "nonum.vti").write_bytes(b"")
    s = load_series(str(tmp_path / "*.vti"))  # a name without a number: positions in name order
    assert [(t, p.name) for t, p in s] == [(0.0, "a_12.vti"), (1.0, "b_7.vti"), (2.0, "c_3.5.vti"),
                                           (3.0, "nonum.vti")]  # fmt: skip
    doc = {
        "file-series-version": "1.0",
        "files": [{"name": "b_7.vti", "time": 2}, {"name": "a_12.vti", "time": 1}],
    }
    (tmp_path / "r.vti.series").write_text(json.dumps(doc))
    assert [(t, p.name) for t, p in load_series(tmp_path / "r.vti.series")] == [
        (1, "a_12.vti"),
        (2, "b_7.vti"),
    ]
    (tmp_path / "bad.series").write_text('{"files": [{"name": "x"}]}')
    with pytest.raises(ReaderError, match=r"bad\.series: a \.series file needs"):
        load_series(tmp_path / "bad.series")
    with pytest.raises(FileNotFoundError, match="no files match"):
        load_series(str(tmp_path / "*.nope"))


def test_grid_on_the_read_field_is_a_flowkit_grid():
    f = load_field(DATA / "rect_ascii.vtr", periodic=(True, False, False), period=(1.0, 0, 0))
    assert isinstance(f.grid, Grid) and f.grid.period == (1.0, 0.0, 0.0)
