"""Synthetic "measured" trials from a truth diagram (for the gap benchmark and the README example)."""

from __future__ import annotations

import numpy as np

from trunk_drake.io.trials import LUMBAR_LEVELS, Trial
from trunk_drake.signals import make_multisine
from trunk_drake.simulation import simulate


def synthetic_trials(model, options, designs, noise_rad: float, seed: int = 0, fs: float = 100.0,
                     period: float = 20.0) -> list[Trial]:
    """Simulate `options` (the truth) on multisines `designs` = [(name, bandwidth_hz, seed), ...]
    and add white noise of `noise_rad` to every angle. Odd harmonic lines only, so the even
    lines in the band reveal nonlinear distortion."""
    rng = np.random.default_rng(seed)
    trials = []
    for name, bandwidth, signal_seed in designs:
        signal = make_multisine(period=period, f_max=bandwidth, seed=signal_seed, lines="odd", fade_shape="quintic")
        result = simulate(model, perturbation=signal, options=options, log_rate=fs, accuracy=1e-3)
        levels = {lvl: result.coordinate(lvl) + rng.normal(0.0, noise_rad, result.time.size) for lvl in LUMBAR_LEVELS}
        trials.append(Trial(time=result.time, fs=fs, platform_displacement=result.platform[:, 0],
                            lumbar_rotation=result.lumbar_rotation + rng.normal(0.0, noise_rad, result.time.size),
                            levels=levels, source=name))
    return trials
