"""``flowkit sample LINES FIELD --attributes vorticity,T -o OUT``: attributes added to lines
already traced, sampled from a field (this snapshot, another one, another grid) at their
vertices, as a trace computes them; vertices outside the field get NaN, and the output says how
many.  The output keeps the lines' positions type and every attribute they had."""

from __future__ import annotations

from pathlib import Path

from . import CLIError
from ._field import add_mesh_options, mesh_options


def register(subparsers) -> None:
    p = subparsers.add_parser("sample", help="add attributes to lines already traced",
                              description=__doc__)
    p.add_argument("lines", help="flowkit lines file (.h5)")
    p.add_argument("field", help="field file, as flowkit trace reads it")
    p.add_argument("--attributes", required=True,
                   help="comma-separated: speed, velocity, vorticity, vorticity_magnitude, "
                        "distance_to_seed, or scalar names of the field")
    p.add_argument("-o", "--output", required=True, help="lines file to write (.h5)")
    p.add_argument("--rename", default="",
                   help="comma-separated NAME=NEW, e.g. T=T_1200 for another snapshot's T")
    p.add_argument("--vector", default=None, help="vector array name (default U)")
    p.add_argument("--snapshot", type=int, help="snapshot position in a series file")
    p.add_argument("--time", type=float, help="snapshot time in a series file")
    add_mesh_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from ..fields.readers import load_field
    from ..integrate.sample import nan_counts, sample
    from ..io.lines_h5 import read_lines, write_lines

    out = Path(args.output)
    if not out.parent.is_dir():
        raise CLIError(f"{out}: the output folder {out.parent} does not exist")
    names = [a.strip() for a in args.attributes.split(",") if a.strip()]
    rename = {}
    for item in filter(None, (r.strip() for r in args.rename.split(","))):
        old, eq, new = item.partition("=")
        if not eq or not old or not new:
            raise CLIError(f"--rename '{item}': expected NAME=NEW")
        rename[old.strip()] = new.strip()
    lines = read_lines(args.lines)
    opts = {k: v for k, v in (("snapshot", args.snapshot), ("time", args.time)) if v is not None}
    field = load_field(args.field, vector=args.vector, **opts, **mesh_options(args))
    result = sample(lines, field, names, rename=rename)
    write_lines(result, out, position_dtype=str(lines.points.dtype))
    nan = nan_counts(result)
    print(f"{out}: {len(result)} lines, {result.n_points} vertices; sampled from {field.source}: "
          + ", ".join(f"{n} ({k} NaN)" if k else n for n, k in nan.items()))
    return 0
