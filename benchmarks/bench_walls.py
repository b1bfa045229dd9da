"""Lines that run onto no-slip walls: what each stepping mode costs and how its lines end.

Real CFD output has walls whose nodes are at rest, and the flow runs onto them (the heated
room's plume onto its ceiling).  On the built-in heated room (``flowkit.datasets.hotroom()``,
the OpenFOAM snapshot at t = 2000 s), 200 seeds drawn uniformly over the domain (random seed
0) are traced forward with ``max_length=20`` and the defaults otherwise (dopri5, rtol 1e-6,
time as the parameter), cell-aware and plain: seconds (best of ``--repeat`` warm runs),
vertices, and the lines' reasons.  A line that hovers at a wall spends its whole step budget
(``max_steps``) there and fills the output with vertices that do not move.

Run: ``python benchmarks/bench_walls.py [--repeat 3]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import flowkit
from flowkit.datasets import hotroom
from flowkit.integrate.reasons import Reason


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    field = hotroom()
    lo, hi = np.asarray(field.grid.bounds, float).T
    seeds = lo + np.random.default_rng(0).random((200, 3)) * (hi - lo)
    print(f"{'mode':10s} {'seconds':>8s} {'vertices':>10s}  reasons")
    for aware in (True, False):
        best = np.inf
        for _ in range(args.repeat + 1):  # the first run compiles (or loads) the kernels
            t = time.perf_counter()
            lines = flowkit.trace(field, seeds, max_length=20.0, cell_aware=aware)
            best = min(best, time.perf_counter() - t)
        codes, counts = np.unique(lines.line_data["reason"], return_counts=True)
        reasons = ", ".join(f"{Reason(c).label} {n}" for c, n in zip(codes, counts))
        mode = "cell-aware" if aware else "plain"
        print(f"{mode:10s} {best:8.3f} {lines.n_points:10d}  {reasons}  [{lines.attrs['kernel_path']}]")


if __name__ == "__main__":
    main()
