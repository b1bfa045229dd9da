"""xarray datasets and netCDF files -> Field.

The velocity components ``u``, ``v``, ``w`` are variable names (default: the first of
(u, v, w), (U, V, W), (U_x, U_y, U_z) the dataset has).  Their three spatial dimensions are
matched to x, y, z by a coordinate's ``axis`` attribute (X/Y/Z), else by the dimension name
(x/y/z, lon/lat/lev...), else give ``dims=("xdim", "ydim", "zdim")``.  A fourth dimension named
time (or with axis T) is selected with ``snapshot=`` (position) or ``time=`` (value); without
one, a scalar time coordinate (what ``ds.isel(time=i)`` leaves) gives the field's time.  Times
are seconds: numbers as they are; dates (CF ``units = "<unit> since <date>"``, which xarray
decodes) as seconds since 1970-01-01 (``Field.time_origin``), the same in every file of a
series, so that pathlines through netCDF snapshots step in seconds.  ``scalars`` lists scalar
variables (default: every other variable on the same dimensions).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..stored import Source, Stored
from ._common import ReaderError, existing, make_field, select_snapshot

_AXIS_NAMES = {
    "x": ("x", "lon", "longitude", "xc", "x1"),
    "y": ("y", "lat", "latitude", "yc", "x2"),
    "z": ("z", "lev", "level", "height", "depth", "zc", "x3"),
}
_TIME_NAMES = ("time", "t")
EPOCH = "1970-01-01T00:00:00"  # dates become seconds since this (Field.time_origin)
_DEFAULT_UVW = (("u", "v", "w"), ("U", "V", "W"), ("U_x", "U_y", "U_z"))


def from_xarray(
    ds,
    u=None,
    v=None,
    w=None,
    scalars=None,
    *,
    vector_name="U",
    dims=None,
    snapshot=None,
    time=None,
    source=None,
    periodic=(False, False, False),
    period=None,
):
    where = source or ds.encoding.get("source") or "<xarray dataset>"
    names = list(ds.data_vars)
    u, v, w = _component_names(ds, u, v, w, where)
    comps = []
    for role, n in zip("uvw", (u, v, w)):
        if n not in ds.data_vars:
            raise ReaderError(
                f"{where}: no variable '{n}' (given for {role}); variables: "
                f"{', '.join(map(str, names)) or 'none'}"
            )
        comps.append(ds[n])
    var_dims = comps[0].dims
    for c in comps[1:]:
        if c.dims != var_dims:
            raise ReaderError(
                f"{where}: '{c.name}' has dimensions {c.dims}, '{comps[0].name}' has {var_dims}"
            )
    sel, notes = {}, []
    td, tc = _time_source(ds, var_dims)
    times = None if tc is None else np.atleast_1d(_seconds(tc, where, notes))
    t_value = None
    if td is not None:
        times = np.arange(ds.sizes[td], dtype=float) if times is None else times
        i = select_snapshot(where, list(times), snapshot, time)
        sel[td] = i
        notes.append(f"time index {i} of {len(times)} along '{td}'")
        t_value = float(times[i])
    elif times is not None:
        t_value = float(times[0])
    dates = tc is not None and np.issubdtype(tc.dtype, np.datetime64)
    space = [d for d in var_dims if d not in sel]
    if len(space) != 3:
        raise ReaderError(
            f"{where}: '{u}' has dimensions {var_dims}; expected 3 spatial dimensions "
            "(plus optionally time)"
        )
    xyz = tuple(dims) if dims is not None else _match_axes(ds, space, where)
    if sorted(xyz) != sorted(space):
        raise ReaderError(f"{where}: dims={xyz} must name the dimensions {tuple(space)} of '{u}'")
    axes = []
    for d in xyz:
        if d not in ds.coords:
            raise ReaderError(
                f"{where}: dimension '{d}' has no coordinate variable (1-D node positions)"
            )
        axes.append(np.asarray(ds[d].values))
    if scalars is None:
        scalars = [n for n in ds.data_vars if n not in (u, v, w) and ds[n].dims == var_dims]
    arrays = {
        f"{vector_name}_{c}": _stored(comp.isel(sel).transpose(*xyz), where)
        for c, comp in zip("xyz", comps)
    }
    for n in scalars:
        if n not in ds.data_vars:
            raise ReaderError(
                f"{where}: no scalar variable '{n}'; variables: {', '.join(map(str, names))}"
            )
        if set(ds[n].dims) != set(var_dims):
            raise ReaderError(
                f"{where}: scalar '{n}' has dimensions {ds[n].dims}, expected {var_dims}"
            )
        arrays[str(n)] = _stored(ds[n].isel(sel).transpose(*xyz), where)
    units = {str(n): ds[n].attrs["units"] for n in scalars if "units" in ds[n].attrs}
    comp_units = {str(c.attrs.get("units", "")) for c in comps}
    if len(comp_units) == 1 and "" not in comp_units:
        units[vector_name] = comp_units.pop()
    lengths = {str(ds[d].attrs.get("units", "")) for d in xyz}
    return make_field(
        where,
        *axes,
        arrays,
        vector_name,
        time=t_value,
        time_origin=EPOCH if dates else None,
        notes=notes,
        periodic=periodic,
        period=period,
        units=units,
        length_units=lengths.pop() if len(lengths) == 1 and "" not in lengths else None,
    )


def read_netcdf(path, vector="U", **opts):
    path = existing(path)
    # the file stays open (lazily, by xarray's file manager) for the arrays read when used
    return _with_dataset(path, lambda ds: from_xarray(ds, vector_name=vector,
                                                      source=str(path), **opts), close=False)


def read_zarr(path, vector="U", **opts):
    """A zarr store (a directory) through xarray: every array read when used, a slab of its
    chunks at a time."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        import xarray as xr
    except ImportError:
        raise ReaderError(f"{path}: reading zarr needs xarray and zarr, in the 'io' extra: "
                          "pip install 'flowkit[io]'") from None
    try:
        ds = xr.open_zarr(path)
    except (OSError, ValueError, KeyError, ImportError) as e:
        raise ReaderError(f"{path}: not a readable zarr store: {e}") from None
    return from_xarray(ds, vector_name=vector, source=str(path), **opts)


class XarraySource(Source):
    """A lazily indexed DataArray (a netCDF or zarr variable, a dask array) ordered x, y, z:
    a box is computed or read alone, never the whole array."""

    def __init__(self, da, where: str):
        self.da, self.where = da, where

    def fill_box(self, out, box):
        try:
            out[...] = self.da.isel(dict(zip(self.da.dims, box))).values
        except (OSError, ValueError, RuntimeError) as e:
            raise ReaderError(f"{self.where}: variable '{self.da.name}' unreadable: {e}") from None


def _stored(da, where) -> Stored:
    """DataArray ``da`` (dims x, y, z) as a Stored array; chunking from dask or the file."""
    chunks = da.encoding.get("chunksizes") or da.encoding.get("chunks")
    if da.chunks:  # dask: the first chunk along each dimension
        chunks = tuple(c[0] for c in da.chunks)
    elif chunks is not None:  # the file's, in its own dimension order
        order = da.encoding.get("original_dims", da.dims)
        chunks = tuple(chunks[order.index(d)] for d in da.dims) if len(chunks) == da.ndim \
            else None
    return Stored(da.shape, da.dtype, XarraySource(da, where), f"{where}:{da.name}", chunks)


def netcdf_times(path) -> list[float]:
    """The times of a netCDF file's snapshots (its velocity's time dimension; one snapshot, at
    its scalar time or 0, without one), read without loading the data."""
    path = existing(path)

    def times(ds):
        u, _, _ = _component_names(ds, None, None, None, str(path))
        td, tc = _time_source(ds, ds[u].dims)
        if tc is not None:
            return [float(t) for t in np.atleast_1d(_seconds(tc, str(path), []))]
        return [float(t) for t in range(ds.sizes[td])] if td is not None else [0.0]

    return _with_dataset(path, times)


def _with_dataset(path, use, close=True):
    """``use(ds)`` on the netCDF file opened lazily with xarray (closed after, unless
    ``close`` is False: arrays read later need it); a missing xarray or an unreadable file is a
    ReaderError naming the file."""
    try:
        import xarray as xr
    except ImportError:
        raise ReaderError(
            f"{path}: reading netCDF needs xarray and h5netcdf, in the 'io' extra: "
            "pip install 'flowkit[io]'"
        ) from None
    try:
        ds = xr.open_dataset(path)
        try:
            out = use(ds)
        except BaseException:
            ds.close()
            raise
        if close:
            ds.close()
        return out
    except (OSError, ValueError) as e:
        if isinstance(e, ReaderError):
            raise
        raise ReaderError(
            f"{path}: not a readable netCDF file (truncated or corrupt): {e}"
        ) from None


def _component_names(ds, u, v, w, where):
    if u is None and v is None and w is None:
        for cand in _DEFAULT_UVW:
            if all(c in ds.data_vars for c in cand):
                return cand
        raise ReaderError(
            f"{where}: give the velocity components u=, v=, w=; variables: "
            f"{', '.join(map(str, ds.data_vars)) or 'none'}"
        )
    return u, v, w


def _is_time(ds, d) -> bool:
    return str(d).lower() in _TIME_NAMES or (d in ds.coords and ds[d].attrs.get("axis") == "T")


def _time_source(ds, var_dims):
    """(time dimension among ``var_dims`` or None, the coordinate holding the time or times or
    None): the dimension's coordinate, else a scalar time coordinate or variable (named time or
    t, or with axis T), as ``ds.isel(time=i)`` leaves one."""
    for d in var_dims:
        if _is_time(ds, d):
            return d, ds[d] if d in ds.coords else None
    for n in [*ds.coords, *ds.data_vars]:
        if ds[n].ndim == 0 and _is_time(ds, n):
            return None, ds[n]
    return None, None


def _seconds(coord, where, notes) -> np.ndarray:
    """Time values in seconds: numbers as they are, durations in seconds, dates in seconds since
    the Unix epoch (not since the file's CF reference date: xarray writes a single date with
    itself as the reference, so each file of a series would start at 0)."""
    vals = np.asarray(coord.values)
    if np.issubdtype(vals.dtype, np.timedelta64):
        return vals / np.timedelta64(1, "s")
    if np.issubdtype(vals.dtype, np.datetime64):
        first = np.datetime_as_string(vals.reshape(-1)[0], unit="s") if vals.size else "?"
        notes.append(f"times are dates, in seconds since 1970-01-01 (the first: {first})")
        return (vals - np.datetime64(EPOCH)) / np.timedelta64(1, "s")
    try:
        return vals.astype(float)
    except (TypeError, ValueError):
        raise ReaderError(
            f"{where}: time coordinate '{coord.name}' holds {vals.dtype} values (a non-standard "
            "calendar?); give numbers of seconds, or open the file with xarray "
            "(decode_times=False) and pass the dataset to from_xarray"
        ) from None


def _match_axes(ds, space, where):
    found = {}
    for d in space:
        ax = str(ds[d].attrs.get("axis", "")).lower() if d in ds.coords else ""
        if ax not in "xyz" or not ax:
            ax = next((a for a, names in _AXIS_NAMES.items() if str(d).lower() in names), None)
        if ax is None or ax in found:
            raise ReaderError(
                f"{where}: cannot tell which of the dimensions {tuple(space)} is x, y, z; "
                "pass dims=(x_dim, y_dim, z_dim)"
            )
        found[ax] = d
    return tuple(found[a] for a in "xyz")
