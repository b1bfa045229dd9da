"""Lines in lock-step (flowkit/integrate/lanes.py): the same lines as the scalar kernel, bit for
bit, with the lock-step doing the steps where it applies."""

import copy
import re
import threading

import numpy as np
import pytest
from numba import njit, typeof

from flowkit import trace
from flowkit.fields.analytic import ABCFlow, SolidBodyRotation
from flowkit.fields.bricks import NO_BRICKS
from flowkit.fields.field import Field
from flowkit.fields.grid import Grid
from flowkit.integrate import kernel as K
from flowkit.integrate import lanes
from flowkit.integrate.reasons import Reason
from flowkit.numba_cache import in_disk_cache


def _abc(holes=False, zero=False):
    f = ABCFlow().to_field(33, bounds=[[0.0, 6.0]] * 3, periodic=False)
    v = f.vector.copy()
    if holes:
        v[10:13, 10:20, 5:25] = np.nan
        v[20, 20, 20] = np.inf
    if zero:
        v[15:18, 15:18, 15:18] = 0.0
        v[0, 0, 0] = 0.0
    return Field(f.grid, v)


def _seeds(n=300):
    rng = np.random.default_rng(1)
    s = rng.uniform(0.1, 5.9, (n, 3))
    s[::41] = [-1.0, 2.0, 2.0]  # outside
    s[::53] = np.nan
    s[1] = [3.0, 3.0, 3.0]  # on a node: on faces of three axes
    return s


def _same(field, seeds, **kw):
    a = trace(field, seeds, backend=K.advance, **kw)
    b = trace(field, seeds, backend=lanes.advance, **kw)
    assert b.attrs["kernel_path"] == "numba lanes"
    assert np.array_equal(a.offsets, b.offsets)
    assert np.array_equal(a.points, b.points, equal_nan=True)
    for key in a.line_data:
        assert np.array_equal(np.asarray(a.line_data[key]), np.asarray(b.line_data[key])), key
    for key in a.point_data:
        assert np.array_equal(np.asarray(a.point_data[key]), np.asarray(b.point_data[key]),
                              equal_nan=True), key
    return a


CASES = {
    "rk4 arc length": {"step": 0.1, "parameter": "arc_length", "max_length": 10.0},
    "rk4 time, both directions": {"step": 0.05, "max_time": 5.0, "max_length": 1e9,
                                  "direction": "both"},
    "rk4 small buffer": {"step": 0.1, "max_length": 40.0, "budget": 7},
    "euler backward": {"method": "euler", "step": 0.01, "max_length": 5.0,
                       "direction": "backward"},
    "rk4 max_steps": {"step": 0.1, "max_length": 500.0, "max_steps": 37},
    "rk4 attributes": {"step": 0.1, "max_length": 10.0,
                       "attributes": ["speed", "time", "vorticity"]},
    "rk4 max_step": {"step": 0.05, "max_step": 0.03, "max_length": 10.0},
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_bit_identical_to_scalar_kernel(name):
    kw = {"method": "rk4", "cell_aware": False} | CASES[name]
    lines = _same(_abc(), _seeds(), **kw)
    reasons = np.asarray(lines.line_data["reason"])
    assert (reasons == int(Reason.OUT_OF_DOMAIN)).sum() > 100  # boundary events handed back


ADAPTIVE = {
    "dopri5 time": {"method": "dopri5", "rtol": 1e-6, "max_time": 8.0, "max_length": 1e9},
    "dopri5 loose, arc length": {"method": "dopri5", "rtol": 1e-3, "parameter": "arc_length",
                                 "max_length": 10.0},
    "bs23 both directions": {"method": "bs23", "rtol": 1e-5, "max_length": 6.0,
                             "direction": "both"},
    "cashkarp small buffer": {"method": "cashkarp", "rtol": 1e-7, "max_length": 20.0,
                              "budget": 9},
    "dop853 max_step": {"method": "dop853", "rtol": 1e-9, "max_step": 0.2, "max_length": 8.0},
    "dopri5 max_steps": {"method": "dopri5", "rtol": 1e-8, "max_length": 500.0,
                         "max_steps": 41},
}


@pytest.mark.parametrize("name", sorted(ADAPTIVE))
def test_adaptive_bit_identical_to_scalar_kernel(name):
    """Error-controlled steps in lock-step: per-lane step sizes, rejected steps redone while
    the other lanes go on, the kernel's controller; the lines are the scalar kernel's."""
    lines = _same(_abc(), _seeds(), cell_aware=False, **ADAPTIVE[name])
    assert np.asarray(lines.line_data["n_rejected"]).sum() > 0  # rejections in lock-step too
    reasons = np.asarray(lines.line_data["reason"])
    assert (reasons == int(Reason.OUT_OF_DOMAIN)).sum() > 50  # boundary events handed back


def _stretched(holes=False):
    """ABC on a rectilinear grid, cells growing 4:1 along x and unevenly along y."""
    x = 6.0 * np.linspace(0.0, 1.0, 40) ** 1.6
    y = np.cumsum(np.r_[0.0, np.random.default_rng(4).uniform(0.1, 0.3, 30)])
    f = ABCFlow().to_field(grid=Grid(x, y * 6.0 / y[-1], np.linspace(0.0, 6.0, 25)))
    v = f.vector.copy()
    if holes:
        v[20:23, 10:14, 5:15] = np.nan
    return Field(f.grid, v)


@pytest.mark.parametrize("method,holes", [("dopri5", False), ("rk4", True), ("dop853", True)])
def test_rectilinear_axes_bit_identical(method, holes):
    kw = {"step": 0.07} if method == "rk4" else {"rtol": 1e-7}
    lines = _same(_stretched(holes), _seeds(), method=method, cell_aware=False,
                  max_length=12.0, **kw)
    reasons = set(np.asarray(lines.line_data["reason"]).tolist())
    assert int(Reason.OUT_OF_DOMAIN) in reasons and (not holes or int(K.R_NAN) in reasons)


def _periodic(holes=False, uniform=True):
    """ABC periodic in x and y, the origin off 0 (the wrap rounds), bounded in z (lines leave
    through its faces); the x axis uneven unless uniform."""
    L = 2 * np.pi
    x = np.linspace(-1.3, L - 1.3, 32, endpoint=False)
    if not uniform:
        x = np.sort(np.r_[-1.3, np.random.default_rng(3).uniform(-1.3, L - 1.3, 30)])
    g = Grid.from_axes(x, np.linspace(0.7, L + 0.7, 24, endpoint=False), np.linspace(0, 6, 20),
                       periodic=(True, True, False), period=(L, L, 0.0))
    f = ABCFlow().to_field(grid=g)
    v = f.vector.copy()
    if holes:
        v[10:13, 5:9, 5:10] = np.nan
    return Field(f.grid, v)


@pytest.mark.parametrize("method,uniform,holes", [
    ("rk4", True, False), ("dopri5", True, True), ("bs23", False, False),
    ("cashkarp", True, False), ("dop853", False, True)])
def test_periodic_axes_bit_identical(method, uniform, holes):
    """Periodic axes in the lanes: cells wrapped as the scalar kernel wraps them, and its cached
    cell followed (a cell found again may differ from it in the last bit of its faces), also
    through a rejected step (cashkarp's f(y1) comes after the error test) and a small buffer."""
    L = 2 * np.pi
    seeds = np.random.default_rng(1).uniform([0.0, 0.0, 0.1], [L, L, 5.9], (300, 3))
    seeds[::37, 0] += 3 * L  # an image of the domain three periods away
    kw = {"step": 0.07} if method == "rk4" else {"rtol": 1e-7}
    lines = _same(_periodic(holes, uniform), seeds, method=method, cell_aware=False,
                  max_length=15.0, budget=40, **kw)
    reasons = set(np.asarray(lines.line_data["reason"]).tolist())
    assert int(Reason.OUT_OF_DOMAIN) in reasons and (not holes or int(K.R_NAN) in reasons)
    if method != "rk4":
        assert lines.line_data["n_rejected"].sum() > 0
    wrapped = np.ptp(lines.points[:, :2], axis=0)
    assert np.all(wrapped > L)  # lines crossed the periodic faces


@pytest.mark.parametrize("method", ["dopri5", "dop853"])
def test_adaptive_bit_identical_at_nan_and_stagnation(method):
    lines = _same(_abc(True, True), _seeds(), method=method, rtol=1e-6, cell_aware=False,
                  max_time=50.0, max_length=1e9)
    reasons = set(np.asarray(lines.line_data["reason"]).tolist())
    assert reasons >= {int(K.R_NAN), int(K.R_STAG)}


def test_stiffness_test_in_lock_step():
    """dopri5's stiffness test runs in the lanes as in the scalar kernel: the stiff field's
    lines are flagged, with the same counts on every line."""
    from flowkit.fields.analytic import LinearField

    seeds = np.random.default_rng(3).uniform([-0.8, -0.8, 0.2], [0.8, 0.8, 8.0], (70, 3))
    lines = _same(LinearField.stiff().to_field((4, 4, 11)), seeds, rtol=1e-6, atol=1e-6,
                  max_time=1.0, cell_aware=False)
    assert np.all(np.asarray(lines.line_data["stiff"]) == 1)


def test_bit_identical_where_lines_stall_at_a_wall():
    """A lane hands the step that would stall its line (kernel._stalled) to the scalar kernel,
    which stops the line there (stagnation); the anchor of the test travels with the line.
    dopri5, the default, is the method whose lines hover at this wall (dop853's and bs23's reach
    its face or slow below the threshold)."""
    from test_extreme import WALL_DIRECTION, no_slip_wall

    seeds = np.random.default_rng(5).uniform([0.02, 0.02, 0.02], [0.6, 0.8, 0.98], (100, 3))
    field = no_slip_wall()
    lines = _same(field, seeds, rtol=1e-6, atol=1e-6, max_time=1e6, max_steps=100_000,
                  cell_aware=False, stagnation=1e-6)
    # every line ends on the wall (stagnation, or a step that reached its face), none at
    # max_steps; lines stopped by their progress, where the field is faster than the threshold
    reasons = np.asarray(lines.line_data["reason"])
    assert set(reasons.tolist()) <= {K.R_STAG, K.R_OUT}
    ends = lines.points[lines.offsets[1:] - 1]
    speeds = np.linalg.norm(field.sample(ends[reasons == K.R_STAG])[0], axis=1)
    assert np.sum(speeds > 1e-6) >= 10, speeds
    assert np.all(np.asarray(lines.line_data["n_accepted"]) < 400)
    np.testing.assert_allclose(ends, seeds + (1.0 - seeds[:, 2:]) * WALL_DIRECTION, atol=5e-6,
                               rtol=0)


@pytest.mark.parametrize("holes,zero,param", [(True, False, "time"), (False, True, "arc_length"),
                                              (False, True, "time")])
def test_bit_identical_at_nan_and_stagnation(holes, zero, param):
    kw = {"max_time": 50.0, "max_length": 1e9} if param == "time" else {"max_length": 50.0}
    lines = _same(_abc(holes, zero), _seeds(), method="rk4", step=0.1, cell_aware=False,
                  parameter=param, **kw)
    reasons = set(np.asarray(lines.line_data["reason"]).tolist())
    assert reasons & {int(K.R_NAN), int(K.R_STAG)}


def _first_launch(field, seeds, **kw):
    """A copy of the first ``Launch`` trace hands its backend, taken before the kernel runs."""
    got = []

    def capture(launch):
        if not got:
            got.append(copy.deepcopy(launch))
        K.advance(launch)

    trace(field, seeds, backend=capture, **kw)
    return got[0]


def test_lockstep_takes_the_interior_steps():
    """Solid-body rotation inside the box, in arc length: the lock-step takes every step, the
    last one clipped at max_length, ends the lines there as the scalar kernel does, and its
    vertices are the scalar kernel's."""
    f = SolidBodyRotation().to_field(25)
    seeds = np.random.default_rng(2).uniform(-0.6, 0.6, (100, 3))
    kw = {"method": "rk4", "step": 0.05, "max_length": 3.0, "cell_aware": False,
          "parameter": "arc_length"}  # (in time, max_length is met on the dense output)
    L = _first_launch(f, seeds, **kw)
    g, m, si, sf, out_p, out_n = L.field, L.method, L.si, L.sf, L.out_p, L.out_n
    assert lanes.eligible(g.period, g.inv, m.info, L.io)
    L.io[K.P_PASS] = K.PASS_SETUP  # start the lines, as lanes.advance does
    K.advance(L)
    lanes.lockstep(*lanes.lockstep_args(L))
    steps = int(np.ceil(3.0 / 0.05))
    assert np.all(si[:, K.I_NACC] >= steps - 1)
    assert np.all(out_n == si[:, K.I_NACC] + 1)  # the seed and a vertex per step
    assert np.all(si[:, K.I_STATUS] == K.DONE)  # nothing left for the finishing pass
    assert np.all(si[:, K.I_REASON] == int(Reason.MAX_LENGTH))
    assert np.all(sf[:, K.S_TAU] == 3.0)  # the last step clipped at the limit exactly
    # the scalar kernel from the same start, as many steps, gives the same vertices
    ref = trace(f, seeds, backend=K.advance, **kw)
    for n in range(len(seeds)):
        m = out_n[n]
        assert np.array_equal(out_p[n, :m], ref.points[ref.offsets[n]:ref.offsets[n] + m])


@njit
def _f(px, py, pz, param, aware, gx, gy, gz, period, inv, vec, ci, cf, coef, k, row):
    # the kernel's helpers have no Python wrapper (they are only called from compiled code)
    return K._f(px, py, pz, param, aware, gx, gy, gz, period, inv, vec, NO_BRICKS, ci, cf, coef,
                k, row)


@njit
def _axis_cell(c, inv, x):
    return lanes._uniform_cell(c, inv, x)


def test_kernel_locates_a_point_on_a_face_afresh():
    """The scalar kernel keeps its cached cell only while a point is strictly inside it, so a
    point on a face gets the cell a fresh lookup gives (what the lock-step does), not the cell
    the line came from: with the cell below cached, a point on its upper face that the lookup
    puts in the cell above is evaluated there."""
    g = _first_launch(_abc(), _seeds(5), method="rk4", step=0.1, max_length=1.0,
                      cell_aware=False).field
    gx, gy, gz, period, inv, vec = g.gx, g.gy, g.gz, g.period, g.inv, g.vec
    # a node the lookup puts in the cell above it (rounding may put a node in the cell below)
    m = next(m for m in range(1, gx.size - 2)
             if _axis_cell(gx, inv[0], gx[m]) == m)
    ci, cf, coef, k = np.full(4, -1, np.int64), np.zeros(9), np.zeros((8, 3)), np.zeros((5, 4))
    y, z = gy[7] + 0.3 * (gy[8] - gy[7]), gz[9] + 0.6 * (gz[10] - gz[9])
    inside = gx[m - 1] + 0.5 * (gx[m] - gx[m - 1])
    _f(inside, y, z, 1, False, gx, gy, gz, period, inv, vec, ci, cf, coef, k, 0)
    assert ci[0] == m - 1
    _f(gx[m], y, z, 1, False, gx, gy, gz, period, inv, vec, ci, cf, coef, k, 1)
    assert ci[0] == m  # located afresh; the cell below holds the point too
    fresh = np.full(4, -1, np.int64), np.zeros(9), np.zeros((8, 3)), np.zeros((5, 4))
    _f(gx[m], y, z, 1, False, gx, gy, gz, period, inv, vec, *fresh, 0)
    assert np.array_equal(k[1], fresh[3][0])


def test_lockstep_is_vector_code():
    """The lock-step's lane loops compile to vector code (packed square roots, gathers) on an
    AVX-512 CPU.  numba lets LLVM vectorize them only while its alias analysis finds nothing in
    the parallel loop: one bool variable or view added there turns it all back into scalar code,
    lines still bit-identical, speed halved.  Compiled afresh here (a cached function has no
    assembly to read).  Only where LLVM surely finds gathers worth it (AVX-512, numba compiling
    for this host): on older CPUs its cost model may keep scalar code, which is slower but right."""
    from llvmlite import binding
    from numba import config

    if config.CPU_NAME or "+avx512f" not in binding.get_host_cpu_features().flatten():
        pytest.skip("needs numba compiling for an AVX-512 host")
    f = SolidBodyRotation().to_field(9)
    L = _first_launch(f, np.full((3, 3), 0.3), method="rk4", step=0.05, max_length=0.5,
                      cell_aware=False, parameter="arc_length")
    L.io[K.P_PASS] = K.PASS_SETUP
    K.advance(L)
    opts = {k: v for k, v in lanes.lockstep.targetoptions.items() if k != "nopython"}
    fresh = njit(**opts)(lanes.lockstep.py_func)  # its own options, not cached
    fresh(*lanes.lockstep_args(L))
    asm = fresh.overloads[fresh.signatures[0]].library.get_asm_str()
    assert re.search(r"vsqrtpd\s+%[yz]mm", asm)  # the evaluations, four or eight lanes at once
    assert re.search(r"vgather[dq]pd", asm)  # the cell corners


def test_eligible_only_where_it_applies():
    f = _abc()
    s = _seeds(5)
    base = {"method": "rk4", "step": 0.1, "max_length": 1.0, "cell_aware": False}

    def ok(field=f, last_row=None, **kw):
        L = _first_launch(field, s, **(base | kw))
        g, m = L.field, L.method
        if last_row is not None:  # the f(y1) stage's weights, changed
            m.a[m.info[K.M_FSAL], :m.info[K.M_NERR]] = last_row
        why = lanes.why_not(g.period, g.inv, m.info, L.io)
        assert lanes.eligible(g.period, g.inv, m.info, L.io) == (why == "")
        reasons.append(why)
        return why == ""

    reasons = []

    assert ok()
    # an f(y1) stage whose row differs from b: its point is summed from its own row, as the
    # scalar kernel sums it
    assert ok(last_row=[1 / 6, 1 / 3, 1 / 3, 1 / 6 + 1e-16])
    assert ok(method="euler")
    assert ok(method="dopri5", step=None)  # adaptive: per-lane steps
    assert ok(method="dop853", step=None)  # the most stages before f(y1)
    # auto's lines may switch to the Rosenbrock stepper, which only the scalar kernel holds
    lines = trace(ABCFlow().to_field(16), np.full((4, 3), 1.0), method="auto", cell_aware=False,
                  max_length=1.0)
    assert lines.attrs["kernel_path"] == "numba scalar: the Rosenbrock stepper"
    assert not ok(cell_aware=True) and reasons[-1] == "cell-aware stepping"
    assert not ok(spacing=0.05) and reasons[-1] == "resampled output"  # the dense output
    periodic = ABCFlow().to_field(16, bounds=[[0.0, 2 * np.pi]] * 3)
    assert ok(periodic, max_length=1.0)
    rect = Grid(np.r_[0.0, 0.5, 2.0, 6.0], np.linspace(0, 6, 7), np.linspace(0, 6, 7))
    assert ok(ABCFlow().to_field(grid=rect))  # bisection on the non-uniform axis


def test_scalar_kernel_traces_while_the_lock_step_compiles(monkeypatch):
    """Where the lock-step is neither compiled nor in the disk cache, the launches go to the
    scalar kernel (the same lines, the path recorded) and it compiles in a background thread
    once the trace is done; then the lanes take over."""
    gate, ready = threading.Event(), []
    monkeypatch.setattr(lanes, "WAIT", False)
    monkeypatch.setattr(lanes, "_pending", {})
    monkeypatch.setattr(lanes, "in_disk_cache", lambda disp, sig: False)
    monkeypatch.setattr(lanes, "_compiled", lambda sig: bool(ready))
    monkeypatch.setattr(lanes, "_compile", lambda sig: gate.wait(30) and ready.append(sig))
    f, s = _abc(True), _seeds()
    kw = {"method": "dopri5", "rtol": 1e-6, "cell_aware": False, "max_length": 8.0,
          "budget": 9}  # several launches
    a = trace(f, s, **kw)
    assert a.attrs["kernel_path"] == "numba scalar: " + lanes.COMPILING
    assert len(lanes._pending) == 1  # one compile, started after the trace
    (t,) = lanes._pending.values()
    assert t is not None and t.is_alive()
    trace(f, s, **kw)
    assert lanes._pending == {next(iter(lanes._pending)): t}
    gate.set()
    t.join(30)
    b = trace(f, s, **kw)
    assert b.attrs["kernel_path"] == "numba lanes"
    assert np.array_equal(a.offsets, b.offsets)
    assert np.array_equal(a.points, b.points, equal_nan=True)


def test_lock_step_found_in_the_disk_cache():
    """The probe of numba's cache index finds the lock-step this process compiled (it is
    cached on disk), so a fresh process loads it instead of tracing without it."""
    f = _abc()
    L = _first_launch(f, _seeds(5), method="rk4", step=0.1, max_length=1.0, cell_aware=False)
    sig = tuple(typeof(a) for a in lanes.lockstep_args(L))
    lanes.lockstep.compile(sig)
    assert in_disk_cache(lanes.lockstep, sig)
    assert not in_disk_cache(lanes.lockstep, sig[:-1] + (typeof(np.zeros(3, np.int32)),))
