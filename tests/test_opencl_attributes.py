"""Per-vertex attributes computed in the OpenCL kernel (PoCL here) against the numba backend.

float64: every attribute within 1e-9 of its largest magnitude (measured: <= 6e-13, from vertex
differences of ~1e-13 on rotation; 0 on ABC and the room, apart from the vorticity's rounding
~2e-16), NaN where numba has NaN.  float32: within the bound of ``test_float32_attributes``.
"""

import numpy as np
import pytest

import flowkit
from flowkit import Grid, datasets
from flowkit.fields import analytic, curl, interp
from flowkit.integrate import attributes as host_attributes

pytest.importorskip("pyopencl")  # the `opencl` extra; CI installs it (pocl-binary-distribution)
from test_opencl import EPS32, _both, _extent, _seeds, _src, assert_same

from flowkit.integrate.opencl import codegen, vertex
from flowkit.integrate.opencl.backend import OpenCLAdvance

BUILTIN = ("time", "arc_length", "speed", "velocity", "vorticity", "vorticity_magnitude",
           "distance_to_seed")


@pytest.fixture(scope="module")
def ocl64():
    return OpenCLAdvance("opencl", dtype="float64")


@pytest.fixture(scope="module")
def fields():
    x = np.linspace(0, 2 * np.pi, 20, endpoint=False)
    x = x + 0.08 * np.sin(x)  # rectilinear, periodic: np.gradient's non-uniform stencils
    return {
        "rotation": analytic.SolidBodyRotation().to_field(shape=17),
        "abc": analytic.ABCFlow().to_field(shape=24),  # periodic (wrap cells)
        "abc_rect": analytic.ABCFlow().to_field(
            grid=Grid.from_axes(x, x, x, periodic=True, period=(2 * np.pi,) * 3)),
        "hotroom": datasets.hotroom(),  # bounded, scalars T and p
    }


def _all(field):
    return BUILTIN + tuple(sorted(field.scalars))


@pytest.mark.parametrize("name", ["rotation", "abc", "abc_rect", "hotroom"])
def test_attributes_match_numba(fields, ocl64, name):
    f = fields[name]
    ref, got = _both(f, _seeds(f, 6, 4), ocl64, attributes=_all(f), rtol=1e-7,
                     max_length=5.0, direction="both")
    assert ref.n_points > 6 * 20
    assert_same(ref, got, _extent(f))
    # real values, not a constant: the attributes vary along the lines
    varying = ("speed", "distance_to_seed") + (() if name == "rotation" else ("vorticity_magnitude",))
    for k in varying:
        assert np.nanstd(got.point_data[k]) > 1e-3 * np.nanmax(np.abs(got.point_data[k])), k
    if name == "rotation":  # solid-body rotation at unit angular velocity: vorticity 2 everywhere
        np.testing.assert_allclose(got.point_data["vorticity_magnitude"], 2.0, rtol=1e-12)


def test_attributes_come_from_the_kernel(fields, ocl64, monkeypatch):
    """With the OpenCL backend the host attribute code is not called; the host path (kept for
    the benchmark) gives the same values."""
    f = fields["hotroom"]
    seeds = _seeds(f, 4, 5)
    host = flowkit.trace(f, seeds, backend=OpenCLAdvance(kernel_attributes=False),
                         attributes=_all(f), max_length=3.0)

    def fail(*a, **k):
        raise AssertionError("host attributes computed")

    monkeypatch.setattr(host_attributes, "compute", fail)
    got = flowkit.trace(f, seeds, backend=ocl64, attributes=_all(f), max_length=3.0)
    assert_same(host, got, _extent(f))
    with pytest.raises(AssertionError, match="host attributes computed"):
        flowkit.trace(f, seeds, backend=OpenCLAdvance(kernel_attributes=False),
                      attributes=("speed",), max_length=3.0)


@pytest.mark.parametrize("opts", [
    {"budget": 2, "direction": "both"},  # every line suspends after each vertex or two
    {"budget": 2, "spacing": 0.05},  # continuation inside a pending resampled step
    {"count": 30, "direction": "both", "budget": 3},
], ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()))
def test_attributes_continue_across_launches(fields, ocl64, opts):
    """A line that outgrows its vertex budget continues in the next launch with its attributes:
    the same values as numba and as one launch per line (bit for bit)."""
    f = fields["hotroom"]
    seeds = _seeds(f, 5, 6)
    kw = {"attributes": _all(f), "max_length": 4.0, "rtol": 1e-6} | opts
    ref, got = _both(f, seeds, ocl64, **kw)
    assert_same(ref, got, _extent(f))
    one = flowkit.trace(f, seeds, backend=ocl64, **(kw | {"budget": None}))
    assert_same(one, got, _extent(f), rel=0.0)
    adv = OpenCLAdvance(chunk=2)  # several chunks per pass as well
    many = flowkit.trace(f, seeds, backend=adv, **kw)
    assert np.diff(many.offsets).min() > 3 * kw["budget"]  # every line continued several times
    assert adv.launches > 3 * len(seeds) / 2
    assert_same(one, many, _extent(f), rel=0.0)


def test_float32_attributes(fields):
    """float32 kernel attributes against the float64 host formulas at the float32 run's own
    vertices (the vertices themselves obey the bound of test_opencl.test_float32_within_bound):

        |a32 - a64| <= 8 eps32 * A

    A: max |v| for speed and velocity, max |scalar| for a scalar field, max |x - seed| + max |x|
    for the distance, max |v| times the largest sum of |stencil weights| of a node (twice: two
    derivatives per component) for the vorticity.  Each is a few float32 roundings of the values
    summed (the field's own rounding to float32, 8 trilinear terms, 3-point stencils); measured
    at most 2.7 eps32 * A (ABC velocity, 50 lines)."""
    adv = OpenCLAdvance(dtype="float32")
    for name in ("abc_rect", "hotroom"):
        f = fields[name]
        seeds = _seeds(f, 6, 7)
        got = flowkit.trace(f, seeds, backend=adv, attributes=_all(f), rtol=1e-5, max_length=4.0)
        seed_of = np.repeat(seeds, np.diff(got.offsets), axis=0)
        t, s = got.point_data["time"], got.point_data["arc_length"]
        want = host_attributes.compute(f, _all(f), got.points, t, s, seed_of)
        vmax = np.abs(f.vector).max()
        _nodes, w, _k = vertex.stencils(f.grid)
        scale = {"speed": vmax, "velocity": vmax,
                 "vorticity": 2 * vmax * np.abs(w).sum(axis=1).max(),
                 "distance_to_seed": np.abs(got.points).max() + want["distance_to_seed"].max()}
        scale["vorticity_magnitude"] = scale["vorticity"]
        for k in _all(f)[2:]:
            a = scale.get(k, np.abs(f.scalars.get(k, 0.0)).max())
            err = np.abs(got.point_data[k] - want[k]).max()
            assert err <= 8 * EPS32 * a, (name, k, err / (EPS32 * a))
        assert np.abs(got.point_data["speed"] - want["speed"]).max() > 0  # really float32


def test_image_field_with_attributes(fields):
    """With an image3d field the attributes still sample the vector buffer (uploaded only then):
    exact trilinear values at the image run's vertices, to float32 rounding."""
    adv = OpenCLAdvance(dtype="float32", image=True)
    f = fields["hotroom"]
    got = flowkit.trace(f, _seeds(f, 4, 8), backend=adv, attributes=("velocity", "vorticity"),
                        rtol=1e-5, max_length=3.0)
    assert any(k[0] == "vector" for k in adv._extra if isinstance(k, tuple))
    want = host_attributes.compute(f, ("velocity",), got.points, None, None, None)["velocity"]
    assert np.abs(got.point_data["velocity"] - want).max() <= 8 * EPS32 * np.abs(f.vector).max()


def test_uploads_only_what_attributes_need(fields):
    f = fields["hotroom"]
    seeds = _seeds(f, 2, 9)

    def uploaded(attrs):
        adv = OpenCLAdvance()
        flowkit.trace(f, seeds, backend=adv, attributes=attrs, max_length=1.0)
        return sorted(k[0] for k in adv._extra if isinstance(k, tuple))

    assert uploaded(("time", "speed", "velocity", "distance_to_seed")) == []
    assert uploaded(("T",)) == ["scalar"]
    # the node curl is computed on the device from the field buffer: only a stencil table goes up
    assert uploaded(("vorticity_magnitude",)) == ["curl"]
    assert uploaded(("p", "T", "vorticity")) == ["curl", "scalar", "scalar"]


def _table_deriv(grid, v, comp, ax):
    """d v[..., comp] / d x_ax at every node by the stencil tables, as curl_nodes applies them:
    the standard stencil where its values are finite, else the first finite fallback."""
    nodes, w, _ = vertex.stencils(grid)
    fb_nodes, fb_w = vertex.fallbacks(grid)
    rows = slice(sum(grid.shape[:ax]), sum(grid.shape[:ax + 1]))
    data = np.moveaxis(v[..., comp], ax, 0)

    def apply(q_all, w_all):  # (n, K) nodes and weights -> (sum, all values finite)
        out = np.zeros_like(data)
        finite = np.ones(data.shape, bool)
        for m in range(q_all.shape[1]):
            q = q_all[:, m]
            used = q >= 0
            val = np.zeros_like(data)
            val[used] = data[q[used]]
            finite &= np.isfinite(val)
            out += w_all[:, m][:, None, None] * val
        return out, finite

    out, done = apply(nodes[rows], w[rows])
    out[~done] = np.nan
    for c in range(4):
        alt, ok = apply(fb_nodes[rows, c], fb_w[rows, c])
        ok &= (fb_nodes[rows, c, 0] >= 0)[:, None, None] & ~done
        out[ok] = alt[ok]
        done |= ok
    return np.moveaxis(out, 0, ax)


def test_stencils_are_the_host_curl(fields):
    """The stencil table applied to node data is fields.curl's derivative, NaN included."""
    rng = np.random.default_rng(0)
    for name in ("abc", "abc_rect", "hotroom"):
        g = fields[name].grid
        assert vertex.stencils(g)[2] <= 3
        v = rng.normal(size=g.shape + (3,))
        v[3, 4, 5, 1] = np.nan
        v[5:7, 2:4, 1:3] = np.nan  # a hole: its neighbours take one-sided differences
        v[1, 6:8, 3:5] = np.nan  # beside the seam: on abc (periodic) node 0's wrap across it
        want = curl.curl(flowkit.Field(g, v, source="probe"))
        got = np.stack([_table_deriv(g, v, 2, 1) - _table_deriv(g, v, 1, 2),
                        _table_deriv(g, v, 0, 2) - _table_deriv(g, v, 2, 0),
                        _table_deriv(g, v, 1, 0) - _table_deriv(g, v, 0, 1)], axis=-1)
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        ok = ~np.isnan(want)
        assert np.abs(got[ok] - want[ok]).max() <= 1e-12 * np.abs(want[ok]).max()


def test_source_has_only_the_requested_attributes():
    none = _src()
    speed = _src(attrs=("speed",))
    vort = _src(attrs=("vorticity",), scalars=2, periodic=True)
    for marker in ("vertex_attributes", "locate_axis_t", "a_speed", "curl", "scalar0",
                   "a_distance_to_seed", "seed[0]"):
        assert marker not in none, marker  # no attribute code at all without attributes
    assert "vertex_attributes(&O, at" in speed and "O->a_speed[at] = sqrt(u * u" in speed
    for marker in ("curl", "st_node", "a_vorticity", "scalar0", "a_velocity",
                   "a_distance_to_seed"):
        assert marker not in speed, marker
    assert "__kernel void curl_nodes" in vort and "O->curl[node[c] * 3]" in vort
    assert "a_scalar1" in vort and "scalar2" not in vort
    assert "a_speed" not in vort and "a_velocity" not in vort
    assert "pymod(x - c[0]" in vort  # the wrap of the vertex's cell on periodic axes
    dist = _src(attrs=("distance_to_seed",))
    assert "a_distance_to_seed" in dist and "locate_axis_t" not in dist  # no field sample needed


def test_attribute_flags_are_part_of_the_program_key(fields, ocl64, monkeypatch):
    monkeypatch.setattr(codegen, "_programs", {})
    f = fields["rotation"]
    seeds = _seeds(f, 2)
    flowkit.trace(f, seeds, backend=ocl64, max_length=1.0, attributes=("time",))
    assert codegen.cached_programs() == 1  # time and arc length need no kernel code
    flowkit.trace(f, seeds, backend=ocl64, max_length=1.0, attributes=("speed",))
    flowkit.trace(f, seeds, backend=ocl64, max_length=2.0, attributes=("arc_length", "speed"))
    assert codegen.cached_programs() == 2
    flowkit.trace(f, seeds, backend=ocl64, max_length=1.0, attributes=("speed", "p"))
    assert codegen.cached_programs() == 3
    keys = {k[0] for k in codegen._programs}
    assert {(k.attrs, k.scalars) for k in keys} == {((), 0), (("speed",), 0), (("speed",), 1)}


@pytest.mark.parametrize("aware", [True, False])
def test_a_line_stopped_by_nan_cells_keeps_finite_attributes_on_opencl(ocl64, aware):
    from test_integrate_attributes import NAN_FACE_SEEDS, nan_face_field

    f = nan_face_field()
    ref, got = _both(f, NAN_FACE_SEEDS, ocl64, attributes=("speed", "velocity", "T"),
                     cell_aware=aware)
    assert_same(ref, got, _extent(f))
    assert all(np.all(np.isfinite(a)) for a in got.point_data.values())


def test_vorticity_beside_a_nan_hole_matches_numba(ocl64):
    """Lines passing a NaN hole: the device's node curl takes the host's one-sided differences
    there, so the vorticity is finite, the same as numba's, and exact for v = (1, 0.2 + x^2, 0.1)
    (curl (0, 0, 2x), linear: the one-sided 3-point differences and the trilinear samples are
    exact)."""
    from test_integrate_attributes import _holed

    f, _, _ = _holed(lambda x, y, z: (1.0 + 0 * x, 0.2 + x**2, 0.1 + 0 * z))
    ax = f.grid.axes
    seeds = np.array([[ax[0][1], y, z] for y in np.linspace(ax[1][2], ax[1][7], 5)
                      for z in np.linspace(ax[2][2], ax[2][6], 4)])
    ref, got = _both(f, seeds, ocl64, attributes=("vorticity",), max_length=2.0)
    assert_same(ref, got, _extent(f))
    w = got.point_data["vorticity"]
    assert np.isfinite(w).all()
    np.testing.assert_allclose(w, np.stack([0 * w[:, 0], 0 * w[:, 0], 2 * got.points[:, 0]], 1),
                               rtol=0, atol=1e-9)
    # the lines do pass the hole: np.gradient's stencils alone leave NaN vorticity at some vertices
    g = f.grid
    d = [[curl.gradient(f.vector[..., c], g.axes[a], g.period[a], a) for a in range(3)]
         for c in range(3)]
    plain = np.stack([d[2][1] - d[1][2], d[0][2] - d[2][0], d[1][0] - d[0][1]], axis=-1)
    sampled, status = np.empty((len(got.points), 3)), np.empty(len(got.points), np.int8)
    interp.sample_vectors(*g.kernel_args(), plain, got.points.astype(np.float64), sampled, status)
    assert np.isnan(sampled).any()
