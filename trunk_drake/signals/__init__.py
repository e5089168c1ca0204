"""Signal processing for perturbation experiments (pure numpy/scipy functions).

- :mod:`.multisine`: random-appearing multisine perturbations with analytic derivatives.
- :mod:`.filters`: zero-phase Butterworth low-pass, offset removal.
- :mod:`.resample`: shape-preserving (PCHIP) resampling of variable-step output.
- :mod:`.metrics`: VAF (thesis eq. 3.3), RMS error.
- :mod:`.frf`: FRF at the excited multisine lines (thesis eq. 3.4), coherence, bounds.
- :mod:`.averaging`: averaging across repetitions, trials, subjects (thesis appendix C).
"""

from .averaging import (
    AveragedSignal,
    average_hierarchical,
    average_repetitions,
    average_subjects,
    average_trials,
    split_repetitions,
)
from .filters import butterworth_response, lowpass_filtfilt, remove_offset
from .frf import FrfResult, estimate_frf
from .metrics import rms, rms_error, vaf
from .multisine import (
    DEFAULT_AMPLITUDE_RMS_M,
    DEFAULT_FADE_S,
    DEFAULT_PERIOD_S,
    Multisine,
    make_multisine,
)
from .resample import resample_pchip, resample_uniform, uniform_grid

__all__ = [
    "AveragedSignal",
    "average_hierarchical",
    "average_repetitions",
    "average_subjects",
    "average_trials",
    "split_repetitions",
    "butterworth_response",
    "lowpass_filtfilt",
    "remove_offset",
    "FrfResult",
    "estimate_frf",
    "rms",
    "rms_error",
    "vaf",
    "DEFAULT_AMPLITUDE_RMS_M",
    "DEFAULT_FADE_S",
    "DEFAULT_PERIOD_S",
    "Multisine",
    "make_multisine",
    "resample_pchip",
    "resample_uniform",
    "uniform_grid",
]
