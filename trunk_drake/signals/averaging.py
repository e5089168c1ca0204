"""Signal averaging across repetitions, trials and subjects (thesis 3.5, 4.7, appendix C).

The thesis validates the model on the van Drunen et al. kinematics of six subjects,
two trials per subject and three repetitions (multisine periods) per trial:

1. average across repetitions (periods within a trial)   - appendix C.1
2. average across trials (of one subject)                - appendix C.2
3. remove the offset ("centred around the zero amplitude line": every record starts
   at 0 deg, section 4.7), then average across subjects  - appendix C.3

Averaging periods of a periodic response removes non-periodic noise (random fluctuations
shrink by ``1/sqrt(n)``) while keeping the periodic response to the multisine.

Arrays are time-first: a trial is ``(n_samples,)`` or ``(n_samples, n_channels)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from .filters import remove_offset as _remove_offset

__all__ = [
    "split_repetitions",
    "average_repetitions",
    "average_trials",
    "average_subjects",
    "average_hierarchical",
    "AveragedSignal",
]


def split_repetitions(
    x, samples_per_period: int, *, n_repetitions: int | None = None, start: int = 0
) -> np.ndarray:
    """Cut a trial into repetitions: returns ``(n_repetitions, samples_per_period, ...)``.

    Parameters
    ----------
    x : array_like (n, ...)
        One trial, time first.
    samples_per_period : int
        Samples in one repetition (``period*fs``).
    n_repetitions : int, optional
        Number of repetitions to take from ``start``. Default: all; then
        ``n - start`` must be a whole number of periods (crop fades first, or give
        ``start``/``n_repetitions``).
    start : int
        Index of the first sample of the first repetition (e.g. after a fade-in).
    """
    x = np.asarray(x, dtype=float)
    if x.ndim == 0:
        raise ValueError("x must be an array with time as first axis, got a scalar.")
    p = int(samples_per_period)
    if p != samples_per_period or p < 1:
        raise ValueError(f"samples_per_period must be a positive integer, got {samples_per_period!r}.")
    if int(start) != start or start < 0:
        raise ValueError(f"start must be a non-negative integer, got {start!r}.")
    avail = x.shape[0] - int(start)
    if n_repetitions is None:
        if avail < p or avail % p:
            raise ValueError(
                f"trial has {avail} samples after start={start}, which is {avail / p:.4g} "
                f"periods of {p} samples; pass n_repetitions (and start) to select whole "
                "periods, or crop the fades."
            )
        k = avail // p
    else:
        k = int(n_repetitions)
        if k != n_repetitions or k < 1:
            raise ValueError(f"n_repetitions must be a positive integer, got {n_repetitions!r}.")
        if k * p > avail:
            raise ValueError(
                f"trial has {avail} samples after start={start}; {k} repetitions of {p} "
                f"samples need {k * p}."
            )
    seg = x[int(start) : int(start) + k * p]
    return seg.reshape((k, p) + x.shape[1:])


def average_repetitions(
    x, samples_per_period: int, *, n_repetitions: int | None = None, start: int = 0
) -> np.ndarray:
    """Mean over the repetitions of one trial: ``(samples_per_period, ...)`` (appendix C.1)."""
    return split_repetitions(
        x, samples_per_period, n_repetitions=n_repetitions, start=start
    ).mean(axis=0)


def _stack(records: Sequence, what: str) -> np.ndarray:
    if len(records) == 0:
        raise ValueError(f"no {what} to average.")
    arrs = [np.asarray(r, dtype=float) for r in records]
    shape0 = arrs[0].shape
    for i, a in enumerate(arrs):
        if a.shape != shape0:
            raise ValueError(
                f"{what} {i} has shape {a.shape} but {what} 0 has {shape0}; average "
                "repetitions first (equal period length) or resample onto a common grid."
            )
        if not np.all(np.isfinite(a)):
            j = tuple(int(v) for v in np.argwhere(~np.isfinite(a))[0])
            raise ValueError(f"{what} {i} has NaN/inf at index {j}.")
    return np.stack(arrs, axis=0)


def average_trials(trials: Sequence, *, remove_offset: bool = False, n_offset_samples: int = 1) -> np.ndarray:
    """Mean over trials of equal shape (appendix C.2).

    ``remove_offset=True`` first subtracts each trial's initial value (mean of its first
    ``n_offset_samples``); the thesis removes offsets only before averaging subjects.
    """
    st = _stack(trials, "trial")
    if remove_offset:
        st = _remove_offset(st, n_offset_samples, axis=1)
    return st.mean(axis=0)


def average_subjects(
    subjects: Sequence, *, remove_offset: bool = True, n_offset_samples: int = 1
) -> np.ndarray:
    """Mean over subjects, after offset removal (appendix C.3).

    Each subject's (already trial-averaged) record is shifted to start at 0 (mean of its
    first ``n_offset_samples`` samples) before averaging, because neutral postures
    differ between subjects (section 4.7).
    """
    st = _stack(subjects, "subject")
    if remove_offset:
        st = _remove_offset(st, n_offset_samples, axis=1)
    return st.mean(axis=0)


@dataclass
class AveragedSignal:
    """Result of :func:`average_hierarchical`.

    Attributes
    ----------
    mean : ndarray (samples_per_period, ...)
        Grand mean over subjects (offset-removed if requested).
    std : ndarray
        Standard deviation across subjects (ddof=1; NaN for a single subject).
    per_subject : ndarray (n_subjects, samples_per_period, ...)
        Each subject's mean over repetitions and trials (offset-removed if requested).
    per_trial : list of list of ndarray
        Each trial's mean over repetitions (before offset removal).
    n_repetitions : list of list of int
        Repetitions averaged per subject and trial.
    """

    mean: np.ndarray
    std: np.ndarray
    per_subject: np.ndarray
    per_trial: list
    n_repetitions: list
    info: dict = field(default_factory=dict)

    @property
    def n_subjects(self) -> int:
        return int(self.per_subject.shape[0])


def average_hierarchical(
    data: Sequence[Sequence],
    samples_per_period: int,
    *,
    start: int = 0,
    n_repetitions: int | None = None,
    remove_offset: bool = True,
    n_offset_samples: int = 1,
) -> AveragedSignal:
    """Thesis averaging: repetitions -> trials -> (offset removal) -> subjects.

    Parameters
    ----------
    data : sequence of sequence of array_like
        ``data[subject][trial]`` is a trial record ``(n, ...)``, time first.
    samples_per_period : int
        Samples per repetition.
    start, n_repetitions :
        Passed to :func:`split_repetitions` for every trial (e.g. skip a fade-in).
    remove_offset : bool
        Subtract each subject's initial value before averaging subjects (default True).
    n_offset_samples : int
        Samples averaged for the offset.
    """
    if len(data) == 0:
        raise ValueError("no subjects to average.")
    per_trial: list = []
    n_reps: list = []
    subj_means = []
    for si, trials in enumerate(data):
        if len(trials) == 0:
            raise ValueError(f"subject {si} has no trials.")
        tmeans = []
        reps = []
        for ti, tr in enumerate(trials):
            try:
                r = split_repetitions(
                    tr, samples_per_period, n_repetitions=n_repetitions, start=start
                )
            except ValueError as e:
                raise ValueError(f"subject {si}, trial {ti}: {e}") from None
            if not np.all(np.isfinite(r)):
                raise ValueError(f"subject {si}, trial {ti} contains NaN/inf.")
            tmeans.append(r.mean(axis=0))
            reps.append(int(r.shape[0]))
        per_trial.append(tmeans)
        n_reps.append(reps)
        subj_means.append(np.mean(np.stack(tmeans, axis=0), axis=0))
    st = _stack(subj_means, "subject")
    if remove_offset:
        st = _remove_offset(st, n_offset_samples, axis=1)
    mean = st.mean(axis=0)
    std = st.std(axis=0, ddof=1) if st.shape[0] > 1 else np.full_like(mean, np.nan)
    return AveragedSignal(
        mean=mean,
        std=std,
        per_subject=st,
        per_trial=per_trial,
        n_repetitions=n_reps,
        info={
            "samples_per_period": int(samples_per_period),
            "start": int(start),
            "remove_offset": bool(remove_offset),
            "n_offset_samples": int(n_offset_samples),
        },
    )
