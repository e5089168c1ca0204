"""Measured motion drawn next to a simulation: the trunk pose that a trial's kinematics give."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trunk_drake.io.trials import LUMBAR_LEVELS


@dataclass
class MeasuredMotion:
    """Coordinate histories of measured data, and how they were obtained (shown in the legend)."""

    label: str
    time: np.ndarray
    coordinates: list[str]
    q: np.ndarray  # (n, len(coordinates))
    note: str

    def at(self, t) -> np.ndarray:
        """q at times t (linear interpolation; the ends are held outside the data)."""
        return np.column_stack([np.interp(t, self.time, column) for column in self.q.T])


def measured_motion(trial, label: str | None = None) -> MeasuredMotion:
    """The pose history a Trial implies: its five level angles, or else its total lumbar
    rotation spread evenly over the five levels; the pelvis at its measured (or the platform's)
    displacement."""
    if all(level in trial.levels for level in LUMBAR_LEVELS):
        levels = np.column_stack([trial.levels[level] for level in LUMBAR_LEVELS])
        note = "measured level angles"
    else:
        levels = np.repeat(trial.total_lumbar_rotation()[:, None] / len(LUMBAR_LEVELS), len(LUMBAR_LEVELS), axis=1)
        note = "lumbar rotation spread evenly over the five levels"
    pelvis = trial.pelvis_displacement if trial.pelvis_displacement is not None else trial.platform_displacement
    if pelvis is None:
        pelvis = np.zeros_like(trial.time)
    return MeasuredMotion(label or str(trial.source or "data"), np.asarray(trial.time, dtype=float),
                          ["pelvis_tx", *LUMBAR_LEVELS], np.column_stack([pelvis, levels]), note)

