"""How flowkit's compiled helpers are compiled: two numba decorators, chosen for compile time.

``inline``: a helper on a kernel's per-step path (field evaluation, cell moves, dense output,
events).  Compiled once, as a function of its own, and inlined by LLVM into every caller
(``forceinline``), so it costs what inline code costs.  numba's IR inlining
(``inline="always"``) gives the same machine code but types and lowers a copy of the helper at
every call site: the tracing kernel took three times as long to compile on a fresh machine
(measured with benchmarks/bench_cold_start.py; docs/integrator.md, cold start).

``helper``: compiled once and called, for work off the per-step path.

Both without NRT (they never allocate, and reference counting of the arrays they take would
cost more than their work) and with numpy's error model (a division by zero gives inf or NaN,
which the step loops test for, e.g. a zero speed in arc-length mode, instead of an exception
path per division).  Constants go to them typed (``np.int64(0)``): a literal 0 or True
argument compiles one more copy per value.
"""

from numba import njit

_FLAGS = {"cache": True, "_nrt": False, "error_model": "numpy", "no_cpython_wrapper": True,
          "no_cfunc_wrapper": True}
helper = njit(**_FLAGS)
inline = njit(forceinline=True, **_FLAGS)
