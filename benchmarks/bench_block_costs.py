"""The constants of the block-mode cost model (docs/scale-out.md, "Cost model"), measured here.

On the ABC flow at N^3 in float32 (``bench_bigfield.write_abc``, chunked 64^3; written to --dir
unless there), with random seeds, max length 10, rtol 1e-5 (``bench_blocks``' trace):

* step: dopri5 steps (accepted and rejected) per second on one core, in one process with the
  field in memory;
* brick read: bytes/s and seconds per brick reading --bricks random bricks as a worker's pool
  does (``BrickPool.load``: h5py), with the file's pages dropped from the page cache
  (``posix_fadvise(DONTNEED)``) and then cached;
* block mode on --workers workers, for --seeds / 5 and --seeds seeds: steps per CPU second of
  the tasks (bricks read in them; CPU, not wall: the machine may be shared), rounds and handoffs per line, and the client's time per round (its
  wall time less its longest task: submission, the states' transfer both ways, the client's
  bookkeeping) fitted as a fixed time per round plus a time per line sent; and the time outside
  the rounds (the job's start, the lines assembled and written by the client) as a fixed time
  plus a time per vertex.

    .venv/bin/python benchmarks/bench_block_costs.py --n 192 --seeds 20000 --dir D
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_bigfield import EXTENT
from bench_blocks import TRACE, field_args, field_file, remove, run_blocks


def _drop_cache(path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED)
    finally:
        os.close(fd)


def _reads(path, n_bricks: int) -> None:
    from flowkit.fields import load_field
    from flowkit.fields.bricks import POOL_SHARE, BrickPool, brick_nodes

    field = load_field(path)
    stored = field.stored_vector()
    size = brick_nodes(stored, field.grid)
    count = -(-np.array(field.grid.shape) // size)
    pick = np.random.default_rng(0).permutation(int(np.prod(count)))[:n_bricks]
    budget = int(pick.size * np.prod(size) * 3 * stored.dtype.itemsize / POOL_SHARE) + 1
    for label in ("cold", "warm"):
        if label == "cold":
            _drop_cache(path)
        pool = BrickPool(stored, field.grid, budget)
        t = time.perf_counter()
        pool.load(pick)
        dt = time.perf_counter() - t
        print(f"brick read, page cache {label}: {pool.bytes_read / dt / 1e6:.0f} MB/s, "
              f"{dt / pick.size * 1e3:.1f} ms per brick of {pool.slot_bytes / 1e6:.2f} MB "
              f"({pick.size} of {int(np.prod(count))} bricks)")


def _steps(lines) -> int:
    d = lines.line_data
    return int(sum(np.sum(d[k], dtype=np.int64) for k in ("n_accepted", "n_rejected")))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    field_args(ap, 192, 20_000, "4GB")
    ap.add_argument("--bricks", type=int, default=64, help="bricks read cold and warm")
    args = ap.parse_args(argv)
    from flowkit import trace
    from flowkit.distributed.tasks import numba_threads
    from flowkit.fields import load_field
    from flowkit.io.lines_h5 import read_lines

    folder = Path(args.dir)
    path = folder / f"abc_{args.n}.h5"
    seeds, out = folder / "seeds.npy", folder / "costs.h5"
    print(f"load average {os.getloadavg()[0]:.2f}; ABC {args.n}^3 float32, {args.seeds} seeds")
    try:
        field_file(args)
        _reads(path, args.bricks)
        pts = np.random.default_rng(0).random((args.seeds, 3)) * EXTENT
        np.save(seeds, pts)
        field = load_field(path)
        assert field.vector.size  # (read whole: the step alone is timed)
        with numba_threads(1):
            trace(field, pts[:20], **TRACE)  # (kernels loaded)
            t, cpu = time.perf_counter(), time.process_time()
            lines = trace(field, pts, **TRACE)
            dt, cpu = time.perf_counter() - t, time.process_time() - cpu
        steps = _steps(lines)
        print(f"one process, 1 thread, in memory: {dt:.2f} s ({cpu:.2f} s CPU), "
              f"{steps / args.seeds:.0f} steps per line, {steps / cpu / 1e6:.2f} M steps per CPU s")
        client, sent = [], []  # per round: the client's seconds, the lines sent
        rest, verts = [], []  # per job: the time outside rounds, the vertices written
        for n in (args.seeds // 5, args.seeds):  # (rounds of many sizes, for the fit)
            np.save(seeds, pts[:n])
            wall, tim, _ = run_blocks(path, seeds, out, args.workers, args.limit)
            task_cpu = sum(sum(r["worker_cpu_s"]) for r in tim["rounds"])
            client += [r["wall_s"] - max(r["worker_s"]) for r in tim["rounds"]]
            sent += [r["lines"] for r in tim["rounds"]]
            rest.append(tim["tasks"] - sum(r["wall_s"] for r in tim["rounds"]))
            verts.append(read_lines(out).points.shape[0])
            print(f"block mode, {n} seeds on {args.workers} workers: {wall:.2f} s, "
                  f"{tim['block_rounds']} rounds, {tim['handoffs_per_line']:.2f} handoffs per "
                  f"line, idle share {tim['idle_share']:.2f}, "
                  f"{tim['field_bytes_read'] / 1e6:.0f} MB read, "
                  f"{_steps(read_lines(out)) / task_cpu / 1e6:.2f} M steps per task CPU s")
        # a round costs the client a fixed time and a time per line it sends (and takes back)
        (per_round, per_line), *_ = np.linalg.lstsq(
            np.column_stack([np.ones(len(sent)), sent]), np.array(client), rcond=None)
        print(f"routing (round wall time less its longest task, {len(sent)} rounds): "
              f"{per_round * 1e3:.0f} ms per round + {per_line * 1e6:.1f} us per line sent")
        # outside the rounds: the job's start (field, layout, typical speed) and the lines'
        # assembly and writing on the client
        per_vertex = (rest[1] - rest[0]) / (verts[1] - verts[0])
        print(f"outside rounds: {rest[0]:.2f} s and {rest[1]:.2f} s for {verts[0]} and "
              f"{verts[1]} vertices: {rest[0] - per_vertex * verts[0]:.2f} s + "
              f"{per_vertex * 1e9:.0f} ns per vertex")
        print(f"load average {os.getloadavg()[0]:.2f}")
    finally:
        remove(args, seeds, out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
