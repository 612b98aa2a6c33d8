"""Fixed-point accelerations (orchestrator/coupling/acceleration.py) on problems with known
solutions: linear maps (contractive and expansive) and nonlinear ones; convergence rates."""

import math

import numpy as np
import pytest

from orchestrator.coupling.acceleration import (
    IQNILS, Aitken, FixedPoint, PassRejected, make_acceleration, scaled_residual, solve_fixed_point)


def linear_problem(n, radius, seed=0):
    """G(x) = A x + b with spectral radius ``radius``, symmetric A; fixed point x* known."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    lam = np.linspace(-radius, radius * 0.3, n)
    lam[-1] = radius
    A = Q @ np.diag(lam) @ Q.T
    x_star = rng.standard_normal(n)
    b = x_star - A @ x_star
    return (lambda x: A @ x + b), x_star


def iterate(acc, G, x0, steps):
    """Errors of the iterates fed to G, |x_k - G(x_k)|, without a stopping test."""
    acc.start(np.ones(len(x0)))
    x = np.array(x0, dtype=float)
    res = []
    for _ in range(steps):
        g = G(x)
        res.append(float(np.max(np.abs(g - x))))
        x = acc.update(x, g)
    acc.finish()
    return np.array(res)


def test_plain_fixed_point_converges_at_the_spectral_radius():
    G, x_star = linear_problem(5, 0.5)
    res = iterate(FixedPoint(), G, np.zeros(5), 40)
    rate = (res[39] / res[19]) ** (1 / 20)
    assert rate == pytest.approx(0.5, rel=0.02)


def test_plain_fixed_point_diverges_on_an_expansive_map():
    G, _ = linear_problem(4, 3.0)
    res = iterate(FixedPoint(), G, np.zeros(4), 12)
    assert res[-1] > 1e4 * res[0]


@pytest.mark.parametrize("radius", [0.5, 3.0, 50.0])
def test_iqn_ils_solves_a_linear_map_in_n_plus_2_evaluations(radius):
    n = 6
    G, x_star = linear_problem(n, radius, seed=3)
    r = solve_fixed_point(G, np.zeros(n), acceleration=IQNILS(), tol=1e-9, scale=np.ones(n),
                          max_iterations=n + 2)
    assert r.converged, r
    assert r.iterations <= n + 2
    np.testing.assert_allclose(r.x, x_star, atol=1e-8 * max(1.0, radius))


def test_iqn_ils_reuse_solves_the_next_problem_of_the_same_map_in_two_evaluations():
    n = 5
    G, x_star = linear_problem(n, 20.0, seed=4)
    acc = IQNILS(reuse=2)
    first = solve_fixed_point(G, np.zeros(n), acceleration=acc, tol=1e-9, scale=np.ones(n), max_iterations=20)
    assert first.converged and first.iterations > 2
    # the same linear map with another offset: the stored secant columns are the whole Jacobian
    shift = np.arange(n, dtype=float)
    second = solve_fixed_point(lambda x: G(x) + shift, np.zeros(n), acceleration=acc, tol=1e-9,
                               scale=np.ones(n), max_iterations=20)
    assert second.converged and second.iterations == 2


def test_aitken_solves_a_scalar_linear_map_of_any_slope_in_three_evaluations():
    for slope in (0.9, -0.99, 4.0, -30.0):
        r = solve_fixed_point(lambda x: slope * x + 1.0, np.array([0.0]), acceleration=Aitken(), tol=1e-12,
                              scale=np.ones(1), max_iterations=3)
        assert r.converged, (slope, r)
        assert r.x[0] == pytest.approx(1.0 / (1.0 - slope), rel=1e-10)


def test_aitken_beats_plain_iteration_on_a_slow_linear_map():
    G, x_star = linear_problem(3, 0.95, seed=1)
    plain = solve_fixed_point(G, np.zeros(3), acceleration=FixedPoint(), tol=1e-8, scale=np.ones(3),
                              max_iterations=2000)
    aitken = solve_fixed_point(G, np.zeros(3), acceleration=Aitken(), tol=1e-8, scale=np.ones(3),
                               max_iterations=2000)
    assert plain.converged and aitken.converged
    assert aitken.iterations * 4 < plain.iterations
    np.testing.assert_allclose(aitken.x, x_star, atol=1e-6)


def test_cosine_fixed_point_rates():
    """x = cos x (x* = 0.7390851332151607, the Dottie number): plain iteration is linear at
    |sin x*| = 0.6736; Aitken and IQN-ILS (1-D secant) are superlinear."""
    x_star = 0.7390851332151607
    G = np.cos
    plain = iterate(FixedPoint(), G, np.array([1.0]), 30)
    rate = (plain[29] / plain[14]) ** (1 / 15)
    assert rate == pytest.approx(math.sin(x_star), rel=0.01)
    for acc in (Aitken(), IQNILS()):
        r = solve_fixed_point(G, np.array([1.0]), acceleration=acc, tol=1e-13, scale=np.ones(1),
                              max_iterations=10)
        assert r.converged and r.iterations <= 8, (acc.name, r)
        assert r.x[0] == pytest.approx(x_star, abs=1e-12)
        res = iterate(type(acc)(), G, np.array([1.0]), 6)
        ratios = res[2:] / res[1:-1]
        assert ratios[-1] < 0.05 and ratios[-1] < ratios[0]          # superlinear: ratios shrink to 0


def test_iqn_ils_on_a_stiff_nonlinear_vector_map():
    """G(x) = x* + M (x - x*) + 0.2 (x - x*)^2 with M of spectral radius 8 (plain iteration
    diverges): IQN-ILS converges to x* from a start 0.1 away."""
    n = 4
    rng = np.random.default_rng(7)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    M = Q @ np.diag([-8.0, 3.0, 0.5, -0.2]) @ Q.T
    x_star = np.array([1.0, -2.0, 0.5, 3.0])

    def G(x):
        d = x - x_star
        return x_star + M @ d + 0.2 * d * d

    x0 = x_star + 0.1 * rng.standard_normal(n)
    r = solve_fixed_point(G, x0, acceleration=IQNILS(), tol=1e-10, scale=np.ones(n), max_iterations=25)
    assert r.converged, r
    np.testing.assert_allclose(r.x, x_star, atol=1e-9)
    with np.errstate(over="ignore", invalid="ignore"):
        p = solve_fixed_point(G, x0, acceleration=FixedPoint(), tol=1e-10, scale=np.ones(n), max_iterations=25)
    assert not p.converged


def test_scaling_makes_iqn_ils_independent_of_units():
    """The same problem in units 1e6 apart converges in the same number of evaluations."""
    n = 4
    G, x_star = linear_problem(n, 5.0, seed=2)
    units = np.array([1e-6, 1.0, 1e3, 1e6])
    Gu = lambda xu: G(xu / units) * units                 # noqa: E731
    a = solve_fixed_point(G, np.zeros(n), acceleration=IQNILS(), tol=1e-9, scale=np.ones(n), max_iterations=20)
    b = solve_fixed_point(Gu, np.zeros(n), acceleration=IQNILS(), tol=1e-9, scale=units, max_iterations=20)
    assert a.converged and b.converged and a.iterations == b.iterations
    np.testing.assert_allclose(b.x / units, x_star, atol=1e-8)


def test_non_finite_residual_stops_and_reports_the_signal():
    r = solve_fixed_point(lambda x: np.array([x[0], math.inf]), np.zeros(2), acceleration=FixedPoint(),
                          tol=1e-8, scale=np.ones(2), max_iterations=10)
    assert not r.converged and r.iterations == 1 and r.worst == 1 and r.residual == math.inf
    assert scaled_residual(np.zeros(2), np.array([0.0, 3.0]), np.array([1.0, 2.0])) == (1.5, 1)


def test_make_acceleration_names():
    assert isinstance(make_acceleration("none"), FixedPoint)
    assert isinstance(make_acceleration("aitken"), Aitken)
    assert isinstance(make_acceleration("iqn-ils"), IQNILS)
    with pytest.raises(ValueError, match="iqn-ils"):
        make_acceleration("anderson")


def test_a_refused_iterate_is_backtracked_towards_the_last_evaluated_one():
    """G(x) = -10 x + 22 (fixed point 2), refused above 2.5 (as an FMU discards an iterate that puts a
    journal outside its bearing): the first relaxed update (11) and its halvings 5.5, 2.75 are refused,
    1.375 is evaluated, and the secant step then lands on the fixed point."""
    seen = []

    def G(x):
        seen.append(float(x[0]))
        if x[0] > 2.5:
            raise PassRejected(RuntimeError("discarded"))
        return -10.0 * x + 22.0

    res = solve_fixed_point(G, np.zeros(1), acceleration=IQNILS(), tol=1e-12, scale=np.ones(1), max_iterations=20)
    assert res.converged and abs(res.x[0] - 2.0) < 1e-9
    assert seen[:5] == [0.0, 11.0, 5.5, 2.75, 1.375]


def test_a_refused_first_iterate_raises_the_subsystems_error():
    def G(x):
        raise PassRejected(ValueError("bearing1 discarded"))

    with pytest.raises(ValueError, match="bearing1 discarded"):
        solve_fixed_point(G, np.zeros(1), acceleration=IQNILS(), tol=1e-12, scale=np.ones(1), max_iterations=5)
