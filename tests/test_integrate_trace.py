"""trace(): exact termination, every reason code, directions, resampling, continuation of lines
that outgrow their vertex budget, periodic wrap, threads, and the file/CLI paths."""

import numba
import numpy as np
import pytest

from flowkit import Field, Grid, TraceOptions, read_lines, trace, trace_to_file
from flowkit.cli import main
from flowkit.fields.analytic import ABCFlow, LinearField, SolidBodyRotation, UniformFlow
from flowkit.integrate.reasons import Reason
from flowkit.integrate.trace import EmptyResultError

BOX = [[-3, 3], [-3, 3], [-1, 1]]


@pytest.fixture(scope="module")
def rotation():
    # 13 x 13 x 5 nodes: many cells, and the linear field is still exact under trilinear
    return SolidBodyRotation(omega=1.0).to_field(shape=(13, 13, 5), bounds=BOX)


@pytest.fixture(scope="module")
def abc():
    return ABCFlow().to_field(24, bounds=[[0, 2 * np.pi]] * 3, periodic=True)


def _ends(lines):
    return lines.points[lines.offsets[1:] - 1]


# -- exact termination ----------------------------------------------------------------------------
@pytest.mark.parametrize("aware", [True, False])
@pytest.mark.parametrize("method", ["dopri5", "cashkarp", "bs23", "rk4"])
def test_boundary_end_lies_on_the_boundary_plane(aware, method):
    # a spiral source pushes every line out through a side of the box
    af = LinearField.spiral(omega=1.0, rate=0.3)
    f = af.to_field(shape=(9, 9, 3), bounds=BOX)
    rng = np.random.default_rng(2)
    seeds = np.c_[rng.uniform(-1, 1, (30, 2)), rng.uniform(-0.5, 0.5, 30)]
    lines = trace(f, seeds, method=method, rtol=1e-8, cell_aware=aware, max_time=100.0)
    assert np.all(lines.line_data["reason"] == Reason.OUT_OF_DOMAIN)
    end = _ends(lines)
    dist = np.min(np.abs(np.abs(end[:, :2]) - 3.0), axis=1)
    assert dist.max() < 1e-9
    assert np.all(np.abs(end[:, :2]) <= 3.0)  # on it, never beyond
    # and the end point is where the exact line crosses that plane (within the tolerance)
    r_end = np.linalg.norm(end[:, :2], axis=1)
    assert np.all(np.isfinite(r_end))


@pytest.mark.parametrize("parameter", ["time", "arc_length"])
@pytest.mark.parametrize("aware", [True, False])
def test_max_length_and_max_time_are_met_exactly(rotation, parameter, aware):
    seeds = np.array([[1.0, 0.0, 0.0], [0.5, 0.5, 0.3], [-1.5, 0.2, -0.4]])
    r = np.linalg.norm(seeds[:, :2], axis=1)
    rot = SolidBodyRotation(omega=1.0)
    L = 2.0
    lines = trace(rotation, seeds, max_length=L, rtol=1e-10, atol=1e-10, parameter=parameter,
                  cell_aware=aware, attributes=("time", "arc_length"))
    assert np.all(lines.line_data["reason"] == Reason.MAX_LENGTH)
    s_end = lines.point_data["arc_length"][lines.offsets[1:] - 1]
    assert np.abs(s_end - L).max() < 1e-9
    t_exact = L / r  # speed is omega * r
    assert np.allclose(lines.point_data["time"][lines.offsets[1:] - 1], t_exact, rtol=1e-8)
    exact = np.array([rot.trajectory(s[None], t)[0] for s, t in zip(seeds, t_exact)])
    assert np.abs(_ends(lines) - exact).max() < 1e-8

    T = 1.7
    lines = trace(rotation, seeds, max_time=T, rtol=1e-10, atol=1e-10, parameter=parameter,
                  cell_aware=aware, attributes=("time",))
    assert np.all(lines.line_data["reason"] == Reason.MAX_TIME)
    assert np.abs(lines.point_data["time"][lines.offsets[1:] - 1] - T).max() < 1e-9
    assert np.abs(_ends(lines) - rot.trajectory(seeds, T)).max() < 1e-8


# -- every reason code ----------------------------------------------------------------------------
def _uniform(shape=(6, 5, 4), U=(1.0, 0.2, 0.0), nan_box=None):
    g = Grid.regular((0, 0, 0), 0.2, shape)
    v = np.broadcast_to(np.asarray(U, float), g.shape + (3,)).copy()
    if nan_box is not None:
        v[nan_box] = np.nan
    return Field(g, v)


@pytest.mark.parametrize("aware", [True, False])
def test_every_reason_code_from_a_purpose_built_case(aware):
    seen = set()

    def check(lines, reason, n_vertices=None):
        assert lines.line_data["reason"].tolist() == [reason], lines.line_data
        assert np.all(np.isfinite(lines.points))
        if n_vertices is not None:
            assert lines.n_points == n_vertices
        seen.add(reason)

    kw = {"cell_aware": aware, "empty": "ignore"}  # (some cases end at their seed)
    f = _uniform()
    check(trace(f, [0.1, 0.1, 0.1], **kw), Reason.OUT_OF_DOMAIN)
    check(trace(f, [0.1, 0.1, 0.1], max_length=0.3, **kw), Reason.MAX_LENGTH)
    check(trace(f, [0.1, 0.1, 0.1], max_time=0.3, **kw), Reason.MAX_TIME)
    check(trace(f, [0.1, 0.1, 0.1], max_steps=3, step=0.01, max_step=0.01, **kw),
          Reason.MAX_STEPS, 4)
    sink = LinearField.sink(rate=1.0, centre=(0.5, 0.4, 0.3)).to_field(shape=(6, 5, 4),
                                                                       bounds=[[0, 1], [0, 0.8], [0, 0.6]])
    check(trace(sink, [0.1, 0.1, 0.1], max_time=1e4, **kw), Reason.STAGNATION)
    rot = SolidBodyRotation().to_field(shape=(5, 5, 3), bounds=BOX)
    check(trace(rot, [1.0, 0.0, 0.0], step=1.0, min_step=0.5, rtol=1e-12, max_time=5, **kw),
          Reason.STEP_UNDERFLOW)
    holed = _uniform(nan_box=(slice(4, None), slice(None), slice(None)))
    lines = trace(holed, [0.1, 0.1, 0.1], **kw)
    check(lines, Reason.NAN_FIELD)
    assert lines.points[-1, 0] <= 0.6 + 1e-12  # stops before the NaN cells (x >= 0.6)
    if aware:  # cell-aware: exactly on the face of the first NaN cell
        assert abs(lines.points[-1, 0] - 0.6) < 1e-12
    check(trace(f, [5.0, 0.1, 0.1], **kw), Reason.SEED_OUTSIDE, 0)
    check(trace(holed, [0.9, 0.1, 0.1], **kw), Reason.SEED_OUTSIDE, 0)
    # LEFT_TIME_RANGE belongs to pathlines through snapshot series, TOO_CLOSE to evenly spaced
    # seeding (flowkit.seeding.even), not to the kernel
    assert seen == set(Reason) - {Reason.LEFT_TIME_RANGE, Reason.TOO_CLOSE}


def test_seed_on_the_boundary_moving_out_is_one_vertex():
    f = _uniform()
    for seed, direction in [([0.0, 0.4, 0.4], "backward"), ([1.0, 0.4, 0.4], "forward")]:
        for aware in (True, False):
            with pytest.raises(EmptyResultError, match="no line has two vertices .*out_of_domain 1"):
                trace(f, seed, direction=direction, cell_aware=aware)
            lines = trace(f, seed, direction=direction, cell_aware=aware, empty="ignore")
            assert lines.lengths.tolist() == [1]
            assert lines.line_data["reason"].tolist() == [Reason.OUT_OF_DOMAIN]


# -- directions -----------------------------------------------------------------------------------
def test_both_directions_make_one_line_through_the_seed(rotation):
    seeds = np.array([[1.0, 0.0, 0.0], [0.0, -2.0, 0.5]])
    opts = TraceOptions(max_time=2.0, rtol=1e-9, attributes=("time", "arc_length"))
    both = trace(rotation, seeds, opts.replace(direction="both"))
    fwd = trace(rotation, seeds, opts)
    bwd = trace(rotation, seeds, opts.replace(direction="backward"))
    for i in range(2):
        t = both.line_attribute("time", i)
        s = both.line_attribute("arc_length", i)
        assert np.all(np.diff(t) > 0) and np.all(np.diff(s) > 0)
        assert t[0] == pytest.approx(-2.0, abs=1e-9) and t[-1] == pytest.approx(2.0, abs=1e-9)
        assert np.count_nonzero(t == 0) == 1
        n_b = bwd.lengths[i]
        assert both.lengths[i] == n_b + fwd.lengths[i] - 1
        np.testing.assert_array_equal(both.line_points(i)[n_b - 1:], fwd.line_points(i))
        np.testing.assert_array_equal(both.line_points(i)[:n_b], bwd.line_points(i)[::-1])
        assert np.all(bwd.line_attribute("time", i)[1:] < 0)
    exact = SolidBodyRotation().trajectory(seeds, -2.0)
    assert np.abs(both.points[both.offsets[:-1]] - exact).max() < 1e-7
    assert both.line_data["reason_backward"].tolist() == [Reason.MAX_TIME] * 2
    assert np.array_equal(both.line_data["n_accepted"],
                          fwd.line_data["n_accepted"] + bwd.line_data["n_accepted"])


# -- vertices: resampling, budget continuation ---------------------------------------------------
def test_resampling_to_a_fixed_arc_length_spacing(rotation):
    seeds = np.array([[1.0, 0.0, 0.0], [2.0, 0.5, -0.2]])
    lines = trace(rotation, seeds, max_length=3.0, spacing=0.1, rtol=1e-10, atol=1e-10,
                  attributes=("arc_length", "time"))
    rot = SolidBodyRotation()
    r = np.linalg.norm(seeds[:, :2], axis=1)
    for i in range(2):
        s = lines.line_attribute("arc_length", i)
        np.testing.assert_allclose(s, np.linspace(0, 3.0, 31), atol=1e-9)
        t = lines.line_attribute("time", i)
        np.testing.assert_allclose(t, s / r[i], rtol=1e-8)
        exact = rot.trajectory(seeds[i:i + 1], s / r[i])[:, 0]
        assert np.abs(lines.line_points(i) - exact).max() < 1e-8


@pytest.mark.parametrize("direction", ["forward", "both"])
def test_resampling_to_a_fixed_count(rotation, direction):
    seeds = np.array([[1.0, 0.0, 0.0], [0.3, 2.5, 0.0]])  # the second leaves the box early
    lines = trace(rotation, seeds, max_length=4.0, count=17, direction=direction,
                  attributes=("arc_length",))
    assert lines.lengths.tolist() == [17, 17]
    for i in range(2):
        ds = np.diff(lines.line_attribute("arc_length", i))
        np.testing.assert_allclose(ds, ds.mean(), rtol=1e-9)


@pytest.mark.parametrize("extra", [{}, {"spacing": 0.05}, {"count": 40}, {"direction": "both"}])
def test_lines_outgrowing_their_budget_continue_unchanged(abc, extra):
    rng = np.random.default_rng(3)
    seeds = rng.uniform(0, 2 * np.pi, (25, 3))
    opts = TraceOptions(max_length=6.0, attributes=("time", "arc_length"), **extra)
    whole = trace(abc, seeds, opts)
    pieces = trace(abc, seeds, opts.replace(budget=3))
    assert whole.lengths.min() > 6  # every line needed several passes
    assert pieces.equals(whole)  # bit for bit


@pytest.mark.parametrize("method", ["rk4", "dopri5"])
def test_plain_lines_keep_their_cell_through_a_suspension(method):
    """Not cell-aware, a line keeps its cached cell from pass to pass: on a periodic axis whose
    origin is not 0 a cell found again can differ from it in the last bit of its faces (the
    rounding of the wrap), and the pieces would drift from the whole line."""
    L = 2 * np.pi
    f = ABCFlow().to_field(24, bounds=[[-1.3, L - 1.3], [0.7, L + 0.7], [0.0, L]])
    seeds = np.random.default_rng(5).uniform(0.0, L, (40, 3))
    opts = TraceOptions(method=method, cell_aware=False, max_length=8.0,
                        step=0.1 if method == "rk4" else None)
    whole = trace(f, seeds, opts)
    pieces = trace(f, seeds, opts.replace(budget=4))
    assert f.grid.periodic == (True, True, True) and whole.lengths.min() > 8
    assert pieces.equals(whole)  # bit for bit


# -- periodic domains, threads ------------------------------------------------------------------
@pytest.mark.parametrize("aware,cross", [(True, False), (True, True), (False, False)])
def test_periodic_wrap_gives_continuous_exact_lines(aware, cross):
    U = np.array([1.0, -0.7, 0.3])
    g = Grid.regular((0, 0, 0), 1 / 8, (8, 8, 8), periodic=(True, True, True))
    f = Field(g, np.broadcast_to(U, g.shape + (3,)))
    seeds = np.array([[0.1, 0.2, 0.3], [0.999, 0.0, 0.5]])
    lines = trace(f, seeds, max_time=5.0, cell_aware=aware, cross_faces=cross,
                  attributes=("time",))
    assert np.all(lines.line_data["reason"] == Reason.MAX_TIME)
    t = lines.point_data["time"]
    exact = seeds[lines.line_index()] + t[:, None] * U
    assert np.abs(lines.points - exact).max() < 1e-10  # unwrapped, continuous
    n_acc = lines.line_data["n_accepted"]
    if aware and not cross:  # one step per cell crossed: 5 periods x 8 cells x (1 + 0.7 + 0.3)
        assert n_acc.min() >= 5 * 8 * 2 - 3
    elif aware:  # a uniform field has no kinks: steps cross faces, wrap included
        assert n_acc.max() < 5 * 8 * 2 / 4 and lines.line_data["n_crossing"].min() > 0


def test_identical_output_for_one_and_two_threads(abc):
    rng = np.random.default_rng(4)
    seeds = rng.uniform(0, 2 * np.pi, (64, 3))
    before = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = trace(abc, seeds, max_length=5.0, direction="both", attributes=("speed",))
        numba.set_num_threads(2)
        two = trace(abc, seeds, max_length=5.0, direction="both", attributes=("speed",))
    finally:
        numba.set_num_threads(before)
    assert one.equals(two)


def test_cell_aware_steps_end_on_faces_and_match_the_reference(abc):
    rng = np.random.default_rng(5)
    seeds = rng.uniform(0, 2 * np.pi, (20, 3))
    ref = trace(abc, seeds, method="dop853", rtol=1e-13, atol=1e-13, max_length=5.0)
    on = trace(abc, seeds, rtol=1e-9, atol=1e-9, max_length=5.0, cell_aware=True)
    off = trace(abc, seeds, rtol=1e-9, atol=1e-9, max_length=5.0, cell_aware=False)
    e_on = np.linalg.norm(_ends(on) - _ends(ref), axis=1)
    e_off = np.linalg.norm(_ends(off) - _ends(ref), axis=1)
    assert np.median(e_on) < 1e-8 and np.median(e_on) < np.median(e_off)
    assert on.line_data["n_rejected"].sum() < off.line_data["n_rejected"].sum()
    # at a loose tolerance the cell limits the steps: the vertices then lie on grid planes
    loose = trace(abc, seeds, rtol=1e-5, max_length=5.0, cell_aware=True, cross_faces=False)
    h = 2 * np.pi / 24
    frac = np.abs(loose.points / h - np.round(loose.points / h)).min(axis=1)
    assert np.mean(frac < 1e-9) > 0.9


def test_cell_aware_fixed_steps_stay_in_their_cell(abc):
    """A fixed step longer than a cell is cut at the faces like an adaptive one: RK4 then takes
    one step per cell, each on that cell's polynomial (before, its stages extended the
    polynomial a whole step beyond the cell: errors of order 1)."""
    rng = np.random.default_rng(5)
    seeds = rng.uniform(0, 2 * np.pi, (20, 3))
    ref = trace(abc, seeds, method="dop853", rtol=1e-13, atol=1e-13, max_length=5.0)
    long = trace(abc, seeds, method="rk4", step=10.0, max_length=5.0, cell_aware=True)
    e = np.linalg.norm(_ends(long) - _ends(ref), axis=1)
    assert np.median(e) < 1e-4  # fourth order over ~0.26-long cells
    h = 2 * np.pi / 24
    frac = np.abs(long.points / h - np.round(long.points / h)).min(axis=1)
    assert np.mean(frac < 1e-9) > 0.9  # the vertices lie on grid planes


# -- files ----------------------------------------------------------------------------------------
def test_trace_to_file_streams_batches_and_reads_back(tmp_path, abc):
    rng = np.random.default_rng(6)
    seeds = rng.uniform(0, 2 * np.pi, (30, 3))
    opts = TraceOptions(max_length=3.0, attributes=("speed", "time"))
    lines = trace(abc, seeds, opts)
    path = trace_to_file(abc, seeds, tmp_path / "l.h5", opts, batch_seeds=7,
                         position_dtype="float64")
    back = read_lines(path)
    assert np.array_equal(back.line_data["seed_id"], np.arange(30))
    assert back.equals(lines)


def test_trace_to_file_writing_behind_the_next_batch(tmp_path, abc, monkeypatch):
    """write_behind: each batch written in a thread while the next is traced; the same file,
    and none where a later batch fails (its append finished before the file is dropped)."""
    from flowkit.integrate import trace as T

    seeds = np.random.default_rng(6).uniform(0, 2 * np.pi, (30, 3))
    opts = TraceOptions(max_length=3.0, attributes=("speed", "time"))
    path = trace_to_file(abc, seeds, tmp_path / "l.h5", opts, batch_seeds=7,
                         position_dtype="float64", write_behind=True)
    assert read_lines(path).equals(trace(abc, seeds, opts))
    real = T._trace_batch

    def fails_at_the_third(field, setup, seeds, opts, id0):
        if id0 == 14:
            raise RuntimeError("batch 3")
        return real(field, setup, seeds, opts, id0)

    monkeypatch.setattr(T, "_trace_batch", fails_at_the_third)
    with pytest.raises(RuntimeError, match="batch 3"):
        trace_to_file(abc, seeds, tmp_path / "x.h5", opts, batch_seeds=7, write_behind=True)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["l.h5"]


def test_cli_trace_writes_lines(tmp_path, capsys):
    f = UniformFlow(U=(1.0, 0.5, 0.0)).to_field(shape=(5, 5, 5), bounds=[[0, 1]] * 3)
    np.savez(tmp_path / "f.npz", x=f.grid.x, y=f.grid.y, z=f.grid.z, U=f.vector,
             T=f.scalars["T"])
    out = tmp_path / "lines.h5"
    rc = main(["trace", str(tmp_path / "f.npz"), "-o", str(out), "--seeds",
               "line:0.1,0.1,0.5:0.1,0.9,0.5:5", "--attributes", "T,arc_length",
               "--max-length", "0.5", "--direction", "both", "--quiet"])
    assert rc == 0
    back = read_lines(out)
    assert len(back) == 5 and set(back.point_data) == {"T", "arc_length"}
    assert main(["trace", str(tmp_path / "f.npz"), "-o", str(out), "--attributes", "nope"]) == 2
    assert "unknown attribute 'nope'" in capsys.readouterr().err


def test_typical_speed_is_kept_with_the_vector_array_it_was_sampled_from():
    """The sample behind the default stagnation threshold and steps is computed once per vector
    array: a second trace reuses it, a field given a new array samples again."""
    from flowkit.integrate import trace as T

    f = _uniform(U=(2.0, 0.0, 0.0))
    assert T.typical_speed(f) == 2.0
    f.vector[...] = 5.0  # changed in place: not noticed (documented)
    assert T.typical_speed(f) == 2.0
    f.vector = np.full_like(f.vector, 3.0)  # a new array
    assert T.typical_speed(f) == pytest.approx(np.sqrt(27.0), rel=1e-15)
