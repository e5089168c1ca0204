"""The trials of a gap diagnosis: whole periods after the fade-in (each split into a training and
a held-out half), the excited lines, and the measurement noise."""

from __future__ import annotations

import numpy as np

from trunk_drake.io import prepared
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.signals import DEFAULT_FADE_S, DEFAULT_PERIOD_S


def prepare_trials(trials, outputs=OUTPUT_NAMES, period: float = DEFAULT_PERIOD_S,
                   fade: float = DEFAULT_FADE_S) -> list[prepared.PreparedTrial]:
    """Check and crop trials to whole periods after the fade-in; clear errors when not possible."""
    out = prepared.prepare_trials(trials, outputs, period=period, steady_start=fade)
    for trial in out:
        if trial.whole_periods < 1:
            raise ValueError(f"{trial.name}: {trial.duration:.1f} s is too short: it must hold the {fade} s fade-in and at least "
                             f"one whole {period} s period to resolve the excited frequencies")
        if not trial.excited_lines[0].size:
            raise ValueError(f"{trial.name}: the platform displacement holds no excitation in its steady window")
    if not out:
        raise ValueError("no trials given")
    return out


def half(trial: prepared.PreparedTrial, which: str) -> slice:
    """The training ("train": first) or held-out ("test": second) half of the steady window."""
    mid = trial.steady_outputs.shape[0] // 2
    return slice(0, mid) if which == "train" else slice(mid, trial.steady_outputs.shape[0])


def estimate_noise(trials) -> np.ndarray:
    """White measurement noise per output (rad) from output power far above the excited band,
    where the trunk's response is negligible (periodogram: E|X_k|^2 = N sigma^2)."""
    estimates = [np.mean(np.abs(spec) ** 2, axis=0) / n for spec, n in _noise_bands(trials)]
    if not estimates:
        raise ValueError("cannot estimate the measurement noise (sampling too slow for a noise band above the excitation): "
                         "give noise=... (rad)")
    return np.sqrt(np.median(estimates, axis=0))


def noise_variance_uncertainty(trials) -> float:
    """Relative standard deviation of the estimated noise variance: each periodogram bin of white
    noise is exponential about sigma^2, so the mean of M bins has 1/sqrt(M); the median over the
    trials widens that by about 1.25."""
    return 1.25 / np.sqrt(sum(spec.shape[0] for spec, _ in _noise_bands(trials)))


def _noise_bands(trials):
    """(spectrum of the outputs above the excited band, samples) per trial with a usable band."""
    for trial in trials:
        y = trial.steady_outputs
        freqs = np.fft.rfftfreq(y.shape[0], 1.0 / trial.fs)
        high = freqs > max(5.0, 3.0 * trial.excited_lines[0].max())
        if high.sum() >= 10:
            yield np.fft.rfft(y, axis=0)[high], y.shape[0]
