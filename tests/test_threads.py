"""threads.run_ranges: every range once, the calling thread among the workers, an error reaches
the caller once no range runs any more, and a call from one of the pool's own threads does not
wait on its own queue."""

from __future__ import annotations

import threading
import time

import numba
import pytest

from flowkit import threads

pytestmark = pytest.mark.skipif(numba.get_num_threads() < 2, reason="needs two numba threads")


def _recording():
    seen, lock = [], threading.Lock()

    def kernel(start, stop, scale):
        time.sleep(0.002 * scale)  # long enough that every thread gets ranges
        with lock:
            seen.append((start, stop, threading.get_ident()))

    return seen, kernel


def test_every_range_runs_once_and_the_calling_thread_takes_part():
    seen, kernel = _recording()
    threads.run_ranges(kernel, 1000, 5.0)  # 16 ranges of 10 ms: the pool thread starts in time
    covered = sorted(i for a, b, _ in seen for i in range(a, b))
    assert covered == list(range(1000))
    idents = {t for *_, t in seen}
    assert threading.get_ident() in idents and len(idents) == numba.get_num_threads()


def test_a_kernel_error_reaches_the_caller_when_no_range_runs_any_more():
    running, lock = [0], threading.Lock()

    def kernel(start, stop, scale):
        with lock:
            running[0] += 1
        time.sleep(0.002 * scale)
        with lock:
            running[0] -= 1
        if start == 0:
            raise ZeroDivisionError("range 0")

    for _ in range(5):  # range 0 on the calling thread or on the pool's
        with pytest.raises(ZeroDivisionError, match="range 0"):
            threads.run_ranges(kernel, 100, 1.0)
        assert running[0] == 0  # nothing still writes into the caller's arrays


def test_a_call_from_a_pool_thread_finishes():
    _, warm = _recording()
    threads.run_ranges(warm, 10, 0.0)  # the pool, at the size run_ranges uses
    seen, kernel = _recording()
    done = threads._executor(numba.get_num_threads() - 1).submit(threads.run_ranges, kernel, 500,
                                                                 0.5)
    done.result(timeout=60)
    assert sorted(i for a, b, _ in seen for i in range(a, b)) == list(range(500))
