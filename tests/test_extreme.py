"""Stiff and extreme cases: every line ends with the right reason, no NaN/inf vertex, within a
bounded step budget (``max_steps`` is the budget; a line that spends it reports max_steps, so each
case also asserts which reason it must end with).  Each case runs both stepping modes."""

import numpy as np
import pytest

from flowkit import trace
from flowkit.fields import Field, Grid
from flowkit.fields.analytic import LinearField, SolidBodyRotation, UniformFlow
from flowkit.integrate.reasons import Reason
from flowkit.integrate.trace import EmptyResultError, EmptyResultWarning

TOL = {"rtol": 1e-6, "atol": 1e-6}
AWARE = pytest.mark.parametrize("aware", [True, False], ids=["cell_aware", "plain"])


def _check(lines, reasons, budget):
    """Reasons as expected, every vertex finite, every line within its step budget."""
    got = [Reason(r) for r in lines.line_data["reason"]]
    assert got == list(reasons), got
    assert np.all(np.isfinite(lines.points))
    steps = lines.line_data["n_accepted"] + lines.line_data["n_rejected"]
    assert np.all(steps <= budget), steps
    return lines


def _last(lines):
    return lines.points[lines.offsets[1:] - 1]


@AWARE
def test_stiff_linear_field_reaches_the_boundary_within_budget(aware):
    # eigenvalues -1 and -1e4: DP5 is held at |h λ| ≈ 3.3 by stability, ~3e4 steps for t = 10
    f = LinearField.stiff()
    L = trace(f.to_field((4, 4, 11)), [[0.5, -0.3, 0.0]], cell_aware=aware, max_steps=40_000, **TOL)
    _check(L, [Reason.OUT_OF_DOMAIN], 40_000)
    assert abs(L.points[-1, 2] - 10.0) < 1e-9
    np.testing.assert_allclose(L.points[-1, :2], f.trajectory([[0.5, -0.3, 0.0]], 10.0)[0, :2], atol=1e-6)
    # the same with a budget that cannot suffice: max_steps, honestly
    L = trace(f.to_field((4, 4, 11)), [[0.5, -0.3, 0.0]], cell_aware=aware, max_steps=500, **TOL)
    _check(L, [Reason.MAX_STEPS], 500)


CRIT = {  # field, seeds (at, 1e-9 from, near, far), the reasons in that order, max_time
    "sink": (LinearField.sink(), [Reason.STAGNATION] * 4),
    "source": (LinearField.source(), [Reason.STAGNATION] * 2 + [Reason.OUT_OF_DOMAIN] * 2),
    "saddle": (LinearField.saddle(), [Reason.STAGNATION] * 2 + [Reason.OUT_OF_DOMAIN] * 2),
    "centre": (LinearField.centre(), [Reason.STAGNATION] * 2 + [Reason.MAX_TIME] * 2),
    "spiral": (LinearField.spiral(), [Reason.STAGNATION] * 2 + [Reason.MAX_TIME] * 2),
}


@AWARE
@pytest.mark.parametrize("kind", list(CRIT))
def test_critical_points(kind, aware):
    f, reasons = CRIT[kind]
    seeds = np.array([[0, 0, 0], [1e-9, 0, 0], [0.3, 0.2, 0.1], [0.5, 0.5, 0.5]])
    L = _check(trace(f.to_field(5), seeds, cell_aware=aware, max_time=50.0, max_steps=2000, **TOL),
               reasons, 2000)
    # exactly at the critical point (a node) and 1e-9 from it: stagnation at once, one vertex
    assert list(np.diff(L.offsets[:3])) == [1, 1]
    np.testing.assert_array_equal(L.points[0], [0, 0, 0])
    ends, exact_ok = _last(L), f.has_exact
    if kind in ("centre", "spiral"):  # closed/spiral orbits: on the exact trajectory at t = 50
        np.testing.assert_allclose(ends[2:], f.trajectory(seeds[2:], 50.0), atol=1e-4)
    elif kind == "sink":  # stops where the speed fell below the threshold (1e-4 of the
        assert np.abs(ends).max() < 2e-4  # median node speed, ~0.5 here): at the sink
    else:  # leaves through the boundary, exactly on it
        assert exact_ok and np.all(np.abs(np.abs(ends[2:]).max(axis=1) - 1.0) < 1e-9)


def _speeds_field():
    """u = (10^(8x), 0, 0) on x in [-1, 1]: speeds from 1e-8 to 1e8 in one field."""
    x = np.linspace(-1, 1, 65)
    g = Grid.from_axes(x, np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    v = np.zeros((65, 3, 3, 3))
    v[..., 0] = (10.0 ** (8 * x))[:, None, None]
    return Field(g, v, source="speeds 1e-8..1e8")


@AWARE
@pytest.mark.parametrize("parameter", ["time", "arc_length"])
def test_speeds_spanning_sixteen_decades(aware, parameter):
    seeds = [[-0.99, 0.5, 0.5], [-0.5, 0.5, 0.5], [0.9, 0.5, 0.5]]
    L = trace(_speeds_field(), seeds, cell_aware=aware, parameter=parameter, stagnation=1e-12,
              max_steps=1000, **TOL)
    _check(L, [Reason.OUT_OF_DOMAIN] * 3, 1000)
    np.testing.assert_allclose(_last(L), [[1, 0.5, 0.5]] * 3, atol=1e-9)
    # with the default threshold (1e-4 of the median node speed, 1 here) the slow seed stagnates
    L = trace(_speeds_field(), seeds[:1], cell_aware=aware, parameter=parameter, empty="ignore",
              **TOL)
    _check(L, [Reason.STAGNATION], 1)


@AWARE
@pytest.mark.parametrize("direction", ["forward", "both"])
def test_nan_hole_stops_before_it(aware, direction):
    f = SolidBodyRotation().to_field(17)  # nodes every 0.125 on [-1, 1]
    f.vector[10:, 8:11, :] = np.nan  # x >= 0.25, y in [0, 0.25]
    seeds = [[0.0, -0.5, 0.0], [0.0, -0.3, 0.2], [0.5, 0.0, 0.0]]
    L = trace(f, seeds, cell_aware=aware, direction=direction, max_time=10.0, max_steps=2000, **TOL)
    _check(L, [Reason.NAN_FIELD, Reason.NAN_FIELD, Reason.SEED_OUTSIDE], 2000)
    assert L.offsets[3] - L.offsets[2] == 0
    # every vertex lies before the hole: a line's last vertex may lie on the face of the NaN
    # cell (the edge of the valid data), so it is sampled a hair back along its last segment
    for line in L[:2]:
        p = line.points.copy()
        p[-1] += 1e-9 * (p[-2] - p[-1])
        p[0] += 1e-9 * (p[1] - p[0])  # direction both: the backward end too
        assert np.all(f.sample(p)[1] == 0)
    # cell-aware: the forward end lies on the face y = -0.125 of the first NaN cell it meets
    end = L.points[L.offsets[1] - 1]
    assert end[0] > 0.0 and (not aware or abs(end[1] + 0.125) < 1e-9)


@AWARE
def test_discontinuous_shear_layer(aware):
    # u = sign(y) jumps across the layer (a one-cell ramp on the grid), v = 0.25 carries lines across
    n = 33
    y = np.linspace(-1, 1, n)
    g = Grid.from_axes(np.linspace(-1, 1, n), y, np.linspace(0, 1, 3))
    v = np.zeros((n, n, 3, 3))
    v[..., 0] = np.where(y > 0, 1.0, -1.0)[None, :, None]
    v[..., 1] = 0.25
    seeds = [[0.0, -0.9, 0.5], [0.9, -0.1, 0.2], [-0.5, 0.5, 0.5]]
    L = _check(trace(Field(g, v), seeds, cell_aware=aware, max_steps=500, **TOL),
               [Reason.OUT_OF_DOMAIN] * 3, 500)
    t = L.point_data.get("time")
    assert t is None  # not asked for
    ends = _last(L)
    assert np.all(np.abs(np.abs(ends[:, :2]).max(axis=1) - 1) < 1e-9)
    # the first seed moves left at speed 1 for t = 3.6 before the layer (y = -0.9 + t / 4)
    np.testing.assert_allclose(ends[0], [-1.0, -0.65, 0.5], atol=1e-9)


@AWARE
def test_seeds_on_the_boundary_on_a_node_and_outside(aware):
    u = UniformFlow(U=(1.0, 0.0, 0.0)).to_field(5)  # the unit box, flow along +x
    seeds = [[0, 0, 0], [0, 0, 0.3], [0.5, 0, 0.5], [1, 0.5, 0.5], [0.25, 0.5, 0.75],
             [1.5, 0.5, 0.5], [np.nan, 0.5, 0.5]]
    L = trace(u, seeds, cell_aware=aware, max_steps=100, **TOL)
    _check(L, [Reason.OUT_OF_DOMAIN] * 5 + [Reason.SEED_OUTSIDE] * 2, 100)
    np.testing.assert_array_equal(np.diff(L.offsets)[3:], [1, *np.diff(L.offsets)[4:5], 0, 0])
    np.testing.assert_allclose(_last(L)[:5, 0], 1.0, atol=1e-12)  # along faces/edges to x = 1
    np.testing.assert_allclose(_last(L)[:5, 1:], np.array(seeds)[:5, 1:], atol=1e-12)
    # backward from the inflow face: leaves at once, one vertex (the seed)
    L = trace(u, seeds[:2], cell_aware=aware, direction="backward", empty="ignore", **TOL)
    _check(L, [Reason.OUT_OF_DOMAIN] * 2, 0)
    assert list(np.diff(L.offsets)) == [1, 1]


@AWARE
def test_all_zero_field_stagnates(aware):
    f = SolidBodyRotation().to_field(5)
    z = Field(f.grid, np.zeros_like(f.vector))
    seeds = [[0.1, 0.2, 0.3], [0.0, 0.0, 0.0]]
    with pytest.raises(EmptyResultError, match=r"no line has two vertices \(2 seeds; reasons: "
                       r"stagnation 2\)"):
        trace(z, seeds, cell_aware=aware, max_steps=10, **TOL)
    with pytest.warns(EmptyResultWarning, match="stagnation 2"):
        L = trace(z, seeds, cell_aware=aware, max_steps=10, empty="warn", **TOL)
    _check(L, [Reason.STAGNATION] * 2, 0)
    assert list(np.diff(L.offsets)) == [1, 1]


@AWARE
@pytest.mark.parametrize("shape", [(9, 9, 2), (2, 2, 2)], ids=["one_cell_thick", "single_cell"])
def test_grid_one_cell_thick(aware, shape):
    sp = (2 / (shape[0] - 1), 2 / (shape[1] - 1), 0.1)
    g = Grid.regular((-1, -1, 0), sp, shape)
    rot = SolidBodyRotation()
    f = rot.to_field(grid=g)
    seeds = [[0.5, 0, 0.05], [0.5, 0, 0.0], [0.5, 0, 0.1]]
    L = _check(trace(f, seeds, cell_aware=aware, max_time=6.0, max_steps=400, **TOL),
               [Reason.MAX_TIME] * 3, 400)
    if shape[0] > 2:  # rotation is bilinear-exact only where the grid resolves it: any grid
        np.testing.assert_allclose(_last(L), rot.trajectory(seeds, 6.0), atol=1e-4)
    # a vertical velocity leaves the slab through its top face
    w = Field(g, f.vector + np.array([0, 0, 1.0]))
    L = _check(trace(w, seeds[:1], cell_aware=aware, max_steps=100, **TOL), [Reason.OUT_OF_DOMAIN], 100)
    assert abs(L.points[-1, 2] - 0.1) < 1e-12


@pytest.mark.parametrize("tol", [1e-4, 1e-6, 1e-8])
def test_closed_orbits_long_time_radius_drift(tol):
    rot = SolidBodyRotation()
    f = rot.to_field(9)
    periods = 100
    seeds = np.array([[0.5, 0, 0], [0.2, 0.3, 0.1]])
    L = trace(f, seeds, rtol=tol, atol=tol, max_time=2 * np.pi * periods, max_steps=200_000)
    _check(L, [Reason.MAX_TIME] * 2, 200_000)
    r = np.hypot(L.points[:, 0], L.points[:, 1])
    r0 = np.repeat(r[L.offsets[:-1]], np.diff(L.offsets))
    drift = np.abs(r - r0).max()
    # global error of DP5 grows like tol^(4/5) per period here (measured 0.24, 0.8, 1.6 x tol per
    # period at tol 1e-4, 1e-6, 1e-8): bounded by 5 tol per period
    assert drift <= 5 * tol * periods, drift
    print(f"radius drift after {periods} periods at tol {tol:g}: {drift:.3g}")


# speeds whose squares overflow or underflow (|v| beyond ~1e154 or below ~1e-154) included
@pytest.mark.parametrize("scale", [1e-200, 1e200, 1e-100, 1e100, 1e-300, 1e300])
@AWARE
def test_huge_and_tiny_speed_units(scale, aware):
    f = SolidBodyRotation().to_field(9)
    L = trace(Field(f.grid, f.vector * scale), [[0, -0.5, 0]], max_time=6.0 / scale,
              max_steps=1000, cell_aware=aware, **TOL)
    _check(L, [Reason.MAX_TIME], 1000)
    np.testing.assert_allclose(L.points[-1], SolidBodyRotation().trajectory([[0, -0.5, 0]], 6.0)[0],
                               atol=1e-4)


WALL_DIRECTION = np.array([0.3, 0.1, 1.0])


def no_slip_wall():
    """A uniform flow along WALL_DIRECTION runs onto the wall z = 1, whose nodes are at rest,
    through a thin top cell, where w = 100 (1 - z): the exact line from a seed runs straight on
    to seed + (1 - z0) WALL_DIRECTION."""
    axis = np.linspace(0.0, 1.0, 5)
    g = Grid.from_axes(axis, axis, np.array([0.0, 0.25, 0.5, 0.75, 0.99, 1.0]))
    v = np.broadcast_to(WALL_DIRECTION, (5, 5, 6, 3)).copy()
    v[:, :, -1] = 0.0
    return Field(g, v)


@AWARE
@pytest.mark.parametrize("backend", ["numba", "opencl"])
def test_flow_onto_a_no_slip_wall_stops_on_it(aware, backend):
    # Within the tolerance of the wall the explicit steps outgrow their stability interval and
    # the error estimate, proportional to the distance, still passes: without the test on the
    # line's progress (kernel._stalled) these lines hovered there until max_steps, plain and
    # cell-aware alike
    if backend == "opencl":
        pytest.importorskip("pyopencl")
    seeds = np.array([[0.1, 0.2, 0.1], [0.5, 0.5, 0.6], [0.2, 0.6, 0.995], [0.3, 0.3, 0.98]])
    L = _check(trace(no_slip_wall(), seeds, cell_aware=aware, backend=backend, max_time=1e6,
                     max_steps=100_000, rtol=1e-6, atol=1e-6),
               [Reason.STAGNATION] * 4, 200)
    # the end within a few tolerances of the exact point on the wall
    np.testing.assert_allclose(_last(L), seeds + (1.0 - seeds[:, 2:]) * WALL_DIRECTION,
                               atol=5e-6, rtol=0)
