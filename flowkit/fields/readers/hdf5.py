"""HDF5 fields: flowkit's own layout, and any HDF5 file given the paths of its datasets.

flowkit field layout, version 1 (``FORMAT_VERSION``)::

    /                  attrs  flowkit_format = "field", flowkit_format_version = 1,
                              vector_name = "U" (the default vector),
                              period = (3,) float64, 0 for a bounded axis (optional),
                              source, notes (optional strings)
    /x, /y, /z         1-D float64 node coordinates, strictly increasing
    one snapshot:      /vectors/<name>  (nx, ny, nz, 3)   node data indexed [i, j, k, c], i along x
                       /scalars/<name>  (nx, ny, nz)
                       attr time on the root (optional)
    several snapshots: /snapshots/0000, /snapshots/0001, ... each a group with attr time and its
                       own vectors/ and scalars/ as above, in time order

Arrays keep the dtype they were written with (e.g. float32) and may be chunked and compressed;
they are read when first used (``stored.py``), a slab along x at a time, straight into the
Field's array.
``load_field(path, snapshot=i)`` or ``time=t`` picks a snapshot (default: the first).

Any other HDF5 file: give dataset paths, e.g.
``load_field("f.h5", x="/grid/x", y="/grid/y", z="/grid/z", u="/vel/u", v="/vel/v", w="/vel/w",
scalars={"T": "/T"})`` or ``vector="/U"`` for one (nx, ny, nz, 3) dataset; ``order="zyx"`` when the
arrays are indexed [k, j, i] (as many C codes write them) instead of the default [i, j, k].
"""

from __future__ import annotations

import contextlib
import threading

import h5py
import numpy as np

from ..stored import Source, Stored
from ._common import ReaderError, existing, fmt_times, make_field, select_snapshot

FORMAT = "field"
FORMAT_VERSION = 1


def open_h5(path) -> h5py.File:
    path = existing(path)
    try:
        return h5py.File(path, "r")
    except OSError as e:
        raise ReaderError(f"{path}: not a readable HDF5 file (truncated or corrupt): {e}") from None


def root_format(path) -> str | None:
    """The root ``flowkit_format`` attribute ("field", "lines", ...) or None."""
    with open_h5(path) as f:
        fmt = f.attrs.get("flowkit_format")
    return fmt.decode() if isinstance(fmt, bytes) else fmt


def snapshot_times(f: h5py.File) -> list[float]:
    if "snapshots" in f:
        g = f["snapshots"]
        return [_time(g[k], i) for i, k in enumerate(sorted(g))]
    return [_time(f, 0)]


def _time(g, default):
    t = g.attrs.get("time")
    return float(default if t is None else np.asarray(t).reshape(()))


def read_hdf5(
    path,
    vector=None,
    snapshot=None,
    time=None,
    x=None,
    y=None,
    z=None,
    u=None,
    v=None,
    w=None,
    scalars=None,
    order="xyz",
    periodic=(False, False, False),
    period=None,
):
    path = existing(path)
    generic = any(p is not None for p in (x, y, z, u)) or (vector is not None and "/" in vector)
    with open_h5(path) as f:
        try:
            if generic:
                return _read_paths(
                    path, f, vector, x, y, z, u, v, w, scalars, order, periodic, period
                )
            fmt = f.attrs.get("flowkit_format")
            fmt = fmt.decode() if isinstance(fmt, bytes) else fmt
            if fmt is None:
                raise ReaderError(
                    f"{path}: not a flowkit field file (no root attribute flowkit_format); "
                    "give the dataset paths, e.g. x='/x', y=..., z=..., u=..., v=..., w=... "
                    "or vector='/U'. "
                    f"Datasets in the file: {', '.join(_datasets(f)) or 'none'}"
                )
            if fmt != FORMAT:
                raise ReaderError(
                    f"{path}: flowkit_format is '{fmt}', not a field file "
                    f"(use `flowkit info` for a summary)"
                )
            return _read_flowkit(path, f, vector, snapshot, time, periodic, period)
        except OSError as e:  # a dataset whose bytes are missing
            raise ReaderError(f"{path}: HDF5 data unreadable (truncated or corrupt): {e}") from None


def _read_flowkit(path, f, vector, snapshot, time, periodic, period):
    version = int(f.attrs.get("flowkit_format_version", 0))
    if version > FORMAT_VERSION:
        raise ReaderError(
            f"{path}: flowkit field format version {version} is newer than this "
            f"flowkit reads ({FORMAT_VERSION}); upgrade flowkit"
        )
    for c in "xyz":
        if c not in f:
            raise ReaderError(f"{path}: flowkit field file without coordinate dataset '/{c}'")
    if vector is None:
        vector = _str(f.attrs.get("vector_name", "U"))
    times = snapshot_times(f)
    where, g, notes = path, f, []
    if "snapshots" in f:
        keys = sorted(f["snapshots"])
        i = select_snapshot(path, times, snapshot, time)
        g = f["snapshots"][keys[i]]
        where = f"{path}[snapshot {i}]"
        notes.append(f"snapshot {i} of {len(keys)} (times {fmt_times(times)})")
    elif snapshot not in (None, 0, -1) or time is not None:
        select_snapshot(path, times, snapshot, time)  # raises with the times the file has
    arrays, units = {}, {}
    for kind in ("vectors", "scalars"):
        if kind in g:
            arrays.update({name: stored(path, ds) for name, ds in g[kind].items()})
            units.update(_units(g[kind].values()))
    if "period" in f.attrs and period is None and not any(np.atleast_1d(periodic)):
        p = np.asarray(f.attrs["period"], float)
        period, periodic = tuple(p), tuple(p > 0)
    notes += [_str(n) for n in np.atleast_1d(f.attrs.get("notes", []))]
    t = g.attrs.get("time")
    return make_field(
        where,
        f["x"][()],
        f["y"][()],
        f["z"][()],
        arrays,
        vector,
        time=None if t is None else float(np.asarray(t).reshape(())),
        time_origin=_str(g.attrs["time_origin"]) if "time_origin" in g.attrs else None,
        notes=notes,
        periodic=periodic,
        period=period,
        units=units,
        length_units=_length_units(path, [f[c] for c in "xyz"]),
    )


def _read_paths(path, f, vector, x, y, z, u, v, w, scalars, order, periodic, period):
    if order not in ("xyz", "zyx"):
        raise ReaderError(
            f"{path}: order must be 'xyz' (arrays indexed [i, j, k]) or 'zyx' ([k, j, i]), "
            f"got {order!r}"
        )

    def dataset(p, role):
        if p not in f or not isinstance(f[p], h5py.Dataset):
            raise ReaderError(
                f"{path}: no dataset '{p}' (given for {role}); datasets in the file: "
                f"{', '.join(_datasets(f)) or 'none'}"
            )
        return f[p]

    def get(p, role):
        return dataset(p, role)[()]

    def node(p, role):  # to [i, j, k(, c)], read when used
        return stored(path, dataset(p, role), order)

    if None in (x, y, z):
        raise ReaderError(f"{path}: give all three coordinate dataset paths x=, y=, z=")
    axes = [get(p, c) for p, c in zip((x, y, z), "xyz")]
    if u is not None:
        if None in (v, w):
            raise ReaderError(f"{path}: give all three component paths u=, v=, w=")
        name = vector if vector and "/" not in vector else "U"
        arrays = {f"{name}_{c}": node(p, r) for p, c, r in zip((u, v, w), "xyz", "uvw")}
    elif vector is not None:
        name = vector.rstrip("/").rsplit("/", 1)[-1]
        arrays = {name: node(vector, "vector")}
    else:
        raise ReaderError(f"{path}: give the vector as vector='/path' or as u=, v=, w= paths")
    for sname, p in (scalars or {}).items():
        arrays[sname] = node(p, f"scalar {sname}")
    units = {n: _str(f[p].attrs["units"]) for n, p in (scalars or {}).items()
             if "units" in f[p].attrs}
    comps = {_str(f[p].attrs.get("units", "")) for p in ((u, v, w) if u is not None else (vector,))}
    if len(comps) == 1 and "" not in comps:
        units[name] = comps.pop()
    return make_field(
        path,
        *axes,
        arrays,
        name,
        periodic=periodic,
        period=period,
        units=units,
        length_units=_length_units(path, [f[p] for p in (x, y, z)]),
        notes=[f"read from HDF5 datasets given by path (order {order})"],
    )


class H5Source(Source):
    """A dataset of an HDF5 file, by path and name (the file opened for each read, so the
    Field that holds it can be pickled); ``order`` "zyx": indexed [k, j, i(, c)] in the file."""

    def __init__(self, path, name: str, order: str = "xyz"):
        self.path, self.name, self.order = str(path), name, order
        self._local = threading.local()  # the file held open, per thread (``held``)

    def __getstate__(self):
        return {k: v for k, v in self.__dict__.items() if k != "_local"}

    def __setstate__(self, state):
        self.__dict__.update(state, _local=threading.local())

    @contextlib.contextmanager
    def held(self):
        if getattr(self._local, "file", None) is not None:
            yield
            return
        with h5py.File(self.path, "r") as f:
            self._local.file = f
            try:
                yield
            finally:
                self._local.file = None

    def fill_box(self, out, box):
        try:
            with self.held():
                ds = self._local.file[self.name]
                if self.order == "zyx":
                    a = ds[box[::-1]]
                    out[...] = a.transpose(2, 1, 0, *range(3, a.ndim))
                else:
                    ds.read_direct(out, source_sel=box)
        except OSError as e:
            raise ReaderError(f"{self.path}: dataset '{self.name}' unreadable (truncated or "
                              f"corrupt): {e}") from None


def stored(path, ds: h5py.Dataset, order: str = "xyz") -> Stored:
    """Dataset ``ds`` as a node array indexed [i, j, k(, c)], read when first used."""
    shape, chunks = ds.shape, ds.chunks
    if order == "zyx" and len(shape) >= 3:
        back = (2, 1, 0, *range(3, len(shape)))
        shape = tuple(shape[a] for a in back)
        chunks = None if chunks is None else tuple(chunks[a] for a in back)
    if not np.issubdtype(ds.dtype, np.number) or np.issubdtype(ds.dtype, np.complexfloating):
        raise ReaderError(f"{path}: dataset '{ds.name}' holds {ds.dtype}, not real numbers")
    return Stored(shape, ds.dtype, H5Source(path, ds.name, order), f"{path}:{ds.name}", chunks)


def _units(datasets) -> dict[str, str]:
    """Dataset name -> its ``units`` attribute (CF), for the datasets that have one."""
    out = {}
    for ds in datasets:
        u = ds.attrs.get("units")
        if u is not None and _str(u).strip():
            out[ds.name.rsplit("/", 1)[-1]] = _str(u).strip()
    return out


def _length_units(path, axes) -> str | None:
    """The coordinates' common ``units`` attribute (None when none or when they differ)."""
    found = {_str(ds.attrs["units"]).strip() for ds in axes if "units" in ds.attrs}
    return found.pop() if len(found) == 1 else None


def _datasets(f) -> list[str]:
    out = []
    f.visititems(lambda n, o: out.append("/" + n) if isinstance(o, h5py.Dataset) else None)
    return out[:30]


def _str(s) -> str:
    return s.decode() if isinstance(s, bytes) else str(s)
