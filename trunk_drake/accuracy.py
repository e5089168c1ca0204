"""Accuracy of forward simulation: the two check trials and their accurate reference.

A faster simulation must give the same answer: the lumbar rotation of the default settings
within 0.01 deg RMS of an accurate reference (radau3 at accuracy 1e-6). Two 20 s, 0.2-1 Hz
trials (multisine seed 0) are checked, one per preset (models/presets/): ``"default"``, the
README's main job (the default passenger on the rhythm, which stays upright), and ``"thesis"``,
the thesis' final model on independent levels, which folds into flexion. The reference is stored in
`REFERENCE_FILE` by ``benchmarks/accuracy_reference.py``; rerun it when the model's physics change.
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

import numpy as np

REFERENCE_ACCURACY = 1e-6
TOLERANCE_DEG = 0.01  # RMS lumbar rotation difference allowed
DURATION = 20.0
REFERENCE_FILE = Path(__file__).resolve().parents[1] / "benchmarks" / "reference" / "accurate_lumbar_rotation.csv"
TRIALS = ("default", "thesis")


def trial_model(name: str):
    """The model of check trial `name` (its preset's)."""
    from trunk_drake.presets import load_preset

    _check(name)
    return load_preset(name).model()


def trial_options(model, name: str) -> dict:
    """`simulate` keywords (besides the integrator's) of check trial `name` on its `trial_model`."""
    from trunk_drake.presets import load_preset

    _check(name)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the thesis preset's co-activation residual is reported elsewhere
        options = load_preset(name).options(model)
    return {"bandwidth": 1.0, "seed": 0, **{f.name: getattr(options, f.name) for f in dataclasses.fields(options)}}


def _check(name: str) -> None:
    if name not in TRIALS:
        raise ValueError(f"unknown check trial {name!r}; expected one of {TRIALS}")


def load_reference() -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Time (s) and the accurate lumbar rotation (rad) of every check trial."""
    from trunk_drake.io.storage import read_csv

    if not REFERENCE_FILE.exists():
        raise FileNotFoundError(f"accurate reference {REFERENCE_FILE} is missing; run python benchmarks/accuracy_reference.py")
    table = read_csv(REFERENCE_FILE)
    return table.time, {name: table.data[:, table.labels.index(name)] for name in TRIALS}


def rms_deviation_deg(result, name: str) -> float:
    """RMS difference (deg) of `result`'s lumbar rotation from the reference over its time span."""
    time, reference = load_reference()
    n = len(result.time)
    if n > len(time) or not np.allclose(result.time, time[:n]):
        raise ValueError(f"result sampled at other times than the reference ({REFERENCE_FILE}: 100 Hz from 0 s)")
    return float(np.degrees(np.sqrt(np.mean((result.lumbar_rotation - reference[name][:n]) ** 2))))
