"""Cell-aware steps across faces: a looser tolerance costs less, and the error still follows it.

ABC flow on a 64-cells-per-period grid (one period), arc length 10; errors of the end point
against a cell-by-cell DOP853 at rtol 1e-12 on the same trilinear interpolant (integration
error only).  Every number asserted is a tolerance-scaled bound or a step count.
"""

from __future__ import annotations

import numpy as np
import pytest

import flowkit
from flowkit.fields import analytic as an
from flowkit.integrate.reasons import Reason

L = 10.0
N = 64


@pytest.fixture(scope="module")
def problem():
    two_pi = 2.0 * np.pi
    field = an.ABCFlow().to_field(shape=(N + 1,) * 3, bounds=((0.0, two_pi),) * 3)
    rng = np.random.default_rng(7)
    seeds = rng.uniform(0.35 * two_pi, 0.65 * two_pi, (40, 3))  # lines of length 10 stay inside
    common = {"max_length": L, "parameter": "arc_length"}
    ref = flowkit.trace(field, seeds, method="dop853", rtol=1e-12, atol=1e-12, cross_faces=False,
                        **common)
    assert np.all(ref.line_data["reason"] == Reason.MAX_LENGTH)
    return field, seeds, common, ref.points[ref.offsets[1:] - 1], two_pi


def _run(problem, rtol, **kw):
    field, seeds, common, ref_end, _ = problem
    lines = flowkit.trace(field, seeds, rtol=rtol, **common, **kw)
    end = lines.points[lines.offsets[1:] - 1]
    steps = (lines.line_data["n_accepted"] + lines.line_data["n_rejected"]).mean()
    return lines, np.median(np.linalg.norm(end - ref_end, axis=1)), steps


def test_cost_falls_with_tolerance_and_error_follows_it(problem):
    extent = problem[4]
    _, err_faces, steps_faces = _run(problem, 1e-3, cross_faces=False)
    prev = np.inf
    for rtol in (1e-6, 1e-5, 1e-4, 1e-3):
        lines, err, steps = _run(problem, rtol)
        assert np.all(lines.line_data["reason"] == Reason.MAX_LENGTH)
        assert steps <= prev * 1.02, (rtol, steps, prev)  # never dearer for a looser tolerance
        prev = steps
        # the default atol is rtol x extent: the median end error stays well below it
        assert err <= 0.5 * rtol * extent, (rtol, err)
    # at the loosest tolerance most steps cross faces, and the line costs a fraction
    assert steps < steps_faces / 2, (steps, steps_faces)
    assert lines.line_data["n_crossing"].sum() > 0
    assert err > err_faces  # (the price: less accuracy than asked-for-nothing face stepping)


def test_tight_tolerance_keeps_face_accuracy(problem):
    """Where the kinks cost more than the tolerance, steps end on faces as before: the same error
    (within 2x) for at most 10 % more attempted steps (the crossings tried and refused)."""
    for rtol in (1e-7, 1e-9):
        _, err, steps = _run(problem, rtol)
        _, err_f, steps_f = _run(problem, rtol, cross_faces=False)
        assert err <= 2.0 * err_f + 1e-12, (rtol, err, err_f)
        assert steps <= 1.1 * steps_f, (rtol, steps, steps_f)


def test_kink_bound_not_the_embedded_estimate_limits_crossing(problem):
    """Without the kink bound a crossing step is judged by the embedded estimate alone, which does
    not see the kinks: plain stepping shows what that costs (errors 100x and more above the
    crossing default at the same rtol)."""
    _, err_cross, _ = _run(problem, 1e-6)
    _, err_plain, _ = _run(problem, 1e-6, cell_aware=False)
    assert err_plain > 30 * err_cross, (err_plain, err_cross)


def test_opencl_crosses_as_numba(problem):
    pytest.importorskip("pyopencl")  # the `opencl` extra; CI installs it (PoCL)
    from flowkit.integrate.opencl.backend import OpenCLAdvance

    adv = OpenCLAdvance("opencl", dtype="float64")
    field, seeds, common, _, _ = problem
    kw = {"rtol": 1e-3, **common}
    ref = flowkit.trace(field, seeds[:12], **kw)
    got = flowkit.trace(field, seeds[:12], backend=adv, **kw)
    assert ref.line_data["n_crossing"].sum() > 0
    for name in ("n_accepted", "n_rejected", "n_crossing", "reason"):
        np.testing.assert_array_equal(got.line_data[name], ref.line_data[name], err_msg=name)
    np.testing.assert_allclose(got.points, ref.points, rtol=0, atol=1e-9)
