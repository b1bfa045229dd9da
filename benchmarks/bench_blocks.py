"""Block mode on Dask: a field larger than each worker's memory limit, traced by workers that
each read their own blocks, its lines compared with one process's.

Writes the ABC flow at N^3 in float32 (``bench_bigfield.write_abc``, chunked 64^3) unless the
file is in --dir already, and traces random seeds (max length 10, rtol 1e-5) on LocalClusters of
worker processes with one thread each.  --compare picks what is compared:

* ``reference`` (default): one process (``flowkit trace --memory`` in a fresh process: the lines
  of the in-memory trace, bit for bit) against block mode on --workers workers of --limit each;
  prints wall time, each worker's peak RSS, the rounds, handoffs, idle share and bytes read, and
  whether the lines are equal.
* ``workers``: block mode on 1 worker against --workers workers (the same field, seeds and
  --limit): the speed-up, with handoffs per line, rounds and idle share of each.
* ``balance``: seeds all in the first block (x below a third of the box: a plume), block mode
  on --workers workers with and without a crowded block's second owner.

Each timed job follows a 40-seed job on the same cluster (the workers' numba kernels loaded);
--repeat takes the best of several.  The two runs of a comparison must give equal lines.

    .venv/bin/python benchmarks/bench_blocks.py --n 1024 --limit 8GB --dir /work/big
    .venv/bin/python benchmarks/bench_blocks.py --n 512 --seeds 100000 --compare workers --dir D
    .venv/bin/python benchmarks/bench_blocks.py --n 192 --seeds 4000 --compare balance --dir D
"""

from __future__ import annotations

import argparse
import logging
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_bigfield import EXTENT, write_abc

TRACE = {"max_length": 10, "rtol": 1e-5}


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6


def run_blocks(path, seeds, out, workers, limit, repeat=1, **kw) -> tuple[float, dict, list]:
    """Best wall time of block mode on a fresh LocalCluster, its timings, the workers' peaks."""
    from distributed import Client, LocalCluster

    from flowkit.distributed.jobs import trace_distributed

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      memory_limit=limit, dashboard_address=":0",
                      silence_logs=logging.CRITICAL) as cl, Client(cl) as c:
        # (seeds all over the box: every worker loads its kernels before the timed jobs)
        warm = np.random.default_rng(1).random((40, 3)) * EXTENT
        trace_distributed(str(path), warm, out, client=c, distribute="blocks", progress=False,
                          **TRACE, **kw)
        best = (np.inf, {})
        for _ in range(repeat):
            tim: dict = {}
            cpu = sum(c.run(time.process_time).values())
            t = time.perf_counter()
            trace_distributed(str(path), str(seeds), out, client=c, distribute="blocks",
                              timings=tim, progress=False, **TRACE, **kw)
            wall = time.perf_counter() - t
            # (on a shared machine the workers may get fewer cores than there are workers)
            tim["cores"] = (sum(c.run(time.process_time).values()) - cpu) / wall
            tim["wall"] = wall
            best = min(best, (wall, tim), key=lambda b: b[0])
        return (*best, sorted(c.run(_peak_gb).values()))


def _counts(tim: dict) -> str:
    rounds = tim["rounds"]
    vertices = sum(sum(r.get("worker_vertices", [0])) for r in rounds)
    back = (f", {sum(r['vertex_bytes'] for r in rounds) / vertices:.1f} bytes back per vertex"
            if vertices and "vertex_bytes" in rounds[0] else "")
    return (f"{tim['blocks']} blocks of {tim['block_bricks']} bricks, {tim['block_rounds']} "
            f"rounds, {tim['handoffs_per_line']:.2f} handoffs per line, idle share "
            f"{tim['idle_share']:.2f}, {tim['shared_blocks']} blocks shared, read "
            f"{tim['field_bytes_read'] / 1e9:.2f} GB, cores the workers got {tim['cores']:.2f}; "
            f"the client's time outside the rounds {tim['wall'] - sum(r['wall_s'] for r in rounds):.2f} s"
            f"{back}")


def _equal(a_path, b_path) -> str:
    from flowkit.io.lines_h5 import read_lines

    a, b = read_lines(a_path), read_lines(b_path)
    same = (np.array_equal(a.points, b.points) and np.array_equal(a.offsets, b.offsets)
            and all(np.array_equal(a.line_data[k], b.line_data[k]) for k in a.line_data))
    return "yes" if same else "NO"


def field_args(ap, n: int, seeds: int, limit: str) -> None:
    """The options of the block-mode benchmarks: the field, the seeds, the workers."""
    ap.add_argument("--n", type=int, default=n)
    ap.add_argument("--seeds", type=int, default=seeds)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--limit", default=limit, help="each worker's memory limit")
    ap.add_argument("--dir", required=True, help="where the field is (or is written)")
    ap.add_argument("--keep", action="store_true", help="keep the field file")


def field_file(args) -> Path:
    """The ABC field's file in --dir, written unless it is there."""
    path = Path(args.dir) / f"abc_{args.n}.h5"
    if not path.exists():
        write_abc(path, args.n)
    return path


def remove(args, *files) -> None:
    """A run's files, and the field's unless --keep."""
    for p in (*files, *(() if args.keep else (Path(args.dir) / f"abc_{args.n}.h5",))):
        p.unlink(missing_ok=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    field_args(ap, 1024, 10_000, "8GB")
    ap.add_argument("--compare", choices=("reference", "workers", "balance"),
                    default="reference")
    ap.add_argument("--repeat", type=int, default=1, help="best of this many timed jobs")
    ap.add_argument("--reference-memory", default="3GB",
                    help="--memory of the one-process trace the lines are compared with")
    args = ap.parse_args(argv)

    folder = Path(args.dir)
    path = folder / f"abc_{args.n}.h5"
    seeds, ref = folder / "seeds.npy", folder / "ref.h5"
    print(f"load average {os.getloadavg()[0]:.2f}; ABC {args.n}^3 float32, {args.seeds} seeds, "
          f"{args.compare}")
    walls, outs = [], []
    try:
        field_file(args)
        box = [EXTENT / 3 if args.compare == "balance" else EXTENT, EXTENT, EXTENT]
        np.save(seeds, np.random.default_rng(0).random((args.seeds, 3)) * box)
        if args.compare == "reference":
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "flowkit", "trace", str(path), "--seeds",
                            str(seeds), "--max-length", str(TRACE["max_length"]), "--rtol",
                            str(TRACE["rtol"]), "--memory", args.reference_memory, "-o", str(ref),
                            "--quiet"], check=True)
            print(f"one process, --memory {args.reference_memory}: "
                  f"{time.perf_counter() - t:.1f} s")
            runs = [(f"block mode, {args.workers} workers of {args.limit}", args.workers, {})]
        elif args.compare == "workers":
            runs = [(f"block mode, 1 worker of {args.limit}", 1, {}),
                    (f"block mode, {args.workers} workers of {args.limit}", args.workers, {})]
        else:
            runs = [(f"{args.workers} workers, one owner per block", args.workers,
                     {"balance": False}),
                    (f"{args.workers} workers, crowded blocks shared", args.workers, {})]
        for i, (label, workers, kw) in enumerate(runs):
            o = folder / f"blocks{i}.h5"
            outs.append(o)
            wall, tim, peaks = run_blocks(path, seeds, o, workers, args.limit, args.repeat, **kw)
            walls.append(wall)
            print(f"{label}: {wall:.2f} s; worker peak RSS "
                  + ", ".join(f"{p:.2f} GB" for p in peaks))
            print(f"  {_counts(tim)}")
            print("  per round (lines and task seconds per worker, idle share): " + "; ".join(
                f"{r['worker_lines']} [{', '.join(f'{s:.2f}' for s in r['worker_s'])}] "
                f"{r['idle_share']:.2f}" for r in tim["rounds"]))
        if len(outs) == 2:
            print(f"speed-up {walls[0] / walls[1]:.2f}x; lines equal: {_equal(*outs)}")
        else:
            print(f"  lines equal to the one-process trace's: {_equal(ref, outs[0])}")
        print(f"load average {os.getloadavg()[0]:.2f}")
    finally:
        remove(args, seeds, ref, *outs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
