"""``flowkit compile [WHAT ...]``: compile the kernels ahead of use, once per machine or image.

WHAT is an option set (default, attributes, rk4, dop853, no-cell-aware, lockstep, rosenbrock,
pathlines, even, meshes for reading unstructured meshes, or all of them) or a scene file (its trace options and the attributes its styles
read, and its views rendered small, which compiles the renderer's level-of-detail kernels);
without WHAT, the default options.  An option set compiles for fields stored as float64 and as
float32 (``--types``: a kernel compiles once per array type it reads); a scene for the type its
field is stored in.  Each is a short trace on a small stand-in field:
the machine code depends on the options, not on the data, and numba's disk cache keeps it for
every later process (a container image built with it, or every worker of a cluster pointed at
one shared NUMBA_CACHE_DIR).  Prints what was compiled and the seconds it took.
"""

from __future__ import annotations

import sys
import time


def register(subparsers) -> None:
    p = subparsers.add_parser("compile", help="compile the kernels that options or a scene "
                              "need, so later runs start warm", description=__doc__)
    p.add_argument("what", nargs="*", default=["default"], metavar="WHAT",
                   help="option set or scene file (default: default)")
    p.add_argument("--types", default="float64,float32",
                   help="field types the option sets compile for (default: float64,float32)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    import logging

    from tqdm import tqdm

    from .. import warmup

    todo = warmup.jobs(args.what, [t.strip() for t in args.types.split(",") if t.strip()])
    notice = logging.getLogger("flowkit.compile")
    was, notice.disabled = notice.disabled, True  # the bar says it already
    t0 = time.perf_counter()
    done = []
    bar = tqdm(todo, unit="set", file=sys.stderr, disable=args.quiet or None,
               bar_format="{desc} {bar} {n_fmt}/{total_fmt} [{elapsed}]")
    try:
        for label, job in bar:
            bar.set_description(f"compiling {label}")
            done.append(warmup.compile_one(label, job))
    finally:
        bar.close()
        notice.disabled = was
    for c in done:
        how = (f"compiled {c.compiled} functions in {c.compile_seconds:.1f} s" if c.compiled
               else "all from the cache")
        print(f"{c.what}: {how} ({c.seconds:.1f} s)")
    total = sum(c.compile_seconds for c in done)
    print(f"compiled {sum(c.compiled for c in done)} functions in {total:.1f} s "
          f"({time.perf_counter() - t0:.1f} s in all); cache: {warmup.cache_location()}")
    return 0
