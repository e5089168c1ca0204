"""A measured perturbation (uniformly sampled displacement) as a smooth signal with derivatives."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import make_interp_spline

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
        self._spline = make_interp_spline(t, x, k=5)
        self._d1, self._d2 = self._spline.derivative(1), self._spline.derivative(2)

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    def evaluate(self, t):
        """(x, v, a) at time(s) t (m, m/s, m/s^2)."""
        scalar = np.ndim(t) == 0
        tt = np.asarray(t, dtype=float)
        inside = (tt >= self.time[0]) & (tt <= self.time[-1])
        tc = np.clip(tt, self.time[0], self.time[-1])
        x = self._spline(tc)
        v = np.where(inside, self._d1(tc), 0.0)
        a = np.where(inside, self._d2(tc), 0.0)
        return (float(x), float(v), float(a)) if scalar else (x, v, a)
