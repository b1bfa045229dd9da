"""Test-session setup: no stale numba machine code.

numba's on-disk cache (``cache=True``) checks only the source file that defines a function, but
kernels inline helpers from other files: lanes.py compiles kernel.py's step loop into its own
code, the integrators inline fields/interp.py.  After an edit to kernel.py, lanes.py's cache
would still run the old loop.  Before the tests import flowkit, each numba package's cache is
dropped when it is older than a source file of that package or of flowkit/fields, so the tests
always run the code as it is (a fresh checkout has no caches: nothing to do).
"""

from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "flowkit"
SHARED = ("fields",)  # packages whose numba helpers others inline


def _newest(folder: Path) -> float:
    return max((p.stat().st_mtime for p in folder.glob("*.py")), default=0.0)


def drop_stale_numba_caches(root: Path = PACKAGE) -> list[Path]:
    dropped = []
    for cache in root.glob("*/__pycache__"):
        files = [p for p in cache.iterdir() if p.suffix in (".nbi", ".nbc")]
        deps = [cache.parent] + [root / name for name in SHARED]
        if files and min(p.stat().st_mtime for p in files) < max(map(_newest, deps)):
            for p in files:
                p.unlink(missing_ok=True)
            dropped.append(cache)
    return dropped


drop_stale_numba_caches()
