"""Pathlines through a series larger than the budget: read whole against brick by brick.

Writes an unsteady ABC flow on [0, 4 pi]^3 as S snapshots of N^3 nodes in float32 (flowkit HDF5,
U only, chunked C^3 nodes: ``bench_bigfield.write_abc`` with the coefficients of time t
A = sqrt 3 (1 + 0.3 sin t), B = sqrt 2 (1 - 0.2 t), C = 1 + 0.1 t, at t = 0, 1, ...), then
traces pathlines of random seeds released at t = 0 to the end of the series (rtol 1e-5), each
run in a fresh process under ``/usr/bin/time -v``:

- ``whole``: every snapshot read whole (``bricks.WHOLE_BYTES`` raised past the files: what
  pathlines did before they read bricks), two at a time;
- ``default``: no budget (brick by brick within the memory free now: a slot for every brick);
- ``--memory SIZE`` (repeatable; default a quarter of one snapshot's U): brick by brick within
  SIZE, two snapshots' bricks in one pool;

and first one seed under the (first) budget: what the process takes besides the field.

Each prints wall time, peak RSS (``/usr/bin/time -v``), bytes read (``rchar``: what the process
read through system calls, page cache included; and the bricks' bytes, ``field_bytes_read``),
the rounds, and whether its lines equal the whole run's (vertices, offsets, reasons, bit for
bit).  The chunks are 32^3 by default so that a quarter of a snapshot holds a trace's pool (12
slots of two snapshots' bricks: 75 MB of 64^3 chunks at 256^3, more than the quarter).  The
generated files are deleted at the end unless --keep.

    .venv/bin/python benchmarks/bench_path_bricks.py --n 256          # 3 x 201 MB of U
    .venv/bin/python benchmarks/bench_path_bricks.py --n 128 --seeds 500   # a quick look
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_bigfield import EXTENT, A, B, C, _stats, write_abc


def coefficients(t: float) -> tuple:
    return A * (1 + 0.3 * np.sin(t)), B * (1 - 0.2 * t), C + 0.1 * t


def child(out: str, folder: str, n_snap: int, n_seeds: int, lines_path: str, memory: str,
          attributes: str) -> None:
    """Pathlines of ``n_seeds`` seeds through the snapshots in ``folder``; ``memory``: "whole",
    "default" or a budget; ``attributes``: comma-separated."""
    from flowkit.fields import bricks

    if memory == "whole":
        bricks.WHOLE_BYTES = 1 << 62
    from flowkit.integrate.pathlines import pathlines
    from flowkit.io.lines_h5 import write_lines

    series = [(float(k), Path(folder) / f"abc_{k}.h5") for k in range(n_snap)]
    seeds = np.random.default_rng(0).random((n_seeds, 3)) * EXTENT
    t0 = time.perf_counter()
    lines = pathlines(series, seeds, 0.0, rtol=1e-5, attributes=attributes,
                      memory=None if memory in ("whole", "default") else memory)
    trace_s = time.perf_counter() - t0
    write_lines(lines, lines_path, position_dtype="float64")
    keys = ("bricks_read", "field_bytes_read", "brick_rounds", "brick_pool_bytes")
    Path(out).write_text(json.dumps({**_stats(), "rc": 0, "trace_s": trace_s,
                                     "points": int(lines.n_points),
                                     **{k: int(lines.attrs[k]) for k in keys if k in lines.attrs}}))


def _same(a: Path, b: Path) -> str:
    from flowkit.io.lines_h5 import read_lines

    x, y = read_lines(a), read_lines(b)
    if not np.array_equal(x.offsets, y.offsets):
        return "no (offsets differ)"
    for name, u, v in [("points", x.points, y.points),
                       *((k, x.line_data[k], y.line_data[k]) for k in x.line_data),
                       *((k, x.point_data[k], y.point_data[k]) for k in x.point_data)]:
        if not np.array_equal(u, v):
            return f"no ({name} differs)"
    return "yes"


def run(label: str, args: list[str]) -> dict:
    """One child process under /usr/bin/time -v: wall time, peak RSS, bytes read."""
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as tmp:
        out = tmp.name
    proc = subprocess.run(["/usr/bin/time", "-v", sys.executable, __file__, "_child", out,
                           *args], capture_output=True, text=True, check=False)
    res = json.loads(Path(out).read_text()) if Path(out).stat().st_size else {"rc": "crashed"}
    Path(out).unlink()
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (?:(\d+):)?(\d+):([\d.]+)",
                     proc.stderr)
    res["label"] = label
    res["peak"] = int(rss.group(1)) * 1024 if rss else 0
    if wall:
        h, m, s = wall.groups()
        res["wall"] = int(h or 0) * 3600 + int(m) * 60 + float(s)
    if proc.returncode != 0 or res.get("rc") != 0:
        res["error"] = " | ".join((proc.stderr or proc.stdout).strip().splitlines()[-3:])
    bricks = (f"  bricks {res['field_bytes_read'] / 1e6:.0f} MB in {res['bricks_read']} reads, "
              f"{res['brick_rounds']} rounds, pool {res['brick_pool_bytes'] / 1e6:.1f} MB"
              if "bricks_read" in res else "")
    print(f"{label:<34} {res.get('wall', 0):7.2f} s (pathlines {res.get('trace_s', 0):6.2f} s)"
          f"  peak RSS {res['peak'] / 1e6:7.1f} MB  read {res.get('read', 0) / 1e6:7.1f} MB"
          + bricks + (f"  ERROR {res['error']}" if "error" in res else ""), flush=True)
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=256, help="nodes per axis (default 256)")
    ap.add_argument("--snapshots", type=int, default=3, help="snapshots at t = 0, 1, ... (3)")
    ap.add_argument("--chunk", type=int, default=32, help="chunk (brick) nodes per axis (32)")
    ap.add_argument("--seeds", type=int, default=2000, help="random seeds (default 2000)")
    ap.add_argument("--memory", action="append", default=[],
                    help="budget (e.g. 50MB; repeatable; default a quarter of one snapshot's U)")
    ap.add_argument("--attributes", default="", help="pathline attributes, e.g. speed,vorticity")
    ap.add_argument("--repeat", type=int, default=1, help="rounds of all runs, interleaved")
    ap.add_argument("--dir", default=None, help="where to write the series (default: temp dir)")
    ap.add_argument("--keep", action="store_true", help="keep the generated files")
    args = ap.parse_args(argv)
    folder = Path(args.dir or tempfile.mkdtemp(prefix="flowkit-pathbricks-"))
    u_bytes = args.n ** 3 * 12
    budgets = args.memory or [str(u_bytes // 4)]
    files = [folder / f"abc_{k}.h5" for k in range(args.snapshots)]
    try:
        t = time.perf_counter()
        for k, path in enumerate(files):
            if not path.exists():
                write_abc(path, args.n, args.chunk, coefficients(float(k)), scalar=False,
                          time=float(k))
        print(f"series: {args.snapshots} snapshots of ABC {args.n}^3 float32 (U {u_bytes / 1e6:.0f}"
              f" MB each, chunks {args.chunk}^3), written in {time.perf_counter() - t:.1f} s; "
              f"{args.seeds} seeds released at t = 0 to t = {args.snapshots - 1}, rtol 1e-5"
              + (f", attributes {args.attributes}" if args.attributes else "") + "; "
              f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}", flush=True)
        common = [str(folder), str(args.snapshots), str(args.seeds), args.attributes]
        for r in range(args.repeat):
            if args.repeat > 1:
                print(f"-- round {r + 1}", flush=True)
            ref = folder / "whole.h5"
            one = [str(folder), str(args.snapshots), "1", args.attributes, str(ref)]
            run("the runtime alone (1 seed, budget)", [*one, budgets[0]])
            run("whole (two snapshots in memory)", [*common, str(ref), "whole"])
            for label, memory in [("default (bricks, no budget)", "default"),
                                  *((f"--memory {m}", m) for m in budgets)]:
                out = folder / "bricks.h5"
                res = run(label, [*common, str(out), memory])
                if "error" not in res:
                    print(f"  lines equal to the whole run's: {_same(ref, out)}; bricks read "
                          f"{res.get('field_bytes_read', 0) / u_bytes:.2f} x one snapshot's U",
                          flush=True)
                out.unlink(missing_ok=True)
            ref.unlink(missing_ok=True)
    finally:
        if not args.keep:
            for path in folder.glob("*.h5"):
                path.unlink()
            if args.dir is None:
                folder.rmdir()
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "_child":
        a = sys.argv[2:]
        child(a[0], a[1], int(a[2]), int(a[3]), a[5], a[6], a[4])
    else:
        sys.exit(main())
