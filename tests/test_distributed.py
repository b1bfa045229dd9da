"""Distributed tracing on a LocalCluster of 2 worker processes: the same lines as one process,
snapshots in parallel, pathlines, a killed worker, retried tasks, idempotent parts."""

import logging
import os
import signal
import threading
import time
from pathlib import Path

import distributed
import numba
import numpy as np
import pytest

from flowkit.datasets import hotroom_path
from flowkit.distributed import JobError, pathlines_distributed, trace_distributed
from flowkit.distributed import tasks as T
from flowkit.fields.readers import load_field, load_series
from flowkit.integrate.options import TraceOptions
from flowkit.integrate.pathlines import pathlines
from flowkit.integrate.trace import trace_to_file
from flowkit.io.lines_h5 import read_lines, write_lines
from flowkit.lines import Lines

OPTS = TraceOptions(max_steps=3000)
SERIES = load_series(hotroom_path())


def _seeds(n, seed=0):
    return np.random.default_rng(seed).uniform([0.3, 0.3, 0.3], [9.7, 4.7, 9.7], (n, 3))


@pytest.fixture(scope="module")
def client():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0", silence_logs=logging.CRITICAL) as cluster, \
            distributed.Client(cluster) as c:
        yield c


def _single(tmp_path, snapshot, seeds, name):
    return read_lines(trace_to_file(load_field(SERIES[snapshot][1]), seeds, tmp_path / name,
                                    OPTS))


def _same(a: Lines, b: Lines):
    assert len(a) == len(b) and a.equals(b)  # exact: rtol = atol = 0
    np.testing.assert_array_equal(b.line_data["seed_id"], np.arange(len(b)))
    assert {k: str(v) for k, v in a.attrs.items()} == {k: str(v) for k, v in b.attrs.items()}


def _no_parts_left(directory: Path):
    assert not [p for p in directory.iterdir() if ".parts-" in p.name or ".tmp" in p.name]


def test_distributed_equals_single_process(client, tmp_path):
    seeds = _seeds(800)
    ref = _single(tmp_path, 4, seeds, "single.h5")  # also compiles the kernels for the workers
    out = trace_distributed(hotroom_path(), seeds, tmp_path / "dist.h5", OPTS, client=client,
                            snapshots=[4], chunk_seeds=100)
    assert out == [tmp_path / "dist.h5"]
    _same(ref, read_lines(out[0]))
    _no_parts_left(tmp_path)


def test_series_one_file_with_snapshot_index_and_per_snapshot(client, tmp_path):
    seeds = _seeds(200, 1)
    refs = [_single(tmp_path, s, seeds, f"single{s}.h5") for s in range(len(SERIES))]
    one = read_lines(trace_distributed(hotroom_path(), seeds, tmp_path / "all.h5", OPTS,
                                       client=client, chunk_seeds=80)[0])
    assert one.attrs["snapshot_times"].tolist() == [400, 800, 1200, 1600, 2000]
    assert "snapshot_time" not in one.attrs  # (each line's is snapshot_times[snapshot])
    assert one.attrs["source"] == str(hotroom_path())
    snap = one.line_data.pop("snapshot")
    np.testing.assert_array_equal(snap, np.repeat(np.arange(5), 200))
    for s, ref in enumerate(refs):
        part = one[snap == s]
        assert part.equals(ref) and one.attrs["snapshot_sources"][s] == str(SERIES[s][1])
    files = trace_distributed(hotroom_path(), seeds, tmp_path / "per.h5", OPTS, client=client,
                              chunk_seeds=80, per_snapshot=True)
    assert [f.name for f in files] == [f"per_{i:04d}.h5" for i in range(5)]
    for s, f in enumerate(files):
        lines = read_lines(f)
        assert lines.attrs["snapshot_time"] == SERIES[s][0]
        assert lines.equals(refs[s])
    _no_parts_left(tmp_path)


def test_pathlines_distributed_equals_single_process(client, tmp_path):
    seeds = _seeds(120, 2)
    release = np.repeat([400.0, 900.0, 1300.0], 40)
    opts = TraceOptions(rtol=1e-6, attributes=("T",))
    ref = read_lines(write_lines(pathlines(hotroom_path(), seeds, release, opts),
                                 tmp_path / "single.h5"))
    out = pathlines_distributed(hotroom_path(), seeds, tmp_path / "dist.h5", release, opts,
                                client=client, chunk_seeds=35)
    _same(ref, read_lines(out))
    _no_parts_left(tmp_path)


def test_a_result_lost_with_its_worker_is_computed_again_not_a_failure(client, tmp_path,
                                                                        monkeypatch):
    """A worker holds the results of the tasks it ran: killed after one of them finished, it
    takes that result with it, and the scheduler computes the task again.  The job waits for
    that (the same lines) instead of failing.  Made certain here: the first finished task's
    worker is killed before the job looks at that task."""
    seeds = _seeds(300, 5)
    ref = _single(tmp_path, 1, seeds, "single.h5")
    real, seen = distributed.as_completed, []

    def as_completed(futures):
        for fut in real(futures):
            if not seen:
                (holder,) = client.who_has([fut])[fut.key]
                os.kill(client.run(os.getpid, workers=[holder])[holder], signal.SIGKILL)
                deadline = time.monotonic() + 30
                while fut.status == "finished" and time.monotonic() < deadline:
                    time.sleep(0.002)
                seen.append(fut.status)
            yield fut

    monkeypatch.setattr(distributed, "as_completed", as_completed)
    out = trace_distributed(hotroom_path(), seeds, tmp_path / "dist.h5", OPTS, client=client,
                            snapshots=[1], chunk_seeds=100)
    assert seen == ["lost"]
    _same(ref, read_lines(out[0]))
    client.wait_for_workers(2, timeout=60)
    _no_parts_left(tmp_path)


def test_killing_a_worker_mid_run_loses_and_duplicates_no_line(client, tmp_path):
    seeds = _seeds(2500, 3)
    ref = _single(tmp_path, 2, seeds, "single.h5")
    pids = set(client.run(os.getpid).values())
    result, killed = {}, []

    def job():
        result["out"] = trace_distributed(hotroom_path(), seeds, tmp_path / "dist.h5", OPTS,
                                          client=client, snapshots=[2], chunk_seeds=100)

    th = threading.Thread(target=job)
    th.start()
    deadline = time.monotonic() + 60
    while not killed and time.monotonic() < deadline:
        parts = [p for d in tmp_path.glob(".dist.parts-*") for p in d.iterdir()
                 if not p.name.startswith(".")]
        busy = [w for w, keys in client.processing().items() if keys]
        if len(parts) >= 3 and busy:  # under way: kill a worker while it runs a task
            victim = busy[0]
            pid = client.run(os.getpid, workers=[victim])[victim]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)
            unfinished = "out" not in result  # the job was still running when the worker died
        time.sleep(0.02)
    th.join(120)
    assert killed and unfinished and not th.is_alive()
    _same(ref, read_lines(result["out"][0]))
    client.wait_for_workers(2, timeout=60)  # the nanny restarted the killed worker
    assert killed[0] in pids and killed[0] not in client.run(os.getpid).values()
    _no_parts_left(tmp_path)


def test_failed_task_is_retried_and_reported(tmp_path, monkeypatch):
    """In-process workers (threads) so that the test can make the first field open fail."""
    calls = []
    real = T.open_field

    def flaky(source, vector, load=None):
        calls.append(source)
        if len(calls) == 1:
            raise OSError("transient read error")
        return real(source, vector, load)

    monkeypatch.setattr(T, "open_field", flaky)
    seeds = _seeds(300, 4)
    ref = _single(tmp_path, 0, seeds, "single.h5")
    with distributed.LocalCluster(processes=False, n_workers=1, threads_per_worker=1,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as c:
        out = trace_distributed(hotroom_path(), seeds, tmp_path / "d.h5", OPTS, client=c,
                                snapshots=[0], chunk_seeds=300, retries=1)
        _same(ref, read_lines(out[0]))
        assert len(calls) == 2
        calls.clear()
        monkeypatch.setattr(T, "open_field", lambda *a: (_ for _ in ()).throw(OSError("gone")))
        with pytest.raises(JobError, match=r"task s00000-c0000000 failed after 0 retries.*gone"):
            trace_distributed(hotroom_path(), seeds, tmp_path / "e.h5", OPTS, client=c,
                              snapshots=[0], chunk_seeds=300, retries=0)
    assert not (tmp_path / "e.h5").exists()


def test_task_output_is_idempotent(tmp_path):
    seeds = _seeds(50, 5)
    task = T.Task("s00000-c0000000", str(tmp_path / "part.h5"), SERIES[1][1], 1, 1000, seeds, OPTS)
    threads = numba.get_num_threads()
    first = T.run_task(task)
    assert numba.get_num_threads() == threads  # a task in the caller's thread gives them back
    stamp = (tmp_path / "part.h5").stat().st_mtime_ns
    again = T.run_task(task)
    assert not first["cached"] and again["cached"] and again["lines"] == first["lines"] == 50
    assert (tmp_path / "part.h5").stat().st_mtime_ns == stamp
    lines = T.read_part(tmp_path / "part.h5")
    np.testing.assert_array_equal(lines.line_data["seed_id"], np.arange(1000, 1050))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["part.h5"]  # no temporary left


def test_chunk_size_balances_tasks():
    assert T.chunk_size(1_000_000, 1, 2) == 62500  # 16 tasks for 2 threads
    assert T.chunk_size(10_000_000, 1, 2) == 65536  # memory cap
    assert T.chunk_size(1000, 1, 2) == 256  # overhead floor
    assert T.chunk_size(100, 1, 2) == 100
    assert T.chunk_size(10_000, 1000, 64) == 10_000  # snapshots alone give enough tasks


def test_seed_file_and_bad_inputs(client, tmp_path):
    seeds = _seeds(400, 6)
    np.save(tmp_path / "seeds.npy", seeds)
    ref = _single(tmp_path, 3, seeds, "single.h5")
    out = trace_distributed(hotroom_path(), tmp_path / "seeds.npy", tmp_path / "d.h5", OPTS,
                            client=client, snapshots=[3], chunk_seeds=150)
    _same(ref, read_lines(out[0]))
    np.save(tmp_path / "bad.npy", seeds[:, :2])
    with pytest.raises(ValueError, match=r"bad.npy: seeds must be an \(n, 3\)"):
        trace_distributed(hotroom_path(), tmp_path / "bad.npy", tmp_path / "x.h5", client=client)
    with pytest.raises(ValueError, match="n >= 1"):
        trace_distributed(hotroom_path(), np.zeros((0, 3)), tmp_path / "x.h5", client=client)
    with pytest.raises(ValueError, match="chunk_seeds must be an integer >= 1, got 0"):
        trace_distributed(hotroom_path(), seeds, tmp_path / "x.h5", client=client, chunk_seeds=0)
    with pytest.raises(ValueError, match="snapshot 7 out of range"):
        trace_distributed(hotroom_path(), seeds, tmp_path / "x.h5", client=client, snapshots=[7])


def test_cli_series_and_pathlines_on_a_running_cluster(client, tmp_path, capsys):
    from flowkit.cli import main
    from flowkit.integrate.seeds import parse_seed_spec

    address = client.scheduler.address
    seeds = parse_seed_spec("random:60:7", load_field(SERIES[0][1]))
    out = tmp_path / "cli.h5"
    assert main(["trace", str(hotroom_path()), "-o", str(out), "--seeds", "random:60:7",
                 "--max-steps", "3000", "--snapshots", "all", "--scheduler", address,
                 "--chunk-seeds", "25"]) == 0
    assert "300 seed x snapshot traces" in capsys.readouterr().out
    lines = read_lines(out)
    assert lines.attrs["source"] == str(hotroom_path())
    snap = lines.line_data.pop("snapshot")
    for s in (0, 4):
        assert lines[snap == s].equals(_single(tmp_path, s, seeds, f"ref{s}.h5"))
    out = tmp_path / "paths.h5"
    assert main(["trace", str(hotroom_path()), "-o", str(out), "--seeds", "random:60:7",
                 "--pathlines", "--release", "800", "--attributes", "T", "--scheduler", address,
                 "--quiet"]) == 0
    ref = pathlines(hotroom_path(), seeds, 800.0, TraceOptions(attributes=("T",)))
    got = read_lines(out)
    assert len(got) == 60 and got.equals(ref, rtol=0, atol=1e-5)  # positions stored float32
    assert main(["trace", str(hotroom_path()), "-o", str(out), "--snapshots", "x",
                 "--scheduler", address]) == 2
    assert "--snapshots 'x'" in capsys.readouterr().err


def test_cli_pathlines_under_a_memory_budget(client, tmp_path):
    """--memory reaches the pathlines on the workers: snapshots two of which do not fit it are
    read brick by brick there, and the lines are those read whole."""
    import json

    from test_bricks import _in_memory, _series

    from flowkit.cli import main
    from flowkit.integrate.seeds import parse_seed_spec

    series = _series(tmp_path)  # four snapshots of 24^3 nodes in chunks of 8^3 (166 kB each)
    (tmp_path / "abc.series").write_text(json.dumps({"file-series-version": "1.0", "files": [
        {"name": Path(p).name, "time": t} for t, p in series]}))
    out = tmp_path / "paths.h5"
    assert main(["trace", str(tmp_path / "abc.series"), "-o", str(out), "--seeds",
                 "random:30:4", "--pathlines", "--release", "0.3", "--max-time", "1.5",
                 "--attributes", "speed,T", "--memory", "185kB", "--float64", "--scheduler",
                 client.scheduler.address, "--quiet"]) == 0
    got = read_lines(out)
    seeds = parse_seed_spec("random:30:4", load_field(series[0][1]))
    ref = pathlines(_in_memory(series), seeds, 0.3, max_time=1.5, attributes=("speed", "T"))
    assert got.equals(ref) and got.attrs["bricks_read"] > 0


def test_local_cluster_started_for_the_job(tmp_path):
    seeds = _seeds(120, 8)
    ref = _single(tmp_path, 1, seeds, "single.h5")
    timings = {}
    out = trace_distributed(hotroom_path(), seeds, tmp_path / "d.h5", OPTS, workers=1,
                            snapshots=[1], chunk_seeds=60, timings=timings)
    _same(ref, read_lines(out[0]))
    assert timings["n_tasks"] == 2 and timings["task_cpu"] > 0
    with pytest.raises(ValueError, match="workers must be at least 1"):
        trace_distributed(hotroom_path(), seeds, tmp_path / "e.h5", workers=0)


def test_a_mesh_is_resampled_on_the_workers(client, tmp_path, capsys):
    """--resample (and --data) with a series, workers, blocks and pathlines: each worker resamples
    the snapshots it traces, onto the grid one process uses."""
    import json

    from meshes import block, linear_u, write_vtu

    from flowkit.cli import main
    from flowkit.integrate.seeds import parse_seed_spec

    pts, cells = block((4, 4, 4), hole=((1, 1, 1), (3, 3, 3)), kinds="poly")
    rot = np.stack([-(pts[:, 1] - 2), pts[:, 0] - 2, np.full(len(pts), 0.3)], -1)
    for i, u in enumerate((rot, rot + 0.1 * linear_u(pts))):
        write_vtu(tmp_path / f"m_{i}.vtu", pts, cells, point_data={"U": u},
                  cell_data={"U": np.full((len(cells), 3), 0.2 + i)})
    (tmp_path / "m.series").write_text(json.dumps({"file-series-version": "1.0", "files": [
        {"name": f"m_{i}.vtu", "time": float(i)} for i in range(2)]}))
    address = client.scheduler.address
    common = ["--seeds", "random:40:3", "--max-length", "6", "--scheduler", address, "--quiet"]
    for load in ({"resample": "13,13,13"}, {"resample": "spacing:0.5", "data": "cell"}):
        flags = [f for k, v in load.items() for f in (f"--{k}", v)]
        out = tmp_path / "s.h5"
        assert main(["trace", str(tmp_path / "m.series"), "-o", str(out), *common, *flags]) == 0
        lines = read_lines(out)
        snap = lines.line_data.pop("snapshot")
        for i in range(2):
            f = load_field(tmp_path / f"m_{i}.vtu", **load)
            ref = read_lines(trace_to_file(f, parse_seed_spec("random:40:3", f),
                                           tmp_path / "ref.h5", TraceOptions(max_length=6)))
            assert lines[snap == i].equals(ref, rtol=0, atol=1e-6)
    f0 = load_field(tmp_path / "m_0.vtu", resample="13,13,13")
    seeds = parse_seed_spec("random:40:3", f0)
    out = tmp_path / "b.h5"
    assert main(["trace", str(tmp_path / "m_0.vtu"), "-o", str(out), *common,
                 "--resample", "13,13,13", "--distribute", "blocks"]) == 0
    ref = read_lines(trace_to_file(f0, seeds, tmp_path / "ref.h5", TraceOptions(max_length=6)))
    assert read_lines(out).equals(ref, rtol=0, atol=1e-6)
    out = tmp_path / "p.h5"
    assert main(["trace", str(tmp_path / "m.series"), "-o", str(out), *common, "--pathlines",
                 "--resample", "13,13,13"]) == 0
    ref = pathlines(tmp_path / "m.series", seeds, 0.0, TraceOptions(max_length=6),
                    load={"resample": "13,13,13"})
    assert read_lines(out).equals(ref, rtol=0, atol=1e-5)
