"""The work–precision benchmark: flowkit against VTK's vtkStreamTracer, streamtracer and
scipy on identical work, in one process.

ABC flow on [0, 6 pi]^3 at 128 nodes per period (385^3 nodes, float64), 2000 seeds, lines of
arc length 10.  Error: distance of each line's point at arc length 10 from a cell-by-cell DOP853
reference on the same trilinear interpolant (benchmarks/common.py).  Prints a Markdown
work–precision table, writes it as CSV (and a PNG plot) to benchmarks/results/, and prints
flowkit's speed ratio against each peer at matched median error (<= 1e-4 and <= 5e-6), taking
for each tool its fastest run that reaches the level.

    .venv/bin/python benchmarks/bench_trace.py             # the full benchmark (~1.4 GB field)
    .venv/bin/python benchmarks/bench_trace.py --quick     # small grid, few seeds
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import common as C  # run as a script: benchmarks/ is on sys.path
import numpy as np
import peers

LEVELS = (1e-4, 5e-6)
FLOWKIT_TOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
# without cell-aware stepping the error follows the tolerance (not the cell floor): a 1-2-5
# grid there, as fine as the peers' step grids (VTK RK4 0.1, 0.05, 0.02, ...)
PLAIN_TOLS = (1e-3, 1e-4, 1e-5, 1e-6, 5e-7, 2e-7, 1e-7, 5e-8, 2e-8, 1e-8, 5e-9, 2e-9, 1e-9,
              5e-10, 2e-10, 1e-10)
# fixed-step RK4 as the peers run it (arc-length steps, no cell splitting) on the peers' step
# grid, so that each tool's RK4 does identical work: at a loose level four evaluations a step
# and no error estimate beat any adaptive run.  The grid is the same for every tool, steps that
# divide the length (streamtracer takes a step count) at most 1.6x apart (an RK4 error of 1e-4
# needs step ~0.19: 0.2 just misses it)
RK4_STEPS = (0.2, 0.125, 0.1, 0.08, 0.05, 0.04, 0.025, 0.02, 0.0125, 0.01, 0.005, 0.002, 0.001)
FLOWKIT_RK4 = RK4_STEPS[:8]
# cell-aware RK4 with a step longer than any cell: one step per cell, on its polynomial
FLOWKIT_RK4_CELL = (1.0,)
VTK_RK45 = (1e-3, 1e-4, 1e-5, 3e-6, 1e-6, 3e-7, 1e-7, 3e-8, 1e-8)
VTK_RK4 = RK4_STEPS[:11]
ST_STEPS = RK4_STEPS
SCIPY_TOLS = (1e-4, 1e-6, 1e-8)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small grid (16/period), 200 seeds")
    ap.add_argument("--seeds", type=int, help="number of seeds (default 2000)")
    ap.add_argument("--nodes-per-period", type=int, help="grid nodes per period (default 128)")
    ap.add_argument("--scipy-seeds", type=int, default=20, help="seeds for scipy (time scaled)")
    ap.add_argument("--processes", type=int, default=2, help="processes for the reference")
    ap.add_argument("--skip", default="", help="comma-separated tools to skip: vtk,streamtracer,"
                    "scipy,flowkit")
    ap.add_argument("--vtk-threads", type=int, default=os.cpu_count(),
                    help="vtkSMPTools STDThread threads for VTK (1: its Sequential default)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="time each setting this many times (passes interleaved over the tools) "
                    "and keep the fastest (scipy: once)")
    ap.add_argument("--no-plot", action="store_true", help="do not write the PNG")
    ap.add_argument("--stretch", type=float, default=1.0,
                    help="> 1: a rectilinear grid, x cells graded to this ratio of widest to "
                    "narrowest (VTK through vtkRectilinearGrid; streamtracer takes uniform grids "
                    "only and is skipped)")
    ap.add_argument("--attributes", default="",
                    help="comma-separated attributes flowkit computes at every vertex (e.g. "
                    "speed,time,vorticity); VTK then computes its vorticity (ComputeVorticity), "
                    "streamtracer and scipy, which compute none, are skipped")
    a = ap.parse_args(argv)
    kw = {"nodes_per_period": 16, "n_seeds": 200} if a.quick else {}
    if a.stretch != 1.0:
        kw["stretch"] = a.stretch
    if a.seeds is not None:
        kw["n_seeds"] = a.seeds
    if a.nodes_per_period is not None:
        kw["nodes_per_period"] = a.nodes_per_period
    problem = C.Problem(**kw)
    skip = {s.strip() for s in a.skip.split(",") if s.strip()}
    attributes = [s.strip() for s in a.attributes.split(",") if s.strip()]
    if problem.stretch != 1.0:
        skip.add("streamtracer")
    if attributes:
        skip |= {"streamtracer", "scipy"}

    print(f"machine: {C.machine()}")
    print(f"problem: ABC on [0, {problem.periods}*2pi]^3, {problem.n_nodes}^3 nodes "
          f"({problem.nodes_per_period}/period, spacing {problem.spacing:.5g}"
          + (f", x graded {problem.stretch:g}:1" if problem.stretch != 1.0 else "")
          + f"), {problem.n_seeds} seeds, arc length {problem.length:g}"
          + (f", attributes {','.join(attributes)}" if attributes else ""))
    t0 = time.perf_counter()
    field = C.abc_field(problem)
    print(f"field: {field.vector.nbytes / 2**30:.2f} GiB float64, sampled in "
          f"{time.perf_counter() - t0:.1f} s")
    seeds = C.make_seeds(problem)
    ref, nfev, ref_s, cached = C.cached_reference(problem, field, seeds, a.processes)
    print(f"reference: cell-by-cell DOP853 rtol={problem.ref_rtol:g} atol={problem.ref_atol:g}, "
          f"{np.mean(nfev):.0f} RHS evaluations per seed, {ref_s:.0f} s"
          + (" (cached)" if cached else ""))

    # Every setting is timed `repeat` times, the passes interleaved over all tools so that
    # each sees the same shared-machine load; the fastest call of each is kept.
    jobs = list(_all_runs(field, seeds, problem, skip, a.scipy_seeds, a.vtk_threads,
                          attributes))
    best = [None] * len(jobs)
    for rep in range(max(a.repeat, 1)):
        for n, job in enumerate(jobs):
            if rep == 0 or job.repeat:
                run = job()
                if best[n] is None or run.wall < best[n].wall:
                    best[n] = run
        print(f"  pass {rep + 1}/{a.repeat} done; {C.machine().split('; ')[2]}", flush=True)
    runs = []
    for run in best:
        run.err = C.errors(run.end_points, ref[: run.n_seeds])
        runs.append(run)
        r = run.stats()
        print(f"  {r['tool']:12s} {r['setting']:36s} median {r['median_err']:.2e}  "
              f"p90 {r['p90_err']:.2e}  {r['wall_s']:8.3f} s  threads used {r['threads_used']:.2f}"
              + (f"  FAILED {r['failed']}" if r["failed"] else "")
              + "".join(f"\n      {n}" for n in run.notes if "thread" not in n), flush=True)
    rows = [r.stats() for r in runs]
    notes = sorted({f"{r.tool}: {n}" for r in runs for n in r.notes if "thread" in n})

    print(f"\n## Work–precision (ABC, {problem.n_nodes}^3 nodes, {problem.n_seeds} seeds, "
          f"arc length {problem.length:g})\n")
    print(C.markdown_table(rows))
    print("\nthreads: " + "; ".join(notes))
    print("\n" + ratio_table(rows))
    print(f"\nmachine at the end: {C.machine()}")
    tag = f"{problem.nodes_per_period}npp_{problem.n_seeds}seeds"
    tag += f"_stretch{problem.stretch:g}" if problem.stretch != 1.0 else ""
    tag += "_" + "_".join(attributes) if attributes else ""
    path = C.write_csv(C.RESULTS / f"bench_trace_{tag}.csv", rows)
    print(f"CSV: {path}")
    if not a.no_plot:
        print(f"plot: {plot(rows, C.RESULTS / f'bench_trace_{tag}.png')}")
    return 0


def _job(fn, *args, repeat=True, **kw):
    """A run to do later (``repeat`` times when timed repeatedly)."""

    def job():
        return fn(*args, **kw)

    job.repeat = repeat
    return job


def _all_runs(field, seeds, problem, skip, scipy_seeds, threads, attributes=()):
    """Zero-argument callables, one per tool setting, each returning a ``common.Run`` (all
    tools set up at once: VTK's transposed copy of the field lives until the end).  With
    ``attributes`` flowkit computes them and VTK its vorticity."""
    L = problem.length
    at = {"attributes": list(attributes)} if attributes else {}
    if "flowkit" not in skip:
        peers.flowkit_run(field, seeds[:4], L, rtol=1e-3, **at)  # compile (cached) untimed
        # the default (cell-aware, steps across faces where the kink bound allows), every step
        # ending on a face, and plain
        for kw, tols in (({}, FLOWKIT_TOLS), ({"cross_faces": False}, FLOWKIT_TOLS),
                         ({"cell_aware": False}, PLAIN_TOLS)):
            for tol in tols:
                yield _job(peers.flowkit_run, field, seeds, L, rtol=tol, **kw, **at)
        for h in FLOWKIT_RK4:
            yield _job(peers.flowkit_run, field, seeds, L, method="rk4", step=h,
                       cell_aware=False, **at)
        for h in FLOWKIT_RK4_CELL:
            yield _job(peers.flowkit_run, field, seeds, L, method="rk4", step=h,
                       cell_aware=True, **at)
    if "vtk" not in skip:
        vt = peers.VTKTracer(field)
        cell = vt.cell_diagonal
        vo = {"vorticity": bool(attributes)}
        for err in VTK_RK45:  # VTK's default backend (Sequential)
            # VTK's defaults: initial 0.2 cell, steps between 0.01 and 1 cell (diagonals)
            yield _job(_vtk, vt, 1, seeds, L, "RK45", err, step=0.2 * cell,
                       min_step=0.01 * cell, max_step=cell, **vo)
        # the same in cell units (each cell's own diagonal): equivalent on a uniform grid
        yield _job(_vtk, vt, 1, seeds, L, "RK45", 1e-5, step=0.2, min_step=0.01, max_step=1.0,
                   unit="cell", **vo)
        for h in VTK_RK4:
            yield _job(_vtk, vt, 1, seeds, L, "RK4", step=h, **vo)
        if threads > 1:  # vtkSMPTools STDThread threads
            for err in VTK_RK45[2:]:  # steps up to 10 cells
                yield _job(_vtk, vt, threads, seeds, L, "RK45", err, step=0.2 * cell,
                           min_step=1e-4 * cell, max_step=10 * cell, **vo)
            for h in VTK_RK4:
                yield _job(_vtk, vt, threads, seeds, L, "RK4", step=h, **vo)
    if "streamtracer" not in skip:
        st = peers.StreamtracerTracer(field)
        for ds in ST_STEPS:
            yield _job(st.run, seeds, L, ds)
    if "scipy" not in skip:
        sub = seeds[:scipy_seeds]
        for tol in SCIPY_TOLS:
            yield _job(peers.scipy_run, field, sub, L, len(seeds), rtol=tol, repeat=False)


def _vtk(vt, threads, *args, **kw):
    vt.set_threads(threads)
    return vt.run(*args, **kw)


def ratio_table(rows) -> str:
    """flowkit's speed ratio against each peer at each accuracy level (peer time / flowkit
    time, each tool's fastest run with median error <= level)."""
    tools = [t for t in dict.fromkeys(r["tool"] for r in rows) if t != "flowkit"]
    out = ["## Speed ratio at matched accuracy (peer wall time / flowkit wall time)\n",
           "| level | flowkit run | flowkit s | peer | peer run | peer s | ratio |",
           "|---|---|---|---|---|---|---|"]
    dopri5 = [r for r in rows if r["tool"] != "flowkit" or r["setting"].startswith("dopri5")]
    for level in LEVELS:
        fk, fk5 = C.fastest_at(rows, "flowkit", level), C.fastest_at(dopri5, "flowkit", level)
        out += _ratio_rows(rows, tools, level, fk, "")
        if fk5 is not fk:  # else dopri5 is already flowkit's fastest here
            out += _ratio_rows(rows, tools, level, fk5, " (dopri5 only)")
    return "\n".join(out)


def _ratio_rows(rows, tools, level, fk, label):
    out = []
    for tool in tools:
        pr = C.fastest_at(rows, tool, level)
        fs = f"{fk['setting']} | {fk['wall_s']:.3f}" if fk else "none reaches it | -"
        ps = f"{pr['setting']} | {pr['wall_s']:.3f}" if pr else "none reaches it | -"
        ratio = f"{pr['wall_s'] / fk['wall_s']:.1f}x" if fk and pr else "-"
        out.append(f"| median <= {level:.0e}{label} | {fs} | {tool} | {ps} | {ratio} |")
    return out


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    groups = {}
    for r in rows:
        kind = r["setting"].split()[0]
        if r["tool"] == "flowkit":
            kind += " cell-aware" if "cell_aware=on" in r["setting"] else " plain"
            kind += " faces only" if "cross_faces=off" in r["setting"] else ""
        if "smp=" in r["setting"]:
            kind += " " + r["setting"].split()[-1]
        groups.setdefault(f"{r['tool']} {kind}", []).append(r)
    for name, rs in groups.items():
        rs = sorted(rs, key=lambda r: r["median_err"])
        ax.loglog([r["median_err"] for r in rs], [r["wall_s"] for r in rs], "o-", label=name)
    for level in LEVELS:
        ax.axvline(level, color="0.7", lw=0.8, ls="--")
    ax.set_xlabel("median error at arc length 10")
    ax.set_ylabel("wall time for all seeds [s]")
    ax.set_title("Work–precision, ABC flow (same trilinear field and seeds)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", lw=0.3)
    with C.atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=120, format="png")
    plt.close(fig)
    return path


if __name__ == "__main__":
    sys.exit(main())
