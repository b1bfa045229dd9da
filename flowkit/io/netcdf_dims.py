"""netCDF-4 dimensions written with plain h5py (HDF5 dimension scales), as netCDF-C writes them.

netCDF-4 files are HDF5 files in which every dimension is a dimension scale: either a coordinate
variable of the same name, or a placeholder dataset whose NAME attribute says it is "a netCDF
dimension but not a netCDF variable". Variables list their dimensions by attaching the scales.
xarray (h5netcdf and netCDF4 engines) then sees named dimensions instead of phony ones.
"""

from __future__ import annotations

import h5py
import numpy as np

NOT_A_VARIABLE = "This is a netCDF dimension but not a netCDF variable."


def create_dimension(group: h5py.Group, name: str, size: int, dimid: int, *,
                     unlimited: bool = False, chunk: int = 1024) -> h5py.Dataset:
    """A dimension that is not a variable; ``unlimited`` dimensions can grow (see ``resize``)."""
    kw = {"maxshape": (None,), "chunks": (chunk,)} if unlimited else {}
    ds = group.create_dataset(name, shape=(size,), dtype=">f4", **kw)  # never written: no storage
    ds.make_scale(_placeholder_name(size))
    ds.attrs["_Netcdf4Dimid"] = np.int32(dimid)
    return ds


def make_coordinate(ds: h5py.Dataset, dimid: int) -> None:
    """Turn a 1-D dataset into a coordinate variable: the dimension of its own name."""
    ds.make_scale(ds.name.rsplit("/", 1)[-1])
    ds.attrs["_Netcdf4Dimid"] = np.int32(dimid)


def resize_dimension(scale: h5py.Dataset, size: int) -> None:
    """Grow a placeholder dimension (its NAME records the size, as netCDF-C does)."""
    scale.resize((size,))
    h5py.h5ds.set_scale(scale.id, _placeholder_name(size).encode())


def attach(ds: h5py.Dataset, *scales: h5py.Dataset) -> None:
    """Label the axes of ``ds`` with dimension scales, one per axis."""
    if len(scales) != ds.ndim:
        raise ValueError(f"{ds.name}: {ds.ndim} axes but {len(scales)} dimensions")
    for axis, scale in enumerate(scales):
        ds.dims[axis].attach_scale(scale)


def _placeholder_name(size: int) -> str:
    return f"{NOT_A_VARIABLE}{size:10d}"
