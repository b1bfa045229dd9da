"""Methods as data: tableau consistency, measured convergence orders, DP5 error vs tolerance."""

import numpy as np
import pytest

from flowkit import TraceOptions, trace
from flowkit.fields.analytic import LinearField, SolidBodyRotation
from flowkit.integrate.methods import METHODS, get_method
from flowkit.integrate.options import OptionsError

# linear fields are reproduced exactly by trilinear interpolation: one cell is the exact field
BOX = [[-3, 3], [-3, 3], [-1, 1]]
FIELDS = {
    "rotation": SolidBodyRotation(omega=1.0),
    "spiral": LinearField.spiral(omega=1.0, rate=-0.1),
}
SEED = np.array([[1.0, 0.2, 0.1]])
T = 2.0
# step counts in the asymptotic range of each method (errors well above rounding)
STEPS = {"euler": (100, 200), "bs23": (10, 20), "rk4": (5, 10), "dopri5": (8, 16),
         "cashkarp": (8, 16), "dop853": (2, 4)}


@pytest.mark.parametrize("name", sorted(METHODS))
def test_tableau_is_consistent(name):
    m = METHODS[name]
    m.check()
    # dense output reproduces y0 at θ = 0 and y1 at θ = 1 (the p rows sum to b)
    assert np.allclose(m.p.sum(axis=1), m.b, atol=1e-12)
    assert m.a[m.fsal_stage].tolist() == m.b.tolist() and m.c[m.fsal_stage] == 1


def test_registry_lookup_and_errors():
    assert get_method("RK45").name == "dopri5"
    with pytest.raises(ValueError, match="unknown method 'rk99'.*dopri5"):
        get_method("rk99")


@pytest.mark.parametrize("fname", sorted(FIELDS))
@pytest.mark.parametrize("name", sorted(STEPS))
def test_convergence_order(name, fname):
    """Fixed steps h and h/2 (adaptive methods with a huge tolerance and max_step = h)."""
    af = FIELDS[fname]
    f = af.to_field(shape=(2, 2, 2), bounds=BOX)
    exact = af.trajectory(SEED, T)[0]
    errs = []
    for n in STEPS[name]:
        h = T / n
        lines = trace(f, SEED, method=name, step=h, max_step=h, rtol=1e3, max_time=T,
                      cell_aware=False)
        assert lines.line_data["reason"][0] == 2  # max_time
        assert lines.line_data["n_accepted"][0] in (n, n + 1)
        errs.append(np.linalg.norm(lines.points[-1] - exact))
    order = np.log2(errs[0] / errs[1])
    assert abs(order - METHODS[name].order) < 0.3, (errs, order)


@pytest.mark.parametrize("fname", sorted(FIELDS))
@pytest.mark.parametrize("rtol", [1e-5, 1e-7, 1e-9])
def test_dopri5_end_point_error_below_ten_times_tolerance(fname, rtol):
    af = FIELDS[fname]
    rng = np.random.default_rng(1)
    seeds = np.c_[rng.uniform(-1.5, 1.5, (20, 2)), rng.uniform(-0.5, 0.5, 20)]
    f = af.to_field(shape=(7, 7, 3), bounds=BOX)  # several cells: cell-aware stepping at work
    exact = af.trajectory(seeds, 3.0)
    for aware in (True, False):
        lines = trace(f, seeds, rtol=rtol, atol=rtol, max_time=3.0, cell_aware=aware)
        assert np.all(lines.line_data["reason"] == 2)
        end = lines.points[lines.offsets[1:] - 1]
        tol = rtol + rtol * np.abs(exact).max(axis=1)
        err = np.linalg.norm(end - exact, axis=1)
        assert np.all(err < 10 * tol), (aware, err.max(), tol.min())


def test_options_are_validated_with_clear_errors():
    with pytest.raises(OptionsError, match="option rtol must be positive"):
        TraceOptions(rtol=0)
    with pytest.raises(OptionsError, match="option direction must be one of"):
        TraceOptions(direction="sideways")
    with pytest.raises(OptionsError, match="spacing and count exclude each other"):
        TraceOptions(spacing=0.1, count=10)
    with pytest.raises(OptionsError, match="option max_length must be positive"):
        TraceOptions(max_length=-1.0)
    with pytest.raises(OptionsError, match="unknown trace option"):
        TraceOptions().replace(tolerance=1)
    with pytest.raises(OptionsError, match="option atol must be a number or 3 numbers"):
        TraceOptions(atol=[1, 2])
    assert TraceOptions(parameter="arc").parameter == "arc_length"
    assert TraceOptions(attributes="speed, time").attributes == ("speed", "time")
