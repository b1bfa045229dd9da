"""Per-vertex attributes against exact values, computed only when requested."""

import numpy as np
import pytest

from flowkit import Field, Grid, trace
from flowkit.fields import curl, interp
from flowkit.fields.analytic import ABCFlow, SolidBodyRotation
from flowkit.fields.curl import gradient
from flowkit.integrate import attributes

OMEGA = 0.7
BOX = [[-3, 3], [-3, 3], [-1, 1]]


def _rotation(grid=None):
    rot = SolidBodyRotation(omega=OMEGA)
    f = rot.to_field(grid=grid) if grid is not None else rot.to_field(shape=(13, 13, 5), bounds=BOX)
    # a linear scalar: trilinear sampling of it is exact
    pts = f.grid.node_points()
    f.scalars["T"] = pts @ np.array([1.0, -2.0, 0.5]) + 3.0
    return f


RECTILINEAR = Grid.from_axes(np.r_[-3, -2.2, -1, -0.1, 0.5, 1.7, 3], np.linspace(-3, 3, 9) ** 1,
                             np.r_[-1, -0.2, 0.3, 1], where="test grid")


@pytest.mark.parametrize("grid", [None, RECTILINEAR], ids=["uniform", "rectilinear"])
def test_attributes_match_exact_values(grid):
    f = _rotation(grid)
    seeds = np.array([[1.0, 0.0, 0.2], [0.0, -2.0, -0.5]])
    names = ("time", "arc_length", "speed", "velocity", "vorticity", "vorticity_magnitude",
             "T", "distance_to_seed")
    lines = trace(f, seeds, max_time=2.5, rtol=1e-10, atol=1e-10, attributes=names)
    assert set(lines.point_data) == set(names)
    pd = lines.point_data
    p = lines.points
    seed = seeds[lines.line_index()]
    r = np.linalg.norm(seed[:, :2], axis=1)
    np.testing.assert_allclose(pd["speed"], OMEGA * r, rtol=1e-8)
    np.testing.assert_allclose(pd["arc_length"], OMEGA * r * pd["time"], rtol=1e-8, atol=1e-12)
    exact = np.stack([SolidBodyRotation(omega=OMEGA).trajectory(s[None], t)[0]
                      for s, t in zip(seed, pd["time"])])
    np.testing.assert_allclose(p, exact, atol=1e-8)
    np.testing.assert_allclose(pd["velocity"], OMEGA * np.c_[-p[:, 1], p[:, 0], 0 * p[:, 0]],
                               atol=1e-12)
    # curl of a solid-body rotation: 2 omega along the axis (second-order differences are exact)
    np.testing.assert_allclose(pd["vorticity"], np.broadcast_to([0, 0, 2 * OMEGA], p.shape),
                               atol=1e-9)
    np.testing.assert_allclose(pd["vorticity_magnitude"], 2 * OMEGA, rtol=1e-9)
    np.testing.assert_allclose(pd["T"], p @ np.array([1.0, -2.0, 0.5]) + 3.0, atol=1e-12)
    np.testing.assert_allclose(pd["distance_to_seed"], np.linalg.norm(p - seed, axis=1), atol=0)
    assert pd["time"][lines.offsets[:-1]].tolist() == [0.0, 0.0]


def test_periodic_curl_of_abc_is_the_field_itself():
    f = ABCFlow().to_field(32, bounds=[[0, 2 * np.pi]] * 3, periodic=True)
    w = curl.curl(f)
    # Beltrami flow: curl u = u; second-order differences err by about h^2 / 6
    h = 2 * np.pi / 32
    err = np.abs(w - f.vector).max()
    assert err < 0.5 * h**2 * np.abs(f.vector).max()
    assert err > 0  # really differences, not the field copied


def test_no_curl_unless_a_vorticity_attribute_is_requested(monkeypatch):
    f = _rotation()
    calls = []
    real = attributes.vorticity_at

    def counting(field, points):
        calls.append(1)
        return real(field, points)

    monkeypatch.setattr(attributes, "vorticity_at", counting)
    trace(f, [1.0, 0.0, 0.0], max_time=1.0, attributes=("speed", "velocity", "time", "T"))
    trace(f, [1.0, 0.0, 0.0], max_time=1.0)
    assert calls == []
    trace(f, [1.0, 0.0, 0.0], max_time=1.0, attributes=("vorticity", "vorticity_magnitude"))
    assert calls == [1]  # once for both


def test_no_attributes_unless_requested_and_clear_error_for_unknown():
    f = _rotation()
    lines = trace(f, [1.0, 0.0, 0.0], max_time=1.0)
    assert lines.point_data == {}
    assert set(lines.line_data) == {"seed_id", "reason", "n_accepted", "n_rejected", "n_crossing",
                                   "stiff"}
    with pytest.raises(KeyError, match="unknown attribute 'pressure'.*available:.*T"):
        trace(f, [1.0, 0.0, 0.0], max_time=1.0, attributes=("pressure",))


def test_attributes_in_arc_length_parameterisation():
    f = _rotation()
    lines = trace(f, [2.0, 0.0, 0.0], max_length=3.0, parameter="arc_length",
                  attributes=("time", "arc_length", "speed"), rtol=1e-10, atol=1e-10)
    pd = lines.point_data
    np.testing.assert_allclose(pd["time"], pd["arc_length"] / (OMEGA * 2.0), rtol=1e-8)
    assert pd["arc_length"][-1] == pytest.approx(3.0, abs=1e-9)
    assert isinstance(f, Field)


def nan_face_field() -> Field:
    """Uniform flow (1, 0.2, 0) and T = i + 0.1 j on 6x5x4 nodes 0.2 apart, NaN from x = 0.8 on:
    the cells from x = 0.6 on have a NaN corner."""
    g = Grid.regular((0, 0, 0), 0.2, (6, 5, 4))
    v = np.broadcast_to(np.array([1.0, 0.2, 0.0]), g.shape + (3,)).copy()
    T = np.fromfunction(lambda i, j, k: i + 0.1 * j, g.shape)
    v[4:] = np.nan
    T[4:] = np.nan
    return Field(g, v, scalars={"T": T})


NAN_FACE_SEEDS = np.array([[0.1, 0.1, 0.1], [0.1, 0.5, 0.3]])


@pytest.mark.parametrize("aware", [True, False])
def test_a_line_stopped_by_nan_cells_keeps_finite_attributes_at_its_end(aware):
    """The last vertex lies on (cell-aware) or just before the face of the first NaN cell: the
    interpolant there is the face's, whose corners are finite, so its attributes are too."""
    from flowkit.integrate.reasons import Reason

    lines = trace(nan_face_field(), NAN_FACE_SEEDS, cell_aware=aware,
                  attributes=("speed", "velocity", "T"))
    assert lines.line_data["reason"].tolist() == [Reason.NAN_FIELD] * 2
    end = lines.offsets[1:] - 1
    np.testing.assert_allclose(lines.points[end, 0], 0.6, atol=1e-9)
    np.testing.assert_allclose(lines.point_data["speed"][end], np.hypot(1.0, 0.2), rtol=1e-12)
    np.testing.assert_allclose(lines.point_data["velocity"][end], [[1.0, 0.2, 0.0]] * 2, rtol=1e-12)
    # T = i + 0.1 j at the nodes, linear: 3 + y / 2 on the face x = 0.6
    np.testing.assert_allclose(lines.point_data["T"][end], 3 + 0.5 * lines.points[end, 1], rtol=1e-9)
    assert all(np.all(np.isfinite(a)) for a in lines.point_data.values())


def _holed(v_of, shape=(14, 12, 10)):
    """The vector field v_of(x, y, z) on a non-uniform grid, with a NaN hole of 3x2x3 nodes."""
    rng = np.random.default_rng(4)
    axes = [np.cumsum(np.r_[0.0, rng.uniform(0.5, 1.5, n - 1)]) * 0.1 for n in shape]
    g = Grid.from_axes(*axes)
    X, Y, Z = np.meshgrid(*axes, indexing="ij")
    v = np.stack(v_of(X, Y, Z), axis=-1)
    hole = (slice(5, 8), slice(4, 6), slice(3, 6))
    v[hole] = np.nan
    nan = np.zeros(shape, bool)
    nan[hole] = True
    return Field(g, v), (X, Y, Z), nan


@pytest.mark.parametrize("kind", ["linear", "quadratic"])
def test_curl_next_to_a_nan_hole_takes_one_sided_differences(kind):
    """Only the hole's own nodes get a NaN curl; its neighbours take one-sided differences, which
    are exact for linear fields and (3-point, second order on the node coordinates) quadratics."""
    if kind == "linear":  # a rotation about z: curl (0, 0, 2)
        f, (X, Y, Z), nan = _holed(lambda x, y, z: (-y, x, 0 * z))
        want = np.stack([0 * X, 0 * X, 2 + 0 * X], axis=-1)
    else:  # v = (y^2, z^2, x^2): curl (-2z, -2x, -2y)
        f, (X, Y, Z), nan = _holed(lambda x, y, z: (y**2, z**2, x**2))
        want = np.stack([-2 * Z, -2 * X, -2 * Y], axis=-1)
    w = curl.curl(f)
    np.testing.assert_array_equal(np.isnan(w).any(axis=-1), nan)
    np.testing.assert_allclose(w[~nan], want[~nan], rtol=0, atol=1e-11)


def test_curl_fallbacks_use_a_two_point_difference_only_between_two_nans():
    """A node with NaN on one side and NaN two nodes away on the other falls back to the 2-point
    difference; a node between two NaN neighbours has no finite derivative on that axis."""
    c = np.array([0.0, 0.1, 0.25, 0.3, 0.5, 0.6])
    f = c**2
    f[[0, 3, 5]] = np.nan  # node 1: NaN at 0 and 3 -> forward 2-point only from 1 to 2
    g = Grid.from_axes(c, [0.0, 1.0], [0.0, 1.0])
    v = np.zeros(g.shape + (3,))
    v[..., 1] = f[:, None, None]  # curl_z = d v_y / dx
    d = curl.curl(Field(g, v))[:, 0, 0, 2]
    assert d[1] == pytest.approx((f[2] - f[1]) / (c[2] - c[1]), rel=1e-14)
    assert d[2] == pytest.approx((f[2] - f[1]) / (c[2] - c[1]), rel=1e-14)  # backward 2-point
    assert np.isnan(d[4])  # NaN on both sides
    assert np.isnan(d[[0, 3, 5]]).all()


def test_curl_fallbacks_wrap_across_a_periodic_seam():
    """Beside NaN nodes next to the seam of a periodic axis, the one-sided differences take
    their nodes across the seam (as np.gradient's wrap does), so the node on the seam keeps a
    finite, second-order curl; with or without a last node repeating the first."""
    for repeat in (False, True):
        n = 40
        x = np.linspace(0, 2 * np.pi, n + 1 if repeat else n, endpoint=repeat)
        g = Grid.from_axes(x, np.linspace(0, 1, 5), np.linspace(0, 1, 4),
                           periodic=(True, False, False), period=(2 * np.pi, 0.0, 0.0))
        X = np.meshgrid(*g.axes, indexing="ij")[0]
        v = np.stack([0 * X, np.sin(X), 0 * X], axis=-1)  # curl_z = cos x
        v[1] = np.nan  # node 0's standard stencil (n-1, 1) and forward stencils meet NaN
        w = curl.curl(Field(g, v))
        assert np.isnan(w[1]).all() and np.isfinite(w[0]).all() and np.isfinite(w[2]).all()
        h = x[1] - x[0]
        np.testing.assert_allclose(w[0, ..., 2], 1.0, atol=h**2)  # 3-point backward, wrapped
        np.testing.assert_allclose(w[2, ..., 2], np.cos(x[2]), atol=h**2)


def test_vorticity_of_a_line_passing_a_nan_hole_is_finite():
    """The uniform flow of nan_face_field has no vorticity; next to its NaN half the vertices'
    vorticity is 0, not NaN (one-sided differences at the nodes beside the NaN ones)."""
    lines = trace(nan_face_field(), NAN_FACE_SEEDS, attributes=("vorticity", "vorticity_magnitude"))
    assert np.isfinite(lines.point_data["vorticity"]).all()
    np.testing.assert_allclose(lines.point_data["vorticity_magnitude"], 0.0, atol=1e-12)


def _np_curl(f):
    """The curl from ``curl.gradient`` (np.gradient, wrapped on periodic axes) of each component
    along each axis: what the compiled node curl must give bit for bit on finite data."""
    g, v = f.grid, f.vector
    d = [[gradient(v[..., c], g.axes[a], g.period[a], a) for a in range(3)] for c in range(3)]
    return np.stack([d[2][1] - d[1][2], d[0][2] - d[2][0], d[1][0] - d[0][1]], axis=-1)


SPACINGS = {  # np.gradient takes its uniform formulas only where every spacing is bitwise equal
    "uniform": Grid.regular((0, 0, 0), 0.25, (9, 7, 5)),
    "linspace": Grid.from_axes(*[np.linspace(0, 6, 13)] * 3),
    "rectilinear": Grid.from_axes(np.r_[0, 0.3, 0.5, 1.2, 1.3, 2.0], np.linspace(0, 3, 9),
                                  np.linspace(0, 2, 7) ** 1.5),
    "two nodes": Grid.from_axes(np.r_[0, 0.3, 0.5, 1.2], [0.0, 0.7], np.linspace(0, 2, 5)),
    "periodic": Grid.from_axes(np.linspace(0, 2 * np.pi, 17), np.linspace(0, 2 * np.pi, 12,
                               endpoint=False), np.linspace(0, 2, 6) ** 1.5,
                               periodic=(True, True, False), period=(2 * np.pi, 2 * np.pi, 0)),
}


@pytest.mark.parametrize("kind", SPACINGS)
def test_node_curl_is_np_gradients_bit_for_bit_and_sampled_at_points_as_the_grid(kind):
    f = ABCFlow().to_field(grid=SPACINGS[kind])
    w = curl.curl(f)
    assert np.array_equal(w, _np_curl(f))
    # at points, from the corners of their cells only: the whole grid's curl sampled, exactly,
    # NaN holes, nodes and points outside included
    v = f.vector.copy()
    v[1, 1:3, 2] = np.nan
    v[-1, 0, 0, 1] = np.inf
    holed = Field(f.grid, v)
    lo, hi = f.grid.origin, np.array([c[-1] for c in f.grid.axes])
    pts = lo + (hi - lo) * np.random.default_rng(3).uniform(-0.05, 1.05, (4000, 3))
    pts[:8] = np.array(np.meshgrid(*[c[:2] for c in f.grid.axes])).reshape(3, -1).T
    # and runs of points in one cell after another, as a line's vertices come (a point in the
    # cell of the point before it reuses that cell's corners), across the NaN hole
    hole = np.array([f.grid.axes[0][1], f.grid.axes[1][1], f.grid.axes[2][2]])
    run = hole + (hi - lo) * np.linspace(-0.5, 0.5, 1000)[:, None] * np.array([1.0, 0.6, 0.3])
    pts = np.concatenate([pts, run, run[::-1]])
    for field in (f, holed):
        want, status = np.empty((len(pts), 3)), np.empty(len(pts), np.int8)
        interp.sample_vectors(*field.grid.kernel_args(), curl.curl(field), pts, want, status)
        assert np.array_equal(attributes.vorticity_at(field, pts), want, equal_nan=True)
    assert np.isnan(want).any() and np.isfinite(want).any()


def test_vorticity_at_few_points_allocates_for_the_points_not_for_the_grid():
    """The node curl is kept at the marked corners only: a vertex's vorticity on a large grid
    costs memory like its points (plus two bytes per node of marks and counts), not a
    grid-sized array of curls (24 bytes per node) as it once did."""
    import tracemalloc

    f = ABCFlow().to_field(shape=(97, 97, 97))  # 22 MB of vectors
    pts = np.random.default_rng(5).uniform(0.5, 5.5, (200, 3))
    attributes.vorticity_at(f, pts)  # compiled outside the measurement
    tracemalloc.start()
    try:
        w = attributes.vorticity_at(f, pts)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2.5 * f.grid.shape[0] ** 3 + 1e5, peak  # marks, counts and the rows
    want, status = np.empty((len(pts), 3)), np.empty(len(pts), np.int8)
    interp.sample_vectors(*f.grid.kernel_args(), curl.curl(f), pts, want, status)
    assert np.array_equal(w, want)


@pytest.mark.parametrize("grid", [None, RECTILINEAR], ids=["uniform", "rectilinear"])
def test_vector_and_scalar_sampled_together_are_the_separate_samples_bit_for_bit(grid):
    """Speed and a scalar (the viewer's heated room: speed, T) are sampled in one pass that
    locates each vertex once: the same values, to the bit, as a pass for each, and the status
    NAN_CELL where either's cell has a NaN corner."""


    f = _rotation(grid)
    f.vector[2:4, 3:5, 1:3] = np.nan  # NaN cells of the vector, others of the scalar
    f.scalars["T"][6:8, 5:7, 2:4] = np.nan
    pts = np.random.default_rng(3).uniform(-3.5, 3.5, (5000, 3)) * [1, 1, 0.4]  # some outside
    pts[:50] = f.grid.node_points().reshape(-1, 3)[:50]  # on nodes, faces: corners of weight 0
    v, sv = f.sample(pts)
    T, sT = f.sample_scalar("T", pts)
    vw, Tw, sw = f.sample_with("T", pts)
    assert vw.tobytes() == v.tobytes() and Tw.tobytes() == T.tobytes()
    assert {interp.INSIDE, interp.OUTSIDE, interp.NAN_CELL} <= set(sv) | set(sT)
    np.testing.assert_array_equal(sw, np.where(sv == interp.OUTSIDE, sv, np.maximum(sv, sT)))
    names = ("T", "speed", "p2")
    f.scalars["p2"] = f.scalars["T"] * 2.0  # a second scalar: sampled alone
    got = attributes.compute(f, names, pts, None, None, None)
    assert got["speed"].tobytes() == np.linalg.norm(v, axis=1).tobytes()
    assert got["T"].tobytes() == T.tobytes()
    assert got["p2"].tobytes() == f.sample_scalar("p2", pts)[0].tobytes()


def test_norm_is_numpys_to_the_bit():
    """Speed, vorticity magnitude and distance to the seed: ``attributes.norm``, the bits of
    np.linalg.norm(axis=1) (the same sum in the same order) at a sixth of its cost."""
    rng = np.random.default_rng(5)
    v = rng.standard_normal((200_000, 3)) * 10.0 ** rng.uniform(-200, 200, (200_000, 1))
    v[:6] = [[np.nan, 0, 1], [np.inf, 1, 0], [-0.0, -0.0, 0.0], [1e308, 1e308, 0],
             [-np.inf, np.nan, 0], [5e-324, 0, 0]]
    with np.errstate(over="ignore"):  # squares beyond the largest float, as numpy's
        for a in (v, v.astype(np.float32)):
            got, want = attributes.norm(a), np.linalg.norm(a, axis=1)
            assert got.dtype == want.dtype and got.tobytes() == want.tobytes()


def test_samples_of_points_in_runs_on_a_graded_grid_are_the_bisections_cells():
    """The samplers try the last point's cell (and its neighbours) before the bisection on a
    non-uniform axis and locate points ahead of sampling them: along runs of points forward and
    back, through nodes and faces, the samples are exactly those of np.searchsorted's cells."""
    x = np.cumsum(np.r_[0.0, 1.3 ** np.arange(12)])  # graded, 13 nodes
    y, z = np.linspace(-1.0, 2.0, 7), np.r_[0.0, 0.1, 0.5, 1.5, 1.6, 3.0]
    g = Grid.from_axes(x, y, z, where="graded test grid")
    v = np.random.default_rng(7).normal(size=(*g.shape, 3))
    t = np.linspace(0.0, 1.0, 3001)[:, None]
    lo, hi = np.array([x[0], y[0], z[0]]), np.array([x[-1], y[-1], z[-1]])
    run = lo + (hi - lo) * t * np.array([1.0, 0.7, 0.9])
    nodes = np.stack(np.meshgrid(x, y[:2], z[:2], indexing="ij"), -1).reshape(-1, 3)
    pts = np.concatenate([run, run[::-1], nodes, run[::7], np.random.default_rng(8).permutation(run)])
    got, status = np.empty((len(pts), 3)), np.empty(len(pts), np.int8)
    interp.sample_vectors(*g.kernel_args(), v, pts, got, status)
    want = np.zeros((len(pts), 3))
    cells, frac = [], []
    for a, c in enumerate((x, y, z)):
        i = np.clip(np.searchsorted(c, pts[:, a], side="right") - 1, 0, c.size - 2)
        cells.append(i)
        frac.append(np.clip((pts[:, a] - c[i]) / (c[i + 1] - c[i]), 0.0, 1.0))
    for corner in range(8):  # interp.trilinear_vector's sum, corner by corner, in its order
        up = [(corner >> a) & 1 for a in range(3)]
        w = np.ones(len(pts))
        for a in range(3):
            w = w * (frac[a] if up[a] else 1.0 - frac[a])
        vals = v[cells[0] + up[0], cells[1] + up[1], cells[2] + up[2]]
        want += np.where(w[:, None] != 0.0, w[:, None] * vals, 0.0)
    assert (status == interp.INSIDE).all()
    assert np.array_equal(got, want)
