"""The method registry: a user's tableau traced on both backends against scipy, check()'s errors,
capabilities instead of names, options and CLI generated from the registry."""

import dataclasses

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.integrate._ivp.rk import RungeKutta

import flowkit
from flowkit.fields.analytic import SolidBodyRotation
from flowkit.integrate import methods as M
from flowkit.integrate.methods import Method, MethodError, RosenbrockMethod, register_method
from flowkit.integrate.options import OptionsError, TraceOptions

# Heun–Euler 2(1): Heun's trapezoidal rule propagates, explicit Euler is the embedded estimate
HEUN_C = [0.0, 1.0]
HEUN_A = [[0.0, 0.0], [1.0, 0.0]]
HEUN_B = [0.5, 0.5]
HEUN_BHAT = [1.0, 0.0]


def heun_euler(name="heuneuler"):
    return Method.from_butcher(name, HEUN_C, HEUN_A, HEUN_B, HEUN_BHAT, order=2, err_order=1,
                               description="Heun–Euler 2(1)")


class ScipyHeunEuler(RungeKutta):
    """The same pair in scipy's explicit Runge–Kutta driver (its controller, not ours)."""

    C = np.array(HEUN_C)
    A = np.array(HEUN_A)
    B = np.array(HEUN_B)
    E = np.array([HEUN_B[0] - HEUN_BHAT[0], HEUN_B[1] - HEUN_BHAT[1], 0.0])  # b - b̂, f(y1): 0
    P = np.array([[1.0, -0.5], [0.0, 0.5], [0.0, 0.0]])  # unused: no dense output asked for
    order, error_estimator_order, n_stages = 2, 1, 2


@pytest.mark.parametrize("backend", ["numba", "opencl"])
def test_user_tableau_traces_on_both_backends_like_its_scipy_run(backend):
    if backend == "opencl":
        pytest.importorskip("pyopencl")  # the `opencl` extra; CI runs it on PoCL
    rot = SolidBodyRotation(omega=1.0)
    field = rot.to_field(shape=(2, 2, 2), bounds=[[-3, 3], [-3, 3], [-1, 1]])  # exact: linear
    seeds = np.array([[1.0, 0.2, 0.1], [-0.5, 0.8, -0.3]])
    T, rtol = 3.0, 1e-6
    m = heun_euler()
    m.check()
    kw = {"method": m, "rtol": rtol, "atol": rtol, "max_time": T, "cell_aware": False}
    L = flowkit.trace(field, seeds, backend=backend, **kw)
    exact = rot.trajectory(seeds, T)
    ref, ref_steps = [], []
    for seed in seeds:
        sol = solve_ivp(lambda _t, y: rot.velocity(y[None])[0], (0, T), seed, method=ScipyHeunEuler,
                        rtol=rtol, atol=rtol)
        ref.append(sol.y[:, -1])
        ref_steps.append(sol.t.size - 1)
    ref = np.array(ref)
    assert np.all(np.linalg.norm(ref - exact, axis=1) < 10 * rtol)  # scipy's run meets it
    assert L.attrs["method"] == "heuneuler"
    assert np.all(L.line_data["reason"] == 2)  # max_time
    ends = L.points[L.offsets[1:] - 1]
    # measured: 2.5e-6 from the exact end, 1e-7 from scipy's, steps within 2 % of scipy's
    assert np.all(np.linalg.norm(ends - ref, axis=1) < 10 * rtol)
    assert np.all(np.linalg.norm(ends - exact, axis=1) < 10 * rtol)
    assert np.all(np.linalg.norm(ends - exact, axis=1) > 0.1 * rtol)  # 2nd order, not exact
    np.testing.assert_allclose(L.line_data["n_accepted"], ref_steps, rtol=0.1)


def test_check_names_the_bad_coefficient():
    with pytest.raises(MethodError, match=r"row a\[1, :\] sums to 0.9, c\[1\] = 1"):
        Method.from_butcher("bad", HEUN_C, [[0, 0], [0.9, 0]], HEUN_B, HEUN_BHAT, order=2).check()
    with pytest.raises(MethodError, match=r"b miss the order condition order 2: Σ b·c = 0.6"):
        Method.from_butcher("bad", HEUN_C, HEUN_A, [0.4, 0.6], HEUN_BHAT, order=2).check()
    with pytest.raises(MethodError, match=r"embedded weights b − e miss the order condition order 2"):
        Method.from_butcher("bad", HEUN_C, HEUN_A, HEUN_B, HEUN_BHAT, order=2, err_order=2).check()
    with pytest.raises(MethodError, match=r"a\[0, 1\] = 1 is on or above the diagonal"):
        Method.from_butcher("bad", HEUN_C, [[0, 1], [1, 0]], HEUN_B, HEUN_BHAT, order=2).check()
    bs23 = M.get_method("bs23")  # FSAL: its last stage, at c = 1, is f(y1) itself
    with pytest.raises(MethodError, match="stiffness_stage 3 is f\\(y1\\) itself"):
        dataclasses.replace(bs23, name="bad", stiffness_stage=3).check()
    ros = M.get_method("ros34pw2")
    bad_b = ros.b.copy()
    bad_b[0] += 1e-3
    with pytest.raises(MethodError, match=r"ros3: b miss the order condition order 1: Σ b"):
        RosenbrockMethod("ros3", 3, 2, ros.gamma, ros.alpha, ros.gammas, bad_b, ros.bhat).check()
    # TraceOptions validates an unregistered method before anything runs
    with pytest.raises(MethodError, match="row a"):
        TraceOptions(method=Method.from_butcher("bad", HEUN_C, [[0, 0], [0.9, 0]], HEUN_B,
                                                HEUN_BHAT, order=2))
    with pytest.raises(OptionsError, match="'dopri5' is a registered method's"):
        TraceOptions(method=heun_euler("dopri5"))


def test_register_method_makes_it_a_name_everywhere(monkeypatch):
    for name in ("REGISTRY", "METHODS", "_ALIASES"):  # registrations end with the test
        monkeypatch.setattr(M, name, dict(getattr(M, name)))
    m = register_method(heun_euler())
    assert M.get_method("HeunEuler") is m and "heuneuler" in M.METHODS
    assert TraceOptions(method="heuneuler").method == "heuneuler"
    assert TraceOptions(method=m).method == "heuneuler"  # the registered object: by name
    with pytest.raises(MethodError, match="registered already"):
        register_method(heun_euler())
    assert register_method(heun_euler(), replace=True) is not m
    with pytest.raises(MethodError, match="alias 'rk45' names method dopri5"):
        register_method(Method.from_butcher("heun2", HEUN_C, HEUN_A, HEUN_B, order=2,
                                            aliases=("rk45",)))
    with pytest.raises(MethodError, match="row a"):  # validated before it is known
        register_method(Method.from_butcher("bad", HEUN_C, [[0, 0], [0.9, 0]], HEUN_B, order=2))
    assert "bad" not in M.REGISTRY


def test_capabilities_replace_names():
    get = M.get_method
    assert get("dopri5").stiffness_stage == 5 and get("cashkarp").stiffness_stage is None
    assert [n for n in M.REGISTRY if not get(n).lockstep] == ["ros34pw2"]
    # (auto's lines switch inside the step loop: the backends of both its steppers)
    assert get("ros34pw2").backends == ("numba",) and get("auto").backends == ("numba",)
    assert get("auto").explicit is get("dopri5") and get("auto").switch_to is get("ros34pw2")
    # user tableaux run lock-step, fixed-step or adaptive, up to the stages the lanes hold
    heun = Method.from_butcher("heun", HEUN_C, HEUN_A, HEUN_B, order=2)
    assert heun.lockstep and heun_euler().lockstep
    s = M.LOCKSTEP_STAGES
    c = np.linspace(0.0, 1.0, s + 1)
    a = np.zeros((s + 1, s + 1))
    a[1:, 0] = c[1:]  # (every stage from the first: explicit, rows summing to c)
    big = Method.from_butcher("big", c, a, np.full(s + 1, 1 / (s + 1)), order=1)
    assert big.n_stages > s and not big.lockstep
    # messages list the registry
    with pytest.raises(ValueError, match="choose one of: dopri5, .*, ros34pw2, auto"):
        M.get_method("rk99")
    with pytest.raises(OptionsError, match=r"method ros34pw2 runs on the numba backend only, got "
                                           r"backend 'opencl'$"):
        field = SolidBodyRotation().to_field(shape=5)
        flowkit.trace(field, [0.5, 0, 0], method="ros34pw2", backend="opencl")
    with pytest.raises(OptionsError, match=r"dense output \(dopri5, cashkarp, bs23, rk4, euler, "
                                           r"dop853\); auto emits its steps"):
        TraceOptions(method="auto", count=10)


def test_user_fixed_step_tableau_runs_lock_step_bit_identical_to_the_scalar_kernel():
    field = SolidBodyRotation().to_field(shape=9)
    heun = Method.from_butcher("heun", HEUN_C, HEUN_A, HEUN_B, order=2)
    seeds = [[0.5, 0.1, 0.0], [0.2, -0.4, 0.3]]
    kw = {"method": heun, "step": 0.01, "max_time": 2.0, "cell_aware": False}
    from flowkit.integrate import kernel

    lock = flowkit.trace(field, seeds, **kw)
    one = flowkit.trace(field, seeds, backend=kernel.advance, **kw)
    assert lock.equals(one) and lock.line_data["n_accepted"].min() >= 200


def test_generated_option_docs_and_cli_choices(capsys):
    from flowkit.cli import main

    for name, m in M.REGISTRY.items():
        assert f"{name}  " in TraceOptions.__doc__ and m.description in TraceOptions.__doc__
    with pytest.raises(SystemExit):
        main(["trace", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "{" + ",".join(M.REGISTRY) + "}" in text
    for name, m in M.REGISTRY.items():
        assert f"{name}: {M.describe(m)}" in text
    with pytest.raises(SystemExit):
        main(["trace", "x.npz", "-o", "y.h5", "--method", "nope"])
    assert "invalid choice: 'nope'" in capsys.readouterr().err


def test_user_rosenbrock_coefficients_run_on_the_rosenbrock_driver():
    """The driver steps the entry's own data: ros34pw2's coefficients under another name trace
    ros34pw2's lines exactly; with γ halved the same α, Γ, b miss the order-2 condition and
    check() refuses them."""
    ros = M.get_method("ros34pw2")
    field = SolidBodyRotation().to_field(shape=9)
    seeds = [[0.5, 0.1, 0.0], [0.2, -0.4, 0.3]]
    kw = {"rtol": 1e-6, "atol": 1e-6, "max_time": 2.0}
    ref = flowkit.trace(field, seeds, method="ros34pw2", **kw)
    mine = RosenbrockMethod("myros", ros.order, ros.err_order, ros.gamma, ros.alpha, ros.gammas,
                            ros.b, ros.bhat, description="a copy")
    got = flowkit.trace(field, seeds, method=mine, **kw)
    assert got.attrs["method"] == "myros"
    np.testing.assert_array_equal(got.points, ref.points)
    other = RosenbrockMethod("myros", 3, 2, 0.5 * ros.gamma, ros.alpha, ros.gammas, ros.b, ros.bhat)
    with pytest.raises(MethodError, match="myros: b miss the order condition order 2"):
        other.check()
