"""The unit of distributed work: one (snapshot, seed chunk) task, run on a worker.

A task carries names, not arrays: the path (and snapshot number) of the field file, the seeds
of its chunk (a small array, or a slice of a ``.npy`` file that the worker memory-maps), the
options, and the path of its part file.  The worker opens the field itself and keeps the last
one it opened (``_FIELD_CACHE``, per worker process), so consecutive tasks on one snapshot read
it once.  The part (``write_part``: a flat HDF5 file, cheaper to write and read than the full lines
layout) is written under a temporary name and renamed when complete, so it either
exists whole or not at all; a task whose part exists returns at once.  Tasks are deterministic,
so a task run twice (a retry, a worker lost after writing) writes the same bytes to the same
name: no line is lost or duplicated.
"""

from __future__ import annotations

import os
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from ..fields import Field
from ..integrate.options import TraceOptions
from ..io.atomic import atomic_path
from ..lines import Lines

_FIELD_CACHE: dict = {}  # (path, snapshot, vector, mtime) -> Field: the last field opened


class JobError(RuntimeError):
    """A task failed after its retries; the message names the task and the error."""


@dataclass(frozen=True)
class SeedSlice:
    """Seeds ``start:stop`` of an (n, 3) float ``.npy`` file (memory-mapped, never unpickled)."""

    path: str
    start: int
    stop: int

    def load(self) -> np.ndarray:
        a = np.load(self.path, mmap_mode="r", allow_pickle=False)
        return np.array(a[self.start:self.stop], dtype=np.float64)


@dataclass(frozen=True)
class Task:
    """Trace seeds ``first .. first + n - 1`` through one snapshot (streamlines), or through the
    whole series (pathlines: ``series`` set, ``snapshot`` -1)."""

    key: str
    part: str
    source: object  # path or SnapshotRef of the snapshot (streamlines)
    snapshot: int
    first: int
    seeds: object  # (n, 3) array or SeedSlice
    options: TraceOptions
    vector: str | None = "U"
    position_dtype: str = "float32"
    series: tuple | None = None  # ((time, path or SnapshotRef), ...) for pathlines
    release: object = None  # release times of the chunk (pathlines)
    numba_threads: int = 1
    load: dict = field(default_factory=dict)  # load_field's keywords (a mesh's resample=, ...)

    @property
    def n_seeds(self) -> int:
        s = self.seeds
        return s.stop - s.start if isinstance(s, SeedSlice) else len(s)


def run_task(task: Task) -> dict:
    """Run one task on a worker; returns counts and timings (small, goes back to the client)."""
    t0, c0 = time.perf_counter(), time.process_time()
    part = Path(task.part)
    if part.exists():  # complete by construction (atomic rename): done before, by someone
        with h5py.File(part, "r") as f:
            n_lines = int(f["offsets"].shape[0]) - 1
        return {"key": task.key, "lines": n_lines, "seeds": task.n_seeds, "cached": True,
                "snapshot": task.snapshot, "seconds": time.perf_counter() - t0, "cpu_s": 0.0}
    with numba_threads(task.numba_threads):
        seeds = task.seeds.load() if isinstance(task.seeds, SeedSlice) else np.asarray(task.seeds)
        if task.series is not None:
            from ..integrate.pathlines import pathlines

            lines = pathlines(list(task.series), seeds, task.release, task.options,
                              vector=task.vector, load=task.load)
        else:
            from ..integrate.trace import trace

            lines = trace(open_field(task.source, task.vector, task.load), seeds, task.options,
                          empty="ignore")  # one chunk of many: one outside the domain is no error
    lines.line_data["seed_id"] = lines.line_data["seed_id"] + task.first
    t1 = time.perf_counter()
    write_part(lines, part, task.position_dtype)
    return {"key": task.key, "lines": len(lines), "seeds": task.n_seeds, "cached": False,
            "snapshot": task.snapshot, "trace_s": t1 - t0, "seconds": time.perf_counter() - t0,
            "cpu_s": time.process_time() - c0}


@contextmanager
def numba_threads(n: int):
    """numba at ``n`` threads in this thread inside the ``with``.  numba's thread count belongs to
    the calling thread: set for a task, given back after (a task run in the caller's own thread
    left it at one thread for whatever ran next)."""
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(min(n, numba.config.NUMBA_NUM_THREADS))
    try:
        yield
    finally:
        numba.set_num_threads(before)


def write_part(lines: Lines, path, position_dtype="float64") -> None:
    """Lines as flat datasets, positions rounded to the output's dtype (once, as a single process
    does), run metadata as root attributes; written atomically."""
    with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
        f["points"] = lines.points.astype(position_dtype, copy=False)
        f["offsets"] = lines.offsets
        for group, data in (("point", lines.point_data), ("line", lines.line_data)):
            g = f.create_group(group, track_order=True)
            for k, v in data.items():
                g[k] = v
        for k, v in lines.attrs.items():
            f.attrs[k] = v


def read_part(path) -> Lines:
    with h5py.File(path, "r") as f:
        attrs = {k: v.item() if isinstance(v, np.generic) else v for k, v in f.attrs.items()}
        return Lines(f["points"][...], f["offsets"][...],
                     {k: d[...] for k, d in f["point"].items()},
                     {k: d[...] for k, d in f["line"].items()}, attrs)


def open_field(source, vector, load=None) -> Field:
    """The field of ``source``, read once per worker process for consecutive tasks; ``load``:
    load_field's keywords (a mesh is resampled on each worker that traces it, once)."""
    from ..fields.readers import SnapshotRef, load_field

    path, snap = (source.path, source.snapshot) if isinstance(source, SnapshotRef) else (source, None)
    load = load or {}
    key = (str(path), snap, vector, os.stat(path).st_mtime_ns, repr(sorted(load.items())))
    field = _FIELD_CACHE.get(key)
    if field is None:
        _FIELD_CACHE.clear()  # one snapshot per worker: drop the last before reading the next
        field = _FIELD_CACHE[key] = load_field(source, vector=vector, **load)
    return field


def chunk_size(n_seeds: int, n_snapshots: int, slots: int, per_task: int = 8,
               lo: int = 256, hi: int = 65536) -> int:
    """Seeds per task: about ``per_task`` tasks per worker thread over the whole job (so the
    scheduler can even out slow and fast chunks), within [lo, hi] seeds (small tasks pay the
    per-task overhead; large ones bound a worker's memory: 65536 seeds of lines are ~100 MB)."""
    want = -(-n_seeds * n_snapshots // (per_task * slots))
    return int(max(1, min(n_seeds, max(lo, min(hi, want)))))
