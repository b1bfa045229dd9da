"""Which dask cluster a job runs on: a Client the caller gives, an existing scheduler by address,
or (the embedded default) a LocalCluster of worker processes started for the job."""

from __future__ import annotations

import logging
import os
from contextlib import contextmanager


def default_workers() -> int:
    """One worker process per core this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


@contextmanager
def connect(client=None, scheduler: str | None = None, workers: int | None = None):
    """Yield a ``distributed.Client``.

    ``client``: used as is (and left open).  ``scheduler``: an address such as
    ``tcp://host:8786`` of a running cluster (the connection is closed afterwards, the cluster
    stays).  Otherwise a LocalCluster of ``workers`` processes (default: one per core), one thread
    each, its dashboard on a free port, shut down when the job ends.
    """
    if sum(x is not None for x in (client, scheduler)) > 1:
        raise ValueError("give a dask client or a scheduler address, not both")
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            c = Client(scheduler)
        except OSError as e:  # (after distributed.comm.timeouts.connect)
            raise OSError(f"dask scheduler {scheduler} cannot be reached: {e}") from None
        with c:
            yield c
        return
    n = default_workers() if workers is None else int(workers)
    if n < 1:
        raise ValueError(f"workers must be at least 1, got {workers!r}")
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.CRITICAL) as cluster, Client(cluster) as c:
        yield c


def slots(client) -> int:
    """Worker threads of the cluster: how many tasks run at once."""
    return max(1, sum(client.nthreads().values()))
