"""``flowkit bench precision``: the work–precision benchmark (benchmarks/precision.py).

The benchmark code and the peers' adapters live in the source tree's ``benchmarks/`` directory
(they import VTK/streamtracer when installed: the ``bench`` extra); this command runs it with
the remaining arguments, e.g. ``flowkit bench precision --quick``.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

from . import CLIError

BENCHES = {"precision": "work–precision: error against run time, every method and tolerance"}


def benchmarks_dir() -> Path:
    d = Path(__file__).resolve().parents[2] / "benchmarks"
    if not (d / "precision.py").is_file():
        raise CLIError(f"{d / 'precision.py'}: benchmark scripts not found; "
                       "flowkit bench runs from a source checkout (git clone) of flowkit")
    return d


def register(subparsers) -> None:
    p = subparsers.add_parser("bench", help="run a benchmark (precision)", description=__doc__)
    p.add_argument("name", choices=sorted(BENCHES), help="; ".join(f"{k}: {v}" for k, v in BENCHES.items()))
    p.add_argument("args", nargs=argparse.REMAINDER, help="options of the benchmark (see --help)")
    p.set_defaults(func=run)


def run(args) -> int:
    d = str(benchmarks_dir())
    if d not in sys.path:
        sys.path.insert(0, d)
    return int(importlib.import_module(args.name).main(args.args) or 0)
