"""``flowkit info FILE``: what a field file (or series, or lines file) holds.

Grid kind, shape, bounds and spacing, every array with its type, size, chunking and units, and
the reader's notes, from the file's metadata alone: no array data is read, so a snapshot of any
size prints at once.  ``--stats`` adds each array's range and NaN/inf counts, read a slab at a
time (memory bounded by a slab, progress on a terminal).  For a series (.series, a glob, a
multi-snapshot flowkit HDF5 or netCDF file) the list of snapshots and times comes first, then
the selected snapshot (default the first).  A flowkit lines file: its counts, bounds, why the
lines stopped, each attribute's range (read block by block) and the run metadata.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import CLIError
from ._field import add_mesh_options, mesh_options


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "info", help="summarise a field, series or lines file", description=__doc__
    )
    p.add_argument(
        "file", nargs="?",
        help="field file (.npz .npy .h5 .vti .vtr .vtu .vtm .nc), .series or glob"
    )
    p.add_argument("--vector", default=None, help="vector array name (default U, or the file's)")
    p.add_argument(
        "--snapshot", type=int, help="snapshot position in a series (negative: from the end)"
    )
    p.add_argument("--time", type=float, help="snapshot time in a series")
    add_mesh_options(p)
    p.add_argument("--stats", action="store_true",
                   help="ranges and NaN/inf counts of every array (reads the data, a slab at a "
                        "time)")
    # OpenCL devices (the opencl backend's hook: flowkit.integrate.opencl.device)
    p.add_argument("--devices", action="store_true", help="list OpenCL platforms and devices")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.devices:
        from ..integrate.opencl.device import describe_devices

        print(describe_devices())
        return 0
    if args.file is None:
        raise CLIError("flowkit info: give a FILE (or --devices)")
    print(
        describe(
            args.file, vector=args.vector, snapshot=args.snapshot, time=args.time,
            stats=args.stats, **mesh_options(args),
        )
    )
    return 0


def describe(file, vector=None, snapshot=None, time=None, data=None, stats=False,
             **mesh) -> str:
    """The text ``flowkit info`` prints (``stats``: with ranges and NaN/inf counts; ``mesh``:
    resample= and block= for unstructured meshes)."""
    from ..fields.readers import HDF5_EXT, NETCDF_EXT, load_field, load_series, root_format
    from ..fields.readers._common import select_snapshot

    path = Path(file)
    if path.suffix.lower() in HDF5_EXT and path.exists() and root_format(path) == "lines":
        return describe_lines(path)
    opts = {
        k: v for k, v in (("snapshot", snapshot), ("time", time), ("data", data)) if v is not None
    } | mesh
    head = []
    is_glob = any(c in str(file) for c in "*?[") and not path.exists()
    if is_glob or path.suffix.lower() in (".series", *HDF5_EXT, *NETCDF_EXT):
        series = load_series(file)
        if len(series) > 1 or is_glob or path.suffix.lower() == ".series":
            head.append(f"series: {file}, {len(series)} snapshot(s)")
            head += [f"  [{i}] t = {t:.10g}  {_name(ref)}" for i, (t, ref) in enumerate(series)]
            if is_glob:  # a glob is not a file load_field opens: pick the snapshot here
                times = [t for t, _ in series]
                i = select_snapshot(file, times, opts.pop("snapshot", None), opts.pop("time", None))
                file = series[i][1]
            head.append("")
    field = load_field(file, vector, **opts)
    if not stats:
        tail = [f"(ranges and NaN counts: flowkit info {file} --stats)"]
        return "\n".join([*head, field.summary(stats=False), *tail])
    from ..fields.stored import progress_bar

    total = sum(a.nbytes for a in field.array_meta().values())
    with progress_bar(total, "statistics") as done:
        return "\n".join([*head, field.summary(stats=True, progress=done)])


def _name(ref) -> str:
    return f"{ref.path.name} snapshot {ref.snapshot}" if hasattr(ref, "snapshot") else str(ref)


def describe_lines(path) -> str:
    """What ``flowkit info`` prints for a flowkit lines file: counts, bounds, why the lines
    stopped, each attribute's type, range and units, the run metadata; attributes are read
    block by block."""
    from ..io.lines_h5 import LinesFileError, open_lines

    path = Path(path)
    with open_lines(path) as f:
        try:
            return _lines_text(f, path)
        except OSError as e:
            raise LinesFileError(f"{path}: cannot read the data (truncated or corrupt file?): {e}")


def _lines_text(f, path: Path) -> str:
    from ..integrate.reasons import Reason
    from ..io.lines_h5 import (
        attribute_names,
        current_reason_codes,
        file_metadata,
        required_dataset,
        required_group,
    )

    vtk = required_group(f, "VTKHDF", path)
    counts = required_dataset(f, "rowSize", path)[...]
    n_points = required_dataset(vtk, "Points", path).shape[0]
    out = [(f"{path}: flowkit lines file (format version {int(f.attrs['flowkit_format_version'])}"
           f", {f.attrs['Conventions']} trajectories + VTKHDF "
           f"{'.'.join(str(v) for v in vtk.attrs['Version'])} PolyData)"),
           f"  lines: {counts.size}   vertices: {n_points}   positions: {vtk['Points'].dtype}"]
    if counts.size:
        out.append(f"  vertices per line: min {counts.min()}  median {np.median(counts):g}  "
                   f"max {counts.max()}")
        out.append("  bounds: " + "  ".join(
            f"{a} [{lo:.6g}, {hi:.6g}]" for a, (lo, hi) in zip("xyz", _ranges(vtk["Points"]))))
    point_names, line_names = attribute_names(f)
    for name, title in (("reason", "reasons"), ("reason_backward", "reasons backward")):
        if name in line_names:  # direction both: the forward half's, then the backward half's
            reasons = current_reason_codes(f, vtk[f"CellData/{name}"][...], path)
            codes, n = np.unique(reasons, return_counts=True)
            out.append(f"  {title}: " + ", ".join(
                f"{Reason(c).label} {k}" for c, k in zip(codes.tolist(), n.tolist())))
    for title, group, names in (("point", vtk.get("PointData"), point_names),
                                ("line", vtk.get("CellData"), line_names)):
        if names:
            out.append(f"  {title} attributes:")
        for name in names:
            ds = group[name]
            kind = f"{ds.dtype}" + (f" x{ds.shape[1]}" if ds.ndim > 1 else "")
            rng = _ranges(ds)
            if ds.shape[0] == 0:
                text = "(empty)"
            elif ds.ndim > 1:
                text = "  ".join(f"[{lo:.6g}, {hi:.6g}]" for lo, hi in rng)
            else:
                text = f"[{rng[0][0]:.6g}, {rng[0][1]:.6g}]"
            u = ds.attrs.get("units")
            u = f"  {u.decode() if isinstance(u, bytes) else u}" if u is not None else ""
            out.append(f"    {name:<22} {kind:<12} {text}{u}")
    meta = file_metadata(f)
    if meta:
        out.append("  metadata:")
        out += [f"    {k} = {v}" for k, v in meta.items()]
    return "\n".join(out)


def _ranges(ds, block: int = 1 << 20) -> list[tuple[float, float]]:
    """Per-column [nanmin, nanmax] of a (n,) or (n, k) dataset, reading ``block`` rows at a time."""
    k = ds.shape[1] if ds.ndim > 1 else 1
    lo, hi = np.full(k, np.inf), np.full(k, -np.inf)
    for start in range(0, ds.shape[0], block):
        a = ds[start:start + block].reshape(-1, k).astype(np.float64)
        a[~np.isfinite(a)] = np.nan  # fmin/fmax skip NaN: the range of the finite values
        lo = np.fmin(lo, np.fmin.reduce(a, axis=0, initial=np.inf))
        hi = np.fmax(hi, np.fmax.reduce(a, axis=0, initial=-np.inf))
    return [(a, b) if a <= b else (np.nan, np.nan) for a, b in zip(lo, hi)]
