"""Every writer round-trips through its reader exactly; outputs are atomic; VTK itself reads
the VTK files flowkit writes (that check needs the optional vtk package)."""

import h5py
import numpy as np
import pytest

from flowkit import Field, Grid
from flowkit.fields.readers import load_field, load_series
from flowkit.fields.writers import save_field, save_series

FORMATS = [
    ("f.npz", {}), ("f.h5", {}), ("f.h5", {"compression": None}), ("f.vti", {}),
    ("f.vti", {"encoding": "ascii"}), ("f.vti", {"encoding": "binary"}),
    ("f.vti", {"encoding": "binary", "compress": False}), ("f.vti", {"compress": False}),
    ("f.vtr", {}), ("f.vtr", {"encoding": "ascii"}), ("f.vtr", {"encoding": "binary"}),
]  # fmt: skip


def random_field(uniform=True, time=2.5, periodic=(False, False, False)):
    rng = np.random.default_rng(3)
    if uniform:
        g = Grid.regular((-1.0, 0.3, 2.0), (0.1, 0.7, 0.13), (17, 9, 6), periodic=periodic)
    else:
        g = Grid.from_axes(*(np.sort(rng.uniform(-2, 2, n)) for n in (7, 5, 6)), periodic=periodic)
    vec = rng.normal(size=g.shape + (3,))
    vec[0, 1, 2, 1] = np.nan  # NaN and inf survive every format
    T = rng.normal(size=g.shape) * 1e-300
    T[3, 3, 3] = -np.inf
    return Field(g, vec, {"T": T, "p": rng.normal(size=g.shape)}, time=time, source="test")


def assert_same(a: Field, b: Field):
    assert a.grid == b.grid
    np.testing.assert_array_equal(a.vector, b.vector)
    assert list(a.scalars) == list(b.scalars)
    for n in a.scalars:
        np.testing.assert_array_equal(a.scalars[n], b.scalars[n])
    assert a.time == b.time and a.vector_name == b.vector_name


@pytest.mark.parametrize(("name", "opts"), FORMATS)
@pytest.mark.parametrize("uniform", [True, False])
def test_round_trip_is_exact(tmp_path, name, opts, uniform):
    f = random_field(uniform)
    if name.endswith(".vti") and not uniform:
        with pytest.raises(ValueError, match=r"f\.vti: \.vti needs a uniform grid.*\.vtr"):
            save_field(f, tmp_path / name, **opts)
        return
    save_field(f, tmp_path / name, **opts)
    assert_same(load_field(tmp_path / name), f)
    assert [p.name for p in tmp_path.iterdir()] == [name]  # no temporary file left behind


@pytest.mark.parametrize("name", ["f.npz", "f.h5"])
def test_periodic_grid_round_trips(tmp_path, name):
    f = random_field(periodic=(True, False, True))
    save_field(f, tmp_path / name)
    g = load_field(tmp_path / name)
    assert g.grid.period == f.grid.period and g.grid.periodic == (True, False, True)


def test_float32_and_other_vector_name(tmp_path):
    f = random_field(time=None)
    f = Field(f.grid, f.vector, f.scalars, vector_name="vel")
    for name in ("a.h5", "a.vti", "a.npz"):
        save_field(f, tmp_path / name, dtype=np.float32)
        g = load_field(tmp_path / name, vector="vel")
        np.testing.assert_array_equal(g.vector, f.vector.astype(np.float32))
        # kept as stored, nothing converted
        assert g.vector.dtype == np.float32 and g.scalars["T"].dtype == np.float32
        assert g.time is None and not any("converted" in n for n in g.notes)


def test_h5_layout_and_series(tmp_path):
    f = random_field()
    fields = [
        Field(f.grid, f.vector * k, {"T": f.scalars["T"]}, time=t) for k, t in ((1, 5.0), (2, 9.0))
    ]
    save_series(fields, tmp_path / "s.h5")
    with h5py.File(tmp_path / "s.h5") as h:
        assert h.attrs["flowkit_format"] == "field" and h.attrs["flowkit_format_version"] == 1
        assert sorted(h["snapshots"]) == ["0000", "0001"]
        assert h["snapshots/0001"].attrs["time"] == 9.0
        ds = h["snapshots/0000/vectors/U"]
        assert ds.shape == f.grid.shape + (3,) and ds.compression == "gzip" and ds.shuffle
    times = [t for t, _ in load_series(tmp_path / "s.h5")]
    assert times == [5.0, 9.0]
    assert_same(load_field(tmp_path / "s.h5", time=9.0), fields[1])
    other = Field(Grid.regular(0, 1, (3, 3, 3)), np.zeros((3, 3, 3, 3)))
    with pytest.raises(ValueError, match=r"x\.h5: snapshot 1 .* different grid"):
        save_series([fields[0], other], tmp_path / "x.h5")
    assert not (tmp_path / "x.h5").exists()


def test_failed_write_leaves_the_old_file(tmp_path):
    f = random_field()
    save_field(f, tmp_path / "k.npz")
    before = (tmp_path / "k.npz").read_bytes()
    bad = Field(f.grid, f.vector, {"x": f.scalars["T"]})  # 'x' clashes with the coordinates
    with pytest.raises(ValueError, match=r"k\.npz: array name\(s\) \['x'\] are reserved"):
        save_field(bad, tmp_path / "k.npz")
    assert (tmp_path / "k.npz").read_bytes() == before
    with pytest.raises(ValueError, match=r"k\.stl: cannot write extension"):
        save_field(f, tmp_path / "k.stl")


@pytest.mark.parametrize("name", ["v.vti", "v.vtr"])
@pytest.mark.parametrize("encoding", ["ascii", "binary", "appended"])
def test_vtk_reads_what_flowkit_writes(tmp_path, name, encoding, vtk):
    from vtk.util.numpy_support import vtk_to_numpy

    f = random_field()
    save_field(f, tmp_path / name, encoding=encoding)
    r = vtk.vtkXMLImageDataReader() if name.endswith("vti") else vtk.vtkXMLRectilinearGridReader()
    r.SetFileName(str(tmp_path / name))
    r.Update()
    out = r.GetOutput()
    assert out.GetDimensions() == f.grid.shape
    U = vtk_to_numpy(out.GetPointData().GetArray("U")).reshape(f.grid.shape[::-1] + (3,))
    np.testing.assert_array_equal(U.transpose(2, 1, 0, 3), f.vector)
    pts = vtk_to_numpy(out.GetPoints().GetData()) if name.endswith("vtr") else None
    if pts is None:
        np.testing.assert_allclose(out.GetOrigin(), f.grid.origin)
    assert out.GetFieldData().GetArray("TimeValue").GetValue(0) == f.time
