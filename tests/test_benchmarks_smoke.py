"""The benchmark harness (benchmarks/) computes errors correctly: its reference against exact
solutions, its arc-length and error helpers, the flowkit adapter at a tiny size, and the ratio
table's choice of runs.  Needs no VTK (streamtracer's adapter is checked when installed)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

import bench_trace
import common as C
import peers

from flowkit.fields.analytic import LinearField

R, Z0, OMEGA = 1.5, 0.3, 0.7


@pytest.fixture(scope="module")
def centre_field():
    """Rotation about the z axis: linear, so its trilinear interpolant is exact, and its lines
    are circles traversed at constant speed: the point at arc length s is known exactly."""
    return LinearField.centre(omega=OMEGA).to_field(9, bounds=[[-2.0, 2.0]] * 3)


def circle_point(s, r=R, z=Z0, phi0=0.0):
    phi = phi0 + s / r
    return np.array([r * np.cos(phi), r * np.sin(phi), z])


def test_reference_matches_exact_circle_across_cells(centre_field):
    # arc length 6 at radius 1.5 crosses ~20 cells of size 0.5: every face switch is exercised
    end, nfev = C.reference_line(centre_field, [R, 0.0, Z0], 6.0)
    assert np.linalg.norm(end - circle_point(6.0)) < 1e-9
    assert nfev > 0


def test_reference_points_parallel_equals_serial(centre_field):
    seeds = np.array([[R, 0.0, Z0], [0.0, 1.0, -0.4], [-0.8, -0.8, 0.1]])
    exact = np.array([circle_point(2.5, np.hypot(*s[:2]), s[2], np.arctan2(s[1], s[0]))
                      for s in seeds])
    serial, _ = C.reference_points(centre_field, seeds, 2.5, processes=1, progress=False)
    forked, _ = C.reference_points(centre_field, seeds, 2.5, processes=2, progress=False)
    np.testing.assert_allclose(forked, serial, rtol=0, atol=1e-13)
    assert np.max(np.linalg.norm(serial - exact, axis=1)) < 1e-9


def test_reference_refuses_a_line_that_leaves_the_grid(centre_field):
    with pytest.raises(RuntimeError, match="left the grid"):
        C.reference_line(centre_field, [1.9, 1.9, 0.0], 3.0)  # radius 2.7 > half-width 2


def test_point_at_arc_length_on_polylines():
    # a straight line sampled unevenly: chord length is arc length, interpolation is exact
    t = np.array([0.0, 0.1, 0.7, 1.3, 2.0, 3.5])
    d = np.array([2.0, -1.0, 2.0]) / 3.0
    line = t[:, None] * d
    pts = np.concatenate([line, line[:2] + 5.0])  # a second line, too short
    got = C.point_at_arc_length(pts, np.array([0, 6, 8]), 1.0)
    np.testing.assert_allclose(got[0], d, atol=1e-15)
    assert np.all(np.isnan(got[1]))
    # a polygon inscribed in the circle: the chord sum falls short of the arc length
    phi = np.linspace(0.0, 2.0, 11)
    poly = np.stack([np.cos(phi), np.sin(phi), 0 * phi], -1)
    end = C.point_at_arc_length(poly, np.array([0, 11]), 2.0 * np.sin(0.1) / 0.1 * 0.999)[0]
    assert np.linalg.norm(end - poly[-1]) < 3e-3


def test_errors_are_distances_and_missing_points_are_inf():
    ref = np.zeros((3, 3))
    pts = np.array([[3.0, 4.0, 0.0], [np.nan, 0, 0], [0, 0, 1e-7]])
    np.testing.assert_array_equal(C.errors(pts, ref), [5.0, np.inf, 1e-7])


@pytest.fixture(scope="module")
def tiny():
    problem = C.Problem(nodes_per_period=8, n_seeds=12, length=4.0)
    field = C.abc_field(problem)
    seeds = C.make_seeds(problem)
    ref, _ = C.reference_points(field, seeds, problem.length, processes=1, progress=False)
    return problem, field, seeds, ref


def test_seeds_are_reproducible_and_central(tiny):
    problem, _, seeds, _ = tiny
    assert seeds.shape == (12, 3)
    np.testing.assert_array_equal(seeds, C.make_seeds(problem))
    mid = problem.span / 2
    assert np.all(np.abs(seeds - mid) <= np.pi)


@pytest.mark.parametrize("cell_aware", [True, False])
def test_flowkit_adapter_error_scales_with_tolerance(tiny, cell_aware):
    problem, field, seeds, ref = tiny
    loose = peers.flowkit_run(field, seeds, problem.length, rtol=1e-4, cell_aware=cell_aware)
    tight = peers.flowkit_run(field, seeds, problem.length, rtol=1e-10, cell_aware=cell_aware)
    e_loose, e_tight = C.errors(loose.end_points, ref), C.errors(tight.end_points, ref)
    assert np.all(np.isfinite(e_tight))
    assert np.median(e_tight) < 1e-6  # the harness and flowkit agree on the same interpolant
    assert np.median(e_tight) < np.median(e_loose) / 10
    assert tight.n_vertices > tight.n_seeds and tight.wall > 0
    stats = tight.__class__(**{**tight.__dict__, "err": e_tight}).stats()
    assert stats["failed"] == 0 and stats["median_err"] == np.median(e_tight)


def test_streamtracer_adapter_on_exact_circle(centre_field):
    pytest.importorskip("streamtracer")  # optional peer (bench extra)
    st = peers.StreamtracerTracer(centre_field)
    run = st.run(np.array([[R, 0.0, Z0]]), 3.0, 0.01)
    err = C.errors(run.end_points, circle_point(3.0)[None])
    assert err[0] < 1e-8  # RK4, h = 0.01, on an exact circle: O(h^4)
    with pytest.raises(ValueError, match="must divide"):
        st.run(np.array([[R, 0.0, Z0]]), 3.0, 0.007)


def test_ratio_table_takes_fastest_run_reaching_each_level():
    rows = [
        {"tool": "flowkit", "setting": "a", "median_err": 5e-5, "wall_s": 1.0},
        {"tool": "flowkit", "setting": "b", "median_err": 1e-6, "wall_s": 2.0},
        {"tool": "peer", "setting": "slow", "median_err": 1e-6, "wall_s": 40.0},
        {"tool": "peer", "setting": "fast", "median_err": 9e-5, "wall_s": 10.0},
        {"tool": "peer", "setting": "bad", "median_err": 1e-3, "wall_s": 0.1},
    ]
    assert C.fastest_at(rows, "peer", 1e-4)["setting"] == "fast"
    assert C.fastest_at(rows, "peer", 5e-6)["setting"] == "slow"
    assert C.fastest_at(rows, "peer", 1e-7) is None
    table = bench_trace.ratio_table(rows)
    assert "| median <= 1e-04 | a | 1.000 | peer | fast | 10.000 | 10.0x |" in table
    assert "| median <= 5e-06 | b | 2.000 | peer | slow | 40.000 | 20.0x |" in table
