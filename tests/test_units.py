"""Units travel: a field file's units reach the lines file as CF ``units`` per attribute."""

from __future__ import annotations

import numpy as np
import pytest

from flowkit import trace
from flowkit.fields.readers import load_field
from flowkit.io.lines_h5 import read_lines, write_lines

xr = pytest.importorskip("xarray")


def _netcdf(path, speed_units="m/s", length_units="m"):
    x = np.linspace(0.0, 1.0, 6)
    y = np.linspace(0.0, 2.0, 7)
    z = np.linspace(0.0, 0.5, 4)
    X, Y, _ = np.meshgrid(x, y, z, indexing="ij")
    dims = ("x", "y", "z")
    ds = xr.Dataset(
        {"u": (dims, np.full(X.shape, 0.2), {"units": speed_units}),
         "v": (dims, 0.1 + 0.05 * X, {"units": speed_units}),
         "w": (dims, np.zeros(X.shape), {"units": speed_units}),
         "T": (dims, 300.0 + Y, {"units": "K"}),
         "q": (dims, X * 0)},  # no units: none invented
        coords={c: (c, a, {"units": length_units}) for c, a in zip(dims, (x, y, z))})
    ds.to_netcdf(path, engine="h5netcdf")
    return path


def test_field_units_reach_the_lines_file_as_cf_attributes(tmp_path):
    fld = load_field(_netcdf(tmp_path / "f.nc"))
    assert fld.units == {"U": "m/s", "T": "K"} and fld.length_units == "m"
    summary = fld.summary()  # (flowkit info)
    assert "U [m/s]: vector" in summary and "T [K]: scalar" in summary and "  q: scalar" in summary
    assert "lengths in m" in summary
    names = ("time", "arc_length", "speed", "vorticity_magnitude", "distance_to_seed", "T", "q")
    lines = trace(fld, [[0.1, 0.2, 0.25], [0.1, 1.0, 0.25]], attributes=names, max_length=0.5)
    path = write_lines(lines, tmp_path / "lines.h5")
    with xr.open_dataset(path, engine="h5netcdf") as ds:  # "s" stays a plain float
        got = {n: ds[n].attrs.get("units") for n in names}
        assert ds["x"].attrs["units"] == "m"
    assert got == {"time": "s", "arc_length": "m", "speed": "m/s", "vorticity_magnitude": "1/s",
                   "distance_to_seed": "m", "T": "K", "q": None}
    assert read_lines(path).units == {k: v for k, v in got.items() if v}


def test_velocity_in_other_units_gives_no_time_in_seconds(tmp_path):
    fld = load_field(_netcdf(tmp_path / "f.nc", speed_units="km/h", length_units="m"))
    lines = trace(fld, [[0.1, 0.2, 0.25]], attributes=("time", "speed", "arc_length"),
                  max_length=0.3)
    assert lines.units == {"speed": "km/h", "arc_length": "m"}


def test_openfoam_export_names_units_and_hdf5_keeps_them(tmp_path):
    from flowkit.datasets import hotroom
    from flowkit.fields.writers import save_series

    fld = hotroom()
    assert fld.units == {"U": "m/s", "T": "K", "p": "m2/s2"} and fld.length_units == "m"
    save_series([fld], tmp_path / "f.h5", single=True)
    back = load_field(tmp_path / "f.h5")
    assert back.units == fld.units and back.length_units == "m"


def test_pathlines_carry_units_too():
    from flowkit.datasets import hotroom_path
    from flowkit.fields.readers import load_series
    from flowkit.integrate.pathlines import pathlines

    last_two = load_series(hotroom_path())[-2:]
    lines = pathlines(last_two, [[5.0, 1.0, 5.0]], attributes=("speed", "T"), max_time=20.0)
    assert lines.units == {"time": "s", "speed": "m/s", "T": "K"}
    assert lines.attrs["length_units"] == "m"
