"""``flowkit trace FIELD -o lines.h5 --seeds SPEC [options]``: streamlines to an HDF5 lines file.

Seeds: points, rakes, boxes and random draws; seeds from the data (``density:N:ATTRIBUTE``,
``where:EXPR:N``); or ``even:DSEP[:DTEST]``, evenly spaced lines (docs/seeding.md).
``--prune DIST[:FRACTION]`` then drops lines that run beside a longer one."""

from __future__ import annotations

import argparse
import math
import sys
import time


def register(subparsers) -> None:
    from ..distributed.cli import add_scale_options
    from ..integrate.methods import REGISTRY, describe
    from ..integrate.seeds import SPEC_HELP
    from ._field import add_mesh_options

    p = subparsers.add_parser("trace", help="trace streamlines through a field into an HDF5 file",
                              description=__doc__)
    p.add_argument("field", help="field file (.npz .h5 .vti .vtr .vtu .nc ...)")
    p.add_argument("-o", "--output", required=True, help="lines HDF5 file to write (atomically)")
    p.add_argument("--vector", default="U", help="name of the vector array (default U)")
    p.add_argument("--seeds", default="random:1000", help=f"seed spec: {SPEC_HELP} (default random:1000)")
    p.add_argument("--method", default="dopri5", choices=list(REGISTRY),
                   help="integration method (default dopri5): " + "; ".join(
                       f"{n}: {describe(m)}" for n, m in REGISTRY.items()))
    p.add_argument("--rtol", type=float, default=1e-6)
    p.add_argument("--atol", type=float, help="absolute tolerance (default: rtol x grid extent)")
    p.add_argument("--step", type=float, help="initial step (adaptive) or fixed step (rk4, euler)")
    p.add_argument("--max-length", type=float, default=math.inf)
    p.add_argument("--max-time", type=float, default=math.inf)
    p.add_argument("--max-steps", type=int, default=100_000)
    p.add_argument("--direction", choices=["forward", "backward", "both"],
                   help="default forward; both for --seeds even")
    p.add_argument("--parameter", default="time", choices=["time", "arc_length"])
    p.add_argument("--cell-aware", dest="cell_aware", action=argparse.BooleanOptionalAction,
                   default=True,
                   help="end steps on cell faces (default on; --no-cell-aware to switch off)")
    p.add_argument("--attributes", default="", help="per-vertex attributes, comma separated "
                   "(time, arc_length, speed, velocity, vorticity, vorticity_magnitude, "
                   "distance_to_seed, or a scalar field's name)")
    p.add_argument("--spacing", type=float, help="resample vertices to this arc-length spacing")
    p.add_argument("--count", type=int, help="resample every line to this many vertices")
    p.add_argument("--prune", metavar="DIST[:FRACTION]",
                   help="after tracing, drop each line within DIST of a longer line along at "
                        "least FRACTION of its vertices (default 0.8); recorded in the file")
    p.add_argument("--float64", action="store_true", help="store positions as float64")
    p.add_argument("--backend", default="numba", help="numba (default) or opencl[:PLATFORM[:DEVICE]]")
    p.add_argument("--memory", metavar="SIZE",
                   help="memory budget, e.g. 4GB (default: what the machine has free); a field "
                        "that does not fit is read brick by brick, only where lines go")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_mesh_options(p)
    add_scale_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..fields.readers import load_field
    from ..integrate.options import TraceOptions
    from ..integrate.seeds import parse_even_spec, parse_seed_spec
    from ..integrate.trace import trace_to_file
    from ..io.atomic import check_output
    from . import CLIError
    from ._field import mesh_options

    check_output(args.output)  # before any work
    even = parse_even_spec(args.seeds)
    direction = args.direction or ("both" if even is not None else "forward")
    opts = TraceOptions(
        method=args.method, rtol=args.rtol, atol=args.atol, step=args.step,
        max_length=args.max_length, max_time=args.max_time, max_steps=args.max_steps,
        direction=direction, parameter=args.parameter, cell_aware=args.cell_aware,
        attributes=args.attributes, spacing=args.spacing, count=args.count,
        progress=False if args.quiet else None, memory=args.memory,
    )
    from ..distributed import cli as scale

    if scale.wanted(args):  # --workers, --scheduler, series, pathlines: flowkit/distributed/cli.py
        if even is not None or args.prune:
            raise CLIError("flowkit trace: --seeds even and --prune place lines against each "
                           "other in one process; they do not run on workers, series or pathlines")
        return scale.run(args, opts)
    prune = None
    if args.prune:
        from ..seeding.prune import parse_prune

        try:
            prune = parse_prune(args.prune)
        except ValueError as e:
            raise CLIError(f"flowkit trace: {e}") from None
    field = load_field(args.field, vector=args.vector, **mesh_options(args))
    seeds = None if even is not None else parse_seed_spec(args.seeds, field)
    if math.isinf(opts.max_length) and math.isinf(opts.max_time) and args.max_steps == 100_000:
        print("flowkit trace: note: no --max-length or --max-time; lines end at the boundary, "
              "a stagnation point or after --max-steps", file=sys.stderr)
    dtype = "float64" if args.float64 else "float32"
    t0 = time.perf_counter()
    if even is None and prune is None:  # streamed, memory bounded by one batch
        path = trace_to_file(field, seeds, args.output, opts, backend=args.backend,
                             position_dtype=dtype)
        what = f"{len(seeds)} seeds traced"
    else:
        from ..io.lines_h5 import write_lines
        from ..seeding import trace_spec
        from ..seeding.prune import prune as prune_lines

        lines = trace_spec(field, args.seeds, opts, backend=args.backend)
        what = f"{len(lines)} lines traced"
        if prune is not None:
            n = len(lines)
            lines = prune_lines(lines, *prune, period=field.grid.period)
            what += f", {n - len(lines)} pruned"
        path = write_lines(lines, args.output, position_dtype=dtype, attrs={"seeds": args.seeds})
    dt = time.perf_counter() - t0
    if not args.quiet:
        if seeds is not None:
            rate = len(seeds) / dt if dt > 0 else float("inf")
            what += f" in {dt:.2f} s ({rate:.0f} seeds/s)"
        else:
            what += f" in {dt:.2f} s"
        print(f"{what} -> {path}")
    return 0
