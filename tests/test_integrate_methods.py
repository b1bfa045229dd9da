"""Methods as data: check() refuses broken tableaux, the orders measured on a nonlinear field are
the declared ones, the error estimate has its declared order, DP5 error vs tolerance."""

import dataclasses

import numpy as np
import pytest

from flowkit import Field, TraceOptions, trace
from flowkit.fields import Grid
from flowkit.fields.analytic import LinearField, SolidBodyRotation
from flowkit.integrate.methods import METHODS, MethodError, get_method
from flowkit.integrate.options import OptionsError

# linear fields are reproduced exactly by trilinear interpolation: one cell is the exact field
BOX = [[-3, 3], [-3, 3], [-1, 1]]
FIELDS = {
    "rotation": SolidBodyRotation(omega=1.0),
    "spiral": LinearField.spiral(omega=1.0, rate=-0.1),
}


class Bilinear:
    """u = -y, v = x, w = x y: bilinear, so trilinear interpolation reproduces it too, and
    nonlinear, so a method's error there shows the order conditions a linear field cannot see
    (on a linear field only the conditions b·A^k·1 = 1 / (k + 1)! are at work)."""

    def to_field(self, shape, bounds):
        axes = [np.linspace(lo, hi, n) for (lo, hi), n in zip(bounds, shape)]
        x, y, _ = np.meshgrid(*axes, indexing="ij")
        return Field(Grid.from_axes(*axes), np.stack([-y, x, x * y], axis=-1))

    def trajectory(self, seeds, t):
        x0, y0, z0 = np.asarray(seeds, float).T
        r2, phi = x0 * x0 + y0 * y0, np.arctan2(y0, x0)
        r = np.sqrt(r2)
        return np.c_[r * np.cos(t + phi), r * np.sin(t + phi),
                     z0 + r2 / 4 * (np.cos(2 * phi) - np.cos(2 * (t + phi)))]


BILINEAR = Bilinear()
SEED = np.array([[1.0, 0.2, 0.1]])
T = 2.0
# step counts in the asymptotic range of each method (errors well above rounding)
STEPS = {"euler": (100, 200), "bs23": (10, 20), "rk4": (5, 10), "dopri5": (16, 32),
         "cashkarp": (8, 16), "dop853": (2, 4)}


def _moved(m, what, d):
    """A copy of method m with d moved between two coefficients of ``what``, everything else
    kept consistent (rows, the f(y1) stage, the dense output), so that check() can only object
    to ``what``: "b" (the weights of y1), "e" (the error weights), "rows" (a row of a no longer
    sums to its c), "p" (the dense output)."""
    a, b, e, p = m.a.copy(), m.b.copy(), m.e.copy(), m.p.copy()
    # stages of different c: the first, and the last one before both the error test and f(y1)
    i, j = 0, min(m.n_err, m.fsal_stage) - 1
    if what == "b":  # b·c changes; the rows of the f(y1) stage and of p follow b
        b[i] += d
        b[j] -= d
        a[m.fsal_stage, i] += d
        a[m.fsal_stage, j] -= d
        p[i, 0] += d
        p[j, 0] -= d
    elif what == "e":  # (b − e)·c changes, Σ e stays 0
        e[i] += d
        e[j] -= d
    elif what == "rows":
        a[1, 0] += d
    elif what == "p":  # every row still sums to its b; the first two columns no longer to (1, 0)
        p[i, 0] += d
        p[i, 1] -= d
    return dataclasses.replace(m, a=a, b=b, e=e, p=p)


BREAKS = {"b": "b miss the order condition",
          "e": "the embedded weights b − e miss the order condition",
          "rows": r"row a\[1, :\] sums to",
          "p": r"dense output column p\[:, 0\]"}
CASES = [(n, w) for n, m in sorted(METHODS.items()) for w in BREAKS
         if not (w == "b" and m.n_err < 2)  # (euler's one weight is fixed by Σ b = 1)
         and not (w == "e" and (m.e2 is not None or m.err_order < 2))]


@pytest.mark.parametrize("name,what", CASES)
def test_check_refuses_a_broken_tableau(name, what):
    """Each registered tableau, a coefficient moved by far more than check()'s tolerance, is
    refused with the condition it breaks; moved by far less, it passes."""
    m = METHODS[name]
    tol = 1e-12 if what == "rows" else 1e-10  # check()'s tolerance for that condition
    _moved(m, what, tol / 100).check()
    with pytest.raises(MethodError, match=BREAKS[what]):
        _moved(m, what, tol * 100).check()


def test_registry_lookup_and_errors():
    assert get_method("RK45").name == "dopri5"
    with pytest.raises(ValueError, match="unknown method 'rk99'.*dopri5"):
        get_method("rk99")


@pytest.mark.parametrize("fname", [*sorted(FIELDS), "bilinear"])
@pytest.mark.parametrize("name", sorted(STEPS))
def test_convergence_order(name, fname):
    """Fixed steps h and h/2 (adaptive methods with a huge tolerance and max_step = h)."""
    af = BILINEAR if fname == "bilinear" else FIELDS[fname]
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


@pytest.mark.parametrize("name", sorted(n for n, m in METHODS.items() if m.adaptive))
def test_error_estimate_has_its_declared_order(name):
    """The controller holds the embedded estimate at the tolerance.  The estimate is of order
    k = min(order, err_order) + 1 in h (DOP853's combined one: 8), so a step is h ~ rtol^(1/k)
    and a line of fixed length takes N ~ rtol^(-1/k) steps; and the end-point error follows the
    tolerance.  Three turns of the bilinear field, rtol = atol over four decades."""
    f = BILINEAR.to_field(shape=(2, 2, 2), bounds=BOX)
    k, t_end, rtols = METHODS[name].error_exponent_k, 20.0, (1e-7, 1e-11)
    exact = BILINEAR.trajectory(SEED, t_end)[0]
    steps, errs = [], []
    for rtol in rtols:
        lines = trace(f, SEED, method=name, rtol=rtol, atol=rtol, max_time=t_end,
                      max_length=1e9, cell_aware=False)
        assert lines.line_data["reason"][0] == 2  # max_time
        steps.append(int(lines.line_data["n_accepted"][0]))
        errs.append(np.linalg.norm(lines.points[-1] - exact) / rtol)
    slope = np.log(steps[1] / steps[0]) / np.log(rtols[0] / rtols[1])
    assert abs(slope * k - 1) < 0.1, (steps, slope, 1 / k)
    # the error in units of the tolerance: bounded, and the same at both tolerances
    assert max(errs) < 100 and 0.5 < errs[1] / errs[0] < 2, errs


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
