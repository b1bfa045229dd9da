"""Distributed jobs: streamlines over (snapshot, seed chunk) tasks, pathlines over seed chunks.

The client only plans, watches and joins: it splits the work into tasks (``tasks.Task``), submits
them with retries, shows progress for the whole job (seeds and snapshots done, seeds/s), and
once every part of an output exists submits the join of that output (``join.join_parts``) to
the cluster too.  Workers must see the same file system (the field files, the output
directory).  Part files live in a hidden directory beside the output whose name is a hash of
the job (inputs, seeds, options, chunking): rerunning an interrupted job resumes it, a different
job never picks up stale parts.  The directory is removed when all outputs are written.
"""

from __future__ import annotations

import hashlib
import shutil
import sys
from pathlib import Path

import numpy as np

from ..integrate.options import TraceOptions
from .blocks import choose, trace_blocks, worker_memory
from .cluster import connect, slots
from .join import join_parts
from .tasks import JobError, SeedSlice, Task, chunk_size, open_field, run_task

__all__ = ["JobError", "pathlines_distributed", "trace_distributed"]


def trace_distributed(source, seeds, out, options: TraceOptions | None = None, *, client=None,
                      scheduler: str | None = None, workers: int | None = None,
                      snapshots=None, per_snapshot: bool = False, vector: str | None = "U",
                      chunk_seeds: int | None = None, position_dtype="float32", retries: int = 2,
                      progress: bool | None = None, timings: dict | None = None,
                      distribute: str = "auto", load: dict | None = None, balance: bool = True,
                      **kw) -> list[Path]:
    """Streamlines of ``seeds`` through every snapshot of ``source`` on a dask cluster.

    ``source``: a field file, a ``.series`` file, a glob or a multi-snapshot flowkit HDF5 file
    (``load_series``); ``snapshots`` picks positions in it (default all).  ``seeds``: (n, 3) points
    or the path of an (n, 3) ``.npy`` file that workers memory-map.  Output: with one snapshot,
    ``out`` is identical to ``trace_to_file`` of that snapshot; with several, one file ``out`` whose
    lines carry ``snapshot`` (position in ``snapshot_times``, a root attribute), snapshot by
    snapshot (root attributes ``source``: the series, ``snapshot_sources``: each snapshot's), or with
    ``per_snapshot`` one file per snapshot named ``<out stem>_<i:04d><suffix>``.
    Cluster: ``client`` (a distributed.Client), ``scheduler`` (an address), else a LocalCluster
    of ``workers`` processes.  ``timings``, if given, receives the seconds spent until the last
    task finished (``tasks``), joining after that (``join``), the task count and the CPU seconds
    the tasks used (``task_cpu``).  Returns the written paths.
    ``distribute``: "seeds" (the seeds split across workers, each reading the whole field),
    "blocks" (the field's bricks split across workers, lines handed between them: ``blocks``;
    a series snapshot after snapshot, with ``per_snapshot``) or "auto": blocks where the
    field's vector (a series': the first snapshot's) does not fit a worker's memory limit.  The choice and why go to ``timings`` (``distribute``, ``distribute_why``) and, unless
    ``progress`` is False, a line on stderr; block mode records them in the file's attrs.
    ``load``: load_field's keywords for every snapshot (a mesh's ``resample``, ``block``,
    ``data``): each worker reads and resamples the snapshots it traces itself, once each.
    ``balance`` (block mode): give a crowded block a second owner (False: one owner each).
    """
    opts = _options(options, kw)
    series = _select(_series(source), snapshots)
    seed_src, n = _seed_source(seeds)
    out = Path(out)
    times = [t for t, _ in series]
    multi = len(series) > 1
    outputs = [out.with_name(f"{out.stem}_{i:04d}{out.suffix}") for i in range(len(series))] \
        if multi and per_snapshot else [out]
    with connect(client, scheduler, workers) as c:
        field = None  # (opened, not read, where its size or bricks matter: a mesh resampled)
        if distribute == "blocks" or (distribute == "auto" and worker_memory(c) is not None):
            field = open_field(series[0][1], vector, load)
        mode, why = choose(distribute, field, c, len(series), per_snapshot)
        if timings is not None:
            timings.update(distribute=mode, distribute_why=why)
        if progress is not False:
            print(f"flowkit: distribute {mode}: {why}", file=sys.stderr)
        if mode == "blocks":
            seeds_in = np.load(seed_src) if isinstance(seed_src, str) else seed_src
            return _blocks_series(c, series, vector, seeds_in, outputs, opts, why, load,
                                  field, timings, position_dtype=position_dtype,
                                  retries=retries, balance=balance)
        chunk = _chunk(chunk_seeds, chunk_size(n, len(series), slots(c)))
        job = _job_hash("trace", [_source_id(r) for _, r in series], vector, seed_src, opts, chunk,
                        position_dtype, *_load_id(load))
        parts_dir = _parts_dir(out, job)
        tasks = []
        for s, (_, ref) in enumerate(series):
            for j, a in enumerate(range(0, n, chunk)):
                b = min(n, a + chunk)
                tasks.append(Task(f"s{s:05d}-c{j:07d}", str(parts_dir / f"s{s:05d}-c{j:07d}.h5"),
                                  ref, s, a, _slice(seed_src, a, b), opts, vector, position_dtype,
                                  load=dict(load or {})))
        joins = []
        for i, o in enumerate(outputs):
            mine = [t for t in tasks if t.snapshot == i] if len(outputs) > 1 else tasks
            # (several snapshots in one file: the first part's snapshot_time is not the file's)
            extra = {"source": _label(source, series), "snapshot_times": np.asarray(times),
                     "snapshot_sources": [str(r) for _, r in series],
                     "snapshot_time": None} if multi else {}
            if multi and per_snapshot:
                extra = {"snapshot_time": float(times[i]), "snapshot_index": i}
            joins.append((o, mine, extra, [t.snapshot for t in mine] if multi and not per_snapshot
                          else None))
        _run(c, tasks, joins, job, retries, position_dtype, progress, len(series), "trace",
             timings)
    shutil.rmtree(parts_dir, ignore_errors=True)
    return outputs


def _blocks_series(client, series, vector, seeds, outputs, opts, why, load, field, timings,
                   **kw) -> list[Path]:
    """Block mode, snapshot after snapshot (each a job of its own: the workers' pools hold one
    snapshot's bricks), into one file each; a series' files carry their snapshot's time and
    position, as the seeds mode writes them.  ``timings``: one snapshot's, or with several
    ``snapshots`` (each one's) and ``tasks`` (their sum)."""
    done, each = [], []
    for i, ((t, ref), out) in enumerate(zip(series, outputs)):
        tim: dict = {}
        extra = {"snapshot_time": float(t), "snapshot_index": i} if len(series) > 1 else None
        done.append(Path(trace_blocks(client, ref, vector, seeds, out, opts, why,
                                      field=field if i == 0 else None, load=load, attrs=extra,
                                      timings=tim, **kw)))
        each.append(tim)
    if timings is not None:
        timings.update(each[0] if len(each) == 1 else
                       {"snapshots": each, "tasks": sum(e["tasks"] for e in each)})
    return done


def pathlines_distributed(series, seeds, out, release=None, options: TraceOptions | None = None,
                          *, client=None, scheduler: str | None = None, workers: int | None = None,
                          vector: str = "U", chunk_seeds: int | None = None,
                          position_dtype="float32", retries: int = 2,
                          progress: bool | None = None, timings: dict | None = None,
                          load: dict | None = None, **kw) -> Path:
    """Pathlines (``flowkit.integrate.pathlines``) of ``seeds`` over seed-chunk tasks, each task
    sweeping the whole series with two snapshots in memory; one output file identical to
    ``write_lines(pathlines(series, seeds, release, ...))``."""
    opts = _options(options, kw)
    entries = tuple(_series(series))
    seed_src, n = _seed_source(seeds)
    rel = None if release is None else np.broadcast_to(np.asarray(release, np.float64), (n,))
    out = Path(out)
    with connect(client, scheduler, workers) as c:
        # every task reads the whole series: fewer, larger tasks than for streamlines
        chunk = _chunk(chunk_seeds, chunk_size(n, 1, slots(c), per_task=2))
        job = _job_hash("pathlines", [f"{t}:{_source_id(r)}" for t, r in entries], vector, seed_src, opts,
                        chunk, position_dtype, None if rel is None else rel.tobytes(),
                        *_load_id(load))
        parts_dir = _parts_dir(out, job)
        tasks = [Task(f"c{j:07d}", str(parts_dir / f"c{j:07d}.h5"), None, -1, a,
                      _slice(seed_src, a, min(n, a + chunk)), opts, vector, position_dtype,
                      series=entries, release=None if rel is None else rel[a:a + chunk].copy(),
                      load=dict(load or {}))
                 for j, a in enumerate(range(0, n, chunk))]
        _run(c, tasks, [(out, tasks, {}, None)], job, retries, position_dtype, progress, 1,
             "pathlines", timings)
    shutil.rmtree(parts_dir, ignore_errors=True)
    return out


# -- running ----------------------------------------------------------------------------------
def _run(client, tasks, joins, job, retries, position_dtype, progress, n_snap, desc, timings):
    """Submit the tasks, join each output as soon as its parts exist, show progress."""
    import time

    from distributed import as_completed

    t0 = time.perf_counter()
    total = sum(t.n_seeds for t in tasks)
    bar = _bar(total, desc, progress)
    pending = {}  # output index -> task keys not yet done
    for i, (_, mine, _, _) in enumerate(joins):
        pending[i] = {t.key for t in mine}
    snap_left = {}
    for t in tasks:
        snap_left[t.snapshot] = snap_left.get(t.snapshot, 0) + 1
    futures = [client.submit(run_task, t, key=f"flowkit-{job}-{t.key}", retries=retries,
                             priority=-max(t.snapshot, 0), pure=False) for t in tasks]
    task_of = {f.key: t for f, t in zip(futures, tasks)}
    join_futures = []
    snaps_done = 0
    cpu = 0.0
    try:
        for fut in as_completed(futures):
            # (status "lost": the worker holding the result died after the task finished; the
            # scheduler computes it again, and result() waits for that)
            try:
                if fut.status == "cancelled":
                    raise RuntimeError("cancelled")
                res = fut.result()
            except Exception as e:  # (whatever the task raised, named in the message)
                raise JobError(f"{desc} task {task_of[fut.key].key} failed after {retries} "
                               f"retries: {e!r}; parts done so far are kept, rerun to "
                               f"resume") from e
            cpu += res["cpu_s"]
            snap_left[res["snapshot"]] -= 1
            snaps_done += snap_left[res["snapshot"]] == 0
            if bar is not None:
                bar.update(res["seeds"])
                bar.set_postfix_str(f"snapshots {snaps_done}/{n_snap}", refresh=False)
            for i, keys in pending.items():
                keys.discard(res["key"])
                if not keys and i not in [j for j, _ in join_futures]:
                    o, mine, extra, snaps = joins[i]
                    join_futures.append((i, client.submit(
                        join_parts, [t.part for t in mine], str(o), snapshots=snaps, attrs=extra,
                        position_dtype=position_dtype, key=f"flowkit-{job}-join{i}",
                        retries=retries, pure=False)))
        t1 = time.perf_counter()
        for _, jf in join_futures:
            jf.result()
        if timings is not None:
            timings.update(tasks=t1 - t0, join=time.perf_counter() - t1, n_tasks=len(tasks),
                           task_cpu=cpu)
    except BaseException:
        for f in futures:
            f.cancel()
        raise
    finally:
        if bar is not None:
            bar.close()


def _bar(total, desc, progress):
    show = progress if progress is not None else sys.stderr.isatty()
    if not show:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="seed", desc=desc, smoothing=0.1)


# -- inputs -----------------------------------------------------------------------------------
def _chunk(chunk_seeds, default) -> int:
    if chunk_seeds is None:
        return default
    if not (isinstance(chunk_seeds, (int, np.integer)) and chunk_seeds >= 1):
        raise ValueError(f"chunk_seeds must be an integer >= 1, got {chunk_seeds!r}")
    return int(chunk_seeds)


def _options(options, kw) -> TraceOptions:
    opts = options if options is not None else TraceOptions()
    if not isinstance(opts, TraceOptions):
        raise TypeError(f"options must be a TraceOptions, got {type(opts).__name__}")
    opts = opts.replace(**kw) if kw else opts
    return opts.replace(progress=False)  # the job shows progress, not each task


def _series(source) -> list:
    if isinstance(source, (list, tuple)):
        return sorted(((float(t), r) for t, r in source), key=lambda e: e[0])
    from ..fields.readers import load_series

    return load_series(source)


def _label(source, series) -> str:
    """What the series is, for the ``source`` attribute: its path or glob, else its ends."""
    if not isinstance(source, (list, tuple)):
        return str(source)
    return f"{series[0][1]} .. {series[-1][1]} ({len(series)} snapshots)"


def _select(series, snapshots):
    if snapshots is None:
        return series
    out = []
    for s in np.atleast_1d(snapshots).tolist():
        if not -len(series) <= int(s) < len(series):
            raise ValueError(f"snapshot {s} out of range: the series has {len(series)} snapshots")
        out.append(series[int(s)])
    return out


def _seed_source(seeds):
    """(array or .npy path, n) with the seeds checked to be (n, 3) floats."""
    if isinstance(seeds, (str, Path)):
        p = Path(seeds)
        if p.suffix.lower() != ".npy":
            raise ValueError(f"{p}: distributed seeds come as an array or an (n, 3) .npy file")
        a = np.load(p, mmap_mode="r", allow_pickle=False)
        if a.ndim != 2 or a.shape[1] != 3 or a.dtype.kind != "f" or a.shape[0] == 0:
            raise ValueError(f"{p}: seeds must be an (n, 3) float array, got {a.dtype} {a.shape}")
        return str(p.resolve()), a.shape[0]
    a = np.ascontiguousarray(np.atleast_2d(np.asarray(seeds, np.float64)))
    if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] == 0:
        raise ValueError(f"seeds must have shape (n, 3) with n >= 1, got {np.shape(seeds)}")
    return a, a.shape[0]


def _slice(seed_src, a, b):
    return SeedSlice(seed_src, a, b) if isinstance(seed_src, str) else seed_src[a:b].copy()


def _job_hash(*items) -> str:
    h = hashlib.sha1()
    for it in items:
        if isinstance(it, np.ndarray):
            h.update(it.tobytes())
        elif isinstance(it, str) and Path(it).is_file():
            st = Path(it).stat()
            h.update(f"{it}:{st.st_size}:{st.st_mtime_ns}".encode())
        else:
            h.update(repr(it).encode())
        h.update(b"\0")
    return h.hexdigest()[:12]


def _load_id(load) -> tuple:
    """load_field's keywords in the job hash: () when none, so older jobs keep their hash."""
    return (repr(sorted(load.items())),) if load else ()


def _source_id(ref) -> str:
    """A snapshot's identity for the job hash: path, snapshot number, size and mtime."""
    path, snap = (ref.path, ref.snapshot) if hasattr(ref, "snapshot") else (ref, None)
    st = Path(path).stat()
    return f"{Path(path).resolve()}:{snap}:{st.st_size}:{st.st_mtime_ns}"


def _parts_dir(out: Path, job: str) -> Path:
    if not out.parent.is_dir():
        raise FileNotFoundError(f"{out}: directory {out.parent} does not exist")
    d = out.parent / f".{out.stem}.parts-{job}"
    d.mkdir(exist_ok=True)
    return d
