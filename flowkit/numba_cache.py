"""Stale numba machine code in a working tree, and how to drop it.

numba's on-disk cache (``cache=True``) checks only the source file that defines a function, but
kernels inline helpers from other files: lanes.py compiles kernel.py's step loop into its own
code, the integrators inline fields/interp.py.  After an edit to kernel.py, lanes.py's cache
would still run the old loop.  ``drop_stale`` removes each numba package's cache when it is
older than a source file of that package or of a package others inline from.  flowkit's
import calls it in a git working tree (a checkout installed in editable mode, where sources
change under their caches); an installed flowkit never does, and is not touched.

Where the cache lives: ``NUMBA_CACHE_DIR`` when set; else the package's own ``__pycache__``
folders when writable; else the user's cache folder (``$XDG_CACHE_HOME/numba`` or
``~/.cache/numba``).  When none is writable (a read-only install run by a user without a home,
as in many containers) numba refuses to define a cached function at all; ``ensure_location``
then points numba at a folder in the temporary directory, so flowkit imports and runs.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
IN_WORKING_TREE = (PACKAGE.parent / ".git").exists()
SHARED = ("fields",)  # packages whose numba helpers others inline


def _newest(folder: Path) -> float:
    return max((p.stat().st_mtime for p in folder.glob("*.py")), default=0.0)


def _mtime(p: Path) -> float:
    """A cache file's time; inf when another process (a test worker) removed it meanwhile."""
    try:
        return p.stat().st_mtime
    except FileNotFoundError:
        return float("inf")


def drop_stale(root: Path = PACKAGE) -> list[Path]:
    """Remove the stale numba caches under ``root``; returns the __pycache__ folders cleared."""
    dropped = []
    for cache in root.glob("*/__pycache__"):
        files = [p for p in cache.iterdir() if p.suffix in (".nbi", ".nbc")]
        deps = [cache.parent] + [root / name for name in SHARED]
        if files and min(map(_mtime, files)) < max(map(_newest, deps)):
            for p in files:
                p.unlink(missing_ok=True)
            dropped.append(cache)
    return dropped


def _writable(folder: Path) -> bool:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def ensure_location() -> str | None:
    """Make sure numba has a writable cache folder (see above); returns the fallback folder
    when one was needed, else None.  Call before any cached kernel is defined."""
    from numba import config

    from .numba_private import AVAILABLE, user_cache_dir

    uid = os.getuid() if hasattr(os, "getuid") else "user"
    if not AVAILABLE and not config.CACHE_DIR:
        # code compiled without the accelerators kept apart from code compiled with them:
        # numba's cache index does not tell the two apart, and a helper compiled without a
        # CPython wrapper cannot stand in for one that has it
        home = user_cache_dir()
        home = Path(home) if home and _writable(Path(home)) else Path(tempfile.gettempdir())
        config.CACHE_DIR = str(home / f"flowkit-plain-{uid}")
        return config.CACHE_DIR
    if config.CACHE_DIR or _writable(PACKAGE / "integrate" / "__pycache__"):
        return None
    home = user_cache_dir()
    if home and _writable(Path(home)):
        return None
    config.CACHE_DIR = str(Path(tempfile.gettempdir()) / f"flowkit-numba-{uid}")
    return config.CACHE_DIR


def in_disk_cache(dispatcher, sig=None, having=None) -> bool:
    """Whether numba's disk cache holds ``dispatcher`` compiled for this CPU and this source,
    for ``sig`` (argument types) or, without one, for any signature (with an argument of type
    ``having``, when given): its index read as numba's ``Cache.load_overload`` reads it; False
    where that cannot be read."""
    from .numba_private import cache_index

    found = cache_index(dispatcher, sig)
    if found is None:
        return False
    key, index = found
    if sig is not None:
        return key in index
    return any(k[1:] == key[1:] and (having is None or having in k[0]) for k in index)
