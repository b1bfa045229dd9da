"""The scale-out options of ``flowkit trace`` (added by ``add_scale_options``) and their run.

``flowkit trace`` hands a run here (``wanted(args)``) when a cluster is asked for (``--workers``,
``--scheduler``, ``--distribute``), when the input is a series (a ``.series`` file or a glob: every snapshot is
traced; ``--snapshots`` picks some, also in a multi-snapshot HDF5 file, which otherwise gives its
first snapshot as before), or for ``--pathlines``.
"""

from __future__ import annotations

import time
from pathlib import Path

from .. import cli


def add_scale_options(parser) -> None:
    g = parser.add_argument_group(
        "scale-out and series (dask; see docs/scale-out.md)")
    g.add_argument("--workers", type=int, metavar="N",
                   help="run on a local dask cluster of N worker processes")
    g.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on an existing dask cluster (e.g. tcp://host:8786)")
    g.add_argument("--snapshots", metavar="SPEC",
                   help="snapshots of a series: all, or positions such as 0,2,4 or 1:4")
    g.add_argument("--per-snapshot", action="store_true",
                   help="one output file per snapshot (OUT_0000.h5 ...) instead of one file with a "
                        "snapshot index")
    g.add_argument("--distribute", choices=("auto", "seeds", "blocks"),
                   help="split the seeds across workers (each reads the whole field) or the "
                        "field's blocks (each reads its own; lines handed between them; a series "
                        "snapshot after snapshot, with --per-snapshot); auto (default): blocks "
                        "where the field does not fit a worker's memory limit")
    g.add_argument("--chunk-seeds", type=int, metavar="N",
                   help="seeds per task (default: about 8 tasks per worker thread)")
    g.add_argument("--pathlines", action="store_true",
                   help="pathlines through the series (linear in time between snapshots)")
    g.add_argument("--release", metavar="T",
                   help="pathlines: release time of every seed, or a .npy file of one time per "
                        "seed (default: the first snapshot time, the last going backward)")


def wanted(args) -> bool:
    """Whether this run belongs to the scale-out path."""
    return bool(args.workers or args.scheduler or args.pathlines or args.snapshots
                or args.per_snapshot or args.distribute or _is_series(args.field))


def run(args, options) -> int:
    """Trace (or pathline) ``args.field`` with ``options`` (TraceOptions) on a dask cluster."""
    import numpy as np

    from ..cli._field import mesh_options
    from ..fields.readers import load_field
    from ..integrate.seeds import parse_seed_spec
    from .jobs import JobError, _series, pathlines_distributed, trace_distributed

    series = _series(args.field)
    snaps = _snapshot_spec(args.snapshots, len(series), args.field)
    if args.snapshots is None and not args.pathlines and not _is_series(args.field):
        snaps = [0]  # a multi-snapshot file gives its first snapshot, as load_field does
    if args.backend != "numba":
        raise cli.CLIError(f"--backend {args.backend}: scale-out runs the numba backend on workers")
    if args.workers is not None and args.workers < 1:
        raise cli.CLIError(f"--workers must be at least 1, got {args.workers}")
    first = series[snaps[0] if snaps is not None and not args.pathlines else 0][1]
    load = mesh_options(args)  # (a mesh: resampled on each worker, as here for the seeds)
    seeds = parse_seed_spec(args.seeds, load_field(first, vector=args.vector, **load))
    cluster = {"scheduler": args.scheduler, "workers": args.workers,
               "chunk_seeds": args.chunk_seeds, "vector": args.vector, "load": load,
               "progress": False if args.quiet else None}
    dtype = "float64" if args.float64 else "float32"
    t0 = time.perf_counter()
    if args.pathlines:
        if args.distribute == "blocks":
            raise cli.CLIError("--distribute blocks traces streamlines of one snapshot, not "
                               "--pathlines")
        series = [series[i] for i in snaps] if snaps is not None else args.field
        release = None
        if args.release is not None:
            release = (np.load(args.release, allow_pickle=False)
                       if args.release.endswith(".npy") else float(args.release))
        outs = [pathlines_distributed(series, seeds, args.output, release, options,
                                      position_dtype=dtype, **cluster)]
    else:
        if args.release is not None:
            raise cli.CLIError("--release applies to --pathlines only")
        try:
            outs = trace_distributed(args.field, seeds, args.output, options, snapshots=snaps,
                                     per_snapshot=args.per_snapshot, position_dtype=dtype,
                                     distribute=args.distribute or "auto", **cluster)
        except JobError as e:  # (one line: it names the task or worker, block and file)
            raise cli.CLIError(str(e)) from None
    dt = time.perf_counter() - t0
    if not args.quiet:
        n = len(seeds) * (1 if args.pathlines else len(snaps or series))
        kind = "pathlines" if args.pathlines else "seed x snapshot traces"
        where = outs[0] if len(outs) == 1 else f"{outs[0]} .. {Path(outs[-1]).name}"
        print(f"{n} {kind} in {dt:.2f} s ({n / dt:.0f}/s) -> {where}")
    return 0


def _is_series(path) -> bool:
    s = str(path)
    return Path(s).suffix.lower() == ".series" or (any(c in s for c in "*?[")
                                                     and not Path(s).exists())


def _snapshot_spec(spec, n, where):
    """None (all of a series), or positions from "all", "0,2,4", "1:4" (Python slice)."""
    if spec is None or spec == "all":
        return None
    try:
        if ":" in spec:
            return list(range(n))[slice(*[int(x) if x else None for x in spec.split(":")])]
        return [int(x) for x in spec.split(",")]
    except ValueError:
        raise cli.CLIError(f"{where}: --snapshots {spec!r} is not 'all', a list like 0,2,4 or a "
                           f"slice like 1:4") from None
