"""Cell-aware stepping on and off, measured on the ABC benchmark problem (flowkit only).

For each method x tolerance x stepping mode (cell-aware with steps across faces where the error
estimate allows, the default; cell-aware with every step ending on a face; plain): accepted and rejected steps per line, median and 90th
percentile error of the point at arc length ``length`` against a tight reference (flowkit's own
DOP853, cell-aware, rtol 1e-13, on the same trilinear interpolant; the peer harness checks it
against scipy), wall time and steps/s.  Also reports the kernel's steps/s per core.

    .venv/bin/python benchmarks/cell_aware.py [--seeds 2000] [--nodes 128]
"""

from __future__ import annotations

import argparse
import os
import time

import numba
import numpy as np
from common import Problem, abc_field, make_seeds

from flowkit import trace


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=2000)
    ap.add_argument("--nodes", type=int, default=128)
    ap.add_argument("--methods", default="dopri5")
    ap.add_argument("--rtols", default="1e-4,1e-6,1e-8,1e-10")
    ap.add_argument("--parameter", default="time", choices=["time", "arc_length"])
    ap.add_argument("--vtk", default="", help="VTK RK4 steps to run on the same work, e.g. 0.05,0.01")
    args = ap.parse_args()
    prob = Problem(nodes_per_period=args.nodes, n_seeds=args.seeds)
    field = abc_field(prob)
    seeds = make_seeds(prob)
    L = prob.length
    common = {"max_length": L, "atol": 1e-12, "parameter": args.parameter}
    ref = trace(field, seeds, method="dop853", rtol=1e-13, cell_aware=True, **common)
    ref_end = ref.points[ref.offsets[1:] - 1]
    assert np.all(ref.line_data["reason"] == 1), "reference lines must all reach max_length"
    threads = numba.get_num_threads()
    print(f"ABC {prob.n_nodes}^3 nodes, {len(seeds)} seeds, length {L}; numba threads {threads}; "
          f"load {os.getloadavg()[0]:.2f}")
    modes = {"cross": {"cell_aware": True, "cross_faces": True},
             "faces": {"cell_aware": True, "cross_faces": False},
             "plain": {"cell_aware": False}}
    print("| method | rtol | stepping | acc/line | rej/line | median err | p90 err | wall s | "
          "steps/s/core |")
    print("|---|---|---|---|---|---|---|---|---|")
    for m in args.methods.split(","):
        for rtol in (float(r) for r in args.rtols.split(",")):
            for mode, kw in modes.items():
                trace(field, seeds[:4], method=m, rtol=rtol, **kw, **common)  # warm
                t0 = time.perf_counter()
                lines = trace(field, seeds, method=m, rtol=rtol, **kw, **common)
                wall = time.perf_counter() - t0
                end = lines.points[lines.offsets[1:] - 1]
                err = np.linalg.norm(end - ref_end, axis=1)
                acc = lines.line_data["n_accepted"].mean()
                rej = lines.line_data["n_rejected"].mean()
                sps = (acc + rej) * len(seeds) / wall / threads
                print(f"| {m} | {rtol:.0e} | {mode} | {acc:.0f} | {rej:.0f} | "
                      f"{np.median(err):.2e} | {np.percentile(err, 90):.2e} | {wall:.3f} | "
                      f"{sps:.3g} |")
    if args.vtk:
        import peers

        tracer = peers.VTKTracer(field)
        for step in (float(x) for x in args.vtk.split(",")):
            run = tracer.run(seeds, L, integrator="RK4", step=step)
            err = np.linalg.norm(run.end_points - ref_end, axis=1)
            print(f"| vtk RK4 step {step:g} | - | - | {L / step:.0f} | 0 | {np.median(err):.2e} | "
                  f"{np.percentile(err, 90):.2e} | {run.wall:.3f} | {tracer.threads()} |")


if __name__ == "__main__":
    main()
