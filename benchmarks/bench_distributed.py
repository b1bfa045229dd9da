"""Scale-out benchmark: seeds/s with 1 and 2 dask workers, and the overhead of one task.

Identical work in every run: ABC flow sampled on a periodic 64^3 grid (one period) and written
to a flowkit HDF5 file, N random seeds, dopri5 at rtol 1e-6, lines of arc length L.  Timed:

* ``in-process``: ``trace_to_file`` in this process with numba on 1 thread (the floor);
* ``1 worker`` / ``2 workers``: ``trace_distributed`` end to end (tasks, part files, join) on a
  running LocalCluster of worker processes with one thread each; the cluster's start-up and the
  workers' first (numba cache) load are excluded by a warm-up job and reported apart;
  each is also split into its tracing phase (until the last task is done: parallel) and the
  join after it (one process per output file: serial for the single output here), and the CPU
  the tasks actually got (on a shared machine 2 workers may get far less than 2 cores);
* task overhead: the job's first 20000 seeds on 2 workers cut into chunks of several sizes; the
  slope of wall time against task count, times the worker count, is the worker-seconds one task
  costs beyond its tracing (submission, scheduling, opening the part, writing it, joining it).

Prints the load average before and after: the machine is shared, so only ratios measured in the
same run mean anything.  ``--quick`` runs a tiny version (a smoke test).

    .venv/bin/python benchmarks/bench_distributed.py [--seeds 100000] [--length 20] [--quick]
"""

from __future__ import annotations

import argparse
import logging
import os
import tempfile
import time
from pathlib import Path

import numpy as np

OVERHEAD_SEEDS = 20000


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=100000,
                    help="seeds of the timed job (20000 gives a 2-second job on 2 workers, where "
                    "the fixed start and tail weigh ~5 %%)")
    ap.add_argument("--length", type=float, default=20.0)
    ap.add_argument("--grid", type=int, default=64)
    ap.add_argument("--repeat", type=int, default=2, help="best of this many runs")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    if args.quick:
        args.seeds, args.length, args.grid, args.repeat = 600, 5.0, 16, 1

    import numba
    from distributed import Client, LocalCluster

    from flowkit.distributed import trace_distributed
    from flowkit.fields.analytic import ABCFlow
    from flowkit.fields.writers import save_field
    from flowkit.integrate.options import TraceOptions
    from flowkit.integrate.trace import trace_to_file

    load0 = os.getloadavg()
    opts = TraceOptions(rtol=1e-6, max_length=args.length)
    rng = np.random.default_rng(7)
    seeds = rng.uniform(0, 2 * np.pi, (args.seeds, 3))
    with tempfile.TemporaryDirectory(prefix="bench_distributed_") as tmp:
        tmp = Path(tmp)
        field = ABCFlow().to_field(args.grid, bounds=[[0, 2 * np.pi]] * 3)
        src = save_field(field, tmp / "abc.h5")

        numba.set_num_threads(1)
        trace_to_file(field, seeds[:50], tmp / "warm.h5", opts)  # compile / load the cache
        t_in = _best(args.repeat, lambda: trace_to_file(field, seeds, tmp / "in.h5", opts))

        rows = [("in-process, numba 1 thread", t_in, None)]
        walls, tasks_s, cores = {}, {}, {}
        for n in (1, 2):
            t0 = time.perf_counter()
            with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                              dashboard_address=":0", silence_logs=logging.CRITICAL) as cl, \
                    Client(cl) as c:
                start = time.perf_counter() - t0
                t0 = time.perf_counter()
                trace_distributed(src, seeds[:200], tmp / "w.h5", opts, client=c, chunk_seeds=50,
                                  progress=False)
                warm = time.perf_counter() - t0
                chunk = -(-args.seeds // 16)  # 16 tasks: 8 per worker with 2 workers

                phases = []

                def job(ch=chunk, c=c, n=n, phases=phases, seeds=seeds):
                    tm = {}
                    trace_distributed(src, seeds, tmp / f"d{n}.h5", opts, client=c,
                                      chunk_seeds=ch, progress=False, timings=tm)
                    phases.append(tm)

                walls[n] = _best(args.repeat, job)
                best = min(phases, key=lambda p: p["tasks"])
                tasks_s[n] = best["tasks"]
                cores[n] = best["task_cpu"] / best["tasks"]
                join_s = min(p["join"] for p in phases[:args.repeat])
                rows.append(((f"{n} worker{'s' if n > 1 else ''} ({chunk} seeds/task, "
                              f"{best['n_tasks']} tasks)"),
                             walls[n], (f"tracing phase {tasks_s[n]:.2f} s "
                                        f"({args.seeds / tasks_s[n]:.0f} seeds/s), join "
                                        f"{join_s:.2f} s; cluster start {start:.1f} s, "
                                        f"first job {warm:.1f} s")))
                if n == 2:  # on at most 20000 seeds: a few large tasks of a big job are
                    # too unequal for the slope to show the overhead
                    sub = seeds[:OVERHEAD_SEEDS]
                    sizes = sorted({max(1, len(sub) // k) for k in (8, 32, 128)})
                    ovh = []
                    for ch in sizes:
                        wall = _best(args.repeat, lambda ch=ch, sub=sub: job(ch, seeds=sub))
                        ovh.append((phases[-1]["n_tasks"], wall))
        ntasks, wall = np.array(ovh, float).T
        slope = np.polyfit(ntasks, wall, 1)[0]

    load1 = os.getloadavg()
    print(f"bench_distributed: ABC {args.grid}^3 (periodic), {args.seeds} seeds, arc length "
          f"{args.length:g}, dopri5 rtol 1e-6; cores {len(os.sched_getaffinity(0))}")
    print(f"load average before {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, "
          f"after {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f} (1, 5, 15 min)")
    print(f"{'run':<44} {'wall s':>8} {'seeds/s':>9}  note")
    for name, t, note in rows:
        print(f"{name:<44} {t:8.2f} {args.seeds / t:9.0f}  {note or ''}")
    print(f"speed-up 2 workers / 1 worker: tracing phase {tasks_s[1] / tasks_s[2]:.2f}x "
          f"(goal >= 1.8x), end to end {walls[1] / walls[2]:.2f}x (the join is serial)")
    print(f"CPU the workers got during the tracing phase (task CPU s / wall s): 1 worker "
          f"{cores[1]:.2f} cores, 2 workers {cores[2]:.2f} cores; seeds per task-CPU-second "
          f"1 worker {args.seeds / (cores[1] * tasks_s[1]):.0f}, 2 workers "
          f"{args.seeds / (cores[2] * tasks_s[2]):.0f} (equal = no loss from scaling out)")
    print(f"1 worker / in-process: {t_in / walls[1]:.2f} (1.0 = no scale-out overhead)")
    print("task overhead: " + ", ".join(f"{int(n)} tasks {w:.2f} s" for n, w in zip(ntasks, wall))
          + f" -> {slope * 2 * 1e3:.1f} ms of worker time per task (slope x 2 workers)")
    return 0


def _best(repeat, fn) -> float:
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


if __name__ == "__main__":
    raise SystemExit(main())
