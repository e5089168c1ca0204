"""Bounded nonlinear least squares: the secant Levenberg-Marquardt solver, the finite-difference
Jacobian and the covariance of the fitted parameters.

Every fit in trunk-drake (reflex gains, gap candidates on linear and nonlinear models) and the
linearisation of the diagram use these. Residual functions for the Jacobian take a *list* of
points and return a list of residual vectors, so a caller can evaluate the displaced points
together (in parallel worker processes, or batched).
"""

from __future__ import annotations

import logging

import numpy as np
from pydrake.solvers import MathematicalProgram, Solve
from scipy.optimize import lsq_linear

log = logging.getLogger(__name__)


def finite_difference_jacobian(residuals, x, steps, *, central: bool = False, upper=None, columns=None,
                               r0=None) -> np.ndarray:
    """d residuals / dx at `x` by finite differences; `residuals(points) -> [vector, ...]`.

    Forward differences by default (`r0`, the residuals at x, is evaluated unless given), with
    a backward step wherever x + step would pass `upper`; central differences with
    ``central=True``. `steps` is a scalar or one per coordinate. Only `columns` (indices) are
    computed, the others are zero: e.g. parameters known to have no effect at x.
    """
    x = np.asarray(x, float)
    steps = np.broadcast_to(np.asarray(steps, float), x.shape).copy()
    if upper is not None:
        steps = np.where(x + steps <= upper, steps, -steps)
    columns = np.arange(x.size) if columns is None else np.asarray(columns, int)
    unit = np.eye(x.size)
    if central:
        values = residuals([x + steps[j] * unit[j] for j in columns] + [x - steps[j] * unit[j] for j in columns])
        plus, minus = values[:columns.size], values[columns.size:]
        size = np.size(values[0]) if values else 0
    else:
        if r0 is None:
            r0 = residuals([x])[0]
        plus = residuals([x + steps[j] * unit[j] for j in columns])
        minus = [r0] * columns.size
        size = np.size(r0)
    J = np.zeros((size, x.size))
    for j, p, m in zip(columns, plus, minus):
        J[:, j] = (np.asarray(p) - np.asarray(m)) / (2 * steps[j] if central else steps[j])
    return J


def levenberg_marquardt(fun, jac, x0, lo, hi, max_iterations: int = 15, tolerance: float = 1e-3,
                        refresh_every: int = 4, progress: bool = False, label: str = "", scale=None):
    """Bounded secant Levenberg-Marquardt: returns (x, J, r, iterations, status).

    Each step solves the bounded, damped Gauss-Newton subproblem as a quadratic program in
    Drake's MathematicalProgram. Damping update of Nielsen (1999); the Jacobian is recomputed
    by `jac` at the start, every `refresh_every` iterations and after two rejected steps in a
    row, otherwise kept current by Broyden's rank-one secant update (Madsen, Nielsen & Tingleff
    2004, "Methods for non-linear least squares problems", section 3.4). Stops when an
    accepted step lowers the cost 0.5 |r|^2 by less than `tolerance` (relative).

    `scale` (one per coordinate, e.g. each one's bound range) sets the units the damping mu |d|^2 measures steps
    in. Without it a coordinate of wide range in small units (a cubic stiffening coefficient over 0-2000 1/rad^2
    beside log10 gains) has a Jacobian column thousands of times smaller than the others', and the damping, set
    from the largest, holds it at its start for the few steps a time-domain refit takes.
    """
    if scale is not None:  # solved for u = (x - x0) / scale: exactly x0 at the start (refits cache simulations by x)
        x0, s = np.asarray(x0, float), np.broadcast_to(np.asarray(scale, float), np.shape(x0))
        if not np.all(np.isfinite(s) & (s > 0)):
            raise ValueError(f"levenberg_marquardt: every scale must be finite and positive (one per coordinate, e.g. its "
                             f"bound range hi - lo); got {s}. A coordinate whose bounds coincide cannot be fitted: hold it instead")
        u, J, r, it, status = levenberg_marquardt(lambda u: fun(x0 + u * s), lambda u: jac(x0 + u * s) * s,
                                                  np.zeros_like(x0), (np.asarray(lo, float) - x0) / s,
                                                  (np.asarray(hi, float) - x0) / s, max_iterations, tolerance,
                                                  refresh_every, progress, label)
        return np.clip(x0 + u * s, lo, hi), J / s, r, it, status
    x = np.asarray(x0, float)
    r = fun(x)
    J = jac(x)
    cost = 0.5 * r @ r
    mu = 1e-3 * max(np.diag(J.T @ J).max(), 1e-12)
    nu, rejected, since_refresh = 2.0, 0, 0
    status = f"maximum iterations ({max_iterations}) reached"
    for it in range(1, max_iterations + 1):
        d = _bounded_step(J, r, mu, lo - x, hi - x)
        if np.linalg.norm(d) < 1e-6 * (np.linalg.norm(x) + 1e-6):
            status = "step below tolerance"
            break
        r_new = fun(x + d)
        cost_new = 0.5 * r_new @ r_new
        predicted = cost - 0.5 * np.sum((J @ d + r) ** 2)
        rho = (cost - cost_new) / predicted if predicted > 0 else -1.0
        J = J + np.outer(r_new - r - J @ d, d) / (d @ d)  # Broyden secant update
        since_refresh += 1
        if rho > 0:
            relative = (cost - cost_new) / cost
            x, r, cost = x + d, r_new, cost_new
            mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
            nu, rejected = 2.0, 0
            if progress:
                print(f"  {label} iteration {it}: cost {cost:.6g} (-{100 * relative:.2f} %), mu {mu:.3g}", flush=True)
            if relative < tolerance:
                status = f"relative cost reduction below {tolerance}"
                break
        else:
            mu *= nu
            nu *= 2.0
            rejected += 1
            if progress:
                print(f"  {label} iteration {it}: step rejected (rho {rho:.3g}), mu {mu:.3g}", flush=True)
        if since_refresh >= refresh_every or rejected >= 2:
            J, since_refresh, rejected = jac(x), 0, 0
    return x, J, r, it, status


def _bounded_step(J, r, mu, lower, upper) -> np.ndarray:
    """argmin_d 0.5|J d + r|^2 + 0.5 mu |d|^2 subject to lower <= d <= upper (a QP). Where Drake's QP solver fails,
    as Clarabel does ("InsufficientProgress") on Jacobians whose columns differ in scale by 1e10 or more (a gap
    candidate's delay column vanishes with its gain), the same problem is solved as bounded linear least squares."""
    prog = MathematicalProgram()
    d = prog.NewContinuousVariables(J.shape[1], "d")
    prog.AddQuadraticCost(J.T @ J + mu * np.eye(J.shape[1]), J.T @ r, d, is_convex=True)
    prog.AddBoundingBoxConstraint(lower, upper, d)
    result = Solve(prog)
    if not result.is_success():
        log.info("Levenberg-Marquardt step: the QP solver returned %s; solved by bounded least squares instead",
                 result.get_solution_result())
        return _bounded_least_squares_step(J, r, mu, lower, upper)
    return np.clip(result.GetSolution(d), lower, upper)


def _bounded_least_squares_step(J, r, mu, lower, upper) -> np.ndarray:
    """The step of `_bounded_step` as the bounded linear least-squares problem [J; sqrt(mu) I] d = [-r; 0], its
    columns scaled to unit norm (unscaled, scipy's BVLS returned a step 6,000 times costlier than none on a Jacobian
    scaled over 14 decades); coordinates whose bounds coincide stay at them."""
    n = J.shape[1]
    lower, upper = np.broadcast_to(lower, n).astype(float), np.broadcast_to(upper, n).astype(float)
    step = lower.copy()
    free = upper > lower
    if free.any():
        A = np.vstack([J[:, free], np.sqrt(mu) * np.eye(n)[:, free]])
        b = -np.concatenate([r + J[:, ~free] @ lower[~free], np.zeros(n)])
        scale = np.linalg.norm(A, axis=0)
        scale[scale == 0.0] = 1.0
        z = lsq_linear(A / scale, b, bounds=(lower[free] * scale, upper[free] * scale), method="bvls").x
        step[free] = z / scale
    return np.clip(step, lower, upper)


def inverse_or_inf(A: np.ndarray, rcond: float = 1e-12) -> np.ndarray:
    """(Pseudo-)inverse of a symmetric positive semi-definite matrix A = J^T J, with infinite
    variance for parameters the data do not touch at all (zero row/column of A)."""
    untouched = np.abs(np.diag(A)) <= rcond * max(np.abs(np.diag(A)).max(), 0.0)
    out = np.linalg.pinv(A, rcond=rcond, hermitian=True)
    out[untouched, :] = np.inf
    out[:, untouched] = np.inf
    return out
