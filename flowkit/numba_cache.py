"""Stale numba machine code in a working tree, and how to drop it.

numba's on-disk cache (``cache=True``) checks only the source file that defines a function, but
kernels inline helpers from other files: lanes.py compiles kernel.py's step loop into its own
code, the integrators inline fields/interp.py.  After an edit to kernel.py, lanes.py's cache
would still run the old loop.  ``drop_stale`` removes each numba package's cache when it is
older than a source file of that package or of a package others inline from.  flowkit's
import calls it in a git working tree (a checkout installed in editable mode, where sources
change under their caches); an installed flowkit never does, and is not touched.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
IN_WORKING_TREE = (PACKAGE.parent / ".git").exists()
SHARED = ("fields",)  # packages whose numba helpers others inline


def _newest(folder: Path) -> float:
    return max((p.stat().st_mtime for p in folder.glob("*.py")), default=0.0)


def drop_stale(root: Path = PACKAGE) -> list[Path]:
    """Remove the stale numba caches under ``root``; returns the __pycache__ folders cleared."""
    dropped = []
    for cache in root.glob("*/__pycache__"):
        files = [p for p in cache.iterdir() if p.suffix in (".nbi", ".nbc")]
        deps = [cache.parent] + [root / name for name in SHARED]
        if files and min(p.stat().st_mtime for p in files) < max(map(_newest, deps)):
            for p in files:
                p.unlink(missing_ok=True)
            dropped.append(cache)
    return dropped
