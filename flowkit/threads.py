"""Lines shared among threads: a compiled kernel that releases the GIL, run on ranges of lines.

The integrators' per-line kernels are compiled ``nogil`` functions of a range of lines; this
module hands the ranges to a pool of Python threads.  It replaces a ``prange`` loop around the
kernel: numba's parallel loop costs several seconds of compilation on every fresh machine (its
gufunc is built and optimised afresh around the whole inlined kernel), where a sequential
``nogil`` loop costs well under one.  The ranges are small (about ``RANGES_PER_THREAD`` per
thread) and taken by whichever thread is free, the calling one included, so long and short
lines balance out.  The thread count is numba's (``NUMBA_NUM_THREADS``,
``numba.set_num_threads``).
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor
from itertools import pairwise

import numba

RANGES_PER_THREAD = 8
_pool: ThreadPoolExecutor | None = None
_pool_threads = 0
_lock = threading.Lock()


def _executor(threads: int) -> ThreadPoolExecutor:
    global _pool, _pool_threads
    with _lock:
        if _pool is None or _pool_threads != threads:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(max_workers=threads, thread_name_prefix="flowkit")
            _pool_threads = threads
        return _pool


def ranges(n: int, threads: int) -> list[tuple[int, int]]:
    """[start, stop) ranges covering 0..n-1 (n >= 1), about RANGES_PER_THREAD per thread."""
    parts = min(n, threads * RANGES_PER_THREAD)
    return list(pairwise(n * i // parts for i in range(parts + 1)))


def run_ranges(kernel, n: int, *args) -> None:
    """``kernel(start, stop, *args)`` for ranges covering 0..n-1, on numba's thread count: the
    calling thread takes ranges too, beside threads - 1 of the pool, each taking the next range
    when it is free.  (A future per range cost a thread hand-off each: about 0.6 ms of a
    trace call that takes 1 ms on 64 short lines.)"""
    threads = numba.get_num_threads()
    if threads <= 1 or n <= 1:
        if n:
            kernel(0, n, *args)
        return
    todo = iter(ranges(n, threads))
    lock = threading.Lock()

    def work():
        while True:
            with lock:
                r = next(todo, None)
            if r is None:
                return
            kernel(r[0], r[1], *args)

    helpers = [_executor(threads - 1).submit(work) for _ in range(threads - 1)]
    try:
        work()
    finally:
        # a helper that has not started finds nothing left: cancelled, not waited for (so a
        # caller that is itself one of the pool's threads cannot wait on its own queue)
        running = [f for f in helpers if not f.cancel()]
        for f in running:
            f.exception()  # waits
    for f in running:
        f.result()  # re-raises a kernel's exception
