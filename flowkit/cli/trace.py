"""``flowkit trace FIELD -o lines.h5 --seeds SPEC [options]``: streamlines to an HDF5 lines file."""

from __future__ import annotations

import argparse
import math
import sys
import time


def register(subparsers) -> None:
    from ..distributed.cli import add_scale_options
    from ..integrate.methods import METHODS
    from ..integrate.options import STIFF_METHODS
    from ..integrate.seeds import SPEC_HELP

    p = subparsers.add_parser("trace", help="trace streamlines through a field into an HDF5 file",
                              description=__doc__)
    p.add_argument("field", help="field file (.npz .h5 .vti .vtr .vtu .nc ...)")
    p.add_argument("-o", "--output", required=True, help="lines HDF5 file to write (atomically)")
    p.add_argument("--vector", default="U", help="name of the vector array (default U)")
    p.add_argument("--seeds", default="random:1000", help=f"seed spec: {SPEC_HELP} (default random:1000)")
    p.add_argument("--method", default="dopri5", choices=sorted(METHODS) + list(STIFF_METHODS))
    p.add_argument("--rtol", type=float, default=1e-6)
    p.add_argument("--atol", type=float, help="absolute tolerance (default: rtol x grid extent)")
    p.add_argument("--step", type=float, help="initial step (adaptive) or fixed step (rk4, euler)")
    p.add_argument("--max-length", type=float, default=math.inf)
    p.add_argument("--max-time", type=float, default=math.inf)
    p.add_argument("--max-steps", type=int, default=100_000)
    p.add_argument("--direction", default="forward", choices=["forward", "backward", "both"])
    p.add_argument("--parameter", default="time", choices=["time", "arc_length"])
    p.add_argument("--cell-aware", dest="cell_aware", action=argparse.BooleanOptionalAction,
                   default=True,
                   help="end steps on cell faces (default on; --no-cell-aware to switch off)")
    p.add_argument("--attributes", default="", help="per-vertex attributes, comma separated "
                   "(time, arc_length, speed, velocity, vorticity, vorticity_magnitude, "
                   "distance_to_seed, or a scalar field's name)")
    p.add_argument("--spacing", type=float, help="resample vertices to this arc-length spacing")
    p.add_argument("--count", type=int, help="resample every line to this many vertices")
    p.add_argument("--float64", action="store_true", help="store positions as float64")
    p.add_argument("--backend", default="numba", help="numba (default) or opencl[:PLATFORM[:DEVICE]]")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_scale_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..fields.readers import load_field
    from ..integrate.options import TraceOptions
    from ..integrate.seeds import parse_seed_spec
    from ..integrate.trace import trace_to_file

    opts = TraceOptions(
        method=args.method, rtol=args.rtol, atol=args.atol, step=args.step,
        max_length=args.max_length, max_time=args.max_time, max_steps=args.max_steps,
        direction=args.direction, parameter=args.parameter, cell_aware=args.cell_aware,
        attributes=args.attributes, spacing=args.spacing, count=args.count,
        progress=False if args.quiet else None,
    )
    from ..distributed import cli as scale

    if scale.wanted(args):  # --workers, --scheduler, series, pathlines: flowkit/distributed/cli.py
        return scale.run(args, opts)
    field = load_field(args.field, vector=args.vector)
    seeds = parse_seed_spec(args.seeds, field)
    if math.isinf(opts.max_length) and math.isinf(opts.max_time) and args.max_steps == 100_000:
        print("flowkit trace: note: no --max-length or --max-time; lines end at the boundary, "
              "a stagnation point or after --max-steps", file=sys.stderr)
    t0 = time.perf_counter()
    path = trace_to_file(field, seeds, args.output, opts, backend=args.backend,
                         position_dtype="float64" if args.float64 else "float32")
    dt = time.perf_counter() - t0
    if not args.quiet:
        rate = len(seeds) / dt if dt > 0 else float("inf")
        print(f"{len(seeds)} seeds traced in {dt:.2f} s ({rate:.0f} seeds/s) -> {path}")
    return 0
