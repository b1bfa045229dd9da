"""Evenly spaced streamlines: the two bounds the method promises, on the heated room and on
periodic ABC flow; too_close recorded per direction; deterministic; CLI and scenes."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from scipy.spatial import cKDTree

from flowkit import TraceOptions, read_lines, trace
from flowkit.datasets import hotroom
from flowkit.fields.analytic import ABCFlow
from flowkit.integrate import seeds
from flowkit.integrate.options import OptionsError
from flowkit.integrate.reasons import Reason
from flowkit.seeding import even, trace_spec
from flowkit.seeding.even import evenly_spaced

TWO_PI = 2 * np.pi


def _tree(points, period):
    if period is None:
        return cKDTree(points), points
    p = np.mod(points, period)
    return cKDTree(p, boxsize=period), p


def check_bounds(field, lines, dsep, dtest, stagnation, period=None, valid=0.9):
    """No two vertices of different lines closer than dtest; every point of a 10 000-point
    random sample of valid cells (speed above the stagnation threshold) within 2 dsep of a
    line.  Returns (closest distance between lines, largest sample distance) over dsep."""
    tree, pts = _tree(lines.points, period)
    line_of = lines.line_index()
    # bound 1, at the vertices: the cuts are exact, so no slack is needed there ...
    pairs = tree.query_pairs(dtest * (1 - 1e-9), output_type="ndarray")
    cross = pairs[line_of[pairs[:, 0]] != line_of[pairs[:, 1]]]
    assert len(cross) == 0, f"{len(cross)} vertex pairs of different lines closer than dtest"
    # ... and along the segments within one vertex spacing: points every 1/4 of a segment
    seg = np.linalg.norm(np.diff(lines.points, axis=0), axis=1)
    inner = np.ones(len(seg), bool)
    inner[lines.offsets[1:-1] - 1] = False  # no segment joins two lines
    h = seg[inner].max()
    a, b = lines.points[:-1][inner], lines.points[1:][inner]
    fine = np.concatenate([a + f * (b - a) for f in (0.25, 0.5, 0.75)])
    fine_line = np.tile(line_of[:-1][inner], 3)
    ft, _ = _tree(fine, period)
    near = ft.query_ball_point(pts, dtest - h)
    for i, js in enumerate(near):
        assert all(fine_line[j] == line_of[i] for j in js), "segments closer than dtest - h"
    # bound 2: coverage of the valid cells
    q = seeds.random_in(field, 10_000, seed=11)
    v, status = field.sample(q)
    ok = (status == 0) & (np.linalg.norm(v, axis=1) > stagnation)
    assert ok.mean() > valid
    d, _ = tree.query(np.mod(q[ok], period) if period is not None else q[ok])
    assert d.max() <= 2 * dsep, f"a valid point {d.max() / dsep:.2f} dsep from every line"
    return d.max() / dsep


@pytest.fixture(scope="module")
def room():
    return hotroom()


@pytest.fixture(scope="module")
def room_lines(room):
    dsep = 15.0 / 15  # a fifteenth of the room's diagonal
    return dsep, evenly_spaced(room, dsep, direction="both", max_length=12.0, stagnation=1e-4,
                               seed=3)


def test_heated_room_bounds(room, room_lines):
    dsep, lines = room_lines
    assert len(lines) > 40
    worst = check_bounds(room, lines, dsep, dsep / 2, 1e-4)
    assert worst < 1.6  # the lattice of dsep / 2 gives about 1.5 dsep in the worst case


def test_abc_periodic_bounds():
    field = ABCFlow().to_field(24)  # periodic on all three axes
    assert field.grid.periodic == (True, True, True)
    dsep = TWO_PI * np.sqrt(3) / 12
    lines = evenly_spaced(field, dsep, 0.4 * dsep, direction="both", max_length=20.0, seed=5)
    assert len(lines) > 15
    # without the minimum image (a seam between lines), the bounds would fail across the seam
    check_bounds(field, lines, dsep, 0.4 * dsep, 1e-6, period=TWO_PI)


def test_holes_and_still_air_get_no_seeds_and_the_rest_is_covered(room, monkeypatch):
    """A NaN hole through the room and a corner of nearly still air: every point elsewhere is
    within 2 dsep of a line, and the lattice, sampled only where a pick falls (the first pick)
    or still far from the lines (later ones), gives the same lines as a lattice whose unusable
    points are dropped before any pick."""
    v = room.vector.copy()
    nx, ny, nz, _ = v.shape
    v[nx // 4:nx // 2, :, nz // 4:nz // 2] = np.nan
    v[3 * nx // 4:, :ny // 3, 3 * nz // 4:] *= 1e-7
    field = dataclasses.replace(room, vector=v)
    dsep = 0.8

    def run():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return evenly_spaced(field, dsep, direction="both", max_length=12.0,
                                 stagnation=1e-4)

    lines = run()
    assert len(lines) > 100
    check_bounds(field, lines, dsep, dsep / 2, 1e-4, valid=0.75)
    init = even._Lattice.__init__

    def drop_unusable(self, seeder, rng):
        init(self, seeder, rng)
        self.state[~seeder._usable(self.pts)] = 0

    monkeypatch.setattr(even._Lattice, "__init__", drop_unusable)
    eager = run()
    assert np.array_equal(lines.offsets, eager.offsets)
    assert np.array_equal(lines.points, eager.points)


def test_too_close_recorded_per_direction_and_cut_exactly(room, room_lines):
    dsep, lines = room_lines
    fwd, bwd = lines.line_data["reason"], lines.line_data["reason_backward"]
    assert (fwd == Reason.TOO_CLOSE).sum() > len(lines) // 3
    assert (bwd == Reason.TOO_CLOSE).sum() > len(lines) // 3
    assert set(np.unique(fwd)) != {Reason.TOO_CLOSE}  # lines also end for their own reasons
    # a too_close end was cut where it came within dtest of another line (exactly dtest from
    # one of its vertices) or of itself more than 2 dsep of arc length away (within dtest and
    # one vertex spacing h of its own earlier vertices: the other half may have been cut since)
    tree = cKDTree(lines.points)
    line_of = lines.line_index()
    seg = np.linalg.norm(np.diff(lines.points, axis=0), axis=1)
    h = seg.max()
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    exact = 0
    ends = np.flatnonzero(fwd == Reason.TOO_CLOSE)
    for i in ends:
        e = lines.offsets[i + 1] - 1
        near = np.array(tree.query_ball_point(lines.points[e], 0.5 * dsep + h))
        other = near[line_of[near] != i]
        own = near[(line_of[near] == i) & (np.abs(arc[e] - arc[near]) > 2 * dsep)]
        d = np.linalg.norm(lines.points[other] - lines.points[e], axis=1)
        exact += bool(len(d) and abs(d.min() - 0.5 * dsep) < 1e-9 * dsep)
        assert len(d) or len(own), f"line {i} cut with nothing near its end"
    assert exact > len(ends) // 2


def test_deterministic_and_seed_dependent(room):
    kw = {"direction": "both", "max_length": 6.0, "stagnation": 1e-4,
          "attributes": ("speed", "time")}
    a = evenly_spaced(room, 1.5, seed=1, **kw)
    b = evenly_spaced(room, 1.5, seed=1, **kw)
    c = evenly_spaced(room, 1.5, seed=2, **kw)
    assert a.equals(b)
    assert not (len(a) == len(c) and np.array_equal(a.points, c.points))
    assert set(a.point_data) == {"speed", "time"}
    # attributes as the tracer computes them on the same vertices
    np.testing.assert_allclose(a.point_data["speed"],
                               np.linalg.norm(room.sample(a.points)[0], axis=1))
    t = a.point_data["time"]
    seed_rows = np.flatnonzero(t == 0.0)
    assert len(seed_rows) == len(a)  # one vertex per line at time 0: its seed
    np.testing.assert_array_equal(a.points[seed_rows], a.line_data["seed"])


def test_options_refused(room):
    with pytest.raises(OptionsError, match="dtest must lie in"):
        evenly_spaced(room, 1.0, 1.0)
    with pytest.raises(OptionsError, match="count"):
        evenly_spaced(room, 1.0, count=20)
    with pytest.raises(KeyError, match="unknown attribute 'nope'"):
        evenly_spaced(room, 1.0, attributes=("nope",))


def test_a_dsep_as_wide_as_the_domain_is_said(room):
    """A fraction of the diagonal can exceed a thin domain's width: said, naming the axis."""
    thin = ABCFlow().to_field(shape=(5, 5, 60), bounds=[[0, 0.4], [0, 0.4], [0, 12]])
    with pytest.warns(UserWarning, match=r"dsep = 0\.6 is not smaller than the domain along x "
                                         r"\(0\.4\).*diagonal 12\.01"):
        evenly_spaced(thin, 0.6, max_length=1.0, max_lines=3)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        evenly_spaced(thin, 0.2, max_length=1.0, max_lines=3)


def test_cli_says_it_in_one_line(tmp_path, capsys):
    from flowkit.cli import main

    rc = main(["trace", "datasets/hotroom.h5", "-o", str(tmp_path / "wide.h5"), "--seeds",
               "even:1/2d", "--max-length", "2", "--quiet"])
    err = capsys.readouterr().err
    assert rc == 0
    assert "flowkit: warning: " in err and "along y (5)" in err and "UserWarning" not in err


def test_stiff_methods_place_vertices_at_their_steps(room):
    lines = evenly_spaced(room, 2.5, method="auto", direction="both", max_length=3.0,
                          stagnation=1e-4)
    assert len(lines) > 3 and "ros34pw2" in lines.line_data
    assert lines.attrs["method"] == "auto"


def test_trace_spec_and_forward_direction(room):
    lines = trace_spec(room, "even:1/10d:0.3:4", TraceOptions(max_length=5.0, stagnation=1e-4))
    assert lines.attrs["seeding"] == "even" and lines.attrs["dsep"] == pytest.approx(1.5)
    assert lines.attrs["dtest"] == 0.3 and "reason_backward" not in lines.line_data
    np.testing.assert_array_equal(lines.points[lines.offsets[:-1]], lines.line_data["seed"])
    plain = trace_spec(room, "line:1,1,1:9,1,9:5", max_length=2.0)
    assert plain.equals(trace(room, seeds.line([1, 1, 1], [9, 1, 9], 5), max_length=2.0))


def test_cli_even_and_prune(tmp_path, capsys):
    from flowkit.cli import main
    from flowkit.cli.info import describe

    out = tmp_path / "even.h5"
    rc = main(["trace", "datasets/hotroom.h5", "-o", str(out), "--seeds", "even:1/8d::2",
               "--max-length", "6", "--quiet"])
    assert rc == 0
    lines = read_lines(out)
    assert lines.attrs["direction"] == "both" and lines.attrs["seeds"] == "even:1/8d::2"
    assert (lines.line_data["reason_backward"] == Reason.TOO_CLOSE).any()
    text = describe(out)
    assert "too_close" in text.split("reasons backward:")[1].splitlines()[0]
    # pruning: what was removed is in the file
    pr = tmp_path / "pruned.h5"
    assert main(["trace", "datasets/hotroom.h5", "-o", str(pr), "--seeds", "box:3,1,3:7,2,7:4",
                 "--max-length", "4", "--direction", "both", "--prune", "0.3:0.7",
                 "--quiet"]) == 0
    p = read_lines(pr)
    gone = p.attrs["pruned_seed_id"]
    assert len(gone) > 0 and len(p) + len(gone) == 64
    assert not set(gone) & set(p.line_data["seed_id"].tolist())
    assert set(p.attrs["pruned_by"].tolist()) <= set(p.line_data["seed_id"].tolist())
    assert np.all(p.attrs["pruned_covered"] >= 0.7)
    assert "pruned_seed_id" in describe(pr)


def test_progress_counts_the_lines_only_when_asked_or_on_a_terminal(room, capsys):
    lines = evenly_spaced(room, 2.0, direction="both", max_length=6.0, progress=True)
    err = capsys.readouterr().err
    assert "evenly spaced" in err and f"{len(lines)}line" in err
    evenly_spaced(room, 2.0, direction="both", max_length=6.0)  # stderr is not a terminal
    evenly_spaced(room, 2.0, direction="both", max_length=6.0, progress=False)
    assert "evenly spaced" not in capsys.readouterr().err


def test_opencl_grows_the_lines_in_resumed_passes_too(room):
    """The kernel passes resume on the OpenCL backend (PoCL in CI) as on numba: a pass of 16
    vertices per half-line, then 32, 64..., each continuing where the last stopped."""
    pytest.importorskip("pyopencl")
    dsep = 1.0
    kw = {"direction": "both", "max_length": 8.0, "stagnation": 1e-4}
    cl = evenly_spaced(room, dsep, backend="opencl", **kw)
    nb = evenly_spaced(room, dsep, **kw)
    assert cl.attrs["kernel_path"] == "opencl"
    assert abs(len(cl) - len(nb)) <= 0.05 * len(nb)
    check_bounds(room, cl, dsep, dsep / 2, 1e-4)
