"""Lines <-> HDF5: one file that xarray reads as CF trajectories and VTK/ParaView as PolyData.

Layout (format "lines", version 1)::

    /                               Conventions="CF-1.8", featureType="trajectory",
                                    flowkit_format="lines", flowkit_format_version=1, run metadata
    ├── obs, trajectory             netCDF dimensions (vertices, lines)
    ├── component                   netCDF dimension of size 3 (component_<k> for k != 3)
    ├── x, y, z       (obs)         positions: virtual datasets on the columns of VTKHDF/Points
    ├── rowSize       (trajectory)  vertices per line; sample_dimension="obs"
    ├── seed_id       (trajectory)  cf_role="trajectory_id"           == VTKHDF/CellData/seed_id
    ├── reason        (trajectory)  flag_values, flag_meanings        == VTKHDF/CellData/reason
    ├── <line attr>   (trajectory)                                    == VTKHDF/CellData/<name>
    ├── <point attr>  (obs) or (obs, component)                       == VTKHDF/PointData/<name>
    ├── reason_code   (reason_code) the code table: codes ...
    ├── reason_name   (reason_code) ... and their names, beside them
    └── VTKHDF/                     Version=(2, 1), Type="PolyData", flowkit_format_version=1
        ├── NumberOfPoints [N], Points (N, 3)
        ├── Lines/  NumberOfCells [L], NumberOfConnectivityIds [N], Offsets (L+1), Connectivity (N)
        ├── Vertices/, Polygons/, Strips/   empty topologies
        ├── PointData/<point attr>, CellData/<line attr>

"==" marks HDF5 hard links: one dataset, two names, stored once. Positions are stored once too:
x, y, z are virtual datasets reading the columns of Points. Line i is rows
offsets[i]:offsets[i+1] of every (obs) variable (the CF contiguous ragged array representation).
"""

from __future__ import annotations

import json
import os
import zlib
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Self

import h5py
import numpy as np

from ..integrate.reasons import REASON_NAMES, Reason
from ..lines import Lines
from . import netcdf_dims as nc
from .atomic import AtomicPath

FORMAT_NAME = "lines"
FORMAT_VERSION = 1
VTKHDF_VERSION = (2, 1)
CONVENTIONS = "CF-1.8"

# Names the layout uses itself: not available to attributes or to run metadata.
_RESERVED_VARIABLES = {"x", "y", "z", "rowSize", "obs", "trajectory", "reason_code", "reason_name",
                       "VTKHDF"}
_RESERVED_ATTRS = {"Conventions", "featureType", "flowkit_format", "flowkit_format_version",
                   "flowkit_json_attrs", "_NCProperties"}
_SYNTHESIZED = "flowkit_synthesized"  # marks a seed_id made up because the Lines had none
_LONG_NAMES = {
    "time": "integration time since the seed", "arc_length": "arc length from the line start",
    "speed": "velocity magnitude", "velocity": "velocity", "vorticity": "vorticity (curl)",
    "vorticity_magnitude": "vorticity magnitude", "distance_to_seed": "distance to the seed",
    "seed_id": "seed index", "reason": "why the line stopped",
    "n_accepted": "accepted integration steps", "n_rejected": "rejected integration steps",
    "n_crossing": "accepted steps that crossed cell faces",
}
_COMPRESSION = {"gzip": {"compression": "gzip", "compression_opts": 4, "shuffle": True},
                "lzf": {"compression": "lzf", "shuffle": True}, None: {}}


class LinesFileError(ValueError):
    """The file is not a readable flowkit lines file (the message names the file and why)."""


# -- writing ------------------------------------------------------------------------------------

def write_lines(lines: Lines, path, *, position_dtype="float32", compression="gzip",
                attrs=None) -> Path:
    """Write ``lines`` to ``path`` atomically; ``attrs`` are added to ``lines.attrs``.

    Positions are stored as ``position_dtype``: float32 by default (half the file; 7 digits,
    finer than any grid's interpolation error), "float64" to read back exactly the vertices
    written (``Lines.equals`` with no tolerance).  Attributes keep their own types."""
    writer = LinesWriter.like(
        lines, path, attrs={**lines.attrs, **(attrs or {})}, position_dtype=position_dtype,
        compression=compression,
        # chunks no larger than the data: an uncompressed chunk is stored whole
        chunk_points=min(65536, max(lines.n_points, 1)), chunk_lines=min(16384, max(len(lines), 1)))
    with writer:
        writer.append(lines)
    return writer.path


class LinesWriter:
    """Stream Lines to one HDF5 file, chunk by chunk, with bounded memory.

    ``point_attributes`` / ``line_attributes`` map names to a dtype, or to ``(dtype, (k,))`` for
    k components (e.g. ``{"velocity": ("float32", (3,))}``); every appended chunk must carry
    exactly these. Each ``append`` writes its chunk straight into resizable chunked datasets, so
    peak memory is about one appended chunk (plus its int64 connectivity, and HDF5's chunk cache
    of 1 MiB per dataset), whatever the total size of the file.

    ``attrs`` is run metadata for the root (str, numbers, arrays natively; lists, dicts and None
    as JSON); ``attrs["length_units"]``, if given, becomes the units of x, y, z (default "1");
    ``attrs["units"]`` (JSON {attribute: units}, see ``Lines.units``) becomes the CF ``units``
    of each attribute's variable, and is read back from them.

    The file is written under a temporary name in the same directory and renamed onto ``path``
    by ``close()``; if the ``with`` block raises (or ``abort()`` is called) the temporary file is
    removed and an existing file at ``path`` is left untouched.
    """

    def __init__(self, path, point_attributes=None, line_attributes=None, *, attrs=None,
                 position_dtype="float32", compression="gzip", chunk_points=65536,
                 chunk_lines=16384):
        self.path = Path(path)
        self.point_schema = _schema(point_attributes or {}, "point", self.path)
        self.line_schema = _schema(line_attributes or {}, "line", self.path)
        # one netCDF dimension per component count: "component" (3) or "component_<k>"
        sizes = {shape[0] for _, shape in (*self.point_schema.values(), *self.line_schema.values())
                 if shape}
        self._component_dims = {k: "component" if k == 3 else f"component_{k}" for k in sizes}
        reserved = _RESERVED_VARIABLES | set(self._component_dims.values())
        clash = (set(self.point_schema) & set(self.line_schema)) | (
            (set(self.point_schema) | set(self.line_schema)) & reserved)
        if clash:
            raise ValueError(f"{self.path}: attribute names {sorted(clash)} clash with each other or "
                             f"with the layout's own names {sorted(reserved)}")
        self.position_dtype = np.dtype(position_dtype)
        if self.position_dtype not in (np.float32, np.float64):
            raise ValueError(f"{self.path}: position_dtype must be float32 or float64, "
                             f"got {position_dtype!r}")
        if compression not in _COMPRESSION:
            raise ValueError(f"{self.path}: compression must be 'gzip', 'lzf' or None, "
                             f"got {compression!r}")
        if "reason" in self.line_schema and self.line_schema["reason"][0].kind not in "iu":
            raise ValueError(f"{self.path}: line attribute 'reason' must hold integer codes "
                             f"(flowkit.integrate.reasons.Reason), got {self.line_schema['reason'][0]}")
        self.attrs = dict(attrs or {})
        self._synthesize_seed_id = "seed_id" not in self.line_schema
        self.n_points = self.n_lines = 0

        self._columns = {}  # gzip datasets: compressed here, on every core (_Column)
        self._atomic = AtomicPath(self.path)
        self._file = h5py.File(self._atomic.tmp, "w", track_order=True)
        try:
            self._create(_COMPRESSION[compression], chunk_points, chunk_lines)
        except BaseException:
            self.abort()
            raise

    @classmethod
    def like(cls, lines: Lines, path, **kw) -> LinesWriter:
        """A writer whose attributes are those of ``lines`` (names, dtypes, components)."""
        def spec(arrays):
            return {k: (v.dtype, v.shape[1:]) for k, v in arrays.items()}
        kw.setdefault("attrs", lines.attrs)
        return cls(path, spec(lines.point_data), spec(lines.line_data), **kw)

    # -- layout ---------------------------------------------------------------------------------
    def _create(self, comp, chunk_points, chunk_lines):
        f = self._file
        units = json.loads(self.attrs.get("units") or "{}")
        # first: unstorable metadata fails before any work
        _put_attrs(f, {k: v for k, v in self.attrs.items() if k != "units"}, self.path)
        ids = iter(range(1 << 30))
        self._obs = nc.create_dimension(f, "obs", 0, next(ids), unlimited=True, chunk=chunk_points)
        self._traj = nc.create_dimension(f, "trajectory", 0, next(ids), unlimited=True,
                                         chunk=chunk_lines)
        components = {k: nc.create_dimension(f, name, k, next(ids))
                      for k, name in self._component_dims.items()}

        vtk = f.create_group("VTKHDF", track_order=True)
        vtk.attrs["Version"] = np.array(VTKHDF_VERSION, np.int64)
        # VTK requires a fixed-length ASCII string here
        vtk.attrs.create("Type", "PolyData", dtype=h5py.string_dtype("ascii", len("PolyData")))
        vtk.attrs["flowkit_format_version"] = np.int64(FORMAT_VERSION)
        vtk.create_dataset("NumberOfPoints", data=np.zeros(1, np.int64))
        for topology in ("Vertices", "Polygons", "Strips"):
            _topology(vtk, topology, {}, 1, 1)
        _topology(vtk, "Lines", comp, chunk_lines, chunk_points)
        self._store([(vtk[f"{t}/Offsets"], np.zeros(1, np.int64))  # Offsets start with 0
                     for t in ("Vertices", "Polygons", "Strips", "Lines")])

        def growing(group, name, dtype, shape, chunk):
            return group.create_dataset(name, shape=(0, *shape), maxshape=(None, *shape),
                                        chunks=(chunk, *shape), dtype=dtype, **comp)

        self._points = growing(vtk, "Points", self.position_dtype, (3,), chunk_points)
        self._rowsize = growing(f, "rowSize", np.int64, (), chunk_lines)
        self._rowsize.attrs.update(long_name="number of vertices of this line",
                                   sample_dimension="obs")
        nc.attach(self._rowsize, self._traj)

        self._point_ds = {}
        pdata = vtk.create_group("PointData", track_order=True)
        for name, (dtype, shape) in self.point_schema.items():
            ds = self._point_ds[name] = growing(pdata, name, dtype, shape, chunk_points)
            f[name] = ds  # hard link: the CF variable and the VTK array are one dataset
            ds.attrs["coordinates"] = "x y z"
            nc.attach(ds, self._obs, *[components[k] for k in shape])
        self._line_ds = {}
        cdata = vtk.create_group("CellData", track_order=True)
        line_schema = dict(self.line_schema)
        if self._synthesize_seed_id:
            line_schema["seed_id"] = (np.dtype(np.int64), ())
        for name, (dtype, shape) in line_schema.items():
            ds = self._line_ds[name] = growing(cdata, name, dtype, shape, chunk_lines)
            f[name] = ds
            nc.attach(ds, self._traj, *[components[k] for k in shape])
        for name, ds in {**self._point_ds, **self._line_ds}.items():
            if name in _LONG_NAMES:
                ds.attrs["long_name"] = _LONG_NAMES[name]
            if units.get(name):
                ds.attrs["units"] = str(units[name])
        seed = self._line_ds["seed_id"]
        seed.attrs["cf_role"] = "trajectory_id"
        if self._synthesize_seed_id:
            seed.attrs[_SYNTHESIZED] = np.int8(1)  # the Lines had no seed_id: read drops it
        if "reason" in line_schema:
            codes = np.array([r.value for r in Reason], line_schema["reason"][0])
            names = REASON_NAMES
            table = f.create_dataset("reason_code", data=codes)
            nc.make_coordinate(table, next(ids))
            table.attrs["long_name"] = "termination reason code"
            text = f.create_dataset("reason_name", data=names, dtype=h5py.string_dtype())
            text.attrs["long_name"] = "termination reason name"
            nc.attach(text, table)
            self._line_ds["reason"].attrs.update(flag_values=codes, flag_meanings=" ".join(names))

    # -- streaming ------------------------------------------------------------------------------
    def append(self, lines: Lines) -> None:
        """Write one chunk of lines after those already written."""
        if not isinstance(lines, Lines):
            raise TypeError(f"{self.path}: append() takes Lines, got {type(lines).__name__}")
        _check_chunk(lines.point_data, self.point_schema, "point", self.path)
        _check_chunk(lines.line_data, self.line_schema, "line", self.path)
        if "reason" in lines.line_data:
            unknown = np.setdiff1d(lines.line_data["reason"], [r.value for r in Reason])
            if unknown.size:
                raise ValueError(f"{self.path}: reason codes {unknown.tolist()} are not "
                                 f"flowkit.integrate.reasons.Reason values")
        n0, l0 = self.n_points, self.n_lines
        n1, l1 = n0 + lines.n_points, l0 + len(lines)
        line_data = dict(lines.line_data)
        if self._synthesize_seed_id:
            line_data["seed_id"] = np.arange(l0, l1)
        topo = self._file["VTKHDF/Lines"]
        rows = [(self._points, lines.points), (self._rowsize, lines.lengths),
                (topo["Offsets"], lines.offsets[1:] + n0),
                (topo["Connectivity"], np.arange(n0, n1, dtype=np.int64))]
        rows += [(ds, lines.point_data[name]) for name, ds in self._point_ds.items()]
        rows += [(ds, line_data[name]) for name, ds in self._line_ds.items()]
        self._store(rows)
        self.n_points, self.n_lines = n1, l1

    def _store(self, rows, final=False) -> None:
        """Append rows to datasets; gzip chunks are compressed in parallel, written in order."""
        jobs = []
        for ds, values in rows:
            if ds.compression != "gzip":
                _put(ds, ds.shape[0], ds.shape[0] + len(values), values)
                continue
            col = self._columns.get(ds.name) or self._columns.setdefault(
                ds.name, _Column(ds, ds.compression_opts))
            jobs += col.append(values, final)
        for ds, offset, size, job in jobs:
            if ds.shape[0] < size:
                ds.resize(size, axis=0)
            ds.id.write_direct_chunk((offset,) + (0,) * (ds.ndim - 1), job.result())

    def set_attrs(self, attrs: dict) -> None:
        """Run metadata known only at the end (numbers, text), written over the first's."""
        self.attrs.update(attrs)
        if self._file is not None:
            _put_attrs(self._file, attrs, self.path)

    def close(self) -> Path:
        """Finish the file and rename it onto ``path``."""
        if self._file is None:
            return self.path
        try:
            self._finish()
            self._file.close()
            self._file = None
            self._atomic.commit()
        except BaseException:
            self.abort()
            raise
        return self.path

    def abort(self) -> None:
        """Drop the temporary file; an existing file at ``path`` stays as it was."""
        if self._file is not None:
            try:
                self._file.close()
            finally:
                self._file = None
        self._atomic.discard()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def _finish(self):
        f, n, nl = self._file, self.n_points, self.n_lines
        self._store([(c.ds, c.tail[:0]) for c in self._columns.values()], final=True)
        nc.resize_dimension(self._obs, n)
        nc.resize_dimension(self._traj, nl)
        f["VTKHDF/NumberOfPoints"][0] = n
        f["VTKHDF/Lines/NumberOfCells"][0] = nl
        f["VTKHDF/Lines/NumberOfConnectivityIds"][0] = n
        for axis, name in enumerate("xyz"):
            ds = _column_view(f, "/VTKHDF/Points", axis, n, self.position_dtype, name)
            ds.attrs.update(axis=name.upper(), long_name=f"{name} position",
                            units=str(self.attrs.get("length_units", "1")))
            nc.attach(ds, self._obs)
        f.attrs.update(Conventions=CONVENTIONS, featureType="trajectory",
                       flowkit_format=FORMAT_NAME, flowkit_format_version=np.int64(FORMAT_VERSION))


def _schema(spec: dict, kind: str, path) -> dict:
    """{name: dtype or (dtype, (k,))} -> {name: (np.dtype, shape)}, checked."""
    out = {}
    for name, s in spec.items():
        dtype, shape = (s if isinstance(s, tuple) and len(s) == 2 else (s, ()))
        dtype, shape = np.dtype(dtype), tuple(int(k) for k in shape)
        if not name or "/" in name or name.startswith("."):
            raise ValueError(f"{path}: {kind} attribute name {name!r} is not a valid HDF5 name")
        if dtype.kind not in "iuf":
            raise ValueError(f"{path}: {kind} attribute '{name}' has dtype {dtype}; "
                             "only integer and floating-point attributes are stored")
        if len(shape) > 1 or (shape and shape[0] < 1):
            raise ValueError(f"{path}: {kind} attribute '{name}' has per-row shape {shape}; "
                             "expected () or (k,)")
        out[name] = (dtype, shape)
    return out


def _check_chunk(arrays: dict, schema: dict, kind: str, path) -> None:
    if set(arrays) != set(schema):
        raise ValueError(f"{path}: chunk has {kind} attributes {sorted(arrays)}, "
                         f"the writer was opened for {sorted(schema)}")
    for name, (dtype, shape) in schema.items():
        a = np.asarray(arrays[name])
        if a.shape[1:] != shape or not np.can_cast(a.dtype, dtype, "same_kind"):
            raise ValueError(f"{path}: {kind} attribute '{name}' is {a.dtype} with rows of shape "
                             f"{a.shape[1:]}, the file holds {dtype} rows of shape {shape}")


_POOL = (None, None)  # (pid, executor): a forked child makes its own


def _pool() -> ThreadPoolExecutor:
    global _POOL
    if _POOL[0] != os.getpid():
        _POOL = (os.getpid(), ThreadPoolExecutor(os.cpu_count() or 1,
                                                 thread_name_prefix="flowkit-gzip"))
    return _POOL[1]


def _deflate(block: np.ndarray, level: int) -> bytes:
    """HDF5's shuffle then deflate filters, as its own pipeline stores a chunk."""
    raw = np.ascontiguousarray(block).view(np.uint8).reshape(-1, block.dtype.itemsize)
    return zlib.compress(raw.T.tobytes(), level)


class _Column:
    """Rows appended to a chunked gzip+shuffle dataset: full chunks go to a thread pool (zlib
    releases the GIL), the rest waits for the next append; ``final`` pads the last chunk, which
    HDF5 stores whole.  Returns jobs (dataset, row offset, rows the dataset needs, future)."""

    def __init__(self, ds: h5py.Dataset, level: int):
        self.ds, self.level, self.rows = ds, level, ds.chunks[0]
        self.stored = 0  # rows handed out in whole chunks
        self.tail = np.empty((0, *ds.shape[1:]), ds.dtype)

    def append(self, values, final=False) -> list:
        data = np.asarray(values, self.ds.dtype)
        if len(self.tail):
            data = np.concatenate([self.tail, data])
        n = len(data)
        whole = n if final else n // self.rows * self.rows
        self.tail = data[whole:].copy()
        jobs = []
        for i in range(0, whole, self.rows):
            block = data[i:i + self.rows]
            need = self.stored + i + len(block)
            if len(block) < self.rows:  # the last, partial chunk
                pad = np.zeros((self.rows - len(block), *data.shape[1:]), data.dtype)
                block = np.concatenate([block, pad])
            jobs.append((self.ds, self.stored + i, need,
                         _pool().submit(_deflate, block, self.level)))
        self.stored += whole
        return jobs


def _put(ds: h5py.Dataset, start: int, stop: int, values) -> None:
    """Grow ``ds`` to ``stop`` rows and write ``values`` into rows start:stop."""
    ds.resize(stop, axis=0)
    if stop > start:
        ds[start:stop] = np.asarray(values, ds.dtype)


def _topology(vtk: h5py.Group, name: str, comp: dict, chunk_cells: int, chunk_ids: int) -> None:
    """A VTKHDF cell category: one partition, no cells yet (``append`` grows Lines)."""
    g = vtk.create_group(name)
    g.create_dataset("NumberOfCells", data=np.zeros(1, np.int64))
    g.create_dataset("NumberOfConnectivityIds", data=np.zeros(1, np.int64))
    g.create_dataset("Offsets", shape=(0,), dtype=np.int64, maxshape=(None,),
                     chunks=(chunk_cells + 1,), **comp)
    g.create_dataset("Connectivity", shape=(0,), dtype=np.int64, maxshape=(None,),
                     chunks=(chunk_ids,), **comp)


def _column_view(f: h5py.File, source: str, axis: int, n: int, dtype, name: str) -> h5py.Dataset:
    """A 1-D virtual dataset showing column ``axis`` of the (n, 3) dataset ``source``."""
    if n == 0:  # HDF5 cannot map an empty selection: an empty dataset says the same
        return f.create_dataset(name, shape=(0,), dtype=dtype)
    layout = h5py.VirtualLayout(shape=(n,), dtype=dtype)
    layout[:] = h5py.VirtualSource(".", source, shape=(n, 3), dtype=dtype)[:, axis]
    return f.create_virtual_dataset(name, layout)


def _put_attrs(f: h5py.File, attrs: dict, path) -> None:
    """Run metadata as root attributes: scalars, strings and arrays natively, the rest as JSON."""
    as_json = []
    for key, value in attrs.items():
        if key in _RESERVED_ATTRS or not isinstance(key, str):
            raise ValueError(f"{path}: metadata key {key!r} is reserved by the file layout")
        if isinstance(value, (str, bool, int, float, np.generic, np.ndarray)):
            try:
                f.attrs[key] = value
            except TypeError as e:
                raise ValueError(f"{path}: metadata '{key}' ({type(value).__name__}) cannot be "
                                 f"stored as an HDF5 attribute: {e}") from None
        else:
            try:
                f.attrs[key] = json.dumps(value)
            except TypeError as e:
                raise ValueError(f"{path}: metadata '{key}' = {value!r} cannot be stored: {e}") \
                    from None
            as_json.append(key)
    if as_json:
        f.attrs["flowkit_json_attrs"] = json.dumps(as_json)


def file_metadata(f: h5py.File) -> dict:
    """The run metadata at the root of the open file ``f`` (``Lines.attrs``)."""
    as_json = set(json.loads(f.attrs.get("flowkit_json_attrs", "[]")))
    out = {}
    for key, value in f.attrs.items():
        if key in _RESERVED_ATTRS:
            continue
        if key in as_json:
            value = json.loads(value)
        elif isinstance(value, np.generic):
            value = value.item()
        elif isinstance(value, bytes):
            value = value.decode()
        out[key] = value
    return out


# -- reading ------------------------------------------------------------------------------------

def read_lines(path, *, attributes=None) -> Lines:
    """Read a lines file. ``attributes``: None for all, or the point/line attribute names to read
    (the others are not read at all); ``[]`` reads the geometry only."""
    path = Path(path)
    if isinstance(attributes, str):
        attributes = [attributes]
    with open_lines(path) as f:
        try:
            return _read(f, path, attributes)
        except OSError as e:
            raise LinesFileError(f"{path}: cannot read the data (truncated or corrupt file?): {e}")


def _read(f: h5py.File, path: Path, attributes) -> Lines:
    vtk = required_group(f, "VTKHDF", path)
    point_names, line_names = attribute_names(f)
    if attributes is None:
        wanted = set(point_names) | set(line_names)
    else:
        wanted = set(attributes)
        missing = wanted - set(point_names) - set(line_names)
        if missing:
            raise KeyError(f"{path}: no attribute {sorted(missing)} in this file; it has point "
                           f"attributes {point_names} and line attributes {line_names}")
    points = required_dataset(vtk, "Points", path)[...]
    offsets = required_dataset(vtk, "Lines/Offsets", path)[...]
    if offsets.size < 1 or offsets[0] != 0 or offsets[-1] != len(points):
        raise LinesFileError(f"{path}: VTKHDF/Lines/Offsets (length {offsets.size}) does not "
                             f"span the {len(points)} points")
    row_size = required_dataset(f, "rowSize", path)[...]
    if not np.array_equal(np.diff(offsets), row_size):
        raise LinesFileError(f"{path}: rowSize disagrees with VTKHDF/Lines/Offsets")
    point_data = {k: vtk["PointData"][k][...] for k in point_names if k in wanted}
    line_data = {k: vtk["CellData"][k][...] for k in line_names if k in wanted}
    for name in ("reason", "reason_backward"):
        if name in line_data:
            line_data[name] = current_reason_codes(f, line_data[name], path)
    attrs = file_metadata(f)
    units = _units(f)
    if units:
        attrs["units"] = json.dumps(units)
    return Lines(points, offsets, point_data, line_data, attrs)


def _units(f: h5py.File) -> dict[str, str]:
    """The CF ``units`` of every point and line attribute that has them."""
    out = {}
    for group in ("VTKHDF/PointData", "VTKHDF/CellData"):
        for name, ds in f.get(group, {}).items():
            u = ds.attrs.get("units")
            if u is not None:
                out[name] = u.decode() if isinstance(u, bytes) else str(u)
    return out


def lines_attributes(path) -> list[str]:
    """Names of the point and line attributes a lines file holds (nothing else is read)."""
    path = Path(path)
    with open_lines(path) as f:
        point, line = attribute_names(f)
    return point + line


def read_metadata(path) -> dict:
    """The file's metadata (``Lines.attrs``: method, options, source, snapshot time...); nothing
    else is read."""
    path = Path(path)
    with open_lines(path) as f:
        return file_metadata(f)


def read_units(path) -> dict[str, str]:
    """The units the file gives (CF ``units`` attributes): ``"position"`` for x, y, z, and each
    point or line attribute that has them; names without units are left out."""
    path = Path(path)
    with open_lines(path) as f:
        out = _units(f)
        u = f["x"].attrs.get("units") if "x" in f else None
        if u is not None:
            out = {"position": u.decode() if isinstance(u, bytes) else str(u), **out}
    return out


def attribute_names(f: h5py.File) -> tuple[list[str], list[str]]:
    """The point and the line attributes of the open file ``f`` (a synthesized seed_id left out)."""
    point = list(f["VTKHDF/PointData"]) if "VTKHDF/PointData" in f else []
    cells = f.get("VTKHDF/CellData", {})
    line = [k for k in cells if _SYNTHESIZED not in cells[k].attrs]
    return point, line


def current_reason_codes(f: h5py.File, codes: np.ndarray, path: Path) -> np.ndarray:
    """Codes as this flowkit numbers them, translated by name from the file's own table."""
    table = required_dataset(f, "reason_code", path)[...]
    names = [n.decode() if isinstance(n, bytes) else n
             for n in required_dataset(f, "reason_name", path)]
    current = {r.label: r.value for r in Reason}
    unknown = sorted(set(names) - set(current))
    if unknown:
        raise LinesFileError(f"{path}: reason names {unknown} are unknown to this flowkit "
                             f"(it knows {sorted(current)})")
    lookup = dict(zip(table.tolist(), (current[n] for n in names)))
    stray = sorted(set(np.unique(codes).tolist()) - set(lookup))
    if stray:
        raise LinesFileError(f"{path}: reason codes {stray} are not in the file's reason table")
    if all(k == v for k, v in lookup.items()):
        return codes
    return np.array([lookup[c] for c in codes.tolist()], codes.dtype)


class open_lines:
    """Open ``path`` as a flowkit lines file this version can read, or raise a clear error
    (``with open_lines(path) as f``: the h5py.File)."""

    def __init__(self, path: Path):
        if not path.exists():
            raise FileNotFoundError(f"{path}: no such file")
        if not h5py.is_hdf5(path):
            raise LinesFileError(f"{path}: not an HDF5 file, so not a flowkit lines file")
        try:
            self.f = h5py.File(path, "r")
        except OSError as e:
            raise LinesFileError(f"{path}: cannot open (truncated or corrupt HDF5 file?): {e}")
        try:
            _check_format(self.f, path)
        except BaseException:
            self.f.close()
            raise

    def __enter__(self) -> h5py.File:
        return self.f

    def __exit__(self, *exc) -> None:
        self.f.close()


def _check_format(f: h5py.File, path: Path) -> None:
    fmt = f.attrs.get("flowkit_format")
    if fmt is None:
        raise LinesFileError(f"{path}: an HDF5 file but not a flowkit lines file "
                             "(no 'flowkit_format' attribute at the root)")
    fmt = fmt.decode() if isinstance(fmt, bytes) else str(fmt)
    if fmt != FORMAT_NAME:
        raise LinesFileError(f"{path}: a flowkit '{fmt}' file, not a '{FORMAT_NAME}' file")
    version = f.attrs.get("flowkit_format_version")
    if version is None or np.ndim(version) != 0 or not float(version).is_integer():
        raise LinesFileError(f"{path}: flowkit_format_version is {version!r}, expected an integer")
    if int(version) > FORMAT_VERSION:
        raise LinesFileError(f"{path}: lines format version {int(version)} was written by a newer "
                             f"flowkit; this flowkit reads lines format version {FORMAT_VERSION}")
    if int(version) < 1:
        raise LinesFileError(f"{path}: lines format version {int(version)} does not exist "
                             f"(this flowkit reads version {FORMAT_VERSION})")


def required_group(f, name, path) -> h5py.Group:
    """Group ``name`` of the open lines file ``f``, or a LinesFileError naming ``path``."""
    g = f.get(name)
    if not isinstance(g, h5py.Group):
        raise LinesFileError(f"{path}: group '{name}' is missing")
    return g


def required_dataset(g, name, path) -> h5py.Dataset:
    """Dataset ``name`` of group ``g``, or a LinesFileError naming ``path``."""
    ds = g.get(name)
    if not isinstance(ds, h5py.Dataset):
        raise LinesFileError(f"{path}: dataset '{g.name.rstrip('/')}/{name}' is missing")
    return ds


def is_lines_file(path) -> bool:
    """True when ``path`` is an HDF5 file that declares itself a flowkit lines file."""
    try:
        if not h5py.is_hdf5(path):
            return False
        with h5py.File(path, "r") as f:
            fmt = f.attrs.get("flowkit_format")
    except OSError:
        return False
    return (fmt.decode() if isinstance(fmt, bytes) else fmt) == FORMAT_NAME
