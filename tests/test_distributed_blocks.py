"""Block mode on a LocalCluster of 2 worker processes: the field's blocks owned by workers, lines
handed between them; the same lines as one process, bit for bit (ABC both ways with attributes,
a NaN hole across a block face, periodic axes, the heated room); the choice of mode; a killed
worker; one-line errors and no output where a scheduler, a file or a block fails."""

import os
import signal
import threading
import time

import h5py
import numpy as np
import pytest
import test_distributed
from test_bricks import SEEDS, _abc_file, _stiff_file
from test_stored_fields import _same

from flowkit import trace
from flowkit.cli import main
from flowkit.distributed import JobError, blocks, trace_distributed
from flowkit.fields import load_field, save_field
from flowkit.integrate.trace import trace_to_file
from flowkit.io.lines_h5 import read_lines

L = 2 * np.pi
client = test_distributed.client  # (the fixture: a LocalCluster of 2 worker processes)
READS = ("bricks_read", "field_bytes_read", "brick_rounds", "brick_pool_bytes")


def _blocks(client, path, seeds, timings=None, balance=True, **kw):
    """Lines of block mode (positions kept float64, as in memory) and the serial trace's."""
    out = path.with_name(path.stem + "_blocks.h5")
    got = read_lines(trace_distributed(path, seeds, out, client=client, distribute="blocks",
                                       position_dtype="float64", timings=timings,
                                       balance=balance, **kw)[0])
    whole = trace(load_field(path), seeds, **kw)
    return whole, got


def _same_lines_and_attrs(whole, got):
    _same(whole, got)
    mine = {k for k in got.attrs if k not in whole.attrs}
    assert mine >= {"distribute", "block_rounds", "handoffs_per_line", "idle_share"}
    # every attribute of the serial trace (options, source, kernel path) but what it read
    assert {k: str(v) for k, v in whole.attrs.items() if k not in READS} == \
        {k: str(got.attrs[k]) for k in whole.attrs if k not in READS}


CASES = {
    "forward": {"max_length": 8.0},
    "both, attributes": {"max_length": 6.0, "direction": "both",
                         "attributes": ["speed", "velocity", "vorticity", "T", "arc_length",
                                        "distance_to_seed"]},
    "backward, resampled": {"max_length": 6.0, "direction": "backward", "count": 30},
    # a pool of 14 bricks of 27: lines wait for bricks outside the pool as well as the block;
    # the vorticity's boxes span more bricks than it holds (sampled through a pool of its own)
    "small pool": {"max_length": 10.0, "direction": "both", "memory": "110kB",
                   "attributes": ["vorticity"]},
    # the Rosenbrock stepper's lines, their state handed between workers like any other
    "ros34pw2": {"max_length": 6.0, "direction": "both", "method": "ros34pw2"},
}


@pytest.mark.parametrize("case", CASES)
def test_block_mode_equals_the_serial_trace(client, tmp_path, case):
    t = {}
    whole, got = _blocks(client, _abc_file(tmp_path / "abc.h5"), SEEDS, t, **CASES[case])
    _same_lines_and_attrs(whole, got)
    # the lines did cross between workers: handed over, round after round
    assert t["blocks"] >= 2 and t["block_rounds"] >= 2 and t["handoffs_per_line"] > 0
    assert all(0 <= r["idle_share"] <= 1 for r in t["rounds"]) and len(t["rounds"]) >= 2
    assert got.attrs["distribute"] == "blocks" and got.attrs["bricks_read"] > 0


def test_stiff_lines_switch_steppers_across_workers(client, tmp_path):
    """auto: a line flagged stiff on one worker goes on with the Rosenbrock stepper there and
    on the next worker's blocks, as in one process."""
    path, seeds = _stiff_file(tmp_path / "stiff.h5")
    t = {}
    whole, got = _blocks(client, path, seeds, t, method="auto", rtol=1e-6, atol=1e-6,
                         max_time=5.0)
    _same_lines_and_attrs(whole, got)
    assert got.line_data["ros34pw2"].sum() >= 6 and t["handoffs_per_line"] > 0


def test_float32_output_rounded_on_the_workers(client, tmp_path):
    """The default float32 positions: rounded by the workers (12 bytes a vertex back, with no
    attribute reading t or s, and a line and a count per run of a line's vertices), or sent as
    float64 with t and s where the client computes the distance to the seed, time and arc
    length from them (40); the file holds what one process writes, bit for bit."""
    path = _abc_file(tmp_path / "abc.h5")
    for kw, least in (({"max_length": 8.0}, 12),
                      ({"max_length": 6.0, "direction": "both",
                        "attributes": ["time", "arc_length", "distance_to_seed"]}, 40)):
        ref = read_lines(trace_to_file(load_field(path), SEEDS, tmp_path / "ref.h5", **kw))
        t = {}
        got = read_lines(trace_distributed(path, SEEDS, tmp_path / "b.h5", client=client,
                                           distribute="blocks", timings=t, **kw)[0])
        assert got.points.dtype == np.float32
        _same_lines_and_attrs(ref, got)
        sent = sum(r["vertex_bytes"] for r in t["rounds"])
        vertices = sum(sum(r["worker_vertices"]) for r in t["rounds"])
        assert t["handoffs_per_line"] > 0 and least < sent / vertices < least + 4


def test_a_nan_hole_across_a_block_face(client, tmp_path):
    """The two blocks meet at x node 16 (bricks of 8, 2 bricks per block along x): NaN nodes
    on both sides end lines there with the serial reasons."""
    path = _abc_file(tmp_path / "hole.h5", hole=(slice(13, 20), slice(4, 12), slice(4, 20)))
    t = {}
    whole, got = _blocks(client, path, SEEDS, t, max_length=10.0, direction="both",
                         attributes=["speed"])
    assert t["block_bricks"] == "2 3 3" and t["handoffs_per_line"] > 0, t
    _same_lines_and_attrs(whole, got)
    reasons = np.concatenate([got.line_data["reason"], got.line_data["reason_backward"]])
    assert np.count_nonzero(reasons == 6) >= 5  # (6: a NaN node)


def test_attributes_are_sampled_by_the_block_owners(client, tmp_path, monkeypatch):
    """Seeds at the face between the 2 blocks (x node 16: bricks of 8, 2 bricks per block along
    x), one owner each: every attribute read from the field is sampled on the workers (the
    client's compute is refused them), the vorticity of vertices within the curl's reach of
    the face from nodes of both blocks; all equal the serial trace's, bit for bit."""
    from flowkit.fields.curl import CURL_REACH
    from flowkit.integrate import attributes

    path = _abc_file(tmp_path / "abc.h5")
    h = L / 23
    seeds = np.random.default_rng(5).random((40, 3)) * [2 * h, L, L] + [15 * h, 0, 0]
    kw = {"max_length": 6.0, "direction": "both",
          "attributes": ["vorticity", "vorticity_magnitude", "velocity", "T", "time",
                         "distance_to_seed"]}
    whole = trace(load_field(path), seeds, **kw)
    compute = attributes.compute

    def on_the_client(field, names, *a, **k):
        assert not attributes.from_field(names), f"the client computed {names}"
        return compute(field, names, *a, **k)

    monkeypatch.setattr(attributes, "compute", on_the_client)
    t = {}
    got = read_lines(trace_distributed(path, seeds, tmp_path / "b.h5", client=client,
                                       distribute="blocks", position_dtype="float64",
                                       timings=t, balance=False, **kw)[0])
    _same_lines_and_attrs(whole, got)
    assert t["block_bricks"] == "2 3 3" and t["handoffs_per_line"] > 0
    # both owners sampled the vertices they emitted: every vertex, the seed of each line twice
    per_worker = np.sum([r["worker_vertices"] for r in t["rounds"]], axis=0)
    assert per_worker.min() > 0 and per_worker.sum() == got.n_points + len(got)
    assert all(s > 0 for r in t["rounds"] for s, v in zip(r["worker_attribute_s"],
                                                          r["worker_vertices"]) if v)
    near = np.abs(got.points[:, 0] / h - 16) < CURL_REACH
    below = near & (got.points[:, 0] < 16 * h)
    assert below.sum() > 20 and (near & ~below).sum() > 20
    assert np.isfinite(got.point_data["vorticity"][near]).all()


def test_periodic_axes(client, tmp_path):
    path = _abc_file(tmp_path / "abcp.h5", periodic=True)
    whole, got = _blocks(client, path, SEEDS, max_length=15.0, attributes=["vorticity", "T"])
    _same_lines_and_attrs(whole, got)
    assert np.ptp(got.points, axis=0).max() > L  # the lines did cross the seams


def test_the_heated_room(client, tmp_path):
    from flowkit.datasets import hotroom

    fld = hotroom()
    path = tmp_path / "room.h5"
    save_field(fld, path)
    with h5py.File(path, "a") as h:  # chunked in bricks of 16: 3 x 2 x 3 bricks
        a = h["vectors/U"][...]
        del h["vectors/U"]
        h.create_dataset("vectors/U", data=a, chunks=(16, 16, 16, 3))
    b = fld.grid.bounds
    seeds = b[:, 0] + (b[:, 1] - b[:, 0]) * np.random.default_rng(2).random((30, 3))
    t = {}
    # (one owner per block: with both of its 2 blocks shared, no line would change worker)
    whole, got = _blocks(client, path, seeds, t, max_time=60.0, direction="both",
                         attributes=["speed", "T"], balance=False)
    _same_lines_and_attrs(whole, got)
    assert t["block_rounds"] >= 2


def test_a_crowded_block_gets_a_second_owner(client, tmp_path, monkeypatch):
    """Every seed in block 0 (x below node 16 of 24: bricks of 8, 2 bricks per block along x),
    which worker 0 owns: the first round gives half its lines to worker 1, which reads block 0
    too (120 half-lines: both directions); the lines are those of one process, bit for bit."""
    # reads slow enough that sharing a block (18 bricks of 6 kB) pays for 20 lines moved: the
    # first round's, not the dozen that cross to block 1 after it (the client decides: here)
    monkeypatch.setattr(blocks, "READ_BYTES_PER_S", 18 * 6144 / (20 * blocks.LINE_SECONDS))
    path = _abc_file(tmp_path / "abc.h5")
    seeds = np.random.default_rng(7).random((60, 3)) * [0.55 * L, L, L]
    t = {}
    whole, got = _blocks(client, path, seeds, t, max_length=10.0, direction="both")
    _same_lines_and_attrs(whole, got)
    assert t["blocks"] == 2 and t["block_bricks"] == "2 3 3", t
    assert t["shared_blocks"] == 1 and got.attrs["shared_blocks"] == 1
    first = t["rounds"][0]
    assert first["lines"] == 120 and first["worker_lines"] == [60, 60] and first["tasks"] == 2
    # without sharing, worker 0 takes the whole first round
    t = {}
    trace_distributed(path, seeds, tmp_path / "one.h5", client=client, distribute="blocks",
                      max_length=10.0, direction="both", timings=t, balance=False)
    assert t["shared_blocks"] == 0 and t["rounds"][0]["worker_lines"] == [120, 0]


def test_workers_own_about_equal_shares_of_the_bricks(tmp_path):
    """8 bricks along each axis in blocks of 6: blocks of 216, 72, 24 and 8 bricks.  Two
    workers own 288 and 224 bricks (an equal count of blocks each gave 384 and 128)."""
    fld = load_field(_abc_file(tmp_path / "abc.h5", n=64))  # bricks of 8^3 nodes, 6 kB
    lay = blocks.Layout(fld, 2, int(508 * 6144 / 0.8) + 1)  # a pool of 508 bricks of 512
    assert lay.span.tolist() == [6, 6, 6] and lay.n_blocks == 8
    per_brick = lay.owner[lay.blocks_of_bricks(np.arange(512))]
    assert np.bincount(per_brick).tolist() == [288, 224]
    for n in (3, 4, 8):  # (every worker owns blocks)
        assert np.unique(blocks.Layout(fld, n, int(508 * 6144 / 0.8) + 1).owner).size == n


def test_a_series_in_block_mode_one_file_per_snapshot(client, tmp_path, capsys):
    """Two snapshots (the second with a NaN hole across the block face), each traced in block
    mode into its own file: the lines, attributes and reasons of the serial trace of each,
    with the snapshot's time and position as the seeds mode writes them."""
    paths = [_abc_file(tmp_path / "s0.h5"),
             _abc_file(tmp_path / "s1.h5", hole=(slice(13, 20), slice(4, 12), slice(4, 20)))]
    kw = {"max_length": 8.0, "direction": "both", "attributes": ["vorticity", "T"]}
    t = {}
    outs = trace_distributed([(10.0, str(paths[0])), (20.0, str(paths[1]))], SEEDS,
                             tmp_path / "lines.h5", client=client, distribute="blocks",
                             per_snapshot=True, position_dtype="float64", timings=t, **kw)
    assert [o.name for o in outs] == ["lines_0000.h5", "lines_0001.h5"]
    for i, (p, o) in enumerate(zip(paths, outs)):
        got = read_lines(o)
        _same_lines_and_attrs(trace(load_field(p), SEEDS, **kw), got)
        assert got.attrs["snapshot_time"] == 10.0 * (i + 1) and got.attrs["snapshot_index"] == i
        assert got.attrs["distribute"] == "blocks" and got.attrs["handoffs_per_line"] > 0
    assert [s["block_rounds"] >= 2 for s in t["snapshots"]] == [True, True]
    assert t["tasks"] == pytest.approx(sum(s["tasks"] for s in t["snapshots"]))
    capsys.readouterr()
    # one file for both: refused in one line, before anything is traced
    rc = main(["trace", str(tmp_path / "s*.h5"), "-o", str(tmp_path / "one.h5"), "--seeds",
               "random:10", "--scheduler", client.scheduler.address, "--distribute", "blocks"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1
    assert "traces the 2 snapshots one after the other into one file each: give " \
           "per_snapshot=True (--per-snapshot)" in err
    assert not (tmp_path / "one.h5").exists()


# -- the choice of mode --------------------------------------------------------------------
class _Info:
    def __init__(self, *limits):
        self.limits = limits

    def scheduler_info(self):
        return {"workers": {f"w{i}": {"memory_limit": m} for i, m in enumerate(self.limits)}}


def test_the_choice_of_mode(tmp_path):
    fld = load_field(_abc_file(tmp_path / "abc.h5"))  # 24^3 x 3 float32: 166 kB
    assert blocks.choose("auto", fld, _Info(10 ** 9, 10 ** 9), 1)[0] == "seeds"
    mode, why = blocks.choose("auto", fld, _Info(10 ** 9, 200_000), 1)  # (the smallest counts)
    assert mode == "blocks" and "166 kB" in why and "does not fit 80%" in why
    assert "200 kB" in why
    assert blocks.choose("auto", fld, _Info(0, 0), 1)[1] == "the workers have no memory limit"
    assert blocks.choose("blocks", fld, _Info(10 ** 9), 1) == ("blocks", "asked for")
    # a series: by its first snapshot, in block mode one file per snapshot
    assert blocks.choose("auto", fld, _Info(10 ** 9), 3)[0] == "seeds"
    mode, why = blocks.choose("auto", fld, _Info(1000), 3, per_snapshot=True)
    assert mode == "blocks" and why.startswith("a snapshot's vector (166 kB) does not fit")
    assert blocks.choose("blocks", fld, _Info(1000), 3, per_snapshot=True)[0] == "blocks"
    with pytest.raises(ValueError, match="traces the 3 snapshots one after the other into one "
                                         "file each: give per_snapshot=True"):
        blocks.choose("blocks", fld, _Info(1000), 3)
    with pytest.raises(ValueError, match="does not fit .* block mode writes one file per "
                                         "snapshot: give per_snapshot=True"):
        blocks.choose("auto", fld, _Info(1000), 3)
    with pytest.raises(ValueError, match="expected one of auto, seeds, blocks"):
        blocks.choose("domains", fld, _Info(1000), 1)


def test_auto_takes_blocks_where_a_worker_cannot_hold_the_field(client, tmp_path, monkeypatch,
                                                                 capsys):
    path = _abc_file(tmp_path / "abc.h5")
    t = {}
    trace_distributed(path, SEEDS[:10], tmp_path / "s.h5", client=client, max_length=2.0,
                      timings=t)
    assert t["distribute"] == "seeds" and "fits" in t["distribute_why"]
    assert "flowkit: distribute seeds: " in capsys.readouterr().err
    # workers of 200 kB each (as the client sees them; the pool gets half of that)
    monkeypatch.setattr(blocks, "worker_memory", lambda c: 200_000)
    out = trace_distributed(path, SEEDS, tmp_path / "b.h5", client=client, max_length=8.0,
                            position_dtype="float64")[0]
    got = read_lines(out)
    assert got.attrs["distribute"] == "blocks" and "does not fit" in got.attrs["distribute_why"]
    assert "flowkit: distribute blocks: the field's vector (166 kB) does not fit" in \
        capsys.readouterr().err
    _same(trace(load_field(path), SEEDS, max_length=8.0), got)


# -- faults and errors -----------------------------------------------------------------------
def test_a_worker_killed_mid_run_loses_nothing(client, tmp_path):
    """A worker SIGKILLed while it runs a block task: dask runs the task again (on the other
    worker, or the one the nanny starts), and the lines are the same."""
    path = _abc_file(tmp_path / "abc.h5", n=48)
    seeds = np.random.default_rng(3).random((400, 3)) * L
    kw = {"max_length": 30.0, "direction": "both"}
    whole = trace(load_field(path), seeds, **kw)
    result, killed = {}, []

    def job():
        result["out"] = trace_distributed(path, seeds, tmp_path / "k.h5", client=client,
                                          distribute="blocks", position_dtype="float64", **kw)

    th = threading.Thread(target=job)
    th.start()
    deadline = time.monotonic() + 120
    while not killed and time.monotonic() < deadline and th.is_alive():
        busy = [w for w, keys in client.processing().items()
                if any("flowkit-blocks" in str(k) for k in keys)]
        if busy:
            time.sleep(0.05)  # (into the task)
            pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)
            unfinished = "out" not in result  # the job was still running when the worker died
        time.sleep(0.01)
    th.join(180)
    assert killed and unfinished and not th.is_alive() and "out" in result
    _same(whole, read_lines(result["out"][0]))
    client.wait_for_workers(2, timeout=60)


def test_an_unreachable_scheduler_is_one_line_and_no_file(tmp_path, capsys):
    import dask

    path = _abc_file(tmp_path / "abc.h5")
    out = tmp_path / "x.h5"
    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        with pytest.raises(OSError, match=r"dask scheduler tcp://127.0.0.1:9 cannot be reached"):
            trace_distributed(path, SEEDS, out, scheduler="tcp://127.0.0.1:9",
                              distribute="blocks")
        rc = main(["trace", str(path), "-o", str(out), "--seeds", "random:10",
                   "--max-length", "2", "--scheduler", "tcp://127.0.0.1:9",
                   "--distribute", "blocks"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "tcp://127.0.0.1:9 cannot be reached" in err
    assert list(tmp_path.iterdir()) == [path]


def test_a_file_the_workers_cannot_read_is_one_line_and_no_file(client, tmp_path, monkeypatch,
                                                                capsys):
    """A relative path the client reads from its folder and the workers, in another, do not
    find: the error names a worker, its blocks and the file; no output appears."""
    _abc_file(tmp_path / "abc.h5")
    monkeypatch.chdir(tmp_path)
    old = client.run(os.getcwd)
    client.run(os.chdir, "/")
    try:
        rc = main(["trace", "abc.h5", "-o", "x.h5", "--seeds", "random:20", "--max-length",
                   "4", "--scheduler", client.scheduler.address, "--distribute", "blocks"])
    finally:
        for w, d in old.items():
            client.run(os.chdir, d, workers=[w])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 2  # (the line of the mode, then the error)
    line = err.splitlines()[-1]
    assert "worker tcp://" in line and "blocks 0" in line and "abc.h5" in line
    assert "FileNotFoundError" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["abc.h5"]


def test_a_block_that_fails_to_load_is_one_line_and_no_file(client, tmp_path):
    """One compressed chunk of the file garbled: the worker whose line reaches it names
    itself, the block, the brick and the file."""
    n = 56  # (above the typical speed's sample of every node: it reads only near the origin)
    path = _abc_file(tmp_path / "bad.h5", n=n)
    with h5py.File(path, "a") as h:
        a = h["vectors/U"][...]
        del h["vectors/U"]
        h.create_dataset("vectors/U", data=a, chunks=(8, 8, 8, 3), compression="gzip")
    with h5py.File(path, "r") as h:
        ds = h["vectors/U"]
        info = ds.id.get_chunk_info_by_coord((40, 40, 40, 0))
    with open(path, "r+b") as f:
        f.seek(info.byte_offset + 10)
        f.write(b"\xff" * 64)
    seeds = np.full((4, 3), 44.0 * L / (n - 1)) + np.arange(4)[:, None] * 0.01
    out = tmp_path / "x.h5"
    with pytest.raises(JobError) as e:
        trace_distributed(path, seeds, out, client=client, distribute="blocks", max_length=4.0,
                          retries=0)
    msg = str(e.value)
    brick = np.ravel_multi_index((5, 5, 5), (7, 7, 7))
    assert msg.startswith("worker tcp://") and f"(brick {brick}) of {path} failed to load" in msg
    assert "\n" not in msg and "block " in msg
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.h5"]
