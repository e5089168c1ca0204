"""A measured perturbation (uniformly sampled displacement) as a smooth signal with derivatives."""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from scipy.interpolate import PPoly, make_interp_spline

from .filters import lowpass_filtfilt


@dataclass
class SampledSignal:
    """Quintic interpolating spline through a sampled displacement, so a simulation can
    evaluate position, velocity and acceleration at any time (``evaluate(t) -> (x, v, a)``).

    Optionally low-pass filtered first (zero phase; the thesis used 2 Hz on its platform
    signal). Outside the sampled interval the signal holds its end value (v = a = 0).
    """

    time: np.ndarray
    displacement: np.ndarray
    lowpass_hz: float | None = None

    def __post_init__(self):
        t = np.asarray(self.time, dtype=float)
        x = np.asarray(self.displacement, dtype=float)
        if t.ndim != 1 or t.shape != x.shape or t.size < 6:
            raise ValueError(f"need matching 1-D time and displacement with >= 6 samples, got {t.shape} and {x.shape}")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(x)) and np.all(np.diff(t) > 0)):
            raise ValueError("time must be finite and strictly increasing and displacement finite")
        if self.lowpass_hz is not None:
            x = lowpass_filtfilt(x, 1.0 / np.median(np.diff(t)), self.lowpass_hz)
        self.time, self.displacement = t, x
        pieces = PPoly.from_spline(make_interp_spline(t, x, k=5))  # the spline as one polynomial per interval
        self._breaks, self._coefficients = np.ascontiguousarray(pieces.x), np.ascontiguousarray(pieces.c)

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    def evaluate(self, t):
        """(x, v, a) at time(s) t (m, m/s, m/s^2): floats for a scalar t (a simulation's every evaluation),
        arrays of t's shape otherwise; compiled either way."""
        if isinstance(t, float):
            return _scalar(t, self._breaks, self._coefficients)
        tt = np.asarray(t, dtype=float)
        if tt.ndim == 0:
            return _scalar(float(tt), self._breaks, self._coefficients)
        values = _many(tt.ravel(), self._breaks, self._coefficients)
        return tuple(v.reshape(tt.shape) for v in values)


@numba.njit(cache=True)
def _scalar(t, breaks, c):
    """(x, v, a) of the piecewise polynomial (breaks, c) (scipy's PPoly layout, highest power first) at float t;
    outside the breaks the end value with v = a = 0."""
    n = breaks.shape[0]
    inside = breaks[0] <= t <= breaks[n - 1]
    tc = min(max(t, breaks[0]), breaks[n - 1])
    i = np.searchsorted(breaks, tc, side="right") - 1
    i = min(max(i, 0), n - 2)
    while i > 0 and breaks[i + 1] == breaks[i]:  # a repeated end knot: the last interval of positive length
        i -= 1
    dt = tc - breaks[i]
    x, v, a = 0.0, 0.0, 0.0
    k = c.shape[0] - 1  # degree
    for j in range(k + 1):
        power = k - j
        x = x * dt + c[j, i]
        if power >= 1:
            v = v * dt + power * c[j, i]
        if power >= 2:
            a = a * dt + power * (power - 1) * c[j, i]
    if not inside:
        v, a = 0.0, 0.0
    return x, v, a


@numba.njit(cache=True)
def _many(times, breaks, c):
    """`_scalar` at every time of a 1-D array: arrays x, v, a."""
    x, v, a = np.empty(times.size), np.empty(times.size), np.empty(times.size)
    for i in range(times.size):
        x[i], v[i], a[i] = _scalar(times[i], breaks, c)
    return x, v, a
