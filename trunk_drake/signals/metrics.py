"""Goodness-of-fit metrics: variance accounted for (VAF) and RMS error.

VAF follows the thesis, eq. (3.3)::

    VAF = 1 - sum_t (theta(t) - theta_mdl(t))^2 / sum_t theta(t)^2

Note that the denominator is the plain sum of squares of the measured signal (not its
variance about the mean): the result depends on the signal offset. In the thesis both
measured and model kinematics are offset-corrected first so that they start at 0 deg
(section 4.7), and VAF is computed on those offset-corrected signals. Use
``offset="start"`` here (or :func:`trunk_drake.signals.filters.remove_offset` on both
signals beforehand) to reproduce that; the default ``offset=None`` applies eq. (3.3) to
the signals as given.

VAF is 1 for a perfect model, 0 for a zero model, and negative when the model error
exceeds the signal itself.
"""

from __future__ import annotations

import numpy as np

from .filters import remove_offset as _remove_offset

__all__ = ["vaf", "rms", "rms_error"]


def _prep(y, y_model, axis, offset, n_offset_samples):
    y = np.asarray(y, dtype=float)
    ym = np.asarray(y_model, dtype=float)
    if y.shape != ym.shape:
        raise ValueError(
            f"y has shape {y.shape} but y_model has shape {ym.shape}; resample both onto "
            "the same time grid first (trunk_drake.signals.resample_pchip)."
        )
    if y.ndim == 0 or y.shape[axis] == 0:
        raise ValueError("y and y_model must be non-empty arrays with a time axis.")
    for name, a in (("y", y), ("y_model", ym)):
        if not np.all(np.isfinite(a)):
            idx = tuple(int(i) for i in np.argwhere(~np.isfinite(a))[0])
            raise ValueError(f"{name} has NaN/inf at index {idx}; clean or crop the signals.")
    if offset is not None:
        if offset not in ("start", "mean"):
            raise ValueError(f"offset must be None, 'start' or 'mean', got {offset!r}.")
        y = _remove_offset(y, n_offset_samples, axis=axis, mode=offset)
        ym = _remove_offset(ym, n_offset_samples, axis=axis, mode=offset)
    return y, ym


def vaf(y, y_model, *, axis: int = 0, offset: str | None = None, n_offset_samples: int = 1):
    """Variance accounted for, thesis eq. (3.3): ``1 - sum((y - y_model)^2) / sum(y^2)``.

    Parameters
    ----------
    y : array_like
        Measured signal(s).
    y_model : array_like
        Model signal(s), same shape and time grid as ``y``.
    axis : int
        Time axis; the sums run over it (other axes give one VAF per signal).
    offset : {None, "start", "mean"}
        Offset removal applied to *both* signals before eq. (3.3): ``"start"`` subtracts
        the mean of the first ``n_offset_samples`` samples (thesis: data start at 0 deg),
        ``"mean"`` subtracts each signal's mean. ``None`` (default): none.
    n_offset_samples : int
        Samples averaged for ``offset="start"``.

    Returns
    -------
    float or ndarray
        VAF as a fraction (multiply by 100 for %); a float for 1-D input.

    Raises
    ------
    ValueError
        Shape mismatch, NaN, or a measured signal that is identically zero (VAF undefined).
    """
    y, ym = _prep(y, y_model, axis, offset, n_offset_samples)
    den = np.sum(y**2, axis=axis)
    if np.any(den == 0):
        raise ValueError(
            "sum(y^2) is zero (measured signal identically zero after offset removal): "
            "VAF is undefined."
        )
    out = 1.0 - np.sum((y - ym) ** 2, axis=axis) / den
    return float(out) if np.ndim(out) == 0 else out


def rms(x, *, axis: int = 0):
    """Root mean square along ``axis``."""
    x = np.asarray(x, dtype=float)
    out = np.sqrt(np.mean(x**2, axis=axis))
    return float(out) if np.ndim(out) == 0 else out


def rms_error(y, y_model, *, axis: int = 0, offset: str | None = None, n_offset_samples: int = 1):
    """RMS of ``y - y_model`` along ``axis`` (same units as ``y``).

    ``offset`` as in :func:`vaf`.
    """
    y, ym = _prep(y, y_model, axis, offset, n_offset_samples)
    out = np.sqrt(np.mean((y - ym) ** 2, axis=axis))
    return float(out) if np.ndim(out) == 0 else out
