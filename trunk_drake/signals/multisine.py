"""Random-appearing multisine perturbations with analytic derivatives.

The thesis (section 3.4.1) drives the pelvis with the platform perturbations of
van Drunen et al.: random-appearing multisines of 20 s period with 0.2 Hz as lowest
and 1, 3 or 10 Hz as highest frequency, fade-in and fade-out periods, and a 2 Hz
low-pass on the recorded platform signal. This module builds such signals as a sum of
sinusoids on the ``1/period`` frequency grid, so that position, velocity and
acceleration are exact closed-form functions of time (a Drake ``LeafSystem`` evaluates
them at integrator times), and so that the FRF estimator (:mod:`trunk_drake.signals.frf`)
knows exactly which lines are excited.

Signal definition
-----------------
With ``tau = t - fade_in``::

    s(t) = sum_k A_k sin(2 pi f_k tau + phi_k),      f_k = h_k / period
    x(t) = w(t) s(t)
    v(t) = w'(t) s(t) + w(t) s'(t)
    a(t) = w''(t) s(t) + 2 w'(t) s'(t) + w(t) s''(t)

where ``h_k`` are the integer harmonic indices of the excited lines and ``w`` is the
fade window: 0 before ``t=0``, rising over ``[0, fade_in]``, 1 on the steady part
``[fade_in, fade_in + n_periods*period]`` (exactly ``n_periods`` whole periods), falling
over the next ``fade_out`` seconds, 0 after ``duration``. The steady part is what the
FRF uses; the fades only avoid abrupt platform motion.

Fade shapes: ``"raised_cosine"`` (``w = (1 - cos(pi u))/2``, ``u`` the normalised fade time)
is continuous in position and velocity, but its second derivative jumps by
``(pi/fade)^2/2`` at both ends of each fade, so the acceleration (and a force ``m*a``)
jumps by ``(pi/fade_in)^2/2 * s(t)`` at ``t=0`` and at ``t=fade_in`` (likewise at the
ends of the fade-out); a variable-step integrator handles this, but it is a
discontinuity. ``"quintic"`` (``w = 10u^3 - 15u^4 + 6u^5``) has continuous acceleration.

Amplitude
---------
No source for the platform displacement amplitude of the van Drunen et al. experiments
(Exp Brain Res 2015, 233:735-749, doi:10.1007/s00221-014-4151-2, the platform study the
thesis cites as [10]; the 2013 J Biomech study of the same group used a pushing
device, not a platform) could be found with the tools available to us: the abstract
gives the bandwidths (0.2 Hz up to 1, 3 or 10 Hz) but not the amplitude, and the
thesis does not print it. :data:`DEFAULT_AMPLITUDE_RMS_M` (0.01 m RMS) is therefore an
UNSOURCED placeholder chosen to be a gentle, car-like fore-aft motion (for the default
0.2-1 Hz flat-displacement spectrum it gives a peak of about 2.4-3.4 cm, depending on
the seed, and an RMS acceleration of roughly 0.2 m/s^2). Set ``amplitude`` explicitly
when reproducing an experiment.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from .filters import butterworth_response

__all__ = [
    "Multisine",
    "make_multisine",
    "DEFAULT_AMPLITUDE_RMS_M",
    "DEFAULT_PERIOD_S",
    "DEFAULT_FADE_S",
]

#: UNSOURCED placeholder: RMS platform displacement (m) of the steady part. See module docstring.
DEFAULT_AMPLITUDE_RMS_M = 0.01
#: Period of the multisine (s); van Drunen et al. / thesis section 3.4.1: 20 s.
DEFAULT_PERIOD_S = 20.0
#: Fade-in / fade-out duration (s); thesis section 3.4.2: a 2 s fade-in.
DEFAULT_FADE_S = 2.0

_FADE_SHAPES = ("raised_cosine", "quintic")
_CHUNK_ELEMENTS = 2_000_000  # bound on (n_times x n_lines) temporaries


def _window_parts(u: np.ndarray, shape: str):
    """Fade function f(u), f'(u), f''(u) for u in [0, 1] (derivatives w.r.t. u)."""
    if shape == "raised_cosine":
        pu = np.pi * u
        return 0.5 * (1.0 - np.cos(pu)), 0.5 * np.pi * np.sin(pu), 0.5 * np.pi**2 * np.cos(pu)
    # quintic smoothstep
    u2 = u * u
    return (
        u2 * u * (10.0 - 15.0 * u + 6.0 * u2),
        30.0 * u2 * (1.0 - u) ** 2,
        60.0 * u * (1.0 - 3.0 * u + 2.0 * u2),
    )


@dataclass(frozen=True, eq=False)
class Multisine:
    """A multisine on the ``1/period`` grid with fade-in/out; evaluates analytically.

    Construct with :func:`make_multisine`. All arrays are per excited line, in the order
    of increasing frequency. Amplitudes (m) and phases (rad) are the *final* ones, i.e.
    after the optional analytic low-pass and after amplitude normalisation.

    Attributes
    ----------
    period : float
        Period of the steady part (s); the frequency resolution is ``1/period``.
    harmonics : ndarray of int
        Harmonic indices ``h_k`` of the excited lines (``f_k = h_k/period``).
    amplitudes, phases : ndarray
        Line amplitudes ``A_k`` (m) and phases ``phi_k`` (rad) in ``s(t)``.
    n_periods : int
        Number of whole periods in the steady part.
    fade_in, fade_out : float
        Fade durations (s).
    fade_shape : str
        ``"raised_cosine"`` or ``"quintic"``.
    info : dict
        How the signal was designed (band, line selection, spectrum, phase method, seed,
        amplitude spec, low-pass); JSON-serialisable, for result metadata.
    """

    period: float
    harmonics: np.ndarray
    amplitudes: np.ndarray
    phases: np.ndarray
    n_periods: int = 1
    fade_in: float = DEFAULT_FADE_S
    fade_out: float = DEFAULT_FADE_S
    fade_shape: str = "raised_cosine"
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        h = np.asarray(self.harmonics)
        if h.ndim != 1 or h.size == 0:
            raise ValueError("harmonics must be a non-empty 1-D array of positive integers.")
        if not np.all(h == np.round(h)) or np.any(h < 1) or np.any(np.diff(h) <= 0):
            raise ValueError("harmonics must be strictly increasing positive integers.")
        a = np.asarray(self.amplitudes, dtype=float)
        p = np.asarray(self.phases, dtype=float)
        if a.shape != h.shape or p.shape != h.shape:
            raise ValueError(
                f"amplitudes {a.shape} and phases {p.shape} must match harmonics {h.shape}."
            )
        if not self.period > 0:
            raise ValueError(f"period must be positive, got {self.period!r}.")
        if int(self.n_periods) != self.n_periods or self.n_periods < 1:
            raise ValueError(f"n_periods must be a positive integer, got {self.n_periods!r}.")
        if self.fade_in < 0 or self.fade_out < 0:
            raise ValueError("fade_in and fade_out must be non-negative.")
        if self.fade_shape not in _FADE_SHAPES:
            raise ValueError(f"fade_shape must be one of {_FADE_SHAPES}, got {self.fade_shape!r}.")
        h = h.astype(np.int64)
        for name, val in (("harmonics", h), ("amplitudes", a), ("phases", p)):
            val = val.copy()
            val.setflags(write=False)
            object.__setattr__(self, name, val)
        w = 2.0 * np.pi * h / float(self.period)
        # precomputed, read-only arrays for cheap evaluation
        object.__setattr__(self, "_omega", w)
        object.__setattr__(self, "_a0", a)
        object.__setattr__(self, "_a1", a * w)
        object.__setattr__(self, "_a2", -a * w * w)
        object.__setattr__(self, "_t_steady0", float(self.fade_in))
        object.__setattr__(
            self, "_t_steady1", float(self.fade_in) + int(self.n_periods) * float(self.period)
        )
        object.__setattr__(self, "_t_end", self._t_steady1 + float(self.fade_out))

    # ------------------------------------------------------------------ properties
    @property
    def frequencies(self) -> np.ndarray:
        """Excited frequencies (Hz), ``harmonics/period``."""
        return self.harmonics / float(self.period)

    excited_frequencies = frequencies

    @property
    def base_frequency(self) -> float:
        """Frequency resolution ``1/period`` (Hz)."""
        return 1.0 / float(self.period)

    @property
    def duration(self) -> float:
        """``fade_in + n_periods*period + fade_out`` (s)."""
        return self._t_end

    @property
    def steady_window(self) -> tuple[float, float]:
        """``(start, end)`` of the steady part (s): ``n_periods`` whole periods, window = 1."""
        return (self._t_steady0, self._t_steady1)

    @property
    def rms(self) -> float:
        """RMS of the steady (periodic) part, ``sqrt(sum(A_k^2)/2)`` (m)."""
        return float(np.sqrt(0.5 * np.sum(self.amplitudes**2)))

    @property
    def peak(self) -> float:
        """Largest ``|x(t)|`` over the whole signal (= over one steady period) (m)."""
        return _periodic_peak(self._omega, self.amplitudes, self.phases, self.period)

    @property
    def crest_factor(self) -> float:
        """``peak / rms`` of the steady part."""
        return self.peak / self.rms

    def nonexcited_harmonics(self, f_lo: float | None = None, f_hi: float | None = None) -> np.ndarray:
        """Grid harmonics in ``[f_lo, f_hi]`` (default: the excited band) that carry no power."""
        lo = self.harmonics[0] if f_lo is None else int(math.ceil(f_lo * self.period - 1e-9))
        hi = self.harmonics[-1] if f_hi is None else int(math.floor(f_hi * self.period + 1e-9))
        grid = np.arange(max(lo, 1), hi + 1)
        return np.setdiff1d(grid, self.harmonics)

    # ------------------------------------------------------------------ evaluation
    def periodic(self, t, derivative: int = 0):
        """The un-windowed periodic signal ``s`` (or its 1st/2nd derivative) at ``t``."""
        if derivative not in (0, 1, 2):
            raise ValueError("derivative must be 0, 1 or 2.")
        s = self._periodic_all(t)
        return s[derivative]

    def _periodic_all(self, t):
        """(s, s', s'') at t (scalar or array)."""
        tarr = np.asarray(t, dtype=float)
        if tarr.ndim == 0:
            th = self._omega * (float(tarr) - self._t_steady0) + self.phases
            sn = np.sin(th)
            cs = np.cos(th)
            return float(self._a0 @ sn), float(self._a1 @ cs), float(self._a2 @ sn)
        flat = tarr.ravel() - self._t_steady0
        out = np.empty((3, flat.size))
        n_lines = self._omega.size
        step = max(1, _CHUNK_ELEMENTS // max(n_lines, 1))
        for i0 in range(0, flat.size, step):
            th = np.multiply.outer(flat[i0 : i0 + step], self._omega)
            th += self.phases
            sn = np.sin(th)
            cs = np.cos(th)
            out[0, i0 : i0 + step] = sn @ self._a0
            out[1, i0 : i0 + step] = cs @ self._a1
            out[2, i0 : i0 + step] = sn @ self._a2
        return tuple(o.reshape(tarr.shape) for o in out)

    def _window_scalar(self, t: float):
        if self._t_steady0 <= t <= self._t_steady1:
            return 1.0, 0.0, 0.0
        if t < 0.0 or t > self._t_end:
            return 0.0, 0.0, 0.0
        if t < self._t_steady0:
            d, sign = self.fade_in, 1.0
            u = t / d
        else:
            d, sign = self.fade_out, -1.0
            u = (self._t_end - t) / d
        if self.fade_shape == "raised_cosine":
            pu = math.pi * u
            f, f1, f2 = 0.5 * (1.0 - math.cos(pu)), 0.5 * math.pi * math.sin(pu), 0.5 * math.pi**2 * math.cos(pu)
        else:
            f = u**3 * (10.0 - 15.0 * u + 6.0 * u * u)
            f1 = 30.0 * u * u * (1.0 - u) ** 2
            f2 = 60.0 * u * (1.0 - 3.0 * u + 2.0 * u * u)
        return f, sign * f1 / d, f2 / (d * d)

    def window(self, t):
        """Fade window ``(w, w', w'')`` at ``t`` (scalar or array)."""
        tarr = np.asarray(t, dtype=float)
        scalar = tarr.ndim == 0
        if scalar:
            return self._window_scalar(float(tarr))
        tt = np.atleast_1d(tarr)
        w = np.zeros_like(tt)
        w1 = np.zeros_like(tt)
        w2 = np.zeros_like(tt)
        steady = (tt >= self._t_steady0) & (tt <= self._t_steady1)
        w[steady] = 1.0
        if self.fade_in > 0:
            m = (tt >= 0.0) & (tt < self._t_steady0)
            if np.any(m):
                u = tt[m] / self.fade_in
                f, f1, f2 = _window_parts(u, self.fade_shape)
                w[m], w1[m], w2[m] = f, f1 / self.fade_in, f2 / self.fade_in**2
        if self.fade_out > 0:
            m = (tt > self._t_steady1) & (tt <= self._t_end)
            if np.any(m):
                u = (self._t_end - tt[m]) / self.fade_out
                f, f1, f2 = _window_parts(u, self.fade_shape)
                w[m], w1[m], w2[m] = f, -f1 / self.fade_out, f2 / self.fade_out**2
        return w.reshape(tarr.shape), w1.reshape(tarr.shape), w2.reshape(tarr.shape)

    def evaluate(self, t):
        """Position (m), velocity (m/s) and acceleration (m/s^2) at ``t``.

        ``t`` may be a float (returns three floats; cheap enough to call from a
        ``LeafSystem`` at every integrator step) or an array (returns three arrays of
        the same shape). Outside ``[0, duration]`` all three are zero.
        """
        if isinstance(t, (float, int)):
            tarr = None
            tf = float(t)
        else:
            tarr = np.asarray(t, dtype=float)
            tf = float(tarr) if tarr.ndim == 0 else None
        if tf is not None:
            if tf < 0.0 or tf > self._t_end:
                return 0.0, 0.0, 0.0
            w, w1, w2 = self._window_scalar(tf)
            th = self._omega * (tf - self._t_steady0) + self.phases
            sn = np.sin(th)
            s = float(self._a0 @ sn)
            s2 = float(self._a2 @ sn)
            s1 = float(self._a1 @ np.cos(th))
            return w * s, w1 * s + w * s1, w2 * s + 2.0 * w1 * s1 + w * s2
        w, w1, w2 = self.window(tarr)
        s, s1, s2 = self._periodic_all(tarr)
        return w * s, w1 * s + w * s1, w2 * s + 2.0 * w1 * s1 + w * s2

    __call__ = evaluate

    def position(self, t):
        """Displacement ``x(t)`` (m)."""
        return self.evaluate(t)[0]

    def velocity(self, t):
        """Velocity ``x'(t)`` (m/s)."""
        return self.evaluate(t)[1]

    def acceleration(self, t):
        """Acceleration ``x''(t)`` (m/s^2)."""
        return self.evaluate(t)[2]

    def time_grid(self, fs: float, t_start: float = 0.0, t_end: float | None = None) -> np.ndarray:
        """Uniform grid ``t_start + i/fs`` up to and including ``t_end`` (default: duration).

        The steady window starts on a grid point when ``fade_in*fs`` is an integer, and
        each period holds ``period*fs`` samples when that is an integer (needed by
        :func:`~trunk_drake.signals.frf.estimate_frf`).
        """
        if not fs > 0:
            raise ValueError(f"fs must be positive, got {fs!r}.")
        t_end = self.duration if t_end is None else float(t_end)
        n = int(math.floor((t_end - t_start) * fs + 1e-9)) + 1
        if n < 1:
            raise ValueError(f"t_end={t_end} is before t_start={t_start}.")
        return t_start + np.arange(n) / fs

    def sample(self, fs: float, t_start: float = 0.0, t_end: float | None = None):
        """Sample on a uniform grid: returns ``(t, x, v, a)`` arrays."""
        t = self.time_grid(fs, t_start, t_end)
        x, v, a = self.evaluate(t)
        return t, x, v, a

    def steady_slice(self, t, skip_periods: int = 0) -> slice:
        """Index slice of a uniform time vector ``t`` covering the steady periods.

        Returns the samples with ``fade_in + skip_periods*period <= t < steady end``, i.e.
        ``(n_periods - skip_periods)`` whole periods, ready for
        :func:`~trunk_drake.signals.frf.estimate_frf`.
        """
        t = np.asarray(t, dtype=float)
        if not 0 <= skip_periods < self.n_periods:
            raise ValueError(
                f"skip_periods={skip_periods} must be in [0, n_periods={self.n_periods})."
            )
        t0 = self._t_steady0 + skip_periods * self.period
        dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
        eps = 1e-6 * dt
        i0 = int(np.searchsorted(t, t0 - eps, side="left"))
        i1 = int(np.searchsorted(t, self._t_steady1 - eps, side="left"))
        if i1 <= i0:
            raise ValueError("the time vector does not cover the steady part of the multisine.")
        return slice(i0, i1)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data description (lists and floats), e.g. for result metadata / JSON."""
        return {
            "period": float(self.period),
            "n_periods": int(self.n_periods),
            "fade_in": float(self.fade_in),
            "fade_out": float(self.fade_out),
            "fade_shape": self.fade_shape,
            "harmonics": self.harmonics.tolist(),
            "frequencies_hz": self.frequencies.tolist(),
            "amplitudes_m": self.amplitudes.tolist(),
            "phases_rad": self.phases.tolist(),
            "rms_m": self.rms,
            "info": dict(self.info),
        }

    def __repr__(self) -> str:
        f = self.frequencies
        return (
            f"Multisine(period={self.period:g} s, {f.size} lines {f[0]:g}-{f[-1]:g} Hz, "
            f"rms={self.rms:.4g} m, n_periods={self.n_periods}, fade_in={self.fade_in:g} s, "
            f"fade_out={self.fade_out:g} s, fade_shape={self.fade_shape!r})"
        )


def _periodic_peak(omega, amps, phases, period) -> float:
    """max |sum A sin(omega t + phi)| over one period: dense grid + Newton refinement."""
    h_max = float(np.max(omega)) * period / (2 * np.pi)
    n = int(max(4096, 64 * math.ceil(h_max)))
    t = np.arange(n) * (period / n)
    best = 0.0
    chunk = max(1, _CHUNK_ELEMENTS // omega.size)
    t_best = 0.0
    for i0 in range(0, n, chunk):
        th = np.multiply.outer(t[i0 : i0 + chunk], omega) + phases
        s = np.sin(th) @ amps
        j = int(np.argmax(np.abs(s)))
        if abs(s[j]) > best:
            best, t_best = abs(float(s[j])), float(t[i0 + j])
    tc = t_best
    for _ in range(8):  # Newton on s'(t) = 0
        th = omega * tc + phases
        s1 = float(np.cos(th) @ (amps * omega))
        s2 = float(-np.sin(th) @ (amps * omega * omega))
        if s2 == 0.0:
            break
        step = -s1 / s2
        if abs(step) > period / n:
            break
        tc += step
    val = abs(float(np.sin(omega * tc + phases) @ amps))
    return max(best, val)


def make_multisine(
    *,
    period: float = DEFAULT_PERIOD_S,
    f_min: float = 0.2,
    f_max: float = 1.0,
    lines: str | int = "all",
    harmonics: Sequence[int] | None = None,
    amplitude: float = DEFAULT_AMPLITUDE_RMS_M,
    amplitude_kind: str = "rms",
    spectrum: str | Sequence[float] = "displacement",
    phases: str | Sequence[float] = "random",
    seed: int | None = None,
    rng: np.random.Generator | None = None,
    n_periods: int = 1,
    fade_in: float = DEFAULT_FADE_S,
    fade_out: float = DEFAULT_FADE_S,
    fade_shape: str = "raised_cosine",
    lowpass_hz: float | None = None,
    lowpass_order: int = 2,
    lowpass_zero_phase: bool = False,
) -> Multisine:
    """Design a random-appearing multisine perturbation (thesis section 3.4.1).

    Parameters
    ----------
    period : float
        Period in s (default 20 s, as van Drunen et al.); lines lie on the ``1/period`` grid.
    f_min, f_max : float
        Band in Hz (default 0.2-1 Hz, the lowest-bandwidth condition the thesis uses;
        van Drunen et al. also used 0.2-3 and 0.2-10 Hz).
    lines : "all", "odd", "even" or int k
        Which grid lines inside ``[f_min, f_max]`` are excited: ``"all"`` every line;
        ``"odd"``/``"even"`` only odd/even harmonic indices ``h`` (``f = h/period``), so
        that the non-excited lines in the band reveal nonlinear distortion; an int ``k``
        every k-th line starting at the first line in the band. The excited lines are
        recorded in ``Multisine.harmonics`` / ``.frequencies``; the complementary grid
        lines are given by :meth:`Multisine.nonexcited_harmonics`.
    harmonics : sequence of int, optional
        Explicit harmonic indices; overrides ``f_min``/``f_max``/``lines``.
    amplitude : float
        Size of the final (filtered) steady signal, in m: RMS (default 0.01 m, an
        UNSOURCED placeholder, see the module docstring) or peak displacement, per
        ``amplitude_kind``.
    amplitude_kind : {"rms", "peak"}
        ``"rms"``: ``sqrt(sum(A_k^2)/2) = amplitude``; ``"peak"``: ``max |x(t)| = amplitude``.
    spectrum : "displacement", "velocity", "acceleration" or sequence
        Which quantity has a flat line spectrum (relative line amplitudes ``1``,
        ``1/omega`` or ``1/omega^2``), or explicit relative amplitudes per excited line.
    phases : "random", "schroeder" or sequence
        ``"random"``: uniform on ``[0, 2 pi)`` from a ``numpy.random.Generator`` (``rng``
        or ``default_rng(seed)``); ``"schroeder"``: ``phi_k = -pi k (k-1) / N`` (low crest
        factor for flat spectra, deterministic); or explicit phases (rad).
    seed : int, optional
        Seed for ``numpy.random.default_rng`` (ignored if ``rng`` is given).
    rng : numpy.random.Generator, optional
        Generator for the random phases.
    n_periods : int
        Number of whole periods in the steady part (default 1: the 20 s signal).
    fade_in, fade_out : float
        Fade durations in s (default 2 s each; thesis section 3.4.2). The total signal
        is ``fade_in + n_periods*period + fade_out`` long.
    fade_shape : {"raised_cosine", "quintic"}
        See the module docstring (raised cosine: acceleration jumps at the fade ends).
    lowpass_hz : float, optional
        Apply a Butterworth low-pass analytically to each line (thesis: 2 Hz). The
        signal remains an exact sum of sinusoids.
    lowpass_order : int
        Butterworth order (default 2).
    lowpass_zero_phase : bool
        ``False``: causal analog filter (magnitude and phase per line). ``True``: the
        forward-backward (filtfilt) equivalent, ``|H|^2`` and zero phase.

    Returns
    -------
    Multisine

    Examples
    --------
    >>> ms = make_multisine(seed=1)              # 0.2-1 Hz, 17 lines, 20 s period
    >>> x, v, a = ms.evaluate(3.7)               # analytic, scalar time
    >>> t, x, v, a = ms.sample(fs=100.0)         # on a grid
    """
    if not period > 0:
        raise ValueError(f"period must be positive, got {period!r}.")
    if harmonics is not None:
        h = np.asarray(harmonics)
        if h.ndim != 1 or h.size == 0 or not np.all(h == np.round(h)) or np.any(h < 1):
            raise ValueError("harmonics must be a non-empty sequence of positive integers.")
        h = np.unique(h.astype(np.int64))
        band = (float(h[0]) / period, float(h[-1]) / period)
        lines_desc: Any = "explicit"
    else:
        if not (f_min > 0 and f_max >= f_min):
            raise ValueError(f"need 0 < f_min <= f_max, got f_min={f_min!r}, f_max={f_max!r}.")
        lo = int(math.ceil(f_min * period - 1e-9))
        hi = int(math.floor(f_max * period + 1e-9))
        grid = np.arange(max(lo, 1), hi + 1)
        if grid.size == 0:
            raise ValueError(
                f"no line of the 1/period = {1 / period:g} Hz grid lies in [{f_min}, {f_max}] Hz; "
                "widen the band or lengthen the period."
            )
        if lines == "all":
            h = grid
        elif lines == "odd":
            h = grid[grid % 2 == 1]
        elif lines == "even":
            h = grid[grid % 2 == 0]
        elif isinstance(lines, (int, np.integer)) and not isinstance(lines, bool) and lines >= 1:
            h = grid[:: int(lines)]
        else:
            raise ValueError(f"lines must be 'all', 'odd', 'even' or a positive int, got {lines!r}.")
        if h.size == 0:
            raise ValueError(f"lines={lines!r} selects no line in [{f_min}, {f_max}] Hz.")
        band = (float(f_min), float(f_max))
        lines_desc = lines if isinstance(lines, str) else int(lines)
    n = h.size
    omega = 2 * np.pi * h / period

    # relative amplitudes
    if isinstance(spectrum, str):
        if spectrum == "displacement":
            rel = np.ones(n)
        elif spectrum == "velocity":
            rel = 1.0 / omega
        elif spectrum == "acceleration":
            rel = 1.0 / omega**2
        else:
            raise ValueError(
                "spectrum must be 'displacement', 'velocity', 'acceleration' or a sequence, "
                f"got {spectrum!r}."
            )
        spectrum_desc: Any = spectrum
    else:
        rel = np.asarray(spectrum, dtype=float)
        if rel.shape != (n,):
            raise ValueError(f"spectrum has shape {rel.shape}; expected ({n},), one value per line.")
        if np.any(rel < 0) or not np.any(rel > 0):
            raise ValueError("explicit spectrum amplitudes must be non-negative and not all zero.")
        spectrum_desc = "explicit"

    # phases
    seed_used = None
    if isinstance(phases, str):
        if phases == "random":
            if rng is None:
                rng = np.random.default_rng(seed)
                seed_used = seed
            ph = rng.uniform(0.0, 2.0 * np.pi, size=n)
        elif phases == "schroeder":
            k = np.arange(1, n + 1)
            ph = -np.pi * k * (k - 1) / n
        else:
            raise ValueError(f"phases must be 'random', 'schroeder' or a sequence, got {phases!r}.")
        phase_desc: Any = phases
    else:
        ph = np.asarray(phases, dtype=float)
        if ph.shape != (n,):
            raise ValueError(f"phases has shape {ph.shape}; expected ({n},), one value per line.")
        phase_desc = "explicit"

    amps = rel.astype(float)
    ph = np.asarray(ph, dtype=float)
    if lowpass_hz is not None:
        g = butterworth_response(h / period, lowpass_hz, lowpass_order)
        if lowpass_zero_phase:
            amps = amps * np.abs(g) ** 2
        else:
            amps = amps * np.abs(g)
            ph = ph + np.angle(g)

    if not amplitude > 0:
        raise ValueError(f"amplitude must be positive, got {amplitude!r}.")
    if amplitude_kind == "rms":
        scale = amplitude / np.sqrt(0.5 * np.sum(amps**2))
    elif amplitude_kind == "peak":
        scale = amplitude / _periodic_peak(omega, amps, ph, period)
    else:
        raise ValueError(f"amplitude_kind must be 'rms' or 'peak', got {amplitude_kind!r}.")
    amps = amps * scale
    ph = np.mod(ph, 2 * np.pi)

    info = {
        "band_hz": list(band),
        "lines": lines_desc,
        "spectrum": spectrum_desc,
        "phases": phase_desc,
        "seed": seed_used,
        "amplitude": float(amplitude),
        "amplitude_kind": amplitude_kind,
        "amplitude_source": (
            "UNSOURCED placeholder default (0.01 m RMS)"
            if (amplitude == DEFAULT_AMPLITUDE_RMS_M and amplitude_kind == "rms")
            else "user"
        ),
        "lowpass_hz": None if lowpass_hz is None else float(lowpass_hz),
        "lowpass_order": int(lowpass_order),
        "lowpass_zero_phase": bool(lowpass_zero_phase),
    }
    return Multisine(
        period=float(period),
        harmonics=h,
        amplitudes=amps,
        phases=ph,
        n_periods=int(n_periods),
        fade_in=float(fade_in),
        fade_out=float(fade_out),
        fade_shape=fade_shape,
        info=info,
    )
