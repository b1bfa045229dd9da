"""A kernel's helpers compiled in a second process while this one compiles the kernel.

numba compiles one function at a time (a process-wide lock, and its typing and lowering are
Python under the GIL), so on a fresh machine the first trace keeps one core busy for seconds
while the other waits.  When the tracing kernel is about to be compiled here and numba's disk
cache does not hold it, ``start`` runs ``python -m flowkit.parallel_compile KERNEL`` beside
it.  That process compiles the kernel's helpers into the same disk cache in the reverse of the
order in which the kernel's typing asks for them, while this process types the kernel from the
front.  They take turns (``turn``): each helper of the table is compiled by whichever process
comes to it first, which claims it with a file in a folder the two share; the other waits for
its done file and numba loads that copy from the disk cache.  Without the claims both compiled
the helper they met at, the largest (``kernel._start`` and what it calls) at the same time, and
this process learnt of the other's copy only after finishing its own.  The table lists callees
before their callers, so the other process, walking it backwards, takes the callees of a helper
this one is compiling from the far end: the work divides down to single helpers.  The
kernel's own typing, lowering and LLVM optimisation stay here.  The machine code is the same,
and so are the lines, bit for bit: a cached helper carries its optimised LLVM bitcode, which
the kernel links and inlines exactly as it links a helper compiled in its own process.

Not started on one core (the CPU set this process may use: a one-CPU container counts one),
where numba's cache is not written (no writable folder), where ``sys.executable`` is not a plain
Python (an application that embeds one), with ``FLOWKIT_PARALLEL_COMPILE=0``, or when the disk
cache already holds the kernel.

Once the kernel's helpers are done, the other process has nothing to do for the seconds this one
spends on the kernel's own lowering and LLVM work.  While this process lives (the other one reads
its standard input until this one closes it, at exit), it goes on with the helpers of the
kernels users add next: the tracing kernel's variants with the Rosenbrock stepper and for
pathlines.  Their first trace then compiles only the step loop again.

The helpers and their argument types are the table in ``helper_sigs.py``, written by ``python -m
flowkit.write_helper_sigs`` from traces on an empty cache and checked by
tests/test_compile_cost.py.  A stale entry only wastes the other process's time (it compiles a
signature nobody asks for); it never changes what this process runs.
"""

from __future__ import annotations

import atexit
import contextlib
import hashlib
import importlib
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from . import numba_private
from .numba_cache import in_disk_cache

LOG = logging.getLogger("flowkit.compile")
_started: set[str] = set()
WAIT_S = 120.0  # the longest either process waits for the other's copy of one helper
# the kernels whose helpers the other process compiles next, while this process lives: the
# tracing kernel's variants with the Rosenbrock stepper and for pathlines (their own helpers)
NEXT = {"flowkit.integrate.kernel._advance_lines": (
    "flowkit.integrate.kernel._advance_lines:rosenbrock",
    "flowkit.integrate.kernel._advance_lines:pathlines")}


def _cores() -> int:
    """The cores this process may run on (a container's CPU set, not the host's count)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _python() -> str | None:
    """This interpreter as a program to start, or None where sys.executable is not a plain
    Python (a frozen application, or one that embeds Python: Blender, uWSGI, a GUI)."""
    exe = sys.executable
    if getattr(sys, "frozen", False) or not exe or not Path(exe).name.lower().startswith("python"):
        return None
    return exe


def enabled() -> bool:
    # (turns are taken by the accelerators' dispatcher)
    return (numba_private.AVAILABLE and os.environ.get("FLOWKIT_PARALLEL_COMPILE", "1") != "0"
            and _cores() > 1 and _python() is not None)


def _writes_cache(dispatcher) -> bool:
    path = numba_private.cache_path(dispatcher)
    return path is not None and os.access(path, os.W_OK)


class _Turns:
    """Which process compiles which helper of the table: a claim file per helper and argument
    types in a folder both share, taken by whichever process comes to it first; the other waits
    for its done file and loads that copy from the disk cache."""

    def __init__(self, folder: str, other_alive, dtype: str = "float64"):
        from .helper_sigs import HELPERS

        self.folder, self.other_alive, self.mine = folder, other_alive, set()
        self.table = {(m, n, for_type(sig, dtype))
                      for entries in HELPERS.values() for m, n, sig in entries}

    def _path(self, key) -> str:
        return os.path.join(self.folder, hashlib.sha1(repr(key).encode()).hexdigest()[:20])

    def claim(self, key) -> bool:
        """True where this process compiles ``key`` (it took the claim, now or before)."""
        if key in self.mine:
            return True
        try:
            os.close(os.open(self._path(key) + ".claim", os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            return False
        except OSError:  # the folder is gone (the first process ended): no more turns
            pass
        self.mine.add(key)
        return True

    def done(self, key) -> None:
        with contextlib.suppress(OSError):
            os.close(os.open(self._path(key) + ".done", os.O_CREAT | os.O_WRONLY))

    def wait(self, key) -> None:
        """Until the other process has stored ``key`` (or has ended, or ``WAIT_S`` passed)."""
        done, end = self._path(key) + ".done", time.monotonic() + WAIT_S
        while not os.path.exists(done) and self.other_alive() and time.monotonic() < end:
            time.sleep(0.002)


_turns: _Turns | None = None


def _share(turns: _Turns) -> None:
    """Take turns with the other process from now on, in every helper's compilation."""
    global _turns
    _turns = turns
    numba_private.compile_turn = turn


@contextlib.contextmanager
def turn(dispatcher, sig):
    """Around a helper's compilation (``numba_private._Shared.compile``): with a second process
    at work and the helper in its table, compile it here only if this process claims it first;
    else wait for the other's copy, which the compilation then loads from the disk cache."""
    turns, key = _turns, None
    if turns is not None:
        from numba.core import sigutils

        args = tuple(sigutils.normalize_signature(sig)[0])
        f = dispatcher.py_func
        k = (f.__module__, f.__qualname__, args)
        if k in turns.table and args not in dispatcher.overloads:
            if turns.claim(k):
                key = k
            else:
                turns.wait(k)
    try:
        yield
    finally:
        if key is not None:
            turns.done(key)


def field_array(dtype: str = "float64"):
    """numba's type of a field's node array (4-D, C-contiguous) of ``dtype``."""
    import numpy as np
    from numba import from_dtype
    from numba.core import types

    return types.Array(from_dtype(np.dtype(dtype)), 4, "C")


def for_type(sig: tuple, dtype: str = "float64") -> tuple:
    """A table entry's argument types (written for float64 fields) for a field of ``dtype``:
    the table's only 4-D float64 arrays are the field's nodes."""
    if dtype == "float64":
        return sig
    f64, ours = field_array(), field_array(dtype)
    return tuple(ours if a == f64 else a for a in sig)


def start(kernel: str, dispatcher, dtype: str = "float64") -> subprocess.Popen | None:
    """Start compiling ``kernel``'s helpers (a key of ``helper_sigs.HELPERS``) for a field of
    ``dtype`` in a second process, once per process and type, unless that would not help
    (above); returns the process."""
    ours = field_array(dtype)
    if ((kernel, dtype) in _started or not enabled()
            or any(ours in sig for sig in dispatcher.overloads)):
        return None
    _started.add((kernel, dtype))
    if not _writes_cache(dispatcher) or in_disk_cache(dispatcher, having=ours):
        return None
    root = str(Path(__file__).resolve().parent.parent)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (root, os.environ.get("PYTHONPATH", "")) if p))
    folder = tempfile.mkdtemp(prefix="flowkit-compile-")
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    try:
        proc = subprocess.Popen([_python(), "-m", "flowkit.parallel_compile", kernel, folder,
                                 dtype],
                                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL, env=env)
    except OSError as e:  # the interpreter cannot be started: compile here alone
        LOG.debug("no second compile process: %s", e)
        return None
    _share(_Turns(folder, lambda: proc.poll() is None, dtype))
    # the reaper holds the process, and so the pipe to it, open until it ends (or this one does)
    threading.Thread(target=_reap, args=(proc,), daemon=True, name="flowkit-compile-reaper").start()
    return proc


def _reap(proc: subprocess.Popen) -> None:
    proc.wait()
    proc.stdin.close()


def compile_helpers(kernel: str, go_on=lambda: True, dtype: str = "float64") -> None:
    """Compile ``kernel``'s helpers for a field of ``dtype``, last asked for first (an entry
    that no longer matches its function, or that the first process has claimed, is skipped),
    while ``go_on()``."""
    from .helper_sigs import HELPERS

    for module, name, sig in reversed(HELPERS[kernel]):
        sig = for_type(sig, dtype)
        if not go_on():
            return
        if _turns is not None and not _turns.claim((module, name, sig)):
            continue
        try:
            getattr(importlib.import_module(module), name).compile(sig)
        except Exception as e:  # noqa: BLE001 (a stale entry: the kernel's process compiles it)
            LOG.debug("%s.%s%s: %s", module, name, sig, e)


def _parent_alive() -> threading.Event:
    """An event cleared when the process that started this one exits (its end of our
    standard input closes)."""
    alive = threading.Event()
    alive.set()

    def watch():  # (os.read: a thread blocked in sys.stdin's reader aborts the exit)
        try:
            while os.read(0, 4096):
                pass
        except OSError:
            pass
        alive.clear()

    threading.Thread(target=watch, daemon=True).start()
    return alive


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    # the folder of turns (where a first process takes its share) and the field's type; the
    # cache location is set as in the process that started this one: `python -m` imported
    # flowkit before this module
    kernel, *rest = argv
    dtype = rest[1] if len(rest) > 1 else "float64"
    alive = _parent_alive()
    if rest:
        _share(_Turns(rest[0], alive.is_set, dtype))
    compile_helpers(kernel, dtype=dtype)
    for nxt in NEXT.get(kernel, ()):
        compile_helpers(nxt, alive.is_set, dtype)
    return 0


if __name__ == "__main__":  # (main of the module flowkit imports, whose turns its helpers take)
    from flowkit.parallel_compile import main as imported_main

    sys.exit(imported_main())
