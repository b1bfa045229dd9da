"""Stiffness detection (Hairer–Wanner's DP5 test) and the L-stable ROS34PW2 driver."""

import dataclasses

import numpy as np
import pytest
from numba import njit

from flowkit import trace
from flowkit.cli import main
from flowkit.fields.analytic import ABCFlow, LinearField, SolidBodyRotation
from flowkit.fields.bricks import NO_BRICKS
from flowkit.integrate import kernel as K
from flowkit.integrate.methods import Method, MethodError, get_method
from flowkit.integrate.options import OptionsError
from flowkit.integrate.reasons import Reason
from flowkit.integrate.stiffness import (
    HLAMBDA_STIFF,
    STIFF_STEPS,
    cell_jacobian,
    is_stiff,
    stage_hlambda,
    stiff_update,
)

STIFF = LinearField.stiff()  # eigenvalues -1, -1e4 in the xy-plane, drift 1 along z
STIFF_GRID = STIFF.to_field((4, 4, 11))  # linear: trilinear-exact; the fixed axis is mid-cell
SEEDS = np.array([[0.5, -0.3, 0.0], [0.9, 0.2, 1.0], [-0.2, -0.7, 0.5]])


@njit
def _relocate(gx, gy, gz, period, inv, vec, px, py, pz, ci, cf, coef):
    # the kernel's helpers have no Python wrapper (they are only called from compiled code)
    return K._relocate(gx, gy, gz, period, inv, vec, NO_BRICKS, px, py, pz, ci, cf, coef)


def test_cell_jacobian_is_the_exact_gradient_of_the_interpolant():
    fld = ABCFlow().to_field(9, bounds=[[0, 2.0]] * 3, periodic=False)
    g = fld.grid
    p = np.array([0.61, 1.13, 0.37])
    coef, cf, ci = np.empty((8, 3)), np.empty(9), np.full(3, -1, np.int64)
    assert _relocate(*g.kernel_args(), fld.vector, *p, ci, cf, coef)
    J = np.empty((3, 3))
    cell_jacobian(coef, cf, *p, J)
    eps = 1e-6  # central differences of the trilinear interpolant (within the same cell)
    fd = np.stack([(fld.sample(p + eps * e)[0] - fld.sample(p - eps * e)[0])[0] / (2 * eps)
                   for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(J, fd, rtol=1e-7, atol=1e-8)
    # and on a linear field it is the field's matrix
    lin = STIFF_GRID
    assert _relocate(*lin.grid.kernel_args(), lin.vector, 0.2, -0.1, 3.3, ci, cf, coef)
    cell_jacobian(coef, cf, 0.2, -0.1, 3.3, J)
    np.testing.assert_allclose(J, STIFF.A, rtol=1e-12, atol=1e-8)


def test_stiff_update_counts_consecutive_steps_and_resets():
    s = 0
    for _ in range(STIFF_STEPS - 1):
        s = stiff_update(s, 2 * HLAMBDA_STIFF)
    assert not is_stiff(s)
    for _ in range(6):  # six non-stiff steps reset the count
        s = stiff_update(s, 0.1)
    for _ in range(STIFF_STEPS - 1):
        s = stiff_update(s, 2 * HLAMBDA_STIFF)
    assert not is_stiff(s)
    s = stiff_update(s, 2 * HLAMBDA_STIFF)
    assert is_stiff(s)
    for _ in range(50):  # the flag is sticky: the line met a stiff stretch
        s = stiff_update(s, 0.1)
    assert is_stiff(s)


def _dp5_detect(A, y0, t_end, rtol):
    """A plain adaptive DP5 on y' = A y (the registry's tableau), feeding the detector; returns
    (flag, steps, first step flagged, median hλ)."""
    m = get_method("dopri5")
    y, t, h, state, first, hl = np.array(y0, float), 0.0, 1e-4, 0, -1, []
    n = 0
    while t < t_end and n < 5000:
        k = np.zeros((7, 4))
        ys = None
        for s in range(7):
            yt = y + h * (m.a[s, :s] @ k[:s, :3])
            if s == 5:
                ys = yt
            k[s, :3] = A @ yt
        y1 = y + h * (m.b @ k[:, :3])
        sc = rtol + rtol * np.maximum(abs(y), abs(y1))
        err = np.sqrt(np.mean((h * (m.e @ k[:, :3]) / sc) ** 2))
        if err <= 1:
            hlam = stage_hlambda(h, k, 6, 5, ys, y1)
            hl.append(hlam)
            state = stiff_update(state, hlam)
            if is_stiff(state) and first < 0:
                first = n
            y, t, n = y1, t + h, n + 1
        h *= min(5.0, max(0.2, 0.9 * err ** -0.2)) if err > 0 else 5.0
    return is_stiff(state), n, first, float(np.median(hl))


def test_hairer_wanner_test_flags_the_stiff_field_and_not_a_mild_one():
    A = STIFF.A.copy()
    flag, _, first, hlam = _dp5_detect(A, [0.5, -0.3, 0.0], 0.5, 1e-6)
    assert flag and 0 < first < 200, (flag, first)
    # the step is held on DP5's stability boundary (|hλ| ≈ 3.3), estimated from the stages
    assert 2.0 < hlam < 4.0, hlam
    flag, _, _, hlam = _dp5_detect(-np.eye(3) + 0.3 * np.eye(3)[::-1], [0.5, -0.3, 0.2], 5.0, 1e-6)
    assert not flag and hlam < HLAMBDA_STIFF


def test_ros34pw2_coefficients_give_order_3_and_l_stability():
    ros = get_method("ros34pw2")
    G = ros.gammas + ros.gamma * np.eye(4)

    def stab(z, b):  # R(z) for y' = λy: (I - z(α + Γ)) k = z 1 y0
        k = np.linalg.solve(np.eye(4) - z * (ros.alpha + G), z * np.ones(4))
        return 1 + b @ k

    for z, p in ((1e-2, 3), (1e-2, 2)):
        b = ros.b if p == 3 else ros.bhat
        ratio = abs(stab(z, b) - np.exp(z)) / abs(stab(z / 2, b) - np.exp(z / 2))
        assert abs(np.log2(ratio) - (p + 1)) < 0.2  # local error O(z^(p+1))
    assert abs(stab(-1e10, ros.b)) < 1e-8  # L-stable
    for z in (-1e4, -1.0, 1e3j, -5 + 50j):
        assert abs(stab(z, ros.b)) <= 1.0


def test_rosenbrock_beats_dopri5_tenfold_on_the_stiff_field():
    T = 5.0
    exact = STIFF.trajectory(SEEDS, T)
    res = {}
    for name, run in (("dopri5", lambda: trace(STIFF_GRID, SEEDS, rtol=1e-6, atol=1e-6, max_time=T)),
                      ("ros34pw2", lambda: trace(STIFF_GRID, SEEDS, method="ros34pw2", rtol=1e-6, atol=1e-6,
                                                            max_time=T))):
        L = run()
        assert np.all(L.line_data["reason"] == Reason.MAX_TIME)
        assert np.all(np.isfinite(L.points))
        end = L.points[L.offsets[1:] - 1]
        res[name] = (np.abs(end - exact).max(), L.line_data["n_accepted"] + L.line_data["n_rejected"])
    err_d, steps_d = res["dopri5"]
    err_r, steps_r = res["ros34pw2"]
    assert err_r < 20 * 1e-6 and err_r < 3 * err_d, res  # same accuracy...
    assert np.all(10 * steps_r <= steps_d), res  # ...with at least 10x fewer steps


def test_rosenbrock_records_stiffness_and_error_scales_with_tolerance():
    T = 5.0
    exact = STIFF.trajectory(SEEDS, T)
    errs = []
    for tol in (1e-4, 1e-7):
        L = trace(STIFF_GRID, SEEDS, method="ros34pw2", rtol=tol, atol=tol, max_time=T)
        assert np.all(L.line_data["stiff"] == 1) and np.all(L.line_data["stiff_steps"] >= 15)
        errs.append(np.abs(L.points[L.offsets[1:] - 1] - exact).max())
        assert errs[-1] < 20 * tol
    assert errs[1] < errs[0] / 30
    # a mild field is not stiff
    rot = SolidBodyRotation()
    fld = rot.to_field(9)
    L = trace(fld, [[0.5, 0.0, 0.1]], method="ros34pw2", rtol=1e-6, atol=1e-6, max_time=3.0)
    assert L.line_data["stiff"][0] == 0 and L.line_data["stiff_steps"][0] == 0
    np.testing.assert_allclose(L.points[-1], rot.trajectory([[0.5, 0.0, 0.1]], 3.0)[0], atol=2e-5)


def test_rosenbrock_on_a_curved_grid_field_and_in_arc_length():
    fld = ABCFlow().to_field(17, bounds=[[0, 2 * np.pi]] * 3, periodic=False)
    seeds = np.array([[3.0, 3.1, 2.9], [2.5, 3.7, 3.3]])
    ref = trace(fld, seeds, method="dop853", rtol=1e-12, atol=1e-12, max_length=2.0,
                parameter="arc_length")
    for tol in (1e-5, 1e-8):
        L = trace(fld, seeds, method="ros34pw2", rtol=tol, atol=tol, max_length=2.0, parameter="arc_length")
        assert np.all(L.line_data["reason"] == Reason.MAX_LENGTH)
        err = np.abs(L.points[L.offsets[1:] - 1] - ref.points[ref.offsets[1:] - 1]).max()
        assert err < 50 * tol, (tol, err)
        # time mode reaches the same curve: arc length integrated as the 4th component
        Lt = trace(fld, seeds, method="ros34pw2", rtol=tol, atol=tol, max_length=2.0)
        assert np.all(Lt.line_data["reason"] == Reason.MAX_LENGTH)
        assert np.abs(Lt.points[Lt.offsets[1:] - 1] - ref.points[ref.offsets[1:] - 1]).max() < 50 * tol


def test_rosenbrock_terminations():
    # leaves the box at z = 10 exactly
    L = trace(STIFF_GRID, SEEDS[:1], method="ros34pw2", rtol=1e-6, atol=1e-6)
    assert L.line_data["reason"][0] == Reason.OUT_OF_DOMAIN
    assert abs(L.points[-1, 2] - 10.0) < 1e-9
    # seed outside: no vertex; a long line through tiny buffers: nothing truncated
    L = trace(STIFF_GRID, [[5.0, 0, 0], [0.5, -0.3, 0.0]], method="ros34pw2", rtol=1e-9, atol=1e-9,
                         max_steps=10_000)
    assert L.line_data["reason"][0] == Reason.SEED_OUTSIDE and L.offsets[1] == 0
    assert L.line_data["reason"][1] == Reason.OUT_OF_DOMAIN and len(L[1].points) > 1024
    # step budget
    L = trace(STIFF_GRID, SEEDS[:1], method="ros34pw2", rtol=1e-9, atol=1e-9, max_steps=20)
    assert L.line_data["reason"][0] == Reason.MAX_STEPS
    assert L.line_data["n_accepted"][0] + L.line_data["n_rejected"][0] == 20
    # a NaN hole ahead: stops before it, every vertex finite
    fld = STIFF.to_field((4, 4, 11))
    fld.vector[:, :, 6:] = np.nan
    L = trace(fld, SEEDS[:1], method="ros34pw2", rtol=1e-6, atol=1e-6)
    assert L.line_data["reason"][0] == Reason.NAN_FIELD
    assert np.all(np.isfinite(L.points)) and L.points[-1, 2] <= 5.0 + 1e-9



@pytest.mark.parametrize("direction", ["forward", "both"])
@pytest.mark.parametrize("aware", [True, False], ids=["cell_aware", "plain"])
def test_kernel_flags_the_stiff_field_and_not_abc_or_rotation(aware, direction):
    # dopri5 in the kernel: line_data["stiff"] from Hairer & Wanner's test on its own stages
    L = trace(STIFF_GRID, SEEDS, rtol=1e-6, atol=1e-6, max_time=1.0, cell_aware=aware,
              direction=direction)
    assert L.line_data["stiff"].dtype == np.int8
    assert np.all(L.line_data["stiff"] == 1), L.line_data["stiff"]
    mild = [(SolidBodyRotation().to_field(9), [[0.5, 0.0, 0.1], [0.2, -0.3, 0.0]], 20.0),
            (ABCFlow().to_field(17, bounds=[[0, 2 * np.pi]] * 3), [[3.0, 3.1, 2.9], [1, 2, 3]], 20.0)]
    for fld, seeds, T in mild:
        for tol in (1e-3, 1e-8):
            L = trace(fld, seeds, rtol=tol, atol=tol, max_time=T, cell_aware=aware,
                      direction=direction)
            assert np.all(L.line_data["n_accepted"] >= STIFF_STEPS)  # room for the flag
            assert np.all(L.line_data["stiff"] == 0), (fld.source, tol)
    # a method without a stiffness stage reports 0, never a guess
    L = trace(STIFF_GRID, SEEDS, method="cashkarp", rtol=1e-6, atol=1e-6, max_time=0.2)
    assert np.all(L.line_data["stiff"] == 0)


def test_the_stiffness_test_reads_the_stages_the_method_names():
    """Cash–Karp's stage at c = 1 is row 4 and its f(y1) row 6, not dopri5's rows 5 and 6:
    named as its stiffness stage, the stiff field is flagged in both kernels (scalar and
    lock-step), the rotation is not; a method whose steps never reach the threshold
    (Heun–Euler, stable to h|λ| = 2) is refused."""
    ck = dataclasses.replace(get_method("cashkarp"), name="ck_stiff", stiffness_stage=4)
    for aware in (True, False):
        L = trace(STIFF_GRID, SEEDS, method=ck, rtol=1e-6, atol=1e-6, max_time=0.2,
                  cell_aware=aware)
        assert np.all(L.line_data["stiff"] == 1), L.line_data["stiff"]
        L = trace(SolidBodyRotation().to_field(9), [[0.5, 0.0, 0.1]], method=ck, rtol=1e-6,
                  atol=1e-6, max_time=20.0, cell_aware=aware)
        assert L.line_data["n_accepted"][0] >= STIFF_STEPS and L.line_data["stiff"][0] == 0
    with pytest.raises(MethodError, match=r"stable only up to h\|λ\| = 2.00"):
        Method.from_butcher("heun", [0.0, 1.0], [[0.0, 0.0], [1.0, 0.0]], [0.5, 0.5],
                            [1.0, 0.0], order=2, err_order=1, stiffness_stage=1).check()


def test_ros34pw2_through_trace_both_directions_and_its_limits():
    rot = SolidBodyRotation()
    fld = rot.to_field(9)
    seeds = np.array([[0.5, 0.0, 0.1], [0.0, -0.3, 0.2]])
    L = trace(fld, seeds, method="ros34pw2", rtol=1e-7, atol=1e-7, max_time=2.0, direction="both",
              attributes=("time",))
    assert L.attrs["method"] == "ros34pw2"
    assert np.all(L.line_data["reason"] == Reason.MAX_TIME)
    assert np.all(L.line_data["reason_backward"] == Reason.MAX_TIME)
    first, last = L.points[L.offsets[:-1]], L.points[L.offsets[1:] - 1]
    np.testing.assert_allclose(first, rot.trajectory(seeds, -2.0), atol=2e-5)
    np.testing.assert_allclose(last, rot.trajectory(seeds, 2.0), atol=2e-5)
    t = L.point_data["time"]  # ordered through the seed, negative before it
    assert np.all(np.diff(t)[np.diff(L.line_index()) == 0] > 0)
    np.testing.assert_allclose(t[L.offsets[:-1]], -2.0)
    np.testing.assert_allclose(t[L.offsets[1:] - 1], 2.0)
    # the wrapper is trace(method="ros34pw2")
    one = trace(fld, seeds, method="ros34pw2", rtol=1e-7, atol=1e-7, max_time=2.0)
    assert one.equals(trace(fld, seeds, method="ros34pw2", rtol=1e-7, atol=1e-7, max_time=2.0))
    with pytest.raises(OptionsError, match="ros34pw2.*spacing"):
        trace(fld, seeds, method="ros34pw2", spacing=0.1)
    with pytest.raises(OptionsError, match="numba backend only"):
        trace(fld, seeds, method="ros34pw2", backend="opencl")


def test_auto_switches_stiff_lines_to_ros34pw2():
    T = 5.0
    exact = STIFF.trajectory(SEEDS, T)
    dp = trace(STIFF_GRID, SEEDS, rtol=1e-6, atol=1e-6, max_time=T)
    L = trace(STIFF_GRID, SEEDS, method="auto", rtol=1e-6, atol=1e-6, max_time=T)
    assert np.all(L.line_data["stiff"] == 1) and np.all(L.line_data["ros34pw2"] == 1)
    np.testing.assert_array_equal(L.line_data["seed_id"], np.arange(len(SEEDS)))
    assert np.all(L.line_data["reason"] == Reason.MAX_TIME)
    assert np.abs(L.points[L.offsets[1:] - 1] - exact).max() < 20e-6
    assert np.all(10 * L.line_data["n_accepted"] <= dp.line_data["n_accepted"])
    # each line switches in place: dopri5's line up to the step its test flags it (at least
    # STIFF_STEPS steps on), the Rosenbrock stepper's after
    for i in range(len(SEEDS)):
        a, b = L.line_points(i), dp.line_points(i)
        same = np.flatnonzero(np.any(a[:len(b)] != b[:len(a)], axis=1))[0]
        assert STIFF_STEPS < same < 200, same
    # a mixed batch: the stiff seed switches, the mild ones (rotation) are dopri5's lines
    rot = SolidBodyRotation().to_field(9)
    seeds = [[0.5, 0.0, 0.1], [0.2, -0.3, 0.0]]
    a = trace(rot, seeds, method="auto", max_time=3.0, direction="both")
    b = trace(rot, seeds, max_time=3.0, direction="both")
    assert np.all(a.line_data["ros34pw2"] == 0)
    np.testing.assert_array_equal(a.points, b.points)


def test_cli_method_ros34pw2(tmp_path):
    from flowkit import read_lines

    f = STIFF_GRID
    np.savez(tmp_path / "f.npz", x=f.grid.x, y=f.grid.y, z=f.grid.z, U=f.vector)
    out = tmp_path / "lines.h5"
    for method in ("ros34pw2", "auto"):
        assert main(["trace", str(tmp_path / "f.npz"), "-o", str(out), "--seeds",
                     "line:0.5,-0.3,0.0:0.9,0.2,1.0:3", "--method", method, "--max-time", "5",
                     "--quiet"]) == 0
        back = read_lines(out)
        assert back.attrs["method"] == method and np.all(back.line_data["stiff"] == 1)
        assert np.all(back.line_data["n_accepted"] < 200)  # dopri5 needs ~15000 here
