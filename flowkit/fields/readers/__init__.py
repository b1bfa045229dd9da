"""Readers: one call, ``load_field(path)``, for every snapshot format flowkit knows.

Formats by extension (module docstrings give the details):

- ``.npz`` / ``.npy`` (npz.py): x, y, z and named node arrays; vector as NAME or NAME_x/_y/_z.
- ``.h5`` ``.hdf5`` ``.hdf`` (hdf5.py): flowkit's versioned field layout (one or several
  snapshots), or any HDF5 file given dataset paths ``x=, y=, z=, u=, v=, w=`` / ``vector="/U"``,
  ``scalars={"T": "/T"}``, ``order="xyz"|"zyx"``.
- ``.vti`` / ``.vtr`` (vtk_xml.py): VTK XML ImageData / RectilinearGrid, every encoding;
  ``data="cell"`` for cell data.
- ``.vtu`` (vtu.py): any mix of tetrahedra, pyramids, wedges, hexahedra and polyhedra, every
  encoding; a lattice of nodes is rebuilt exactly, anything else resampled by cell location
  (``resample="NX,NY,NZ"``, ``"spacing:DX"``, ``"auto"`` or a Grid; ``bounds=``); ``data="cell"``
  for cell data.  ``.vtm`` multiblock files (foamToVTK's): ``block=`` (default "internal").
- ``.nc`` ``.nc4`` ``.netcdf`` (xarray_io.py): ``u=, v=, w=, scalars=, dims=``; ``.zarr``
  stores (a directory) the same way; an xarray Dataset (dask-backed or not) through
  ``from_xarray``.

Arrays are read when first used, a slab at a time, in the type the file stores (float32 or
float64; ``fields/stored.py``), except where the format needs the whole file parsed (.npz,
.vti/.vtr, .vtu, .vtm).
- ``.series`` (ParaView series JSON): one snapshot of the series, loaded by its own reader.

Options every reader takes: ``vector`` (default "U"), ``periodic`` and ``period`` (see Grid).
Files with several snapshots (.series, flowkit .h5, netCDF with a time dimension) take
``snapshot=i`` (position, negative from the end) or ``time=t``; the default is the first.
"""

from __future__ import annotations

from pathlib import Path

from ..field import Field
from ._common import ReaderError, existing, select_snapshot
from .hdf5 import read_hdf5, root_format, snapshot_times
from .npz import read_npy, read_npz
from .series import SnapshotRef, read_glob, read_series_json
from .vtk_xml import read_vtk_xml
from .vtu import find_lattice, read_vtm, read_vtu
from .xarray_io import from_xarray, netcdf_times, read_netcdf, read_zarr

HDF5_EXT = (".h5", ".hdf5", ".hdf")
NETCDF_EXT = (".nc", ".nc4", ".netcdf")
READERS = {
    ".npz": read_npz,
    ".npy": read_npy,
    ".vti": read_vtk_xml,
    ".vtr": read_vtk_xml,
    ".vtu": read_vtu,
    ".vtm": read_vtm,
    **{e: read_hdf5 for e in HDF5_EXT},
    **{e: read_netcdf for e in NETCDF_EXT},
    ".zarr": read_zarr,
}
KNOWN_EXTENSIONS = tuple(sorted([*READERS, ".series"]))

__all__ = [
    "KNOWN_EXTENSIONS",
    "ReaderError",
    "SnapshotRef",
    "find_lattice",
    "from_xarray",
    "load_field",
    "load_series",
]


def load_field(path, vector: str | None = "U", **opts) -> Field:
    """Read a Field from ``path`` (a file, or a ``SnapshotRef`` from ``load_series``).

    ``vector`` names the vector array (default "U"; for HDF5 None means the file's default).
    Other keyword options are passed to the format's reader (see the module docstring); an
    option the reader does not know is an error naming it.
    """
    if isinstance(path, SnapshotRef):
        path, opts = path.path, {**opts, "snapshot": path.snapshot}
    path = Path(path)
    ext = path.suffix.lower()
    if ext == ".series":
        entries = read_series_json(existing(path))
        i = select_snapshot(
            path, [t for t, _ in entries], opts.pop("snapshot", None), opts.pop("time", None)
        )
        return load_field(entries[i][1], vector, **opts)
    reader = READERS.get(ext)
    if reader is None:
        existing(path)
        raise ReaderError(
            f"{path}: unknown extension '{path.suffix}'; known: {', '.join(KNOWN_EXTENSIONS)}"
        )
    if vector is None and reader is not read_hdf5:
        vector = "U"
    try:
        return reader(path, vector=vector, **opts)
    except TypeError as e:
        if "unexpected keyword argument" in str(e):
            bad = str(e).split("argument")[-1].strip()
            raise ReaderError(f"{path}: option {bad} is not one the {ext} reader takes") from None
        raise


def load_series(path_or_glob) -> list[tuple[float, Path | SnapshotRef]]:
    """Snapshots as (time, path or SnapshotRef), sorted by time; each loads with ``load_field``.

    A ``.series`` file gives its files and times; a flowkit HDF5 file gives one SnapshotRef per
    snapshot (its ``time`` attribute, else its position); any other string with ``*``, ``?`` or
    ``[`` is a glob (times from file names, see ``series.py``); a netCDF file with a time
    dimension gives one SnapshotRef per time; any other single file is a series of one snapshot
    at its own time (0 when it has none).
    """
    s = str(path_or_glob)
    if any(ch in s for ch in "*?[") and not Path(s).exists():
        return read_glob(s)
    path = existing(s)
    ext = path.suffix.lower()
    if ext == ".series":
        return read_series_json(path)
    if ext in HDF5_EXT and root_format(path) == "field":
        import h5py

        with h5py.File(path, "r") as f:
            times = snapshot_times(f)
            multi = "snapshots" in f
        if multi:
            return sorted(
                ((t, SnapshotRef(path, i)) for i, t in enumerate(times)), key=lambda e: e[0]
            )
        return [(times[0], path)]
    if ext in NETCDF_EXT:  # (the times without loading the data)
        times = netcdf_times(path)
        if len(times) > 1:
            return sorted(((t, SnapshotRef(path, i)) for i, t in enumerate(times)),
                          key=lambda e: e[0])
        return [(times[0], path)]
    f = load_field(path)
    return [(f.time if f.time is not None else 0.0, path)]
