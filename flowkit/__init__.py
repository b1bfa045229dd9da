"""flowkit: streamlines through gridded 3D vector fields, stored in HDF5, rendered with line styles."""

from . import compile_notice, numba_cache

compile_notice.install()  # say so when a kernel compiles for seconds (a fresh machine)

numba_cache.ensure_location()  # a read-only install without a home still gets a cache
if numba_cache.IN_WORKING_TREE:  # edited sources: no stale compiled kernels (see numba_cache)
    numba_cache.drop_stale()

from . import datasets  # flowkit.datasets.hotroom() after a plain `import flowkit`
from .fields import Field, Grid
from .integrate.options import TraceOptions
from .integrate.sample import sample
from .integrate.trace import trace as _trace_points
from .integrate.trace import trace_to_file
from .io.lines_h5 import read_lines, write_lines
from .lines import Lines

__version__ = "0.1.0"


def trace(field, seeds, options=None, *, backend="numba", **kw) -> Lines:
    """Streamlines of ``field`` from ``seeds``: points ((n, 3) or (3,)) or a seed spec as
    ``flowkit trace --seeds`` takes it ("line:0,0,0:1,1,1:50", "random:1000", "where:T > 302:500",
    "even:1/30d" for evenly spaced lines...; ``flowkit.integrate.seeds.SPEC_HELP``).
    ``options`` (TraceOptions) and ``kw`` (its fields, e.g. ``max_length=20``) set the trace;
    ``backend``: "numba" (CPU, all cores), "opencl[:PLATFORM[:DEVICE]]" or a callable.
    No line with two vertices (seeds all outside, a field at rest) raises EmptyResultError
    saying why; ``empty="warn"`` warns and returns the lines instead."""
    if isinstance(seeds, str):
        from .seeding import trace_spec

        return trace_spec(field, seeds, options, backend=backend, **kw)
    return _trace_points(field, seeds, options, backend=backend, **kw)


__all__ = ["Field", "Grid", "Lines", "TraceOptions", "__version__", "datasets", "read_lines",
           "sample", "trace", "trace_to_file", "write_lines"]
