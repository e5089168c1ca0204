"""Shape-preserving resampling of (variable-step) simulator output onto a fixed grid.

The thesis (section 3.5) compares OpenSim's variable-step output with fixed-rate
measurements by fitting a "shape-preserving interpolant" (piecewise cubic Hermite,
MATLAB ``pchip``) through both and evaluating on common time arrays. The same is done
here with :class:`scipy.interpolate.PchipInterpolator`, which does not overshoot
between samples (monotone data stay monotone).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.interpolate import PchipInterpolator

__all__ = ["resample_pchip", "resample_uniform", "uniform_grid"]


def uniform_grid(t_start: float, t_end: float, fs: float) -> np.ndarray:
    """``t_start + i/fs`` for ``i = 0..n-1``, the last point not after ``t_end`` (+1e-9/fs)."""
    if not fs > 0:
        raise ValueError(f"fs must be positive, got {fs!r}.")
    if not (np.isfinite(t_start) and np.isfinite(t_end)) or t_end < t_start:
        raise ValueError(f"need finite t_start <= t_end, got {t_start!r}, {t_end!r}.")
    n = int(math.floor((t_end - t_start) * fs + 1e-9)) + 1
    return t_start + np.arange(n) / fs


def _validate_time(t: np.ndarray, name: str, drop_duplicates: bool):
    if t.ndim != 1:
        raise ValueError(f"{name} must be 1-D, got shape {t.shape}.")
    if t.size < 2:
        raise ValueError(f"{name} needs at least 2 samples to interpolate, got {t.size}.")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(
            f"{name} has NaN/inf at index {bad[0]} ({bad.size} in total); remove those samples."
        )
    d = np.diff(t)
    keep = None
    if drop_duplicates:
        keep = np.ones(t.size, dtype=bool)
        keep[:-1] = d != 0  # keep the last of a run of equal times
        t = t[keep]
        d = np.diff(t)
    nonmono = np.flatnonzero(d <= 0)
    if nonmono.size:
        i = int(nonmono[0])
        kind = "repeats" if d[i] == 0 else "decreases"
        hint = (
            "pass drop_duplicates=True to keep the last sample of each repeated time"
            if d[i] == 0
            else "sort the samples by time or cut the record where the time resets"
        )
        raise ValueError(
            f"{name} must be strictly increasing but {kind} at index {i + 1} "
            f"({name}[{i}]={float(t[i])!r}, {name}[{i + 1}]={float(t[i + 1])!r}); {hint}."
        )
    return t, keep


def resample_pchip(
    t,
    y,
    t_new,
    *,
    axis: int = 0,
    drop_duplicates: bool = False,
    tol: float = 1e-9,
) -> np.ndarray:
    """Evaluate a shape-preserving piecewise cubic (PCHIP) through ``(t, y)`` at ``t_new``.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times (s), strictly increasing (variable steps are fine).
    y : array_like
        Samples; ``y.shape[axis] == n``. Several signals may be stacked on other axes.
    t_new : array_like
        Query times; must lie within ``[t[0], t[-1]]`` (points outside by less than
        ``tol*(t[-1]-t[0])`` are clipped to the end points; no extrapolation).
    axis : int
        Time axis of ``y``.
    drop_duplicates : bool
        Keep only the last sample of repeated time stamps (some simulators publish the
        same time twice); otherwise repeated times are an error.
    tol : float
        Relative tolerance for query points just outside the data range.

    Returns
    -------
    ndarray
        ``y`` evaluated at ``t_new``; the time axis of ``y`` is replaced by ``t_new``'s shape.

    Raises
    ------
    ValueError
        Non-monotonic or NaN times, NaN samples (with the index), length mismatch,
        or query times outside the data (says by how much and what to do).
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    t_new = np.asarray(t_new, dtype=float)
    if y.ndim == 0:
        raise ValueError("y must be an array, got a scalar.")
    axis = axis % y.ndim
    if t.ndim == 1 and y.shape[axis] != t.size:
        raise ValueError(
            f"t has {t.size} samples but y has {y.shape[axis]} along axis {axis}; "
            "they must have equal length."
        )
    t, keep = _validate_time(t, "t", drop_duplicates)
    if keep is not None:
        y = np.compress(keep, y, axis=axis)
    bad = np.argwhere(~np.isfinite(y))
    if bad.size:
        idx = tuple(int(i) for i in bad[0])
        raise ValueError(
            f"y has NaN/inf at index {idx} (time index {idx[axis]}, t={float(t[idx[axis]])!r}); "
            "fill or drop missing samples before resampling."
        )
    if np.any(~np.isfinite(t_new)):
        raise ValueError("t_new contains NaN/inf.")
    span = t[-1] - t[0]
    slack = tol * span
    if t_new.size:
        lo, hi = float(np.min(t_new)), float(np.max(t_new))
        if lo < t[0] - slack or hi > t[-1] + slack:
            raise ValueError(
                f"t_new spans [{lo!r}, {hi!r}] but the data cover only [{float(t[0])!r}, {float(t[-1])!r}]; "
                "PCHIP does not extrapolate. Restrict the grid to the data range "
                "(e.g. uniform_grid(t[0], t[-1], fs)) or simulate longer."
            )
        t_new = np.clip(t_new, t[0], t[-1])
    f = PchipInterpolator(t, y, axis=axis, extrapolate=False)
    return f(t_new)


def resample_uniform(
    t,
    y,
    fs: float,
    *,
    t_start: float | None = None,
    t_end: float | None = None,
    axis: int = 0,
    drop_duplicates: bool = False,
):
    """Resample ``(t, y)`` onto the uniform grid ``t_start + i/fs`` with PCHIP.

    ``t_start``/``t_end`` default to the data range. Returns ``(t_grid, y_grid)``.
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size < 2:
        raise ValueError("t must be 1-D with at least 2 samples.")
    t0 = float(t[0]) if t_start is None else float(t_start)
    t1 = float(t[-1]) if t_end is None else float(t_end)
    grid = uniform_grid(t0, t1, fs)
    return grid, resample_pchip(t, y, grid, axis=axis, drop_duplicates=drop_duplicates)
