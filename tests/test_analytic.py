"""Analytic fields: exact trajectories solve the ODE, jacobians match finite differences, the
physical identities they claim hold, and sampling onto grids is exact at the nodes."""

import numpy as np
import pytest

from flowkit.fields import Grid
from flowkit.fields import analytic as an
from flowkit.fields.interp import INSIDE

RNG = np.random.default_rng(42)


def rand_points(f, n=40, margin=0.0, rng=RNG):
    b = f.default_bounds
    lo, hi = b[:, 0] + margin, b[:, 1] - margin
    return rng.uniform(lo, hi, (n, 3))


def fd(fun, x, h):
    """4th-order central difference of fun (array -> array) at x with step h."""
    return (fun(x - 2 * h) - 8 * fun(x - h) + 8 * fun(x + h) - fun(x + 2 * h)) / (12 * h)


def fd_jacobian(f, p, h=1e-4, t=0.0):
    J = np.empty((p.shape[0], 3, 3))
    for j in range(3):
        e = np.zeros(3)
        e[j] = 1.0
        J[:, :, j] = fd(lambda s, e=e: f.velocity(p + s * e, t), 0.0, h)
    return J


def fd_gradient(fun, p, h=1e-4):
    return np.stack([fd(lambda s, j=j: fun(p + s * np.eye(3)[j]), 0.0, h) for j in range(3)], -1)


A_GENERAL = np.array([[0.3, -1.2, 0.5], [2.0, 0.1, -0.7], [0.4, 0.9, -1.1]])
EXACT = {
    "uniform": (an.UniformFlow(U=(0.5, -1.0, 2.0)), 1e-3),
    "rotation": (an.SolidBodyRotation(omega=1.7, axis=(1, 2, 2), centre=(0.1, -0.2, 0.3)), 1e-3),
    "unsteady_rotation": (an.UnsteadyRotation(omega0=0.8, omega1=-0.6, axis=(0, 1, 1)), 1e-3),
    "linear": (an.LinearField(A_GENERAL, x0=(0.2, 0.1, -0.3), drift=(0.5, 0, 1)), 1e-3),
    "sink": (an.LinearField.sink(2.0, centre=(0.5, 0, 0)), 1e-3),
    "source": (an.LinearField.source(0.5), 1e-3),
    "saddle": (an.LinearField.saddle(1.5), 1e-3),
    "centre": (an.LinearField.centre(2.0), 1e-3),
    "spiral_sink": (an.LinearField.spiral(1.0, -0.2, axial=0.1), 1e-3),
    "spiral_source": (an.LinearField.spiral(3.0, 0.3), 1e-3),
    "stiff": (an.LinearField.stiff(), 1e-6),
    "burgers": (an.BurgersVortex(gamma=3.0, alpha=0.7, nu=0.1, centre=(0.2, -0.1, 0)), 1e-3),
}


@pytest.mark.parametrize("name", list(EXACT))
def test_exact_trajectory_solves_the_ode(name):
    f, h = EXACT[name]
    assert f.has_exact
    p0 = rand_points(f, 30)
    t0 = 0.3 if f.unsteady else 0.0
    np.testing.assert_allclose(f.trajectory(p0, t0, t0=t0), p0, rtol=0, atol=1e-13)
    # backwards the stiff field's fast mode grows like e^(1e4 |t|): keep |t| small there
    times = np.array([-0.7 if name != "stiff" else -2e-3, -1e-3, 0.0, 2e-4, 0.05, 1.3]) + t0
    X = f.trajectory(p0, times, t0=t0)
    assert X.shape == (times.size, 30, 3)
    for m, tm in enumerate(times):
        np.testing.assert_array_equal(X[m], f.trajectory(p0, tm, t0=t0))
        dxdt = fd(lambda s, tm=tm: f.trajectory(p0, tm + s, t0=t0), 0.0, h)
        v = f.velocity(X[m], tm)
        err = np.linalg.norm(dxdt - v, axis=1)
        scale = np.linalg.norm(v, axis=1) + 1e-9 * np.abs(X[m]).max()
        assert np.all(err <= 1e-6 * scale), (name, tm, (err / scale).max())


@pytest.mark.parametrize("name", [n for n in EXACT if not EXACT[n][0].unsteady])
def test_steady_flow_map_composes(name):
    # phi(t2, phi(t1, p)) = phi(t1 + t2, p): a check independent of the finite differences
    f, _ = EXACT[name]
    p0 = rand_points(f, 10)
    t2 = 0.15 if name == "stiff" else -0.15  # stiff backwards is exponentially ill-conditioned
    two = f.trajectory(f.trajectory(p0, 0.4), t2)
    one = f.trajectory(p0, 0.4 + t2)
    np.testing.assert_allclose(two, one, rtol=1e-10, atol=1e-12 * np.abs(p0).max())


def test_unsteady_rotation_depends_on_start_time():
    f = an.UnsteadyRotation(omega0=1.0, omega1=2.0)
    p0 = np.array([[1.0, 0.0, 0.5]])
    # angle from t0=1 to t=2: 1 * 1 + 2 * (4 - 1) / 2 = 4
    np.testing.assert_allclose(f.trajectory(p0, 2.0, t0=1.0), [[np.cos(4), np.sin(4), 0.5]], atol=1e-14)
    # per-point times
    pts = np.array([[1.0, 0, 0], [1.0, 0, 0]])
    v = f.velocity(pts, np.array([0.0, 1.0]))
    np.testing.assert_allclose(v, [[0, 1.0, 0], [0, 3.0, 0]], atol=1e-15)
    with pytest.raises(ValueError, match=r"one time per point \(2,\)"):
        f.velocity(pts, np.array([0.0, 1.0, 2.0]))
    snaps = f.to_series([0.0, 1.0], shape=5)
    assert [t for t, _ in snaps] == [0.0, 1.0] and snaps[1][1].time == 1.0
    assert "t=1" in snaps[1][1].source
    P = snaps[1][1].grid.node_points().reshape(-1, 3)
    np.testing.assert_array_equal(snaps[1][1].vector.reshape(-1, 3), f.velocity(P, 1.0))


def test_burgers_trajectory_on_and_near_axis():
    f = an.BurgersVortex()
    p0 = np.array([[0.0, 0.0, 0.5], [1e-9, 0.0, 0.5]])
    X = f.trajectory(p0, 1.0)
    np.testing.assert_allclose(X[0], [0, 0, 0.5 * np.e], rtol=1e-15)
    # near the axis the swirl is solid-body: angle gamma / (2 pi delta^2) * t, radius shrinks
    ang = f.gamma / (2 * np.pi * f.delta**2)
    np.testing.assert_allclose(X[1, :2], 1e-9 * np.exp(-0.5) * np.array([np.cos(ang), np.sin(ang)]),
                               rtol=1e-8)


ALL = {
    **{k: v[0] for k, v in EXACT.items()},
    "abc": an.ABCFlow(),
    "abc_other": an.ABCFlow(A=1.0, B=0.7, C=0.43),
    "taylor_green": an.TaylorGreen(U0=1.3),
    "hill": an.HillVortex(a=1.2, U=0.8, centre=(0.1, 0.2, -0.1)),
    "lorenz": an.Lorenz(),
}


@pytest.mark.parametrize("name", list(ALL))
def test_jacobian_matches_finite_differences(name):
    f = ALL[name]
    p = rand_points(f, 60)
    if name == "hill":  # the jacobian jumps on the sphere: stay off it
        R = np.linalg.norm(p - f.centre, axis=1)
        p = p[np.abs(R - f.a) > 0.05]
        assert p.shape[0] > 20
    t = 0.7 if f.unsteady else 0.0
    J = f.jacobian(p, t)
    Jfd = fd_jacobian(f, p, h=1e-6 if name == "stiff" else 1e-4, t=t)
    scale = np.abs(J).max()
    np.testing.assert_allclose(J, Jfd, rtol=0, atol=1e-7 * scale)
    curl = f.vorticity(p, t)
    np.testing.assert_allclose(curl[:, 0], Jfd[:, 2, 1] - Jfd[:, 1, 2], atol=1e-7 * scale)
    np.testing.assert_allclose(curl[:, 2], Jfd[:, 1, 0] - Jfd[:, 0, 1], atol=1e-7 * scale)
    np.testing.assert_allclose(f.divergence(p, t), np.trace(Jfd, axis1=1, axis2=2), atol=1e-7 * scale)


def test_burgers_jacobian_across_axis_and_series_switch():
    f = an.BurgersVortex(gamma=2.0, alpha=1.5, nu=0.3)
    d = f.delta
    # the series is used below r^2/delta^2 = 1e-2: probe both sides, and the axis itself
    r = d * np.sqrt(np.array([0.0, 1e-12, 1e-4, 0.99e-2, 1.01e-2, 0.3, 4.0]))
    p = np.stack([r * np.cos(0.3), r * np.sin(0.3), np.full_like(r, 0.2)], -1)
    np.testing.assert_allclose(f.jacobian(p), fd_jacobian(f, p, h=1e-4), atol=1e-8)
    w = f.vorticity(p)
    np.testing.assert_allclose(w[:, 2], f.gamma / (np.pi * d**2) * np.exp(-(r / d) ** 2), rtol=1e-13)
    np.testing.assert_array_equal(w[:, :2], 0.0)
    # velocity continuous at the switch and at the axis (u_theta -> gamma r / (2 pi delta^2))
    s = d * np.sqrt(1e-2) * np.array([1 - 1e-12, 1 + 1e-12])
    u = f.velocity(np.stack([s, 0 * s, 0 * s], -1))
    assert abs(u[0, 1] - u[1, 1]) < 1e-13
    np.testing.assert_array_equal(f.velocity([[0.0, 0.0, 1.0]]), [[0.0, 0.0, f.alpha]])


@pytest.mark.parametrize("name", ["abc", "abc_other", "taylor_green", "hill", "rotation", "burgers",
                                  "saddle", "centre", "unsteady_rotation"])
def test_divergence_free(name):
    f = ALL[name]
    p = rand_points(f, 200)
    if name == "hill":  # both sides of the sphere, excluding a thin shell around it
        R = np.linalg.norm(p - f.centre, axis=1)
        p = p[np.abs(R - f.a) > 0.02]
        assert np.sum(np.linalg.norm(p - f.centre, axis=1) < f.a) > 10
    div = np.trace(fd_jacobian(f, p, t=0.5), axis1=1, axis2=2)
    speed = np.linalg.norm(f.velocity(p, 0.5), axis=1).max()
    assert np.abs(div).max() < 1e-9 * speed
    assert np.abs(f.divergence(p, 0.5)).max() < 1e-12 * speed


def test_lorenz_divergence_and_no_exact_solution():
    f = an.Lorenz()
    p = rand_points(f, 20)
    np.testing.assert_allclose(f.divergence(p), -(10 + 1 + 8 / 3), rtol=1e-14)
    for g in (f, an.ABCFlow(), an.TaylorGreen(), an.HillVortex()):
        assert not g.has_exact
        with pytest.raises(an.NoExactSolution, match=g.name):
            g.trajectory(p, 1.0)


def test_vorticity_identities():
    abc = an.ABCFlow()
    p = rand_points(abc, 50)
    np.testing.assert_allclose(abc.vorticity(p), abc.velocity(p), atol=1e-14)  # Beltrami
    rot = an.SolidBodyRotation(omega=1.5, axis=(0, 3, 4))
    np.testing.assert_allclose(rot.vorticity(p), np.broadcast_to([0, 2 * 1.5 * 0.6, 2 * 1.5 * 0.8],
                                                                  (50, 3)), atol=1e-14)
    hill = an.HillVortex(a=1.0, U=2.0)
    q = np.array([[0.3, 0.4, 0.1], [1.5, 0.0, 0.3]])  # inside, outside
    w = hill.vorticity(q)
    rho = 0.5
    np.testing.assert_allclose(w[0], 15 * 2.0 * rho / 2 * np.array([-0.4, 0.3, 0]) / rho, atol=1e-14)
    np.testing.assert_allclose(w[1], 0.0, atol=1e-14)  # irrotational outside


def test_hill_continuity_on_the_sphere():
    f = an.HillVortex(a=1.3, U=0.9, centre=(0.5, 0.0, -0.2))
    n = RNG.normal(size=(100, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    inner = f.centre + f.a * (1 - 1e-10) * n
    outer = f.centre + f.a * (1 + 1e-10) * n
    ui, uo = f.velocity(inner), f.velocity(outer)
    np.testing.assert_allclose(ui, uo, atol=1e-8)
    # no flow through the sphere; on it the flow is tangential
    assert np.abs(np.einsum("ij,ij->i", ui, n)).max() < 1e-8
    np.testing.assert_allclose(f.scalars(inner)["psi"], f.scalars(outer)["psi"], atol=1e-8)
    # far field is the uniform stream -U e_z
    np.testing.assert_allclose(f.velocity([[0.5, 0.0, 1e4]]), [[0, 0, -0.9]], atol=1e-9)


def test_hill_stream_function_is_constant_along_streamlines():
    f = an.HillVortex(a=1.0, U=1.0)
    p = rand_points(f, 200)
    R = np.linalg.norm(p, axis=1)
    p = p[np.abs(R - 1.0) > 0.02]
    grad = fd_gradient(lambda q: f.scalars(q)["psi"], p)
    assert np.abs(np.einsum("ij,ij->i", grad, f.velocity(p))).max() < 1e-9


@pytest.mark.parametrize("name", ["rotation", "abc", "abc_other"])
def test_pressure_balances_steady_euler(name):
    # steady Euler, unit density: grad p = -(u . grad) u = -J u
    f = ALL[name]
    p = rand_points(f, 50)
    grad = fd_gradient(lambda q: f.scalars(q)["p"], p)
    Ju = np.einsum("nij,nj->ni", f.jacobian(p), f.velocity(p))
    np.testing.assert_allclose(grad, -Ju, atol=1e-9 * np.abs(Ju).max())


def test_taylor_green_pressure_solves_the_poisson_equation():
    f = ALL["taylor_green"]
    p = rand_points(f, 50)
    def second(e):
        return fd(lambda s: fd(lambda r: f.scalars(p + r * e)["p"], s, 1e-3), 0.0, 1e-3)

    lap = sum(second(e) for e in np.eye(3))
    J = f.jacobian(p)
    rhs = -np.einsum("nij,nji->n", J, J)
    np.testing.assert_allclose(lap, rhs, atol=1e-7 * np.abs(rhs).max())


@pytest.mark.parametrize("cls", [an.ABCFlow, an.TaylorGreen])
def test_periodic_fields_repeat_every_2pi(cls):
    f = cls()
    assert f.periodic == (True, True, True)
    p = rand_points(f, 50)
    for a in range(3):
        for k in (1, -3):
            np.testing.assert_allclose(f.velocity(p + k * 2 * np.pi * np.eye(3)[a]), f.velocity(p),
                                       atol=1e-13)


def test_to_field_is_exact_at_nodes_uniform_grid():
    f = an.HillVortex(a=1.0, U=1.0)
    F = f.to_field((9, 8, 7))
    assert F.grid.shape == (9, 8, 7) and F.grid.uniform and F.grid.period == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(F.grid.bounds, f.default_bounds, rtol=1e-15)
    P = F.grid.node_points().reshape(-1, 3)
    np.testing.assert_array_equal(F.vector.reshape(-1, 3), f.velocity(P))
    np.testing.assert_array_equal(F.scalars["psi"].ravel(), f.scalars(P)["psi"])
    v, st = F.sample(P)
    assert np.all(st == INSIDE)
    np.testing.assert_array_equal(v, f.velocity(P))
    assert "hill(a=1, U=1" in F.source and F.vector_name == "U" and F.time is None


def test_to_field_on_a_rectilinear_grid_and_chunking(monkeypatch):
    monkeypatch.setattr(an, "_CHUNK", 10)  # several slabs per grid
    f = an.BurgersVortex()
    g = Grid.from_axes(np.sort(RNG.uniform(-2, 2, 7)), np.sort(RNG.uniform(-2, 2, 6)),
                       np.sort(RNG.uniform(-2, 2, 5)))
    F = f.to_field(grid=g)
    assert F.grid is g
    np.testing.assert_array_equal(F.vector.reshape(-1, 3), f.velocity(g.node_points().reshape(-1, 3)))
    with pytest.raises(ValueError, match="either grid or shape"):
        f.to_field(shape=8, grid=g)


def test_to_field_linear_scalar_is_exact_everywhere():
    f = an.UniformFlow(U=(1.0, 2.0, 3.0), T_gradient=(0.3, -1.0, 2.0))
    F = f.to_field(5, bounds=[[0, 1], [-1, 2], [3, 4]])
    q = RNG.uniform([0, -1, 3], [1, 2, 4], (100, 3))
    T, st = F.sample_scalar("T", q)
    assert np.all(st == INSIDE)
    np.testing.assert_allclose(T, q @ [0.3, -1.0, 2.0], atol=1e-12)


def test_to_field_periodic_axes():
    f = an.ABCFlow()
    F = f.to_field(16)
    assert F.grid.period == pytest.approx((2 * np.pi,) * 3, rel=1e-15)
    np.testing.assert_allclose(F.grid.x, np.arange(16) * 2 * np.pi / 16, rtol=1e-15)
    # three periods (the benchmark's grid) stay periodic; a partial span is bounded
    F3 = f.to_field((48, 16, 8), bounds=[[0, 6 * np.pi], [0, 2 * np.pi], [0, np.pi]])
    assert F3.grid.periodic == (True, True, False)
    assert F3.grid.period[0] == pytest.approx(6 * np.pi)
    assert F3.grid.z[-1] == pytest.approx(np.pi)
    # nodes shifted by whole periods sample the exact node values (the wrap cell is used)
    P = F.grid.node_points().reshape(-1, 3)
    v, st = F.sample(P + 2 * np.pi * np.array([1.0, -2.0, 3.0]))
    assert np.all(st == INSIDE)
    np.testing.assert_allclose(v, f.velocity(P), atol=1e-12)
    Fb = f.to_field(8, periodic=False)
    assert Fb.grid.periodic == (False,) * 3 and Fb.grid.x[-1] == pytest.approx(2 * np.pi)
    with pytest.raises(ValueError, match=r"axis z cannot be periodic over span 3\.14"):
        f.to_field(8, bounds=[[0, 6.3], [0, 6.3], [0, np.pi]], periodic=(False, False, True))
    with pytest.raises(ValueError, match="grid axis x is periodic with period 5"):
        f.to_field(grid=Grid.regular(0, 1.0, (5, 5, 5), periodic=(True, False, False)))
    with pytest.raises(ValueError, match="bounds must be"):
        f.to_field(8, bounds=[[1, 0], [0, 1], [0, 1]])


def test_stiff_field_eigenvalues_and_drift():
    f = an.LinearField.stiff()
    ev = np.sort(np.linalg.eigvals(f.A).real)
    np.testing.assert_allclose(ev, [-1e4, -1.0, 0.0], atol=1e-9)
    # after the fast mode decays the line follows the slow direction while drifting along z
    X = f.trajectory([[0.5, 0.1, 0.0]], 0.01)[0]
    slow = (0.5 + 0.1) / 2 * np.exp(-0.01)
    np.testing.assert_allclose(X, [slow, slow, 0.01], rtol=1e-12)


def test_make_and_bad_parameters():
    assert isinstance(an.make("abc", A=1.0), an.ABCFlow)
    assert an.make("spiral", rate=0.2).kind == "spiral_source"
    with pytest.raises(ValueError, match="unknown analytic field 'abd'.*abc"):
        an.make("abd")
    with pytest.raises(ValueError, match="axis must be a nonzero"):
        an.SolidBodyRotation(axis=(0, 0, 0))
    with pytest.raises(ValueError, match="alpha and nu must be > 0"):
        an.BurgersVortex(alpha=-1.0)
    with pytest.raises(ValueError, match="3x3"):
        an.LinearField(np.eye(2))
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        an.ABCFlow().velocity(np.zeros((4, 2)))
