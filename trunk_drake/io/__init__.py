"""File input/output: OpenSim storage (.sto/.mot) and CSV tables, measured trials.

- :mod:`.storage`: :class:`StorageData`, ``read_storage``/``write_storage`` (.sto/.mot),
  ``read_csv``/``write_csv``, ``read_table``/``write_table`` (by extension).
- :mod:`.trials`: :func:`load_trial` -> :class:`Trial` (SI units, checked).
"""

from .storage import (
    TIME_LABELS,
    StorageData,
    read_csv,
    read_storage,
    read_table,
    write_csv,
    write_storage,
    write_table,
)
from .trials import FIELD_ALIASES, LUMBAR_LEVELS, Trial, load_trial, trial_from_table

__all__ = [
    "TIME_LABELS",
    "StorageData",
    "read_csv",
    "read_storage",
    "read_table",
    "write_csv",
    "write_storage",
    "write_table",
    "FIELD_ALIASES",
    "LUMBAR_LEVELS",
    "Trial",
    "load_trial",
    "trial_from_table",
]
