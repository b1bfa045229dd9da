"""flowkit: streamlines through gridded 3D vector fields, stored in HDF5, rendered with line styles."""

from . import compile_notice, numba_cache

compile_notice.install()  # say so when a kernel compiles for seconds (a fresh machine)

numba_cache.ensure_location()  # a read-only install without a home still gets a cache
if numba_cache.IN_WORKING_TREE:  # edited sources: no stale compiled kernels (see numba_cache)
    numba_cache.drop_stale()

from . import datasets  # flowkit.datasets.hotroom() after a plain `import flowkit`
from .fields import Field, Grid
from .integrate.options import TraceOptions
from .integrate.trace import trace, trace_to_file
from .io.lines_h5 import read_lines, write_lines
from .lines import Lines

__version__ = "0.1.0"

__all__ = ["Field", "Grid", "Lines", "TraceOptions", "__version__", "datasets", "read_lines",
           "trace", "trace_to_file", "write_lines"]
