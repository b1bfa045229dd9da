"""``flowkit info FILE``: what a field file (or series, or lines file) holds.

Grid kind, shape, bounds and spacing, every array with its type, size, chunking and units, and
the reader's notes, from the file's metadata alone: no array data is read, so a snapshot of any
size prints at once.  ``--stats`` adds each array's range and NaN/inf counts, read a slab at a
time (memory bounded by a slab, progress on a terminal).  For a series (.series, a glob, a
multi-snapshot flowkit HDF5 or netCDF file) the list of snapshots and times comes first, then
the selected snapshot (default the first).
"""

from __future__ import annotations

import importlib
from pathlib import Path

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
    p.add_argument(
        "--data", choices=["point", "cell"], help="VTK files: point data (default) or cell data"
    )
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
            args.file, vector=args.vector, snapshot=args.snapshot, time=args.time, data=args.data,
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
    """Summary of a flowkit lines file, by flowkit.io.lines_h5.summary when that module has it."""
    try:
        mod = importlib.import_module("flowkit.io.lines_h5")
    except ImportError:
        mod = None
    if mod is None or not hasattr(mod, "summary"):
        raise CLIError(
            f"{path}: a flowkit lines file, and this flowkit has no lines reader to summarise it"
        )
    return mod.summary(path)
