"""Bounded least squares: Levenberg-Marquardt, the finite-difference Jacobian, the covariance."""

import numpy as np
import pytest

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
