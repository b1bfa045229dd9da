"""``flowkit resample MESH -o FIELD.h5``: an unstructured mesh (.vtu, .vtm, or a series of them)
resampled onto a grid once and written as a field file (.h5, .npz, .vti, .vtr; atomically), so
that every later trace, sample or scene reads the grid at once instead of resampling again.
The written field keeps the reader's notes (grid, method, NaN nodes)."""

from __future__ import annotations

from ._field import add_mesh_options, mesh_options


def register(subparsers) -> None:
    p = subparsers.add_parser("resample", help="resample an unstructured mesh onto a grid, once",
                              description=__doc__)
    p.add_argument("mesh", help="unstructured mesh (.vtu, .vtm, .series)")
    p.add_argument("-o", "--output", required=True, help="field file to write (.h5 .npz .vti .vtr)")
    p.add_argument("--vector", default="U", help="vector array name (default U)")
    p.add_argument("--snapshot", type=int, help="snapshot position in a series")
    p.add_argument("--time", type=float, help="snapshot time in a series")
    p.add_argument("--float64", action="store_true",
                   help="write float64 (default: the type the mesh stores)")
    add_mesh_options(p)
    p.set_defaults(func=run)


def run(args) -> int:
    import time

    from ..fields.readers import load_field
    from ..fields.writers import save_field

    opts = {k: v for k, v in (("snapshot", args.snapshot), ("time", args.time)) if v is not None}
    t0 = time.perf_counter()
    field = load_field(args.mesh, vector=args.vector, **opts,
                       **mesh_options(args))
    out = save_field(field, args.output, dtype="float64" if args.float64 else field.dtype)
    dt = time.perf_counter() - t0  # (located and interpolated as the arrays are written)
    print(f"{out}: {' x '.join(map(str, field.grid.shape))} grid, read, resampled and written "
          f"in {dt:.2f} s; {field.notes[0]}")
    return 0
