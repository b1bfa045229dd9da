"""Block mode on Dask: a field larger than each worker's memory limit, traced by workers that
each read their own blocks, its lines compared with one process's.

Writes the ABC flow at N^3 in float32 (``bench_bigfield.write_abc``, chunked 64^3) unless the
file is in --dir already, traces 10 000 random seeds (max length 10, rtol 1e-5) once in one
process (``flowkit trace --memory`` in a fresh process: the lines of the in-memory trace, bit for
bit) and once in block mode on a LocalCluster of --workers processes of --limit memory each, and
prints wall time, each worker's peak RSS, the rounds, handoffs, idle share and bytes read, and
whether the lines are equal.

    .venv/bin/python benchmarks/bench_blocks.py --n 1024 --limit 8GB --dir /work/big
"""

from __future__ import annotations

import argparse
import logging
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_bigfield import EXTENT, write_abc


def _peak_gb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=1024)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--limit", default="8GB", help="each worker's memory limit")
    ap.add_argument("--seeds", type=int, default=10_000)
    ap.add_argument("--reference-memory", default="3GB",
                    help="--memory of the one-process trace the lines are compared with")
    ap.add_argument("--dir", required=True, help="where the field is (or is written)")
    ap.add_argument("--keep", action="store_true", help="keep the field file")
    args = ap.parse_args(argv)
    from distributed import Client, LocalCluster

    from flowkit.distributed.jobs import trace_distributed
    from flowkit.io.lines_h5 import read_lines

    folder = Path(args.dir)
    path = folder / f"abc_{args.n}.h5"
    seeds, ref, out = folder / "seeds.npy", folder / "ref.h5", folder / "blocks.h5"
    try:
        if not path.exists():
            write_abc(path, args.n)
        np.save(seeds, np.random.default_rng(0).random((args.seeds, 3)) * EXTENT)
        common = ["--max-length", "10", "--rtol", "1e-5"]
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "flowkit", "trace", str(path), "--seeds", str(seeds),
                        *common, "--memory", args.reference_memory, "-o", str(ref), "--quiet"],
                       check=True)
        print(f"one process, --memory {args.reference_memory}: {time.perf_counter() - t:.1f} s")
        with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True,
                          memory_limit=args.limit, dashboard_address=":0",
                          silence_logs=logging.CRITICAL) as cl, Client(cl) as c:
            tim: dict = {}
            t = time.perf_counter()
            trace_distributed(str(path), str(seeds), out, client=c, distribute="blocks",
                              max_length=10, rtol=1e-5, timings=tim, progress=False)
            wall = time.perf_counter() - t
            peaks = sorted(c.run(_peak_gb).values())
        print(f"block mode, {args.workers} workers of {args.limit}: {wall:.1f} s; worker peak RSS "
              + ", ".join(f"{p:.2f} GB" for p in peaks))
        print(f"  {tim['blocks']} blocks of {tim['block_bricks']} bricks, {tim['block_rounds']} "
              f"rounds, {tim['handoffs_per_line']:.2f} handoffs per line, idle share "
              f"{tim['idle_share']:.2f}, read {tim['field_bytes_read'] / 1e9:.1f} GB "
              f"({tim['field_bytes_read'] / (args.n ** 3 * 12):.2f} x U)")
        a, b = read_lines(ref), read_lines(out)
        same = (np.array_equal(a.points, b.points) and np.array_equal(a.offsets, b.offsets)
                and all(np.array_equal(a.line_data[k], b.line_data[k]) for k in a.line_data))
        print(f"  lines equal to the one-process trace's: {'yes' if same else 'NO'}")
    finally:
        for p in (seeds, ref, out):
            p.unlink(missing_ok=True)
        if not args.keep:
            path.unlink(missing_ok=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
