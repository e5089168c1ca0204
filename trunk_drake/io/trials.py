"""Load a measured perturbation trial (CSV / .sto / .mot) into a checked :class:`Trial`.

Column-name conventions
-----------------------
Labels are matched case-insensitively after removing an optional unit suffix
(``_m``, ``_mm``, ``_cm`` for displacements; ``_n`` for forces; ``_rad``, ``_deg`` for
angles). Recognised names (``<suffix>`` optional):

==========================  ==============================================================
field                       column labels
==========================  ==============================================================
time                        ``time`` (s; also ``t``, ``time_s``), first column in .sto/.mot
platform_displacement (m)   ``platform_displacement``, ``platform_disp``, ``platform_x``,
                            ``platform_position``, ``platform_pos``
pelvis_displacement (m)     ``pelvis_displacement``, ``pelvis_disp``, ``pelvis_x``,
                            ``pelvis_tx``, ``pelvis_position``
platform_force (N)          ``platform_force``, ``platform_fx``
pelvis_force (N)            ``pelvis_force``, ``pelvis_fx``, ``force``
lumbar_rotation (rad)       ``lumbar_rotation``, ``lumbar_angle``, ``lumbar_flexion``,
                            ``lumbar_total``, ``s1_l1``, ``s1_l1_angle`` (total: angle of
                            the S1-L1 link to the vertical, = sum of the five levels)
levels (rad)                ``L5_S1_FE`` (or ``flex_extension``, see below), ``L4_L5_FE``,
                            ``L3_L4_FE``, ``L2_L3_FE``, ``L1_L2_FE`` (sagittal
                            flexion-extension per joint)
trunk_in_space (rad)        ``trunk_in_space``, ``trunk_in_space_angle``, ``trunk_angle``
emg (any unit)              any label starting with ``emg_`` (key: the rest of the label)
==========================  ==============================================================

Other columns are kept, unconverted, in :attr:`Trial.extra`. ``columns={field: label}``
maps non-standard labels explicitly (``field`` as in the table, or ``"emg:<name>"``).

Units and sign
--------------
SI inside: metres, newtons, radians, seconds; positive angle = flexion.
Angles are converted from degrees when the column has a ``_deg`` suffix, or, without
suffix, when the file header says ``inDegrees=yes`` (OpenSim convention) or
``angle_units="deg"`` is passed. A file with a ``flex_extension`` column (the L5-S1
coordinate of Lumbar_C_210.osim and MyoTorso, e.g. an OpenSim inverse-kinematics ``.mot``
or trunk-drake's own states.sto) is in that model's convention, flexion negative: its
five level angles are negated (``conversions`` shows the sign). Displacements with ``_mm``/``_cm`` suffix (or
``displacement_units="mm"``) are converted to metres.

Plausibility checks (each failure is a ``ValueError`` that says what, where - file,
column, row and line - and what to do):

- time: present, no NaN, strictly increasing, uniformly sampled (relative step
  deviation <= ``sampling_rtol``);
- every used column: no NaN/missing values (a missing tail is reported as columns of
  unequal length);
- displacements: ``|x| <= max_displacement_m`` (default 1 m; larger values usually mean
  millimetres);
- angles (after conversion): ``|angle| <= max_angle_rad`` (default pi; larger values
  usually mean degrees labelled as radians).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from trunk_drake.model.levels import LUMBAR_LEVELS

from .storage import StorageData, read_table

__all__ = ["Trial", "load_trial", "trial_from_table", "available_outputs", "LUMBAR_LEVELS", "OUTPUT_NAMES", "FIELD_ALIASES"]


#: Recognised base labels (lower case, without unit suffix) per field.
FIELD_ALIASES: dict[str, tuple[str, ...]] = {
    "platform_displacement": (
        "platform_displacement", "platform_disp", "platform_x", "platform_position", "platform_pos",
    ),
    "pelvis_displacement": (
        "pelvis_displacement", "pelvis_disp", "pelvis_x", "pelvis_tx", "pelvis_position",
    ),
    "platform_force": ("platform_force", "platform_fx"),
    "pelvis_force": ("pelvis_force", "pelvis_fx", "force"),
    "lumbar_rotation": (
        "lumbar_rotation", "lumbar_angle", "lumbar_flexion", "lumbar_total", "s1_l1", "s1_l1_angle",
    ),
    "trunk_in_space": ("trunk_in_space", "trunk_in_space_angle", "trunk_angle"),
}
for _lv in LUMBAR_LEVELS:
    FIELD_ALIASES[_lv] = (_lv.lower(),)
#: Lumbar_C_210.osim (and MyoTorso) name the L5-S1 coordinate ``flex_extension`` and count
#: flexion negative (trunk_drake.model.plant.opensim_coordinate).
OPENSIM_L5_S1 = "flex_extension"
FIELD_ALIASES["L5_S1_FE"] += (OPENSIM_L5_S1,)

_KIND = {
    "platform_displacement": "length",
    "pelvis_displacement": "length",
    "platform_force": "force",
    "pelvis_force": "force",
    "lumbar_rotation": "angle",
    "trunk_in_space": "angle",
    **{lv: "angle" for lv in LUMBAR_LEVELS},
}
_SUFFIX = {
    "length": {"_m": 1.0, "_mm": 1e-3, "_cm": 1e-2},
    "force": {"_n": 1.0},
    "angle": {"_rad": 1.0, "_deg": math.pi / 180.0},
}
_PERTURBATION_FIELDS = ("platform_displacement", "pelvis_displacement", "platform_force", "pelvis_force")
#: the kinematic outputs a trial can give: the total lumbar rotation and the level angles
OUTPUT_NAMES = ("lumbar_rotation", *LUMBAR_LEVELS)


@dataclass
class Trial:
    """A measured perturbation trial, SI units, checked.

    Attributes
    ----------
    time : ndarray (n,)
        Time (s), strictly increasing, uniformly sampled.
    fs : float
        Sampling rate (Hz).
    platform_displacement, pelvis_displacement : ndarray or None
        Fore-aft displacement (m).
    platform_force, pelvis_force : ndarray or None
        Fore-aft force (N).
    lumbar_rotation : ndarray or None
        Total lumbar rotation (rad): angle of the S1-L1 link to the vertical, flexion +.
    levels : dict
        Per-level angles (rad) keyed by :data:`LUMBAR_LEVELS` names (only those present).
    trunk_in_space : ndarray or None
        Trunk-in-space angle (rad).
    emg : dict
        EMG envelopes keyed by the label after ``emg_`` (units as in the file).
    extra : dict
        Unrecognised columns, as read.
    source : str or None
        File the trial was read from.
    column_map : dict
        ``field -> source column label`` for every recognised field.
    conversions : dict
        ``field -> scale factor`` applied (e.g. pi/180 for degrees).
    metadata : dict
        File header entries.
    """

    time: np.ndarray
    fs: float
    platform_displacement: np.ndarray | None = None
    pelvis_displacement: np.ndarray | None = None
    platform_force: np.ndarray | None = None
    pelvis_force: np.ndarray | None = None
    lumbar_rotation: np.ndarray | None = None
    levels: dict = field(default_factory=dict)
    trunk_in_space: np.ndarray | None = None
    emg: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    source: str | None = None
    column_map: dict = field(default_factory=dict)
    conversions: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return int(self.time.size)

    @property
    def duration(self) -> float:
        return float(self.time[-1] - self.time[0])

    @property
    def perturbation_name(self) -> str | None:
        """First available of platform/pelvis displacement, platform/pelvis force."""
        for f in _PERTURBATION_FIELDS:
            if getattr(self, f) is not None:
                return f
        return None

    @property
    def perturbation(self) -> np.ndarray | None:
        """The signal named by :attr:`perturbation_name` (m or N)."""
        n = self.perturbation_name
        return None if n is None else getattr(self, n)

    def output(self, name: str) -> np.ndarray:
        """A kinematic output by name: ``lumbar_rotation`` (see total_lumbar_rotation) or a
        level angle such as ``L4_L5_FE``; ValueError naming what the trial has otherwise."""
        if name == "lumbar_rotation":
            return self.total_lumbar_rotation()
        if name not in self.levels:
            raise ValueError(f"trial {self.source or ''}: output {name!r} missing (found: {sorted(self.column_map)}); "
                             "give it or choose outputs that are present")
        return self.levels[name]

    def total_lumbar_rotation(self) -> np.ndarray:
        """Total lumbar rotation (rad): the measured total if present, else the sum of
        all five per-level angles (raises if some levels are missing)."""
        if self.lumbar_rotation is not None:
            return self.lumbar_rotation
        missing = [lv for lv in LUMBAR_LEVELS if lv not in self.levels]
        if missing:
            raise ValueError(
                f"trial {self.source or ''} has no total lumbar rotation and lacks levels "
                f"{missing}; the total is the sum of all five levels."
            )
        return np.sum([self.levels[lv] for lv in LUMBAR_LEVELS], axis=0)


def available_outputs(trials, names=OUTPUT_NAMES) -> tuple[str, ...]:
    """The kinematic outputs every trial provides (the total counts when it can be summed)."""
    def has(trial, name):
        try:
            trial.output(name)
        except ValueError:
            return False
        return True

    found = tuple(n for n in names if all(has(t, n) for t in trials))
    if not found:
        raise ValueError("the trials share no kinematic output: give lumbar_rotation and/or the level angles "
                         f"{', '.join(LUMBAR_LEVELS)} in every trial")
    return found


def _split_suffix(label_low: str, kind: str) -> tuple[str, str | None]:
    for suf in sorted(_SUFFIX[kind], key=len, reverse=True):
        if label_low.endswith(suf) and len(label_low) > len(suf):
            return label_low[: -len(suf)], suf
    return label_low, None


def _where(table: StorageData, label: str, row: int) -> str:
    line = table.line_of_row(row)
    src = table.path or "<table>"
    s = f"{src}, column {label!r}, row {row + 1}"
    return s + (f" (line {line})" if line else "")


def _check_column(table: StorageData, label: str, values: np.ndarray) -> None:
    bad = np.flatnonzero(~np.isfinite(values))
    if not bad.size:
        return
    n = values.size
    first = int(bad[0])
    if bad.size == n - first and np.all(bad == np.arange(first, n)):
        others = [
            lab for i, lab in enumerate(table.labels)
            if lab != label and np.isfinite(table.data[first:, i]).all()
        ]
        raise ValueError(
            f"{_where(table, label, first)}: column has no values from this row to the end "
            f"(rows {first + 1}-{n}) while {others[:4]}{'...' if len(others) > 4 else ''} "
            "continue: columns of unequal length. Trim all columns to a common length "
            "(or resample them onto one time base) before loading."
        )
    raise ValueError(
        f"{_where(table, label, first)}: missing value (NaN/empty); {bad.size} missing in this "
        "column. Fill the gap (e.g. interpolate) or crop the trial to a part without gaps."
    )


def trial_from_table(
    table: StorageData,
    *,
    columns: Mapping[str, str] | None = None,
    angle_units: str | None = None,
    displacement_units: str | None = None,
    require_perturbation: bool = True,
    require_response: bool = True,
    sampling_rtol: float = 1e-3,
    max_displacement_m: float = 1.0,
    max_angle_rad: float = math.pi,
) -> Trial:
    """Build a checked :class:`Trial` from a table (see :func:`load_trial` for the options)."""
    src = table.path or "<table>"
    if angle_units not in (None, "deg", "rad"):
        raise ValueError(f"angle_units must be None, 'deg' or 'rad', got {angle_units!r}.")
    if displacement_units not in (None, "m", "mm", "cm"):
        raise ValueError(
            f"displacement_units must be None, 'm', 'mm' or 'cm', got {displacement_units!r}."
        )
    if angle_units is not None and table.in_degrees is not None:
        if (angle_units == "deg") != table.in_degrees:
            raise ValueError(
                f"{src}: header says inDegrees={'yes' if table.in_degrees else 'no'} but "
                f"angle_units={angle_units!r} was passed; fix the header or drop angle_units."
            )

    # ---------------- time
    t = table.time
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise ValueError(
            f"{_where(table, table.time_label, int(bad[0]))}: time is NaN/missing; every row "
            "needs a time stamp."
        )
    if t.size < 2:
        raise ValueError(f"{src}: only {t.size} data row(s); a trial needs at least 2.")
    dt = np.diff(t)
    nonmono = np.flatnonzero(dt <= 0)
    if nonmono.size:
        r = int(nonmono[0]) + 1
        raise ValueError(
            f"{_where(table, table.time_label, r)}: time is not strictly increasing "
            f"({float(t[r - 1])!r} -> {float(t[r])!r}); sort the rows, drop duplicates, or split the file "
            "where the clock restarts."
        )
    dt_med = float(np.median(dt))
    dev = np.abs(dt - dt_med) / dt_med
    if np.any(dev > sampling_rtol):
        r = int(np.argmax(dev > sampling_rtol)) + 1
        raise ValueError(
            f"{_where(table, table.time_label, r)}: non-uniform sampling (step {float(dt[r - 1]):.6g} s "
            f"vs typical {dt_med:.6g} s, deviation {dev[r - 1]:.2g} > sampling_rtol={sampling_rtol:g}). "
            "Measured trials must be uniformly sampled: resample with "
            "trunk_drake.signals.resample_uniform (PCHIP) or fill dropped frames."
        )
    fs = 1.0 / float(np.mean(dt))

    # ---------------- map columns to fields
    col_for: dict[str, str] = {}
    suffix_for: dict[str, str | None] = {}
    emg_cols: dict[str, str] = {}
    explicit = dict(columns or {})
    used: set[str] = set()
    for fld, lab in explicit.items():
        if lab not in table.labels:
            raise ValueError(f"{src}: columns[{fld!r}] = {lab!r} is not a column; available: {table.labels}")
        if fld.startswith("emg:"):
            emg_cols[fld[4:]] = lab
        elif fld in _KIND:
            col_for[fld] = lab
            suffix_for[fld] = _split_suffix(lab.lower(), _KIND[fld])[1]
        else:
            raise ValueError(
                f"columns: unknown field {fld!r}; known fields: {sorted(_KIND)} or 'emg:<name>'."
            )
        used.add(lab)
    for lab in table.labels:
        if lab in used:
            continue
        low = lab.lower()
        if low.startswith("emg_") and len(low) > 4:
            emg_cols[lab[4:]] = lab
            continue
        for fld, aliases in FIELD_ALIASES.items():
            if fld in explicit:
                continue
            base, suf = _split_suffix(low, _KIND[fld])
            if base in aliases:
                if fld in col_for:
                    raise ValueError(
                        f"{src}: columns {col_for[fld]!r} and {lab!r} both look like {fld}; "
                        f"pass columns={{'{fld}': '<label>'}} to choose one."
                    )
                col_for[fld] = lab
                suffix_for[fld] = suf
                break

    if require_perturbation and not any(f in col_for for f in _PERTURBATION_FIELDS):
        raise ValueError(
            f"{src}: no perturbation column (platform/pelvis displacement or force) among "
            f"{table.labels}. Recognised names: "
            f"{[FIELD_ALIASES[f][0] for f in _PERTURBATION_FIELDS]} (with optional unit "
            "suffix); rename the column or pass columns={'platform_displacement': '<label>'}."
        )
    if require_response and not any(f in col_for for f in OUTPUT_NAMES):
        raise ValueError(
            f"{src}: no lumbar angle column among {table.labels}. Recognised names: "
            f"'lumbar_rotation' or the levels {list(LUMBAR_LEVELS)} (optional _deg/_rad "
            "suffix); rename the column or pass columns={'lumbar_rotation': '<label>'}."
        )

    # ---------------- convert + check
    values: dict[str, np.ndarray] = {}
    conv: dict[str, float] = {}
    for fld, lab in col_for.items():
        v = table.column(lab).astype(float)
        _check_column(table, lab, v)
        kind = _KIND[fld]
        suf = suffix_for.get(fld)
        if kind == "length":
            if suf is not None:
                scale = _SUFFIX["length"][suf]
            else:
                scale = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, None: 1.0}[displacement_units]
            v = v * scale
            imax = int(np.argmax(np.abs(v)))
            if abs(v[imax]) > max_displacement_m:
                raise ValueError(
                    f"{_where(table, lab, imax)}: displacement {v[imax]:.6g} m exceeds "
                    f"{max_displacement_m:g} m, implausible for a seat/platform perturbation. "
                    "The column is probably in millimetres: rename it with a '_mm' suffix "
                    f"(e.g. '{lab}_mm'), or pass displacement_units='mm'."
                )
        elif kind == "angle":
            if suf is not None:
                scale = _SUFFIX["angle"][suf]
            elif angle_units is not None:
                scale = math.pi / 180.0 if angle_units == "deg" else 1.0
            elif table.in_degrees:
                scale = math.pi / 180.0
            else:
                scale = 1.0
            v = v * scale
            imax = int(np.argmax(np.abs(v)))
            if abs(v[imax]) > max_angle_rad:
                raise ValueError(
                    f"{_where(table, lab, imax)}: angle {v[imax]:.6g} rad exceeds "
                    f"{max_angle_rad:.4g} rad, implausible for a lumbar/trunk angle. The column "
                    "is probably in degrees: add a '_deg' suffix, write inDegrees=yes in the "
                    "header, or pass angle_units='deg'."
                )
        else:
            scale = 1.0
        values[fld] = v
        conv[fld] = scale
    if "L5_S1_FE" in col_for and _split_suffix(col_for["L5_S1_FE"].lower(), "angle")[0] == OPENSIM_L5_S1:
        for lv in LUMBAR_LEVELS:  # the .osim's convention: flexion negative
            if lv in values:
                values[lv], conv[lv] = -values[lv], -conv[lv]
    emg = {}
    for name, lab in emg_cols.items():
        v = table.column(lab).astype(float)
        _check_column(table, lab, v)
        emg[name] = v
    recognised = set(col_for.values()) | set(emg_cols.values())
    extra = {lab: table.column(lab) for lab in table.labels if lab not in recognised}

    return Trial(
        time=t.copy(),
        fs=fs,
        platform_displacement=values.get("platform_displacement"),
        pelvis_displacement=values.get("pelvis_displacement"),
        platform_force=values.get("platform_force"),
        pelvis_force=values.get("pelvis_force"),
        lumbar_rotation=values.get("lumbar_rotation"),
        levels={lv: values[lv] for lv in LUMBAR_LEVELS if lv in values},
        trunk_in_space=values.get("trunk_in_space"),
        emg=emg,
        extra=extra,
        source=table.path,
        column_map={**col_for, **{f"emg:{k}": v for k, v in emg_cols.items()}},
        conversions=conv,
        metadata=dict(table.header),
    )


def load_trial(
    path,
    *,
    columns: Mapping[str, str] | None = None,
    angle_units: str | None = None,
    displacement_units: str | None = None,
    time_column: str | None = None,
    require_perturbation: bool = True,
    require_response: bool = True,
    sampling_rtol: float = 1e-3,
    max_displacement_m: float = 1.0,
    max_angle_rad: float = math.pi,
) -> Trial:
    """Read a measured trial from ``.csv``, ``.sto`` or ``.mot`` and check it.

    Parameters
    ----------
    path : str or PathLike
        The file; format from the extension.
    columns : mapping, optional
        Explicit ``{field: column label}`` (fields as in the module docstring, or
        ``"emg:<name>"``); other columns are matched by name.
    angle_units : {None, "deg", "rad"}
        Units of angle columns without a ``_deg``/``_rad`` suffix. Default: the file's
        ``inDegrees`` flag, else radians. Must agree with ``inDegrees`` if both are given.
    displacement_units : {None, "m", "mm", "cm"}
        Units of displacement columns without a unit suffix (default m).
    time_column : str, optional
        Time label for CSV files (default: ``time``/``t``/``time_s``).
    require_perturbation, require_response : bool
        Demand a perturbation column / a lumbar angle column (default True).
    sampling_rtol : float
        Allowed relative deviation of a time step from the median step.
    max_displacement_m, max_angle_rad : float
        Plausibility limits (see module docstring).

    Returns
    -------
    Trial

    Raises
    ------
    ValueError
        With file, column, row (and line) of the problem and what to do about it.
    FileNotFoundError
        If ``path`` does not exist.
    """
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    kwargs = {"time_column": time_column} if (ext == ".csv" and time_column) else {}
    if time_column and ext != ".csv":
        raise ValueError("time_column applies to CSV files only (storage files start with time).")
    table = read_table(path, **kwargs)
    return trial_from_table(
        table,
        columns=columns,
        angle_units=angle_units,
        displacement_units=displacement_units,
        require_perturbation=require_perturbation,
        require_response=require_response,
        sampling_rtol=sampling_rtol,
        max_displacement_m=max_displacement_m,
        max_angle_rad=max_angle_rad,
    )
