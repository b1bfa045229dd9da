"""auto on the stiff linear field: lines switched to ros34pw2 where flagged, against dopri5 and
ros34pw2 alone (numba, cell-aware).  The field's eigenvalues are -1 and -1e4: dopri5's steps are
held at its stability boundary whatever the tolerance, so every line gets flagged.

    .venv/bin/python benchmarks/bench_stiff_switch.py [--seeds 128] [--tol 1e-6]

Prints error at t = 5 against the exact trajectory (median, max), steps per line and the best of
three wall times for each method.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flowkit import trace
from flowkit.fields.analytic import LinearField


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=128)
    ap.add_argument("--tol", type=float, default=1e-6)
    args = ap.parse_args(argv)
    stiff = LinearField.stiff()
    field = stiff.to_field((4, 4, 11))
    rng = np.random.default_rng(0)
    seeds = rng.uniform([-0.9, -0.9, 0.2], [0.9, 0.9, 1.0], (args.seeds, 3))
    T = 5.0
    exact = stiff.trajectory(seeds, T)
    kw = {"rtol": args.tol, "atol": args.tol, "max_time": T, "max_steps": 10**6,
          "stagnation_rel": 1e-6}
    print(f"stiff linear field, {args.seeds} seeds, tol {args.tol:g}, t = {T}")
    print("| method | median err | max err | steps/line | s (best of 3) | switched |")
    print("|---|---|---|---|---|---|")
    for method in ("dopri5", "ros34pw2", "auto"):
        trace(field, seeds[:2], method=method, **kw)  # compile outside the timing
        best = np.inf
        for _ in range(3):
            t = time.perf_counter()
            L = trace(field, seeds, method=method, **kw)
            best = min(best, time.perf_counter() - t)
        err = np.linalg.norm(L.points[L.offsets[1:] - 1] - exact, axis=1)
        steps = np.mean(L.line_data["n_accepted"] + L.line_data["n_rejected"])
        switched = int(L.line_data["ros34pw2"].sum()) if "ros34pw2" in L.line_data else "-"
        print(f"| {method} | {np.median(err):.2e} | {err.max():.2e} | {steps:.0f} | {best:.4f} | "
              f"{switched} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
