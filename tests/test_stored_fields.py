"""Fields held as the file stores them: float32 stays float32 and gives the lines of its
float64 copy bit for bit; arrays are read when first used, only those a call needs; a field
that cannot fit in memory is a one-line error naming the file and the sizes."""

import h5py
import numpy as np
import pytest

from flowkit import Field, TraceOptions, trace
from flowkit.cli import main
from flowkit.fields import load_field, save_field
from flowkit.fields.analytic import ABCFlow
from flowkit.fields.stored import FieldMemoryError
from flowkit.integrate.pathlines import pathlines

SEEDS = np.array([[1.0, 2.0, 3.0], [4.0, 1.0, 0.5], [2.5, 5.0, 4.0], [0.3, 0.3, 6.0]])


def _pair(t=0.0, periodic=True):
    """(float32 field, its float64 copy): ABC on 20^3 nodes with a scalar T."""
    f = ABCFlow().to_field(20, bounds=[[0, 2 * np.pi]] * 3, periodic=periodic, t=t)
    v32 = f.vector.astype(np.float32)
    t32 = (np.sin(f.grid.x)[:, None, None] + np.cos(f.grid.z)[None, None, :]
           + 0 * f.grid.y[None, :, None]).astype(np.float32)
    f32 = Field(f.grid, v32, {"T": t32}, source="f32", time=t)
    f64 = Field(f.grid, v32.astype(np.float64), {"T": t32.astype(np.float64)}, source="f64",
                time=t)
    assert f32.vector.dtype == np.float32 and f64.vector.dtype == np.float64
    return f32, f64


def _same(a, b):
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.offsets, b.offsets)
    for k in a.line_data:
        np.testing.assert_array_equal(a.line_data[k], b.line_data[k], err_msg=k)
    assert set(a.point_data) == set(b.point_data)
    for k in a.point_data:
        np.testing.assert_array_equal(a.point_data[k], b.point_data[k], err_msg=k)


CASES = {
    "default": {},
    "both directions, attributes": {"direction": "both",
                                    "attributes": ("speed", "T", "vorticity", "arc_length")},
    "dop853": {"method": "dop853"},
    "not cell-aware": {"cell_aware": False},
    "rk4 lock-step": {"method": "rk4", "step": 0.05, "cell_aware": False},
    "ros34pw2": {"method": "ros34pw2"},
}


@pytest.mark.parametrize("case", list(CASES))
def test_float32_field_gives_its_float64_copys_lines_bit_for_bit(case):
    f32, f64 = _pair()
    opts = TraceOptions(max_length=6.0, rtol=1e-6, **CASES[case])
    a, b = trace(f32, SEEDS, opts), trace(f64, SEEDS, opts)
    assert len(a) == len(SEEDS)
    assert a.points.shape[0] > 10 * len(a)
    _same(a, b)


def test_float32_pathlines_give_their_float64_copys_bit_for_bit():
    (a0, b0), (a1, b1) = _pair(0.0, periodic=False), _pair(1.0, periodic=False)
    a1.vector[...] *= np.float32(1.5)
    b1.vector[...] = a1.vector.astype(np.float64)
    opts = TraceOptions(max_time=1.0, attributes=("speed", "T"))
    _same(pathlines([(0.0, a0), (1.0, a1)], SEEDS, options=opts),
          pathlines([(0.0, b0), (1.0, b1)], SEEDS, options=opts))


def _h5(tmp_path, dtype=np.float32):
    f32, _ = _pair()
    f = Field(f32.grid, f32.vector, {"T": f32.scalars["T"], "p": 2 * f32.scalars["T"]})
    path = tmp_path / "abc.h5"
    save_field(f, path, dtype=dtype)
    return path


def test_a_float32_file_is_read_lazily_and_traced_as_it_is_stored(tmp_path):
    path = _h5(tmp_path)
    fld = load_field(path)
    assert fld.dtype == np.float32 and not fld.vector_in_memory()
    assert not fld.scalars.in_memory("T") and not fld.scalars.in_memory("p")
    lines = trace(fld, SEEDS, max_length=4.0, attributes=["T"])
    # the vector and T were read, p never was
    assert fld.vector_in_memory() and fld.vector.dtype == np.float32
    assert fld.scalars.in_memory("T") and not fld.scalars.in_memory("p")
    _, f64 = _pair()
    _same(lines, trace(f64, SEEDS, max_length=4.0, attributes=["T"]))


def test_arrays_stored_in_other_types_are_held_as_float64_and_said_so(tmp_path):
    f32, _ = _pair()
    path = tmp_path / "f16.h5"
    with h5py.File(path, "w") as h:
        for c in "xyz":
            h[c] = getattr(f32.grid, c)
        h["U"] = f32.vector.astype(">f4")  # big-endian float32: kept float32, native order
        h["T"] = f32.scalars["T"].astype(np.float16)
        h["Uzyx"] = f32.vector.transpose(2, 1, 0, 3)
        h["Tzyx"] = f32.scalars["T"].transpose(2, 1, 0)
    fld = load_field(path, x="/x", y="/y", z="/z", vector="/U", scalars={"T": "/T"})
    assert fld.vector.dtype == np.float32 and fld.vector.dtype.isnative
    np.testing.assert_array_equal(fld.vector, f32.vector)
    assert fld.scalars["T"].dtype == np.float64
    assert any("float16" in n and "converted to float64" in n for n in fld.notes)
    g = load_field(path, x="/x", y="/y", z="/z", vector="/Uzyx", scalars={"T": "/Tzyx"},
                   order="zyx")
    np.testing.assert_array_equal(g.vector, f32.vector)
    np.testing.assert_array_equal(g.scalars["T"], f32.scalars["T"])


def test_slab_reads_assemble_the_array_exactly(tmp_path, monkeypatch):
    """Arrays read in many slabs (chunked or not, components stacked, axes reversed) equal the
    array read whole."""
    from flowkit.fields import stored

    monkeypatch.setattr(stored, "SLAB_BYTES", 3000)  # a few nodes along x per slab
    f32, _ = _pair()
    path = tmp_path / "parts.h5"
    v = f32.vector
    with h5py.File(path, "w") as h:
        h["x"], h["y"], h["z"] = f32.grid.x[::-1], f32.grid.y, f32.grid.z
        for c, name in enumerate("uvw"):
            h.create_dataset(name, data=v[::-1, :, :, c], chunks=(3, 5, 20) if c else None)
    fld = load_field(path, x="/x", y="/y", z="/z", u="/u", v="/v", w="/w")
    assert fld.vector.dtype == np.float32
    np.testing.assert_array_equal(fld.vector, v)
    assert any("reversed" in n for n in fld.notes)


def test_a_field_too_large_for_memory_is_a_named_error_and_leaves_no_file(tmp_path, capsys,
                                                                          monkeypatch):
    from flowkit.fields import stored

    path = _h5(tmp_path)
    monkeypatch.setattr(stored, "available_memory", lambda: 500)
    out = tmp_path / "lines.h5"
    rc = main(["trace", str(path), "-o", str(out), "--seeds", "points:1,2,3",
               "--max-length", "4"])
    err = capsys.readouterr().err
    assert rc == 2 and not out.exists() and "Traceback" not in err
    assert err.count("\n") == 1 and str(path) in err and "/vectors/U" in err
    # (a trace reads a field that does not fit brick by brick; even those do not fit here)
    assert "a memory budget of 500 B holds 0 bricks" in err and "--memory" in err
    with pytest.raises(FieldMemoryError, match="abc.h5"):
        _ = load_field(path).vector
    # info reads nothing, so it still works
    assert main(["info", str(path)]) == 0


def _dataset(f32):
    import xarray as xr

    g, v = f32.grid, f32.vector
    dims = ("x", "y", "z")
    return xr.Dataset({"u": (dims, v[..., 0]), "v": (dims, v[..., 1]), "w": (dims, v[..., 2]),
                       "T": (dims, f32.scalars["T"])},
                      coords={"x": g.x, "y": g.y, "z": g.z})


def _slab_reads(monkeypatch, cls):
    """Every slab a source of class ``cls`` fills, as (i0, i1)."""
    reads, fill = [], cls.fill
    monkeypatch.setattr(cls, "fill", lambda self, out, i0, i1: (reads.append((i0, i1)),
                                                                 fill(self, out, i0, i1)))
    return reads


@pytest.mark.parametrize("kind", ["dask", "zarr", "netcdf"])
def test_xarray_inputs_are_read_a_slab_at_a_time_never_whole(kind, tmp_path, monkeypatch):
    pytest.importorskip("xarray")
    from flowkit.fields import stored
    from flowkit.fields.readers import from_xarray
    from flowkit.fields.readers.xarray_io import XarraySource

    f32, f64 = _pair(periodic=False)
    ds = _dataset(f32)
    if kind == "dask":
        pytest.importorskip("dask")
        fld = from_xarray(ds.chunk({"x": 4}), source="dask")
    elif kind == "zarr":
        pytest.importorskip("zarr")
        ds.chunk({"x": 4}).to_zarr(tmp_path / "f.zarr")
        fld = load_field(tmp_path / "f.zarr")
    else:
        ds.to_netcdf(tmp_path / "f.nc")
        fld = load_field(tmp_path / "f.nc")
    reads = _slab_reads(monkeypatch, XarraySource)
    monkeypatch.setattr(stored, "SLAB_BYTES", 20 * 20 * 4 * 5)  # 5 nodes along x a slab
    assert fld.dtype == np.float32 and not fld.vector_in_memory() and not reads
    lines = trace(fld, SEEDS, max_length=4.0, attributes=["T"])
    assert reads and max(i1 - i0 for i0, i1 in reads) < 20  # slabs, never the whole x range
    _same(lines, trace(Field(f64.grid, f64.vector, {"T": f64.scalars["T"]}), SEEDS,
                       max_length=4.0, attributes=["T"]))
