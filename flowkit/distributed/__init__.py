"""Scale-out on dask.distributed: the same traces on a LocalCluster, an existing cluster or a
given Client; many snapshots in parallel; pathlines over seed chunks.  See docs/scale-out.md."""

from .cluster import connect
from .jobs import JobError, pathlines_distributed, trace_distributed

__all__ = ["JobError", "connect", "pathlines_distributed", "trace_distributed"]
