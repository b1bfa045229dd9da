"""How flowkit's compiled code is compiled: three decorators, on public numba at heart.

``kernel(**options)``: a step loop, ``njit(cache=True, **options)``.

``inline``: a helper on a kernel's per-step path (field evaluation, cell moves, dense output,
events): compiled once, as a function of its own, and inlined by LLVM into every caller
(``forceinline``), so it costs what inline code costs.

``helper``: compiled once and called, for work off the per-step path.

Helpers use numpy's error model (a division by zero gives inf or NaN, which the step loops test
for, e.g. a zero speed in arc-length mode, instead of an exception path per division).
Constants go to them typed (``np.int64(0)``): a literal 0 or True argument compiles one more
copy per value.

Where numba's internals allow (``numba_private.py``: ``ACCELERATED``), the three also get the
accelerators that cut compile time (a leaner pass pipeline, no NRT or wrappers, forced LLVM
inlining, turns with a second compile process) and ``prefetch`` is a real cache hint; without
them flowkit runs on public numba alone, slower to compile, with the same lines bit for bit.
"""

from numba import njit

from . import numba_private as _private

ACCELERATED = _private.AVAILABLE
prefetch = _private.prefetch


def kernel(**options):
    """A step loop: ``njit(cache=True, **options)``, with the accelerators where available."""
    return njit(cache=True, **options, **_private.KERNEL_OPTIONS)


def helper(fn):
    return _private.shared_dispatcher(fn, {})


def inline(fn):
    return _private.shared_dispatcher(fn, {"forceinline": True})
