"""Filtering and offset removal (pure functions on numpy arrays).

- :func:`lowpass_filtfilt`: zero-phase Butterworth low-pass (``scipy.signal.sosfiltfilt``).
- :func:`butterworth_response`: complex frequency response of an *analog* Butterworth
  low-pass, used to filter a multisine analytically line by line.
- :func:`remove_offset`: subtract the initial value (thesis section 4.7: "all acquired
  experimental data starts at 0 deg rotation"; the same is done for model outcomes).
"""

from __future__ import annotations

import numpy as np
from scipy import signal as _sig

__all__ = ["lowpass_filtfilt", "butterworth_response", "remove_offset"]


def _check_finite(x: np.ndarray, what: str) -> None:
    if not np.all(np.isfinite(x)):
        bad = np.argwhere(~np.isfinite(x))[0]
        raise ValueError(
            f"{what} contains NaN or inf (first at index {tuple(int(i) for i in bad)}); "
            "interpolate or drop the missing samples before filtering."
        )


def lowpass_filtfilt(x, fs: float, cutoff_hz: float, order: int = 2, *, axis: int = 0) -> np.ndarray:
    """Zero-phase Butterworth low-pass filter (forward-backward, ``sosfiltfilt``).

    Parameters
    ----------
    x : array_like
        Uniformly sampled signal(s); filtered along ``axis``.
    fs : float
        Sampling rate in Hz.
    cutoff_hz : float
        Cut-off frequency of the single-pass Butterworth design, in Hz. Must lie in
        ``(0, fs/2)``.
    order : int
        Order of the single-pass design. Forward-backward filtering squares the
        magnitude response: the effective order is ``2*order`` and the gain at
        ``cutoff_hz`` is -6 dB (not -3 dB). Phase is zero at all frequencies.
    axis : int
        Time axis.

    Returns
    -------
    ndarray
        Filtered signal, same shape as ``x``.
    """
    x = np.asarray(x, dtype=float)
    _check_finite(x, "x")
    if not fs > 0:
        raise ValueError(f"fs must be positive, got {fs!r}.")
    if not 0 < cutoff_hz < fs / 2:
        raise ValueError(
            f"cutoff_hz={cutoff_hz!r} must lie in (0, fs/2) = (0, {fs / 2:g}) Hz; "
            "choose a lower cut-off or a higher sampling rate."
        )
    if int(order) != order or order < 1:
        raise ValueError(f"order must be a positive integer, got {order!r}.")
    sos = _sig.butter(int(order), cutoff_hz, btype="low", fs=fs, output="sos")
    n = x.shape[axis]
    padlen = 3 * (2 * len(sos) + 1)
    if n <= padlen:
        raise ValueError(
            f"signal has {n} samples along axis {axis}; forward-backward filtering of order "
            f"{order} needs more than {padlen}. Use a longer record or a lower order."
        )
    return _sig.sosfiltfilt(sos, x, axis=axis)


def butterworth_response(f, cutoff_hz: float, order: int = 2) -> np.ndarray:
    """Complex response ``H(j 2 pi f)`` of an analog Butterworth low-pass.

    ``|H| = 1/sqrt(1 + (f/fc)^(2 order))``; the phase is that of the causal analog filter
    (``scipy.signal.butter(..., analog=True)``), e.g. -90 deg at ``fc`` for order 2.

    Parameters
    ----------
    f : array_like
        Frequencies in Hz (non-negative).
    cutoff_hz : float
        -3 dB frequency in Hz.
    order : int
        Filter order.
    """
    f = np.asarray(f, dtype=float)
    if not cutoff_hz > 0:
        raise ValueError(f"cutoff_hz must be positive, got {cutoff_hz!r}.")
    if int(order) != order or order < 1:
        raise ValueError(f"order must be a positive integer, got {order!r}.")
    b, a = _sig.butter(int(order), 2 * np.pi * cutoff_hz, btype="low", analog=True)
    s = 1j * 2 * np.pi * f
    return np.polyval(b, s) / np.polyval(a, s)


def remove_offset(x, n_samples: int = 1, *, axis: int = 0, mode: str = "start") -> np.ndarray:
    """Remove a constant offset so that the signal starts at (or is centred on) zero.

    Parameters
    ----------
    x : array_like
        Signal(s); time along ``axis``.
    n_samples : int
        With ``mode="start"``, the offset is the mean of the first ``n_samples`` samples
        (``1``: the first sample, as in the thesis, section 4.7: all data starts at 0 deg).
        A few samples (e.g. 0.1 s worth) make the offset less sensitive to noise.
    axis : int
        Time axis.
    mode : {"start", "mean"}
        ``"start"``: subtract the mean of the first ``n_samples``; ``"mean"``: subtract
        the mean over the whole record (zero-mean signal).

    Returns
    -------
    ndarray
        ``x`` minus the offset (a new array).
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 0:
        raise ValueError("x must be an array with a time axis, got a scalar.")
    n = x.shape[axis]
    if mode == "start":
        if int(n_samples) != n_samples or n_samples < 1:
            raise ValueError(f"n_samples must be a positive integer, got {n_samples!r}.")
        if n_samples > n:
            raise ValueError(f"n_samples={n_samples} exceeds the {n} samples along axis {axis}.")
        head = np.take(x, np.arange(int(n_samples)), axis=axis)
        off = np.mean(head, axis=axis, keepdims=True)
    elif mode == "mean":
        off = np.mean(x, axis=axis, keepdims=True)
    else:
        raise ValueError(f"mode must be 'start' or 'mean', got {mode!r}.")
    if not np.all(np.isfinite(off)):
        raise ValueError(
            "the offset is NaN/inf (missing samples at the start of the record?); "
            "clean the data or choose more n_samples."
        )
    return x - off
