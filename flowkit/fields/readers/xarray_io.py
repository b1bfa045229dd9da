"""xarray datasets and netCDF files -> Field.

The velocity components ``u``, ``v``, ``w`` are variable names (default: the first of
(u, v, w), (U, V, W), (U_x, U_y, U_z) the dataset has).  Their three spatial dimensions are
matched to x, y, z by a coordinate's ``axis`` attribute (X/Y/Z), else by the dimension name
(x/y/z, lon/lat/lev...), else give ``dims=("xdim", "ydim", "zdim")``.  A fourth dimension named
time (or with axis T) is selected with ``snapshot=`` (position) or ``time=`` (value).  ``scalars``
lists scalar variables (default: every other variable on the same dimensions).
"""

from __future__ import annotations

import numpy as np

from ._common import ReaderError, existing, make_field, select_snapshot

_AXIS_NAMES = {
    "x": ("x", "lon", "longitude", "xc", "x1"),
    "y": ("y", "lat", "latitude", "yc", "x2"),
    "z": ("z", "lev", "level", "height", "depth", "zc", "x3"),
}
_TIME_NAMES = ("time", "t")
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
    if u is None and v is None and w is None:
        for cand in _DEFAULT_UVW:
            if all(c in ds.data_vars for c in cand):
                u, v, w = cand
                break
        else:
            raise ReaderError(
                f"{where}: give the velocity components u=, v=, w=; variables: "
                f"{', '.join(map(str, names)) or 'none'}"
            )
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
    tdim = [d for d in var_dims if _is_time(ds, d)]
    sel, notes = {}, []
    if tdim:
        td = tdim[0]
        times = (
            np.asarray(ds[td].values, dtype=float)
            if td in ds.coords
            else np.arange(ds.sizes[td], dtype=float)
        )
        i = select_snapshot(where, list(times), snapshot, time)
        sel[td] = i
        notes.append(f"time index {i} of {len(times)} along '{td}'")
        t_value = float(times[i])
    else:
        t_value = None
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
        f"{vector_name}_{c}": comp.isel(sel).transpose(*xyz).values for c, comp in zip("xyz", comps)
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
        arrays[str(n)] = ds[n].isel(sel).transpose(*xyz).values
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
        notes=notes,
        periodic=periodic,
        period=period,
        units=units,
        length_units=lengths.pop() if len(lengths) == 1 and "" not in lengths else None,
    )


def read_netcdf(path, vector="U", **opts):
    path = existing(path)
    try:
        import xarray as xr
    except ImportError:
        raise ReaderError(
            f"{path}: reading netCDF needs xarray and h5netcdf, in the 'io' extra: "
            "pip install 'flowkit[io]'"
        ) from None
    try:
        with xr.open_dataset(path) as ds:
            return from_xarray(ds.load(), vector_name=vector, source=str(path), **opts)
    except (OSError, ValueError) as e:
        if isinstance(e, ReaderError):
            raise
        raise ReaderError(
            f"{path}: not a readable netCDF file (truncated or corrupt): {e}"
        ) from None


def _is_time(ds, d) -> bool:
    return str(d).lower() in _TIME_NAMES or (d in ds.coords and ds[d].attrs.get("axis") == "T")


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
