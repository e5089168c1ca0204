"""Synthetic "measured" trials from a truth diagram (for the gap benchmark and the README example)."""

from __future__ import annotations

import dataclasses

import numpy as np

from trunk_drake.io.trials import LUMBAR_LEVELS, Trial
from trunk_drake.signals import DEFAULT_FADE_S, DEFAULT_PERIOD_S, make_multisine
from trunk_drake.simulation import simulate


def synthetic_trials(model, options, designs, noise_rad: float, seed: int = 0, fs: float = 100.0,
                     period: float = DEFAULT_PERIOD_S) -> list[Trial]:
    """Simulate `options` (the truth) on multisines `designs` = [(name, bandwidth_hz, seed), ...]
    and add white noise of `noise_rad` to every angle. Odd harmonic lines only, so the even
    lines in the band reveal nonlinear distortion."""
    return add_noise(clean_trials(model, options, designs, fs, period), noise_rad, seed)


def clean_trials(model, options, designs, fs: float = 100.0, period: float = DEFAULT_PERIOD_S,
                 fade: float = DEFAULT_FADE_S) -> list[Trial]:
    """Noise-free trials of `options` on the multisines `designs` (see synthetic_trials), faded in and out over `fade` s."""
    trials = []
    for name, bandwidth, signal_seed in designs:
        signal = make_multisine(period=period, f_max=bandwidth, seed=signal_seed, lines="odd", fade_shape="quintic",
                                fade_in=fade, fade_out=fade)
        result = simulate(model, perturbation=signal, options=options, log_rate=fs, accuracy=1e-3)
        trials.append(Trial(time=result.time, fs=fs, platform_displacement=result.platform[:, 0],
                            lumbar_rotation=result.lumbar_rotation,
                            levels={lvl: result.coordinate(lvl) for lvl in LUMBAR_LEVELS}, source=name))
    return trials


def add_noise(trials: list[Trial], noise_rad: float, seed: int = 0) -> list[Trial]:
    """The trials with white noise of `noise_rad` added to every angle."""
    rng = np.random.default_rng(seed)
    out = []
    for t in trials:
        levels = {lvl: y + rng.normal(0.0, noise_rad, y.size) for lvl, y in t.levels.items()}
        out.append(dataclasses.replace(t, levels=levels,
                                       lumbar_rotation=t.lumbar_rotation + rng.normal(0.0, noise_rad, t.time.size)))
    return out


def signature_chi2(a: list[Trial], b: list[Trial], noise_rad: float, skip: float = 0.0) -> float:
    """How far two sets of noise-free trials differ, in chi-square units of the measurement
    noise: sum over trials, angles and samples after `skip` seconds of the squared difference
    (constant offsets removed) over noise^2."""
    total = 0.0
    for ta, tb in zip(a, b):
        keep = ta.time >= skip
        for ya, yb in [(ta.lumbar_rotation, tb.lumbar_rotation)] + [(ta.levels[k], tb.levels[k]) for k in ta.levels]:
            d = ya[keep] - yb[keep]
            total += float(np.sum((d - d.mean()) ** 2)) / noise_rad**2
    return total
