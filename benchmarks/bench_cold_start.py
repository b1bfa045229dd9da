"""Cold start: seconds to the first result in a fresh process with an empty compile cache.

Each scenario runs in a fresh subprocess whose NUMBA_CACHE_DIR (and PoCL kernel cache) is a new
empty folder: that is what a fresh machine, CI job, container or Dask worker pays.  Then the
same scenario again in another fresh process on the now filled cache (warm start: imports,
loading the compiled code, the work itself).  Then, in a third fresh process on a cache that
holds only what the default trace compiled, the scenario again: what adding its options costs
the first time after a default trace ("after default", process start included).  Prints a
Markdown table: cold s, warm s, cold/warm, after default s.

    .venv/bin/python benchmarks/bench_cold_start.py                 # every scenario
    .venv/bin/python benchmarks/bench_cold_start.py default attributes
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SETUP = """
import time
t0 = time.perf_counter()
import numpy as np
import flowkit
from flowkit import datasets
from flowkit.integrate import seeds
field = datasets.hotroom()
s = seeds.line((1, 1, 1), (9, 1, 9), 64)
"""
SCENARIOS = {
    "default": "flowkit.trace(field, s, max_length=20)",
    "attributes": "flowkit.trace(field, s, max_length=20, attributes=['speed', 'T'])",
    "rk4": "flowkit.trace(field, s, max_length=20, method='rk4')",
    "dop853": "flowkit.trace(field, s, max_length=20, method='dop853')",
    "no_cell_aware": "flowkit.trace(field, s, max_length=20, cell_aware=False)",
    "rk4_plain": "flowkit.trace(field, s, max_length=20, method='rk4', step=0.05, "
                 "cell_aware=False)",
    "rosenbrock": "flowkit.trace(field, s, max_length=20, method='ros34pw2')",
    "auto": "flowkit.trace(field, s, max_length=20, method='auto')",
    "pathlines": "from flowkit.integrate.pathlines import pathlines\n"
                 "pathlines(str(datasets.hotroom_path()), s, max_time=200.0)",
    "demo_scene": "from flowkit.cli.demo import scene_path\nfrom flowkit.scene import run_scene\n"
                  "import tempfile\nout = tempfile.mkdtemp()\n"
                  "run_scene(scene_path(), out_dir=out, cache_dir=out + '/cache')",
    "opencl_pocl": "flowkit.trace(field, s, max_length=20, backend='opencl')",
    "even": "from flowkit.seeding import trace_spec\n"
            "trace_spec(field, 'even:1/30d', max_length=12.0, direction='both')",
}


def run(name: str, cache: Path) -> float:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache / "numba"),
               POCL_CACHE_DIR=str(cache / "pocl"), PYOPENCL_NO_CACHE="1")
    code = SETUP + SCENARIOS[name] + "\nprint('seconds', time.perf_counter() - t0)\n"
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True,
                       text=True, check=False)
    wall = time.perf_counter() - t
    if p.returncode != 0:
        print(f"{name}: failed\n{p.stderr[-2000:]}", file=sys.stderr)
        return float("nan")
    return wall


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    # (checked here: argparse's choices refuse an empty or default list for nargs="*")
    ap.add_argument("scenarios", nargs="*", help=f"default: all of {', '.join(SCENARIOS)}")
    args = ap.parse_args(argv)
    bad = [n for n in args.scenarios if n not in SCENARIOS]
    if bad:
        ap.error(f"unknown scenario {bad[0]!r}; choose from {', '.join(SCENARIOS)}")
    print("| scenario | cold s | warm s | cold/warm | after default s |\n|---|---|---|---|---|")
    for name in args.scenarios or SCENARIOS:
        with tempfile.TemporaryDirectory(prefix="flowkit-cold-") as tmp:
            cold = run(name, Path(tmp))
            warm = run(name, Path(tmp))
        with tempfile.TemporaryDirectory(prefix="flowkit-cold-") as tmp:
            run("default", Path(tmp))
            after = run(name, Path(tmp))
        print(f"| {name} | {cold:.1f} | {warm:.1f} | {cold / warm:.0f}x | {after:.1f} |",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
