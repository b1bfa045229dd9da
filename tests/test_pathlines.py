"""Pathlines through time-dependent fields: exact references, termination, memory, real data."""

import gc
import weakref

import numpy as np
import pytest

from flowkit.datasets import hotroom_path
from flowkit.fields.analytic import UnsteadyRotation
from flowkit.fields.writers import save_field
from flowkit.integrate import pathlines as P
from flowkit.integrate.options import OptionsError
from flowkit.integrate.reasons import Reason

FLOW = UnsteadyRotation(omega0=1.0, omega1=0.5)
TIMES = np.linspace(0.0, 2.0, 5)
# rotation is linear in space and its rate linear in time: trilinear-in-space, linear-in-time
# interpolation of the snapshots reproduces the field exactly, so only the integrator errs
SERIES = FLOW.to_series(TIMES, shape=5, bounds=[[-2, 2], [-2, 2], [-1, 1]])
EXTENT = 4.0


def _max_error(lines, seeds, release):
    err = 0.0
    for i in range(len(lines)):
        t = lines.line_attribute("time", i)
        exact = FLOW.trajectory(seeds[i:i + 1], t, release[i])[:, 0]
        err = max(err, np.abs(lines.line_points(i) - exact).max())
    return err


@pytest.mark.parametrize("rtol", [1e-6, 1e-9])
@pytest.mark.parametrize("direction", ["forward", "backward"])
def test_unsteady_rotation_matches_exact_trajectory(rtol, direction):
    rng = np.random.default_rng(1)
    seeds = rng.uniform(-1.0, 1.0, (40, 3)) * [1, 1, 0.5]
    release = rng.uniform(0.5, 1.5, 40)
    lines = P.pathlines(SERIES, seeds, release, rtol=rtol, max_time=0.5, direction=direction)
    tol = rtol * EXTENT  # atol defaults to rtol times the largest extent
    assert _max_error(lines, seeds, release) < 10 * tol
    assert np.all(lines.line_data["reason"] == Reason.MAX_TIME)
    ends = lines.point_data["time"][lines.offsets[1:] - 1]
    sign = 1 if direction == "forward" else -1
    np.testing.assert_allclose(ends, release + sign * 0.5, rtol=0, atol=1e-12)
    # the time attribute is physical time, monotone along each line, starting at the release
    np.testing.assert_array_equal(lines.point_data["time"][lines.offsets[:-1]], release)
    for i in range(len(lines)):
        assert np.all(sign * np.diff(lines.line_attribute("time", i)) > 0)


def test_reasons_boundary_time_range_and_seed_outside():
    seeds = np.array([[1.8, 1.5, 0.0],    # radius 2.34 in a box of half-width 2: leaves it
                      [0.3, 0.2, 0.1],    # stays inside, runs out of snapshots at t = 2
                      [0.3, 0.2, 0.1],    # released after the last snapshot
                      [5.0, 0.0, 0.0]])   # outside the domain
    release = np.array([0.0, 1.0, 2.5, 0.0])
    lines = P.pathlines(SERIES, seeds, release, rtol=1e-9, attributes=("arc_length", "speed"))
    reasons = lines.line_data["reason"].tolist()
    assert reasons == [Reason.OUT_OF_DOMAIN, Reason.LEFT_TIME_RANGE, Reason.SEED_OUTSIDE,
                       Reason.SEED_OUTSIDE]
    assert lines.lengths[2] == 0 and lines.lengths[3] == 0
    end = lines.line_points(0)[-1]
    assert np.isclose(np.abs(end[:2]).max(), 2.0, rtol=0, atol=1e-9)  # ON the boundary
    exact = FLOW.trajectory(seeds[:1], lines.line_attribute("time", 0)[-1], 0.0)[0]
    assert np.abs(end - exact).max() < 10 * 1e-9 * EXTENT
    assert lines.line_attribute("time", 1)[-1] == 2.0
    # speed is the time-interpolated field speed, arc length its integral
    for i in (0, 1):
        t = lines.line_attribute("time", i)
        r = np.linalg.norm(lines.line_points(i)[:, :2], axis=1)
        rate = FLOW.omega0 + FLOW.omega1 * t
        np.testing.assert_allclose(lines.line_attribute("speed", i), rate * r, rtol=1e-9, atol=1e-9)
        r0 = np.linalg.norm(seeds[i, :2])
        t0 = release[i]
        exact_s = r0 * (FLOW.omega0 * (t - t0) + 0.5 * FLOW.omega1 * (t * t - t0 * t0))
        np.testing.assert_allclose(lines.line_attribute("arc_length", i), exact_s, atol=1e-7)


@pytest.mark.parametrize("direction", ["forward", "backward"])
def test_max_length_met_exactly(direction):
    """Both ways: the arc length is signed like the time (negative backward), its limit met on
    the dense output."""
    seeds = np.array([[1.0, 0.0, 0.0]])
    back = direction == "backward"
    lines = P.pathlines(SERIES, seeds, 2.0 if back else 0.0, rtol=1e-9, max_length=1.5,
                        direction=direction, attributes=("arc_length",))
    assert lines.line_data["reason"][0] == Reason.MAX_LENGTH
    assert abs(abs(lines.point_data["arc_length"][-1]) - 1.5) < 1e-12
    # radius 1: the arc length is the angle turned
    t = lines.point_data["time"][-1]
    turned = FLOW.omega0 * t + 0.5 * FLOW.omega1 * t * t
    assert abs(abs(turned - (FLOW.omega0 * 2 + 2 * FLOW.omega1 if back else 0.0)) - 1.5) < 1e-7


def test_at_most_two_snapshots_in_memory(tmp_path, monkeypatch):
    paths = []
    for t, f in SERIES:
        paths.append((t, save_field(f, tmp_path / f"rot_{t:.2f}.npz")))
    alive, peak = [], [0]
    load = P._load

    def counting_load(src, vector, opts):
        gc.collect()
        live = [r for r in alive if r() is not None]
        peak[0] = max(peak[0], len(live) + 1)
        f = load(src, vector, opts)
        alive.append(weakref.ref(f))
        return f

    monkeypatch.setattr(P, "_load", counting_load)
    seeds = np.array([[0.5, 0.0, 0.0], [0.0, 0.7, 0.2]])
    lines = P.pathlines(paths, seeds, 0.0, rtol=1e-8)
    assert len(alive) == len(SERIES)  # each snapshot loaded once
    assert peak[0] == 2
    assert np.all(lines.line_data["reason"] == Reason.LEFT_TIME_RANGE)
    assert _max_error(lines, seeds, np.zeros(2)) < 10 * 1e-8 * EXTENT


@pytest.mark.parametrize("step", [0.02, 0.01])
def test_fixed_step_rk4_converges_at_fourth_order(step):
    """rk4 at a fixed step (Parcels' default scheme): the error against the exact trajectory is
    O(h^4) (the interpolation is exact here), the last step clipped to each interval's end."""
    rng = np.random.default_rng(4)
    seeds = np.c_[rng.uniform(-0.8, 0.8, (6, 2)), rng.uniform(-0.5, 0.5, 6)]
    release = np.zeros(6)
    lines = P.pathlines(SERIES, seeds, release, method="rk4", step=step)
    err = _max_error(lines, seeds, release)
    coarse = _max_error(P.pathlines(SERIES, seeds, release, method="rk4", step=2 * step), seeds,
                        release)
    assert 12.0 < coarse / err < 20.0, (coarse, err)  # 2^4
    assert np.all(lines.line_data["reason"] == Reason.LEFT_TIME_RANGE)
    t = lines.line_attribute("time", 0)
    np.testing.assert_allclose(np.diff(t)[:-1], step, rtol=1e-9)  # (whole steps to t = 0.5 ...)


def test_bad_options_and_series():
    with pytest.raises(OptionsError, match="direction"):
        P.pathlines(SERIES, [[0, 0, 0]], direction="both")
    with pytest.raises(OptionsError, match="ros34pw2 is offered by flowkit.trace"):
        P.pathlines(SERIES, [[0, 0, 0]], method="ros34pw2")
    with pytest.raises(KeyError, match="unknown pathline attribute 'vort'"):
        P.pathlines(SERIES, [[0, 0, 0]], attributes=("vort",))
    with pytest.raises(ValueError, match="two snapshots"):
        P.pathlines(SERIES[:1], [[0, 0, 0]])
    other = FLOW.to_field(shape=6, bounds=[[-2, 2], [-2, 2], [-1, 1]], t=2.5)
    with pytest.raises(ValueError, match="one grid"):
        P.pathlines([*SERIES[:2], (2.5, other)], [[0, 0, 0]])


def test_heated_room_series_end_to_end():
    path = hotroom_path()
    rng = np.random.default_rng(3)
    seeds = rng.uniform([0.5, 0.5, 0.5], [9.5, 4.5, 9.5], (60, 3))
    release = rng.choice([400.0, 800.0, 1000.0], 60)
    lines = P.pathlines(path, seeds, release, rtol=1e-6, attributes=("T", "speed"))
    assert len(lines) == 60 and lines.attrs["snapshot_times"].tolist() == [400, 800, 1200, 1600, 2000]
    reasons = set(lines.line_data["reason"].tolist())
    assert reasons <= {Reason.OUT_OF_DOMAIN, Reason.LEFT_TIME_RANGE, Reason.STEP_UNDERFLOW}
    assert Reason.LEFT_TIME_RANGE in reasons
    t = lines.point_data["time"]
    assert t.min() >= 400 and t.max() <= 2000
    for i in range(len(lines)):
        ti = lines.line_attribute("time", i)
        assert ti[0] == release[i] and np.all(np.diff(ti) > 0)
        if lines.line_data["reason"][i] == Reason.LEFT_TIME_RANGE:
            assert ti[-1] == 2000.0
    T = lines.point_data["T"]
    assert np.all((T >= 300 - 1e-9) & (T <= 600 + 1e-9))
    assert np.all(np.isfinite(lines.points)) and np.all(lines.points >= -1e-9)
    assert np.all(lines.points <= [10 + 1e-9, 5 + 1e-9, 10 + 1e-9])


def test_vorticity_follows_the_rotation_rate_in_time():
    """Rotation at rate omega0 + omega1 t: vorticity (0, 0, 2 (omega0 + omega1 t)), linear in
    space and time, so the node curl of each snapshot, its trilinear samples and the linear
    interpolation between the two snapshots around a vertex are all exact."""
    rng = np.random.default_rng(5)
    seeds = np.c_[rng.uniform(-0.8, 0.8, (6, 2)), rng.uniform(-0.5, 0.5, 6)]
    lines = P.pathlines(SERIES, seeds, 0.2, rtol=1e-8, max_time=1.5,
                        attributes=("vorticity", "vorticity_magnitude"))
    t = lines.point_data["time"]
    want = 2 * (FLOW.omega0 + FLOW.omega1 * t)
    w = lines.point_data["vorticity"]
    assert w.shape == (lines.n_points, 3) and len(np.unique(np.round(t, 6))) > 20
    np.testing.assert_allclose(w[:, :2], 0.0, atol=1e-12)
    np.testing.assert_allclose(w[:, 2], want, rtol=1e-12)
    np.testing.assert_allclose(lines.point_data["vorticity_magnitude"], want, rtol=1e-12)


@pytest.mark.parametrize("method", ["dopri5", "dop853", "bs23", "cashkarp"])
def test_steady_series_steps_as_the_streamline_kernel(method):
    """Two equal snapshots: a pathline is the streamline of the field, and the two kernels share
    the step's end, its error norm (DOP853's with its second estimate), the reject rule and the
    controller, so they take the same steps to the same end (to rounding: the velocity is
    evaluated in another order)."""
    import flowkit

    steady = UnsteadyRotation(omega0=1.0, omega1=0.0)
    box = [[-2, 2], [-2, 2], [-1, 1]]
    series = steady.to_series([0.0, 10.0], shape=5, bounds=box)
    seeds = np.random.default_rng(1).uniform(-1.0, 1.0, (20, 3)) * [1, 1, 0.5]
    kw = {"method": method, "rtol": 1e-7, "max_time": 3.0}
    path = P.pathlines(series, seeds, np.zeros(20), **kw)
    stream = flowkit.trace(steady.to_field(5, bounds=box), seeds, cell_aware=False, **kw)
    np.testing.assert_array_equal(path.line_data["n_accepted"], stream.line_data["n_accepted"])
    np.testing.assert_allclose(path.points[path.offsets[1:] - 1],
                               stream.points[stream.offsets[1:] - 1], rtol=0, atol=1e-12)
