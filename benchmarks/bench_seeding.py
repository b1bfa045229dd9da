"""Evenly spaced seeding of the heated room against tracing as many vertices from given seeds.

The heated room (last snapshot), ``dsep`` = 1/30 of the domain diagonal (0.5 m), ``dtest`` =
dsep / 2, lines both ways, at most 12 m per direction, vertices every dtest / 2, stagnation
below 1e-4 m/s.  After a warm-up run (numba JIT), the best of ``--repeat`` runs is reported:
seconds, lines, vertices, the share of the time spent tracing (the kernel's passes and the
vertices they returned, also those later cut or rejected) against placement (hash, cuts,
candidates), and the ratio against tracing the same number of vertices from given seeds: the
seeds of the evenly spaced lines, traced with the same options (the lines are then not cut, so
they hold more vertices; that time is scaled to the evenly spaced vertex count).  Goal: <= 2x.

    .venv/bin/python benchmarks/bench_seeding.py [--repeat 3] [--fraction 30]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from flowkit import TraceOptions, trace
from flowkit.datasets import hotroom
from flowkit.seeding.even import EvenSeeder


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--fraction", type=float, default=30.0, help="dsep = diagonal / this")
    a = ap.parse_args(argv)
    field = hotroom()
    diag = float(np.linalg.norm(np.diff(field.grid.bounds, axis=1)))
    dsep = diag / a.fraction
    opts = TraceOptions(direction="both", max_length=12.0, stagnation=1e-4)

    def even():
        s = EvenSeeder(field, dsep, None, opts, seed=0)
        t0 = time.perf_counter()
        lines = s.run()
        return time.perf_counter() - t0, s.stats, lines

    even()  # warm-up: numba compiles (or loads) the kernels
    runs = [even() for _ in range(a.repeat)]
    dt, stats, lines = min(runs, key=lambda r: r[0])
    given = lines.line_data["seed"]
    gopts = opts.replace(spacing=0.25 * dsep)
    trace(field, given, gopts)
    times = []
    for _ in range(a.repeat):
        t0 = time.perf_counter()
        glines = trace(field, given, gopts)
        times.append(time.perf_counter() - t0)
    tg = min(times)
    scaled = tg * lines.n_points / glines.n_points
    share = stats["trace_seconds"] / dt
    print(f"heated room, dsep = diagonal / {a.fraction:g} = {dsep:.3f} m, dtest = {dsep / 2:.3f} "
          f"m, both ways, max 12 m per direction; best of {a.repeat} (warm)")
    print("| | seconds | lines | vertices |")
    print("|---|---:|---:|---:|")
    print(f"| evenly spaced | {dt:.3f} | {len(lines)} | {lines.n_points:,} |")
    print(f"| ... of which tracing ({stats['trace_calls']} kernel passes) | "
          f"{stats['trace_seconds']:.3f} ({share:.0%}) | "
          f"{stats['traced']} traced, {stats['rejected']} rejected | "
          f"{stats['trace_vertices']:,} traced |")
    print(f"| ... of which placement | {dt - stats['trace_seconds']:.3f} ({1 - share:.0%}) | | |")
    print(f"| given seeds (the same seeds, not cut) | {tg:.3f} | {len(glines)} | "
          f"{glines.n_points:,} |")
    print(f"| given seeds, scaled to {lines.n_points:,} vertices | {scaled:.3f} | | |")
    print(f"ratio evenly spaced / given seeds at equal vertices: {dt / scaled:.2f}x (goal <= 2x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
