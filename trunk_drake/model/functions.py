"""One-variable functions of OpenSim models (transform axes, couplers, moving path points).

Plain data with numpy evaluation, reproducing OpenSim 4.6's definitions: ``Constant``,
``LinearFunction`` (slope, intercept), ``PolynomialFunction`` (highest power first),
``PiecewiseLinearFunction`` and ``SimmSpline`` (alias ``NaturalCubicSpline``: Forsythe,
Malcolm and Moler's cubic spline with end conditions from third divided differences), both
extrapolated linearly with their end slopes, and ``MultiplierFunction`` (scale times a
function).
"""

from __future__ import annotations

from bisect import bisect_left
from dataclasses import dataclass, field

import numpy as np

_TINY = 1e-7         # smallest knot spacing used in the slopes (OpenSim's TINY_NUMBER)
_ROUNDOFF = 2e-13    # an abscissa this close to an end knot takes the end value


@dataclass(frozen=True)
class Function:
    """``kind`` is one of constant, linear, polynomial, piecewise_linear, spline, multiplier."""

    kind: str
    coefficients: tuple[float, ...] = ()   # constant: (c,); linear: (slope, intercept); polynomial: highest power first
    x: tuple[float, ...] = ()               # knots (piecewise_linear, spline)
    y: tuple[float, ...] = ()
    scale: float = 1.0                      # multiplier
    inner: "Function | None" = None         # multiplier
    _pieces: tuple = field(default=(), repr=False, compare=False)

    def __post_init__(self):
        if self.kind in ("piecewise_linear", "spline"):
            if len(self.x) != len(self.y) or len(self.x) < 1:
                raise ValueError(f"{self.kind} function needs as many x as y knots (got {len(self.x)} and {len(self.y)})")
            if np.any(np.diff(self.x) < 0):
                raise ValueError(f"{self.kind} function knots must be increasing, got x={list(self.x)}")
            b, c, d = (_spline_coefficients if self.kind == "spline" else _linear_coefficients)(np.array(self.x), np.array(self.y))
            object.__setattr__(self, "_pieces", (b, c, d))
        elif self.kind not in ("constant", "linear", "polynomial", "multiplier"):
            raise ValueError(f"unknown function kind {self.kind!r}")

    # ------------------------------------------------------------------ evaluation
    def value(self, x):
        """f(x), elementwise."""
        return self._evaluate(np.asarray(x, dtype=float), 0)

    def derivative(self, x):
        """f'(x), elementwise."""
        return self._evaluate(np.asarray(x, dtype=float), 1)

    def at(self, x: float, order: int = 0) -> float:
        """f(x) (order 0) or f'(x) (order 1) of one float, without numpy overhead."""
        kind = self.kind
        if kind == "constant":
            return 0.0 if order else self.coefficients[0]
        if kind == "linear":
            return self.coefficients[0] if order else self.coefficients[0] * x + self.coefficients[1]
        if kind == "multiplier":
            return self.scale * self.inner.at(x, order)
        if kind == "polynomial":
            return float(self._evaluate(np.asarray(x, dtype=float), order))
        knots, values = self.x, self.y
        b, c, d = self._pieces
        last = len(knots) - 1
        if last == 0:
            return 0.0 if order else values[0]
        if abs(x - knots[0]) <= _ROUNDOFF or x < knots[0]:
            return b[0] if order else values[0] + min(x - knots[0], 0.0) * b[0]
        if abs(x - knots[last]) <= _ROUNDOFF or x > knots[last]:
            return b[last] if order else values[last] + max(x - knots[last], 0.0) * b[last]
        k = min(max(bisect_left(knots, x) - 1, 0), last - 1)
        dx = x - knots[k]
        if order:
            return b[k] + dx * (2.0 * c[k] + 3.0 * dx * d[k])
        return values[k] + dx * (b[k] + dx * (c[k] + dx * d[k]))

    def _evaluate(self, x, order):
        if self.kind == "constant":
            return np.full_like(x, 0.0 if order else self.coefficients[0])
        if self.kind == "linear":
            slope, intercept = self.coefficients
            return np.full_like(x, slope) if order else slope * x + intercept
        if self.kind == "polynomial":
            p = np.poly1d(self.coefficients)
            return (p.deriv() if order else p)(x) + 0.0 * x
        if self.kind == "multiplier":
            return self.scale * self.inner._evaluate(x, order)
        return self._piecewise(x, order)

    def _piecewise(self, x, order):
        knots, values = np.array(self.x), np.array(self.y)
        b, c, d = self._pieces
        n = knots.size
        if n == 1:
            return np.full_like(x, 0.0 if order else values[0])
        k = np.clip(np.searchsorted(knots, x, side="left") - 1, 0, n - 2)
        dx = x - knots[k]
        if order:
            inside = b[k] + dx * (2.0 * c[k] + 3.0 * dx * d[k])
            out = np.where(x < knots[0], b[0], np.where(x > knots[-1], b[-1], inside))
            return np.where(np.abs(x - knots[0]) <= _ROUNDOFF, b[0], np.where(np.abs(x - knots[-1]) <= _ROUNDOFF, b[-1], out))
        inside = values[k] + dx * (b[k] + dx * (c[k] + dx * d[k]))
        out = np.where(x < knots[0], values[0] + (x - knots[0]) * b[0],
                       np.where(x > knots[-1], values[-1] + (x - knots[-1]) * b[-1], inside))
        return np.where(np.abs(x - knots[0]) <= _ROUNDOFF, values[0], np.where(np.abs(x - knots[-1]) <= _ROUNDOFF, values[-1], out))

    # ------------------------------------------------------------------ structure
    def linear_form(self) -> tuple[float, float] | None:
        """(slope, intercept) if the function is affine everywhere, else None."""
        if self.kind == "constant":
            return 0.0, float(self.coefficients[0])
        if self.kind == "linear":
            return float(self.coefficients[0]), float(self.coefficients[1])
        if self.kind == "polynomial":
            coefs = np.trim_zeros(np.asarray(self.coefficients, float), "f")
            if coefs.size <= 2:
                coefs = np.concatenate([np.zeros(2 - coefs.size), coefs])
                return float(coefs[0]), float(coefs[1])
            return None
        if self.kind == "multiplier":
            inner = self.inner.linear_form()
            return None if inner is None else (self.scale * inner[0], self.scale * inner[1])
        if len(self.x) == 2 or (self.kind == "piecewise_linear" and np.ptp(self._pieces[0]) == 0):
            b = self._pieces[0]
            return float(b[0]), float(self.y[0] - b[0] * self.x[0])
        return None

    @property
    def is_constant(self) -> bool:
        form = self.linear_form()
        return form is not None and form[0] == 0.0


def constant(value: float) -> Function:
    return Function("constant", (float(value),))


def _linear_coefficients(x, y):
    n = x.size
    b = np.zeros(n)
    if n > 1:
        b[:-1] = (y[1:] - y[:-1]) / np.maximum(_TINY, x[1:] - x[:-1])
        b[-1] = b[-2]
    return b, np.zeros(n), np.zeros(n)


def _spline_coefficients(x, y):
    """Cubic spline coefficients b, c, d (value y_k + dx (b_k + dx (c_k + dx d_k)))."""
    n = x.size
    b, c, d = np.zeros(n), np.zeros(n), np.zeros(n)
    if n < 2:
        return b, c, d
    if n == 2:
        b[:] = (y[1] - y[0]) / max(_TINY, x[1] - x[0])
        return b, c, d
    last = n - 1
    h = np.maximum(_TINY, np.diff(x))           # interval widths
    d[:last] = h
    slope = np.diff(y) / h
    # tridiagonal system: diagonal b, off-diagonal d, right-hand side c (second differences)
    c[1:last] = slope[1:] - slope[:-1]
    b[1:last] = 2.0 * (h[:-1] + h[1:])
    b[0], b[last] = -h[0], -h[last - 1]
    if n > 3:
        d31 = max(_TINY, x[3] - x[1]); d20 = max(_TINY, x[2] - x[0])
        d1 = max(_TINY, x[last] - x[n - 3]); d2 = max(_TINY, x[last - 1] - x[n - 4])
        d30 = max(_TINY, x[3] - x[0]); d3 = max(_TINY, x[last] - x[n - 4])
        c0 = c[2] / d31 - c[1] / d20
        cl = c[last - 1] / d1 - c[n - 3] / d2
        c[0] = c0 * h[0] * h[0] / d30
        c[last] = -cl * h[last - 1] * h[last - 1] / d3
    for i in range(1, n):
        t = d[i - 1] / b[i - 1]
        b[i] -= t * d[i - 1]
        c[i] -= t * c[i - 1]
    c[last] /= b[last]
    for i in range(last - 1, -1, -1):
        c[i] = (c[i] - d[i] * c[i + 1]) / b[i]
    b_last = (y[last] - y[last - 1]) / h[last - 1] + h[last - 1] * (c[last - 1] + 2.0 * c[last])
    b[:last] = slope - h * (c[1:] + 2.0 * c[:last])
    d[:last] = (c[1:] - c[:last]) / h
    c *= 3.0
    b[last] = b_last
    d[last] = d[last - 1]
    return b, c, d
