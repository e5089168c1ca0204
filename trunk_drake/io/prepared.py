"""A measured trial prepared for comparison with simulations: the one type the reflex-gain fit
and the gap diagnosis share.

The perturbation that drives the simulation is the platform displacement, else the pelvis
displacement (both start at 0); the outputs are the named kinematics (rad) with their first
sample subtracted; the steady window is the whole multisine periods after the fade-in.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from trunk_drake.signals.multisine import DEFAULT_FADE_S, DEFAULT_PERIOD_S
from trunk_drake.signals.sampled import SampledSignal


@dataclass
class PreparedTrial:
    """One comparison between simulation and data on the data's uniform time grid."""

    name: str
    time: np.ndarray  # s, uniform, starting at 0
    fs: float  # Hz
    outputs: dict[str, np.ndarray]  # measured (rad), first sample subtracted
    noise: dict[str, float] | None = None  # standard deviation per output (rad), when known
    signal: object | None = None  # platform signal evaluate(t) -> (x, v, a); None: no perturbation
    platform: np.ndarray | None = None  # measured platform displacement (m), from 0
    period: float | None = None  # multisine period (s)
    steady_start: float = 2.0  # end of the fade-in (s): the steady window starts here

    @property
    def duration(self) -> float:
        return float(self.time[-1])

    @property
    def whole_periods(self) -> int:
        """Number of whole multisine periods after `steady_start` (0 without a period)."""
        if not self.period or self.platform is None:
            return 0
        return int((len(self.time) - round(self.steady_start * self.fs)) // round(self.period * self.fs))

    @property
    def steady(self) -> slice:
        """Samples of the whole periods after the fade-in."""
        start = int(round(self.steady_start * self.fs))
        return slice(start, start + self.whole_periods * int(round(self.period * self.fs)))

    @cached_property
    def steady_outputs(self) -> np.ndarray:
        """(n_steady, n_outputs) outputs in the steady window, each with its mean removed."""
        y = np.column_stack([self.outputs[n] for n in self.outputs])[self.steady]
        return y - y.mean(axis=0)

    @cached_property
    def excited_lines(self) -> tuple[np.ndarray, np.ndarray]:
        """(frequencies in Hz, indices in the FFT of the steady window) of the lines that carry the
        platform excitation: power above 1e-6 times the strongest line."""
        u = self.platform[self.steady]
        spectrum = np.fft.rfft(u - u.mean())
        freqs = np.fft.rfftfreq(u.size, 1.0 / self.fs)
        power = np.abs(spectrum) ** 2
        bins = np.flatnonzero((power > 1e-6 * power.max()) & (freqs > 0))
        return freqs[bins], bins


def prepare_trials(trials, outputs=("lumbar_rotation",), noise: float | dict | None = None, period: float | None = DEFAULT_PERIOD_S,
                   steady_start: float = DEFAULT_FADE_S, lowpass_hz: float | None = None, t_max: float | None = None) -> list[PreparedTrial]:
    """Prepared trials from measured ones (trunk_drake.io.Trial): the platform (else pelvis)
    displacement drives the prescribed pelvis motion, `outputs` are compared (total and/or
    per-level angles), optionally only up to `t_max` seconds; `noise` (rad, scalar or per
    output) when known."""
    prepared = []
    names = trial_names([trial.source for trial in trials])
    for k, trial in enumerate(trials):
        where = trial.source or f"trial {k}"
        x = trial.platform_displacement if trial.platform_displacement is not None else trial.pelvis_displacement
        if x is None:
            raise ValueError(f"{where}: no platform or pelvis displacement: the perturbation is needed to simulate the trial")
        keep = slice(None) if t_max is None else trial.time - trial.time[0] <= t_max + 1e-9
        x, t = x[keep], (trial.time - trial.time[0])[keep]
        measured = {}
        for name in outputs:
            series = np.asarray(trial.output(name), float)[keep]
            measured[name] = series - series[0]
        sigma = None if noise is None else {n: float(noise[n] if isinstance(noise, dict) else noise) for n in outputs}
        prepared.append(PreparedTrial(names[k], t, float(trial.fs), measured, sigma, SampledSignal(t, x - x[0], lowpass_hz),
                                      x - x[0], period, steady_start))
    return prepared


def trial_names(sources) -> list[str]:
    """Each trial's name in results: its file's name (not the path, which differs between machines), the
    path where two files share a name, "trial k" for a trial without a file."""
    base = [Path(s).name if s else f"trial {k}" for k, s in enumerate(sources)]
    return [b if base.count(b) == 1 else str(s or b) for b, s in zip(base, sources)]
