"""Bounded least squares: Levenberg-Marquardt, the finite-difference Jacobian, the covariance."""

import numpy as np
import pytest

from trunk_drake.optim import least_squares
from trunk_drake.optim.least_squares import finite_difference_jacobian, inverse_or_inf, levenberg_marquardt


def test_levenberg_marquardt_on_a_known_problem():
    t = np.linspace(0, 1, 50)
    truth = np.array([-0.5, -1.2])

    def fun(x):
        return 10 ** x[0] * np.exp(-t / 10 ** x[1]) - 10 ** truth[0] * np.exp(-t / 10 ** truth[1])

    def jac(x):
        h = 1e-7
        return np.column_stack([(fun(x + h * e) - fun(x)) / h for e in np.eye(2)])

    x, _, r, _, status = levenberg_marquardt(fun, jac, np.array([-2.0, 0.0]), np.array([-3.0, -3.0]), np.zeros(2),
                                             max_iterations=100, tolerance=1e-14)
    np.testing.assert_allclose(x, truth, atol=1e-5)
    # a bound is respected exactly when the optimum lies outside
    x, *_ = levenberg_marquardt(fun, jac, np.array([-2.0, -2.0]), np.array([-3.0, -3.0]), np.array([-0.8, 0.0]),
                                max_iterations=100, tolerance=1e-12)
    assert x[0] == pytest.approx(-0.8)


def test_levenberg_marquardt_scale_frees_a_coordinate_in_wide_small_units():
    # a log10 gain over [-1, 1] and a cubic coefficient over [0, 2000] 1/rad^2, each moving its residual alike over its
    # range: without `scale` the damping, set by the gain's column, holds the coefficient at its start for the few
    # steps of a time-domain refit (the gap search's stiffening law: 50.00007 from 50)
    lo, hi, x0 = np.array([-1.0, 0.0]), np.array([1.0, 2000.0]), np.array([0.0, 50.0])
    truth = np.array([0.3, 400.0])

    def fun(x):
        return np.array([100.0 * (x[0] - truth[0]) / 2.0, 100.0 * (x[1] - truth[1]) / 2000.0])

    def jac(x):
        return np.diag([50.0, 0.05])

    held, *_ = levenberg_marquardt(fun, jac, x0, lo, hi, max_iterations=3)
    freed, J, r, *_ = levenberg_marquardt(fun, jac, x0, lo, hi, max_iterations=3, scale=hi - lo)
    assert held[1] < 60.0  # under 3 % of the way to 400
    np.testing.assert_allclose(freed, truth, rtol=1e-2)
    np.testing.assert_allclose(J, np.diag([50.0, 0.05]), atol=1e-9)  # the Jacobian returned in x's units (secant-updated)
    with pytest.raises(ValueError, match="finite and positive"):
        levenberg_marquardt(fun, jac, x0, lo, hi, scale=np.array([2.0, 0.0]))
    # the start is passed to `fun` exactly, and the bounds hold
    seen = []
    levenberg_marquardt(lambda x: seen.append(x.copy()) or fun(x), jac, x0, lo, np.array([1.0, 100.0]), scale=hi - lo)
    assert np.array_equal(seen[0], x0) and all(x[1] <= 100.0 for x in seen)


def test_untouched_parameters_get_infinite_variance():
    cov = inverse_or_inf(np.array([[4.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 0.0]]))
    assert cov[0, 0] == pytest.approx(0.25) and cov[1, 1] == pytest.approx(1.0) and np.isinf(cov[2, 2])
    assert np.isfinite(cov[:2, :2]).all()


def test_finite_difference_jacobian_forward_backward_central_and_columns():
    def residuals(points):
        return [np.array([x[0] ** 2 + x[1], np.sin(x[1]), x[0] * x[1]]) for x in points]

    x = np.array([0.7, -0.4])
    exact = np.array([[2 * x[0], 1.0], [0.0, np.cos(x[1])], [x[1], x[0]]])
    forward = finite_difference_jacobian(residuals, x, 1e-6)
    np.testing.assert_allclose(forward, exact, atol=1e-5)
    central = finite_difference_jacobian(residuals, x, 1e-4, central=True)
    np.testing.assert_allclose(central, exact, atol=1e-7)  # second order: far closer than forward at this step
    # at an upper bound the step goes backward: the displaced points never pass it
    seen = []

    def recording(points):
        seen.extend(points)
        return residuals(points)

    backward = finite_difference_jacobian(recording, x, 1e-6, upper=np.array([0.7, 1.0]))
    assert max(p[0] for p in seen) <= 0.7
    np.testing.assert_allclose(backward, exact, atol=1e-5)
    only = finite_difference_jacobian(residuals, x, 1e-6, columns=[1], r0=residuals([x])[0])
    assert np.all(only[:, 0] == 0.0)
    np.testing.assert_allclose(only[:, 1], exact[:, 1], atol=1e-5)


def _step_cost(J, r, mu, d):
    return 0.5 * np.sum((J @ d + r) ** 2) + 0.5 * mu * d @ d


def test_a_failed_step_qp_is_solved_as_bounded_least_squares_with_the_same_answer(monkeypatch):
    rng = np.random.default_rng(3)
    J, r = rng.normal(size=(40, 5)), 3.0 * rng.normal(size=40)
    lower, upper = np.array([-0.1, -1.0, 0.0, -1.0, 0.2]), np.array([0.1, 1.0, 1.0, -1.0, 0.2 + 1e-3])  # d3 fixed
    qp = least_squares._bounded_step(J, r, 0.5, lower, upper)
    assert np.sum(np.isclose(qp, lower) | np.isclose(qp, upper)) >= 3  # bounds active, so the test means something

    class Failed:
        def is_success(self):
            return False

        def get_solution_result(self):
            return "kSolverSpecificError"

    monkeypatch.setattr(least_squares, "Solve", lambda prog: Failed())
    fallback = least_squares._bounded_step(J, r, 0.5, lower, upper)
    np.testing.assert_allclose(fallback, qp, atol=1e-7)
    assert fallback[3] == -1.0


def test_a_step_on_a_jacobian_scaled_over_14_decades_is_solved_not_raised():
    """Clarabel stops with InsufficientProgress on this one (drake 1.x); it crashed the gap case
    outside_coactivation_factor1.5 in the all-case run on ca892f7."""
    rng = np.random.default_rng(21)
    J = rng.normal(size=(400, 8)) * 10.0 ** rng.uniform(-4, 10, size=8)
    J[:, 1] = J[:, 0] * (1 + 1e-9)
    r = rng.normal(size=400) * 10.0 ** rng.uniform(0, 8)
    mu = 10.0 ** rng.uniform(-15, 5)
    lower, upper = -10.0 ** rng.uniform(-8, 2, size=8), 10.0 ** rng.uniform(-8, 2, size=8)
    lower[2] = 0.0
    d = least_squares._bounded_step(J, r, mu, lower, upper)
    assert np.all((d >= lower) & (d <= upper))
    unconstrained = np.clip(np.linalg.lstsq(np.vstack([J, np.sqrt(mu) * np.eye(8)]), -np.concatenate([r, np.zeros(8)]),
                                            rcond=None)[0], lower, upper)
    cost = _step_cost(J, r, mu, d)
    assert cost <= min(_step_cost(J, r, mu, np.zeros(8)), _step_cost(J, r, mu, unconstrained)) * (1 + 1e-9)
