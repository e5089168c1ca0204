"""Frequency response function (FRF) estimation at the excited multisine lines.

Thesis eq. (3.4): ``H(f) = S_Py(f) / S_PP(f)``, with ``S_Py`` the cross-spectral density
of perturbation ``P`` and response ``y``. Following the thesis (and van Drunen et al.),
the spectral densities are evaluated *only* at frequencies where the perturbation has
power, averaged over time segments (here: each segment is one multisine period, so the
excited lines fall exactly on DFT bins and there is no leakage) and over adjacent
excited frequency points (thesis: two).

Estimator
---------
For segments ``m = 1..M`` (whole periods of ``N_p = period*fs`` samples) and excited
lines ``k`` in a group ``G`` of ``n_adjacent`` neighbouring excited lines::

    S_uu(G) = mean_{m, k in G} |U_m(k)|^2 / 2
    S_uy(G) = mean_{m, k in G} conj(U_m(k)) Y_m(k) / 2
    S_yy(G) = mean_{m, k in G} |Y_m(k)|^2 / 2
    H(G)    = S_uy / S_uu,      coherence = |S_uy|^2 / (S_uu S_yy)

with ``U_m(k)`` the DFT amplitude (``2/N_p * rfft``) of segment ``m`` at harmonic ``k``;
``S`` is thus the power (units^2) per line. The frequency of a group is the mean of its
lines' frequencies. ``n_averages = M * |G|`` (``n_d`` in Bendat & Piersol).

Pooling adjacent lines treats them as realisations of one ``H``. Where ``H`` changes
noticeably from line to line (steep gain slopes, resonances), the pooled estimate is the
``|U|^2``-weighted mean of ``H`` over the group (a bias with respect to ``H`` at the group
frequency) and the coherence drops below 1 even without noise, which widens the
coherence-based bounds. Example (noise-free, base-excited mass-spring-damper,
``fn = 1 Hz``, ``zeta = 0.3``, 0.05 Hz lines, pairs): coherence 0.95 and gain bound
+-9 % at 0.225 Hz where ``|H| ~ f^2``, gain bias up to 1.5 % near resonance. Use
``n_adjacent=1`` with several periods when this matters.

Confidence bounds
-----------------
``bounds="coherence"`` (default) uses the standard normalised random errors of
Bendat & Piersol (Random Data, ch. 9; 2nd ed. p. 317)::

    eps_gain  = sqrt(1 - coh) / (sqrt(coh) * sqrt(2 n_d))        (relative, gain)
    sigma_phi = sqrt(1 - coh) / (sqrt(coh) * sqrt(2 n_d))        (rad, phase)

and reports ``gain * (1 -/+ z eps_gain)`` (lower bound clipped at 0) and
``phase -/+ z sigma_phi``, ``z`` the two-sided normal quantile of ``confidence``.
These are first-order (small-error) approximations valid for Gaussian noise on the
output; they are NaN when ``n_d < 2`` (coherence is identically 1 then). With a noise-free
linear system the coherence is 1 and the bounds collapse onto the estimate.

``bounds="segments"`` instead uses the spread of the per-segment estimates
``H_m(G) = sum_k conj(U_m)Y_m / sum_k |U_m|^2``: standard error of the gain
``std_m |H_m| / sqrt(M)`` and of the phase ``std_m angle(H_m/H) / sqrt(M)``, with a
Student-t quantile on ``M-1`` degrees of freedom (needs ``M >= 2``).

Nonlinearity and noise indicators
---------------------------------
The output spectrum averaged over periods (the periodic part) is split into excited
lines and non-excited lines of the ``1/period`` grid inside ``nonexcited_band``
(default: from the lowest to the highest excited line). For a linear time-invariant
system driven by a noise-free multisine, the periodic output has power only at the
excited lines; power at non-excited lines (e.g. the even lines of an odd-line
multisine) reveals nonlinear distortion. Noise shows up as period-to-period variation:
``noise_power_excited`` is the single-period noise power at the excited lines estimated
from the variance across periods.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from scipy import stats

__all__ = ["FrfResult", "estimate_frf"]


@dataclass(repr=False)
class FrfResult:
    """Result of :func:`estimate_frf`.

    Arrays indexed ``[frequency]`` or ``[frequency, output]``; the output axis is dropped
    when ``y`` was 1-D. Phases in rad, unwrapped along frequency.

    Attributes
    ----------
    frequencies : ndarray (n_f,)
        Frequency of each (line-group-averaged) estimate, Hz.
    H : ndarray complex
        FRF ``S_uy/S_uu`` (output units per input unit).
    gain, phase : ndarray
        ``|H|`` and unwrapped ``angle(H)`` (rad).
    coherence : ndarray
        Magnitude-squared coherence in ``[0, 1]``.
    gain_lower, gain_upper, phase_lower, phase_upper : ndarray
        Confidence bounds at level ``confidence`` (method ``bounds_method``; see module
        docstring). NaN where not computable.
    n_averages : ndarray of int (n_f,)
        Number of averaged spectral estimates per frequency (segments x lines in group).
    n_segments : int
        Number of whole periods averaged.
    n_adjacent : int
        Requested number of adjacent excited lines per group.
    group_harmonics : tuple of tuple of int
        Harmonic indices (``f = h/period``) pooled into each estimate.
    S_uu, S_uy, S_yy : ndarray
        Averaged auto/cross power per line (units^2), the ingredients of ``H``.
    excited_output_power : ndarray or float
        Power of the period-averaged output at the excited lines.
    nonexcited_frequencies : ndarray
        Non-excited grid lines inside ``nonexcited_band`` (Hz).
    nonexcited_output_power : ndarray
        Power of the period-averaged output at those lines.
    nonexcited_ratio : ndarray or float
        ``sum(nonexcited_output_power) / excited_output_power``: nonlinearity indicator
        (0 for a linear system; meaningful only if the design leaves lines out, e.g.
        ``lines="odd"``).
    input_nonexcited_ratio : float
        Same ratio for the input (checks that the perturbation is as designed).
    noise_power_excited : ndarray or float
        Single-period noise power at the excited lines from the across-period variance
        (NaN if only one period).
    """

    frequencies: np.ndarray
    H: np.ndarray
    gain: np.ndarray
    phase: np.ndarray
    coherence: np.ndarray
    gain_lower: np.ndarray
    gain_upper: np.ndarray
    phase_lower: np.ndarray
    phase_upper: np.ndarray
    n_averages: np.ndarray
    n_segments: int
    n_adjacent: int
    group_harmonics: tuple
    S_uu: np.ndarray
    S_uy: np.ndarray
    S_yy: np.ndarray
    excited_output_power: Any
    nonexcited_frequencies: np.ndarray
    nonexcited_output_power: np.ndarray
    nonexcited_ratio: Any
    input_nonexcited_ratio: float
    noise_power_excited: Any
    period: float
    fs: float
    confidence: float
    bounds_method: str
    output_names: tuple | None = None
    info: dict = field(default_factory=dict)

    @property
    def phase_deg(self) -> np.ndarray:
        """Unwrapped phase in degrees (for reports)."""
        return np.degrees(self.phase)

    @property
    def n_outputs(self) -> int:
        return 1 if self.H.ndim == 1 else self.H.shape[1]

    def __repr__(self) -> str:
        f = self.frequencies
        return (
            f"FrfResult({f.size} frequencies {f[0]:.3g}-{f[-1]:.3g} Hz, outputs={self.n_outputs}, "
            f"n_segments={self.n_segments}, n_adjacent={self.n_adjacent}, "
            f"bounds={self.bounds_method!r} @ {self.confidence:g})"
        )


def _as_2d_output(y: np.ndarray, n: int) -> tuple[np.ndarray, bool]:
    if y.ndim == 1:
        y2 = y[:, None]
        squeeze = True
    elif y.ndim == 2:
        y2 = y
        squeeze = False
    else:
        raise ValueError(f"y must be 1-D (n,) or 2-D (n, n_outputs), got shape {y.shape}.")
    if y2.shape[0] != n:
        raise ValueError(
            f"u has {n} samples but y has {y2.shape[0]}; input and outputs must be sampled "
            "on the same time grid (same length)."
        )
    return y2, squeeze


def estimate_frf(
    u,
    y,
    fs: float,
    period: float | None = None,
    *,
    excited=None,
    band: tuple[float, float] | None = None,
    n_adjacent: int = 2,
    skip_periods: int = 0,
    confidence: float = 0.95,
    bounds: str = "coherence",
    detect_threshold: float = 1e-6,
    nonexcited_band: tuple[float, float] | None = None,
    output_names: Sequence[str] | None = None,
) -> FrfResult:
    """Estimate the FRF from input ``u`` (perturbation) to output(s) ``y``.

    Parameters
    ----------
    u : array_like (n,)
        Perturbation (e.g. platform/pelvis displacement), uniformly sampled.
    y : array_like (n,) or (n, n_outputs)
        Response(s) on the same time grid (e.g. lumbar rotation, per-level angles).
    fs : float
        Sampling rate (Hz). ``period*fs`` must be an integer.
    period : float, optional
        Multisine period (s); taken from ``excited`` when that is a
        :class:`~trunk_drake.signals.multisine.Multisine`.
    excited : Multisine, array_like of float, or None
        Excited lines: a ``Multisine`` (its harmonics), frequencies in Hz (must lie on the
        ``1/period`` grid), or ``None`` to detect them as the lines where the
        period-averaged input power exceeds ``detect_threshold`` times its maximum.
    band : (f_lo, f_hi), optional
        Keep only excited lines in this band (Hz).
    n_adjacent : int
        Number of adjacent excited lines averaged into one estimate (thesis: 2). A
        remainder group at the top of the band holds fewer lines (see ``n_averages``).
    skip_periods : int
        Whole periods dropped at the start (transient) before segmenting.
    confidence : float
        Confidence level of the bounds, in (0, 1).
    bounds : {"coherence", "segments"}
        Method of the confidence bounds (module docstring).
    detect_threshold : float
        Relative power threshold for ``excited=None``.
    nonexcited_band : (f_lo, f_hi), optional
        Band of non-excited lines for the nonlinearity indicator (default: the excited
        band).
    output_names : sequence of str, optional
        Names of the output columns, stored in the result.

    The data after ``skip_periods`` must hold a whole number (>= 1) of periods: crop with
    :meth:`Multisine.steady_slice` (fades excluded) before calling.

    Returns
    -------
    FrfResult

    Raises
    ------
    ValueError
        Non-integer samples per period, a record that is not a whole number of periods
        or is shorter than one period, excited frequencies off the grid or above Nyquist,
        no excited line in ``band``, no input power at an excited line, NaN in the data.
    """
    from .multisine import Multisine  # local import: avoid a cycle at package import

    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    if u.ndim != 1:
        raise ValueError(f"u must be 1-D (one perturbation signal), got shape {u.shape}.")
    n = u.size
    y2, squeeze = _as_2d_output(y, n)
    n_out = y2.shape[1]
    for name, a in (("u", u), ("y", y2)):
        if not np.all(np.isfinite(a)):
            idx = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
            raise ValueError(f"{name} has NaN/inf at index {idx}; clean or crop the record.")
    if not fs > 0:
        raise ValueError(f"fs must be positive, got {fs!r}.")
    if isinstance(excited, Multisine):
        if period is None:
            period = excited.period
        elif abs(period - excited.period) > 1e-9 * excited.period:
            raise ValueError(
                f"period={period} differs from the multisine's period {excited.period}."
            )
    if period is None or not period > 0:
        raise ValueError("period (s) must be given (or pass excited=<Multisine>).")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}.")
    if int(n_adjacent) != n_adjacent or n_adjacent < 1:
        raise ValueError(f"n_adjacent must be a positive integer, got {n_adjacent!r}.")
    n_adjacent = int(n_adjacent)
    if bounds not in ("coherence", "segments"):
        raise ValueError(f"bounds must be 'coherence' or 'segments', got {bounds!r}.")

    p_float = period * fs
    p = int(round(p_float))
    if abs(p_float - p) > 1e-6 * max(1.0, p_float) or p < 2:
        raise ValueError(
            f"period*fs = {period}*{fs} = {p_float!r} samples is not an integer >= 2; "
            "resample to a rate at which one period holds a whole number of samples "
            "(e.g. trunk_drake.signals.resample_uniform with fs = k/period)."
        )
    start = int(skip_periods) * p
    if skip_periods < 0 or int(skip_periods) != skip_periods:
        raise ValueError(f"skip_periods must be a non-negative integer, got {skip_periods!r}.")
    n_use = n - start
    if n_use < p:
        raise ValueError(
            f"record too short: {n} samples ({n / fs:g} s) minus {skip_periods} skipped "
            f"period(s) leaves {max(n_use, 0) / fs:g} s, less than one period ({period:g} s). "
            f"The 1/period = {1 / period:g} Hz excitation grid cannot be resolved; "
            "record at least one whole steady period."
        )
    if n_use % p:
        raise ValueError(
            f"record (after skipping {skip_periods} period(s)) holds {n_use / p:.4g} periods "
            f"({n_use} samples, {p} per period); it must hold a whole number. Crop it, e.g. "
            f"to the first {n_use // p * p} samples, or use Multisine.steady_slice(t)."
        )
    m = n_use // p
    nyq_bin = p // 2  # bins >= this are at/above Nyquist (or the Nyquist bin itself)

    U = np.fft.rfft(u[start:].reshape(m, p), axis=1) * (2.0 / p)  # (m, p//2+1)
    Y = np.fft.rfft(y2[start:].reshape(m, p, n_out), axis=1) * (2.0 / p)  # (m, bins, n_out)
    Ubar = U.mean(axis=0)
    Ybar = Y.mean(axis=0)

    # --- excited harmonics
    if isinstance(excited, Multisine):
        h = np.asarray(excited.harmonics, dtype=np.int64)
    elif excited is None:
        pw = np.abs(Ubar[1:nyq_bin]) ** 2
        if pw.size == 0 or not np.max(pw) > 0:
            raise ValueError("the input has no power at any grid line: no excitation to analyse.")
        h = 1 + np.flatnonzero(pw > detect_threshold * np.max(pw))
    else:
        f_exc = np.atleast_1d(np.asarray(excited, dtype=float))
        hf = f_exc * period
        h = np.round(hf).astype(np.int64)
        off = np.abs(hf - h) > 1e-6
        if np.any(off) or np.any(h < 1):
            bad = f_exc[off | (h < 1)][0]
            raise ValueError(
                f"excited frequency {bad:g} Hz is not on the 1/period = {1 / period:g} Hz grid "
                "(or is <= 0); give the multisine's line frequencies."
            )
        h = np.unique(h)
    too_high = h >= nyq_bin if p % 2 == 0 else h > nyq_bin
    if np.any(too_high):
        raise ValueError(
            f"excited frequency {h[too_high][0] / period:g} Hz is at or above the Nyquist "
            f"frequency {fs / 2:g} Hz; it cannot be resolved at fs={fs:g} Hz. Sample faster."
        )
    h_all = h  # every excited line (before band selection): never counted as non-excited
    if band is not None:
        lo, hi = band
        fsel = h / period
        h = h[(fsel >= lo - 1e-12) & (fsel <= hi + 1e-12)]
        if h.size == 0:
            raise ValueError(
                f"no excited line lies in band [{lo:g}, {hi:g}] Hz; the excitation covers "
                f"{fsel.min():g}-{fsel.max():g} Hz."
            )
    if h.size == 0:
        raise ValueError("no excited lines: nothing to estimate.")

    Uh = U[:, h]  # (m, L)
    Yh = Y[:, h, :]  # (m, L, n_out)
    line_suu = np.mean(np.abs(Uh) ** 2, axis=0) / 2.0
    zero_in = line_suu <= 1e-30 * max(1.0, float(np.max(line_suu)))
    if np.any(zero_in) or not np.all(line_suu > 0):
        f0 = h[zero_in | ~(line_suu > 0)][0] / period
        raise ValueError(
            f"the input has (almost) no power at the excited line {f0:g} Hz; the excited "
            "lines do not match the perturbation (wrong multisine, period or band?)."
        )

    groups = [np.arange(i, min(i + n_adjacent, h.size)) for i in range(0, h.size, n_adjacent)]
    n_f = len(groups)
    freqs = np.empty(n_f)
    s_uu = np.empty(n_f)
    s_uy = np.empty((n_f, n_out), dtype=complex)
    s_yy = np.empty((n_f, n_out))
    n_avg = np.empty(n_f, dtype=np.int64)
    h_seg = np.empty((m, n_f, n_out), dtype=complex)
    for g, idx in enumerate(groups):
        Ug = Uh[:, idx]  # (m, g)
        Yg = Yh[:, idx, :]  # (m, g, n_out)
        freqs[g] = np.mean(h[idx]) / period
        s_uu[g] = np.mean(np.abs(Ug) ** 2) / 2.0
        s_uy[g] = np.mean(np.conj(Ug)[:, :, None] * Yg, axis=(0, 1)) / 2.0
        s_yy[g] = np.mean(np.abs(Yg) ** 2, axis=(0, 1)) / 2.0
        n_avg[g] = m * idx.size
        h_seg[:, g, :] = np.sum(np.conj(Ug)[:, :, None] * Yg, axis=1) / np.sum(
            np.abs(Ug) ** 2, axis=1
        )[:, None]

    H = s_uy / s_uu[:, None]
    gain = np.abs(H)
    phase = np.unwrap(np.angle(H), axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        coh = np.abs(s_uy) ** 2 / (s_uu[:, None] * s_yy)
    coh = np.where(s_yy > 0, np.clip(coh, 0.0, 1.0), np.nan)

    alpha = 1.0 - confidence
    if bounds == "coherence":
        z = stats.norm.ppf(1.0 - alpha / 2.0)
        nd = n_avg[:, None].astype(float)
        with np.errstate(invalid="ignore", divide="ignore"):
            eps = np.sqrt(np.maximum(1.0 - coh, 0.0)) / (np.sqrt(coh) * np.sqrt(2.0 * nd))
        eps = np.where(nd >= 2, eps, np.nan)
        g_lo = np.maximum(gain * (1.0 - z * eps), 0.0)
        g_hi = gain * (1.0 + z * eps)
        p_lo = phase - z * eps
        p_hi = phase + z * eps
    else:
        if m < 2:
            raise ValueError(
                "bounds='segments' needs at least 2 periods; the record holds 1. "
                "Use bounds='coherence' with n_adjacent >= 2, or record more periods."
            )
        tq = stats.t.ppf(1.0 - alpha / 2.0, m - 1)
        se_gain = np.std(np.abs(h_seg), axis=0, ddof=1) / np.sqrt(m)
        dphi = np.angle(h_seg / H[None, :, :])
        se_phase = np.sqrt(np.sum(dphi**2, axis=0) / (m - 1)) / np.sqrt(m)
        g_lo = np.maximum(gain - tq * se_gain, 0.0)
        g_hi = gain + tq * se_gain
        p_lo = phase - tq * se_phase
        p_hi = phase + tq * se_phase

    # --- nonlinearity / noise indicators (period-averaged spectra)
    exc_pow = np.sum(np.abs(Ybar[h, :]) ** 2, axis=0) / 2.0  # (n_out,)
    in_exc_pow = float(np.sum(np.abs(Ubar[h]) ** 2) / 2.0)
    if nonexcited_band is None:
        lo_h, hi_h = int(h.min()), int(h.max())
    else:
        lo_h = int(np.ceil(nonexcited_band[0] * period - 1e-9))
        hi_h = int(np.floor(nonexcited_band[1] * period + 1e-9))
    hi_h = min(hi_h, nyq_bin - 1 if p % 2 == 0 else nyq_bin)
    grid = np.arange(max(lo_h, 1), hi_h + 1)
    ne = np.setdiff1d(grid, h_all)
    ne_pow = np.abs(Ybar[ne, :]) ** 2 / 2.0 if ne.size else np.zeros((0, n_out))
    with np.errstate(invalid="ignore", divide="ignore"):
        ne_ratio = np.sum(ne_pow, axis=0) / exc_pow
        in_ne_ratio = float(np.sum(np.abs(Ubar[ne]) ** 2) / 2.0 / in_exc_pow) if ne.size else 0.0
    if m >= 2:
        var = np.sum(np.abs(Yh - Ybar[h, :][None]) ** 2, axis=0) / (m - 1)  # (L, n_out)
        noise = np.sum(var, axis=0) / 2.0
    else:
        noise = np.full(n_out, np.nan)

    def sq(a):
        if not squeeze:
            return a
        a = np.asarray(a)
        return a[..., 0] if a.ndim >= 1 else a

    def sq_scalar(a):
        return float(a[0]) if squeeze else a

    names = None
    if output_names is not None:
        names = tuple(str(s) for s in output_names)
        if len(names) != n_out:
            raise ValueError(f"output_names has {len(names)} names for {n_out} outputs.")

    return FrfResult(
        frequencies=freqs,
        H=sq(H),
        gain=sq(gain),
        phase=sq(phase),
        coherence=sq(coh),
        gain_lower=sq(g_lo),
        gain_upper=sq(g_hi),
        phase_lower=sq(p_lo),
        phase_upper=sq(p_hi),
        n_averages=n_avg,
        n_segments=int(m),
        n_adjacent=n_adjacent,
        group_harmonics=tuple(tuple(int(x) for x in h[idx]) for idx in groups),
        S_uu=s_uu,
        S_uy=sq(s_uy),
        S_yy=sq(s_yy),
        excited_output_power=sq_scalar(exc_pow),
        nonexcited_frequencies=ne / period,
        nonexcited_output_power=sq(ne_pow),
        nonexcited_ratio=sq_scalar(ne_ratio),
        input_nonexcited_ratio=in_ne_ratio,
        noise_power_excited=sq_scalar(noise),
        period=float(period),
        fs=float(fs),
        confidence=float(confidence),
        bounds_method=bounds,
        output_names=names,
        info={
            "samples_per_period": p,
            "skip_periods": int(skip_periods),
            "excited_harmonics": h.tolist(),
            "excitation_detected": excited is None,
        },
    )
