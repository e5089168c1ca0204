"""Read and write OpenSim storage files (``.sto``/``.mot``) and CSV tables.

OpenSim storage format (version 1, as written by OpenSim 4)::

    <name>
    version=1
    nRows=<number of data rows>
    nColumns=<number of columns including time>
    inDegrees=<yes|no>
    endheader
    time<TAB>label_1<TAB>...<TAB>label_n
    0<TAB>...

``.sto`` and ``.mot`` share the format. The reader also accepts the older header style
(``name ...``, ``datacolumns 3``, ``datarows 100``, ``range 0 1``), space-separated rows,
and extra ``key=value`` lines; it requires the ``endheader`` line. ``inDegrees`` tells
whether *rotational* columns are in degrees (OpenSim semantics: translations are always
in metres); it is reported, not applied: unit handling belongs to the consumer (see
:func:`trunk_drake.io.trials.load_trial`).

CSV: one header row of column labels, comma separated, optionally preceded by comment
lines starting with ``#``; comment lines of the form ``# key=value`` are read as
metadata (``# inDegrees=yes`` sets :attr:`StorageData.in_degrees`). Empty fields are read
as NaN; rows with too few or too many fields are an error naming the file, line and
missing column(s).

Numbers are written with 17 significant digits, so a write/read round trip is exact.
"""

from __future__ import annotations

import csv
import io as _io
import math
import os
import warnings
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

__all__ = [
    "StorageData",
    "read_storage",
    "write_storage",
    "read_csv",
    "write_csv",
    "read_table",
    "write_table",
    "TIME_LABELS",
]

#: Column labels recognised as time (case-insensitive) when reading CSV files.
TIME_LABELS = ("time", "t", "time_s", "time (s)", "time[s]", "time_sec")


@dataclass
class StorageData:
    """A table of time-series columns, as read from / written to .sto/.mot/CSV.

    Attributes
    ----------
    time : ndarray (n_rows,)
        Time column (s).
    labels : list of str
        Labels of the data columns (time excluded), in file order.
    data : ndarray (n_rows, n_columns)
        Data columns (time excluded), float.
    in_degrees : bool or None
        The file's ``inDegrees`` flag (``None`` if the file does not say).
    name : str
        Table name (first header line of a storage file).
    header : dict
        All ``key=value`` header entries as strings (keys as written).
    path : str or None
        Source file, if read from disk.
    time_label : str
        Label of the time column in the file.
    first_data_line : int
        1-based line number of the first data row in the file (0 if not from a file);
        data row ``i`` (0-based) is on line ``first_data_line + i`` for storage files.
    """

    time: np.ndarray
    labels: list
    data: np.ndarray
    in_degrees: bool | None = None
    name: str = ""
    header: dict = field(default_factory=dict)
    path: str | None = None
    time_label: str = "time"
    first_data_line: int = 0
    line_numbers: np.ndarray | None = None

    def __post_init__(self):
        self.time = np.asarray(self.time, dtype=float)
        self.data = np.asarray(self.data, dtype=float)
        self.labels = [str(s) for s in self.labels]
        if self.data.ndim == 1 and len(self.labels) == 1:
            self.data = self.data[:, None]
        if self.data.ndim != 2:
            raise ValueError(f"data must be 2-D (rows, columns), got shape {self.data.shape}.")
        if self.time.ndim != 1 or self.time.size != self.data.shape[0]:
            raise ValueError(
                f"time has shape {self.time.shape} but data has {self.data.shape[0]} rows."
            )
        if self.data.shape[1] != len(self.labels):
            raise ValueError(
                f"{len(self.labels)} labels for {self.data.shape[1]} data columns."
            )
        if len(set(self.labels)) != len(self.labels):
            dup = sorted({s for s in self.labels if self.labels.count(s) > 1})
            where = f" in {self.path}" if self.path else ""
            raise ValueError(f"duplicate column label(s) {dup}{where}; labels must be unique.")

    @classmethod
    def from_columns(
        cls,
        time,
        columns: Mapping[str, Sequence[float]],
        *,
        in_degrees: bool | None = None,
        name: str = "",
        header: Mapping[str, str] | None = None,
    ) -> "StorageData":
        """Build from a time vector and a ``{label: values}`` mapping (insertion order kept)."""
        labels = list(columns.keys())
        t = np.asarray(time, dtype=float)
        cols = []
        for k in labels:
            v = np.asarray(columns[k], dtype=float)
            if v.shape != t.shape:
                raise ValueError(f"column {k!r} has shape {v.shape}, time has {t.shape}.")
            cols.append(v)
        data = np.column_stack(cols) if cols else np.zeros((t.size, 0))
        return cls(time=t, labels=labels, data=data, in_degrees=in_degrees, name=name,
                   header=dict(header or {}))

    @property
    def n_rows(self) -> int:
        return int(self.time.size)

    def column(self, label: str) -> np.ndarray:
        """Values of column ``label`` (exact match, then case-insensitive)."""
        if label in self.labels:
            return self.data[:, self.labels.index(label)]
        low = [s.lower() for s in self.labels]
        if label.lower() in low and low.count(label.lower()) == 1:
            return self.data[:, low.index(label.lower())]
        if label.lower() == self.time_label.lower():
            return self.time
        where = f" in {self.path}" if self.path else ""
        raise KeyError(f"no column {label!r}{where}; available: {self.labels}")

    def as_dict(self, include_time: bool = True) -> dict:
        """``{label: values}`` (time first under ``time_label`` if requested)."""
        d = {self.time_label: self.time} if include_time else {}
        for i, k in enumerate(self.labels):
            d[k] = self.data[:, i]
        return d

    def line_of_row(self, row: int) -> int | None:
        """1-based file line number of 0-based data row ``row`` (None if unknown)."""
        if self.line_numbers is not None and 0 <= row < self.line_numbers.size:
            return int(self.line_numbers[row])
        if self.first_data_line:
            return self.first_data_line + row
        return None


# ----------------------------------------------------------------------------- helpers
def _parse_bool(v: str) -> bool | None:
    s = v.strip().lower()
    if s in ("yes", "true", "1", "y"):
        return True
    if s in ("no", "false", "0", "n"):
        return False
    return None


def _to_float(s: str, path: str, line_no: int, label: str) -> float:
    s = s.strip()
    if s == "":
        return math.nan
    try:
        return float(s)
    except ValueError:
        raise ValueError(
            f"{path}, line {line_no}, column {label!r}: cannot read {s!r} as a number; "
            "fix or remove that value (missing values may be left empty or written as NaN)."
        ) from None


def _ragged_error(path, line_no, labels_all, n_fields):
    n_exp = len(labels_all)
    if n_fields < n_exp:
        missing = labels_all[n_fields:]
        return ValueError(
            f"{path}, line {line_no}: row has {n_fields} values but the header has {n_exp} "
            f"columns; no value for column(s) {missing} (ragged columns: columns of unequal "
            "length?). Fill the missing values (NaN or empty field) so every row has one "
            "value per column, or trim all columns to the same length."
        )
    return ValueError(
        f"{path}, line {line_no}: row has {n_fields} values but the header has {n_exp} "
        f"columns ({labels_all}); remove the extra values or add the missing column labels."
    )


def _format(v: float, precision: int) -> str:
    if math.isnan(v):
        return "NaN"
    return f"{v:.{precision}g}"


# ----------------------------------------------------------------------------- .sto/.mot
def read_storage(path) -> StorageData:
    """Read an OpenSim ``.sto``/``.mot`` storage file.

    Returns
    -------
    StorageData
        ``in_degrees`` from the ``inDegrees`` header entry (None if absent).

    Raises
    ------
    ValueError
        Missing ``endheader``, missing/duplicate labels, no time column first, a row with
        the wrong number of values (names the line and the missing columns), or a
        non-numeric value (names line and column).
    """
    path = os.fspath(path)
    with open(path, "r", encoding="utf-8-sig") as fh:
        lines = fh.read().splitlines()
    header: dict = {}
    name = ""
    end = None
    for i, raw in enumerate(lines):
        s = raw.strip()
        if s.lower() == "endheader":
            end = i
            break
        if not s:
            continue
        if "=" in s:
            k, v = s.split("=", 1)
            header[k.strip()] = v.strip()
        elif i == 0 and not name:
            name = s
            if s.lower().startswith("name "):
                name = s[5:].strip()
        else:
            parts = s.split(None, 1)
            header[parts[0]] = parts[1].strip() if len(parts) > 1 else ""
    if end is None:
        raise ValueError(
            f"{path}: no 'endheader' line; not an OpenSim storage file. For plain tables "
            "with a header row, use read_csv (or save as .csv)."
        )
    j = end + 1
    while j < len(lines) and not lines[j].strip():
        j += 1
    if j >= len(lines):
        raise ValueError(f"{path}: no column-label line after 'endheader'.")
    lab_line = lines[j].strip("\r\n")
    labels_all = [s.strip() for s in (lab_line.split("\t") if "\t" in lab_line else lab_line.split())]
    labels_all = [s for s in labels_all if s != ""]
    if not labels_all:
        raise ValueError(f"{path}, line {j + 1}: empty column-label line.")
    if labels_all[0].lower() not in ("time", "t"):
        raise ValueError(
            f"{path}, line {j + 1}: the first column is {labels_all[0]!r}; OpenSim storage "
            "files must have 'time' as first column."
        )
    rows = []
    line_nos = []
    n_exp = len(labels_all)
    for k in range(j + 1, len(lines)):
        s = lines[k].strip()
        if not s:
            continue
        if "\t" in s:
            fields = [f.strip() for f in s.split("\t")]
        else:
            fields = s.split()
        if len(fields) != n_exp:
            raise _ragged_error(path, k + 1, labels_all, len(fields))
        rows.append([_to_float(f, path, k + 1, labels_all[c]) for c, f in enumerate(fields)])
        line_nos.append(k + 1)
    arr = np.array(rows, dtype=float).reshape(len(rows), n_exp)
    in_deg = None
    for key, v in header.items():
        if key.lower() == "indegrees":
            in_deg = _parse_bool(v)
    for key, expect in (("nrows", arr.shape[0]), ("datarows", arr.shape[0]),
                        ("ncolumns", n_exp), ("datacolumns", n_exp)):
        for hk, hv in header.items():
            if hk.lower() == key:
                try:
                    val = int(hv)
                except ValueError:
                    continue
                if val != expect:
                    warnings.warn(
                        f"{path}: header says {hk}={val} but the file has {expect}; "
                        "using the data as found (file truncated or hand-edited?).",
                        stacklevel=2,
                    )
    return StorageData(
        time=arr[:, 0],
        labels=labels_all[1:],
        data=arr[:, 1:],
        in_degrees=in_deg,
        name=name,
        header=header,
        path=path,
        time_label=labels_all[0],
        first_data_line=line_nos[0] if line_nos else 0,
        line_numbers=np.asarray(line_nos, dtype=np.int64),
    )


def _coerce(data, time, columns, in_degrees, name) -> StorageData:
    if data is not None:
        if not isinstance(data, StorageData):
            raise TypeError("data must be a StorageData (or pass time= and columns=).")
        return data
    if time is None or columns is None:
        raise ValueError("pass either a StorageData or both time= and columns=.")
    return StorageData.from_columns(time, columns, in_degrees=in_degrees, name=name or "")


def write_storage(
    path,
    data: StorageData | None = None,
    *,
    time=None,
    columns: Mapping[str, Sequence[float]] | None = None,
    in_degrees: bool | None = None,
    name: str | None = None,
    precision: int = 17,
    extra_header: Mapping[str, str] | None = None,
) -> None:
    """Write an OpenSim storage file (``.sto`` or ``.mot``), version 1, tab separated.

    Parameters
    ----------
    path : str or PathLike
    data : StorageData, optional
        Table to write; or give ``time`` and ``columns`` (``{label: values}``).
    in_degrees : bool, optional
        Written as ``inDegrees=yes/no``; default: ``data.in_degrees``, else ``no``
        (SI: radians).
    name : str, optional
        First header line; default ``data.name`` or the file stem.
    precision : int
        Significant digits (17: exact round trip).
    extra_header : mapping, optional
        Additional ``key=value`` lines (before ``endheader``).
    """
    path = os.fspath(path)
    d = _coerce(data, time, columns, in_degrees, name)
    if in_degrees is None:
        in_degrees = bool(d.in_degrees) if d.in_degrees is not None else False
    nm = name or d.name or os.path.splitext(os.path.basename(path))[0]
    for lab in [d.time_label] + d.labels:
        if "\t" in lab or "\n" in lab or lab.strip() != lab or lab == "":
            raise ValueError(f"column label {lab!r} is empty or contains tabs/newlines/edge spaces.")
    buf = _io.StringIO()
    buf.write(f"{nm}\nversion=1\nnRows={d.n_rows}\nnColumns={len(d.labels) + 1}\n")
    buf.write(f"inDegrees={'yes' if in_degrees else 'no'}\n")
    for k, v in (extra_header or {}).items():
        if k.lower() in ("version", "nrows", "ncolumns", "indegrees"):
            continue
        buf.write(f"{k}={v}\n")
    buf.write("endheader\n")
    buf.write("\t".join([d.time_label] + d.labels) + "\n")
    full = np.column_stack([d.time, d.data]) if d.data.size else d.time[:, None]
    for row in full:
        buf.write("\t".join(_format(float(v), precision) for v in row) + "\n")
    with open(path, "w", encoding="utf-8", newline="\n") as fh:
        fh.write(buf.getvalue())


# ----------------------------------------------------------------------------- CSV
def read_csv(path, *, time_column: str | None = None, delimiter: str = ",") -> StorageData:
    """Read a CSV table with one header row (see module docstring).

    Parameters
    ----------
    time_column : str, optional
        Label of the time column; default: the first label in :data:`TIME_LABELS`
        (case-insensitive).
    delimiter : str
        Field separator (default ``,``).
    """
    path = os.fspath(path)
    with open(path, "r", encoding="utf-8-sig", newline="") as fh:
        text = fh.read()
    lines = text.splitlines()
    meta: dict = {}
    i = 0
    while i < len(lines) and (lines[i].lstrip().startswith("#") or not lines[i].strip()):
        s = lines[i].strip().lstrip("#").strip()
        if "=" in s:
            k, v = s.split("=", 1)
            meta[k.strip()] = v.strip()
        i += 1
    if i >= len(lines):
        raise ValueError(f"{path}: no header row (file is empty or only comments).")
    header_line_no = i + 1
    reader = csv.reader(lines[i:], delimiter=delimiter)
    labels_all = [s.strip() for s in next(reader)]
    if any(s == "" for s in labels_all):
        k = labels_all.index("")
        raise ValueError(
            f"{path}, line {header_line_no}: column {k + 1} has an empty label; every column "
            "needs a unique name in the header row."
        )
    low = [s.lower() for s in labels_all]
    if time_column is None:
        tcol = next((low.index(c) for c in TIME_LABELS if c in low), None)
        if tcol is None:
            raise ValueError(
                f"{path}: no time column among {labels_all}; name it 'time' (seconds) or "
                "pass time_column='<label>'."
            )
    else:
        if time_column in labels_all:
            tcol = labels_all.index(time_column)
        elif time_column.lower() in low:
            tcol = low.index(time_column.lower())
        else:
            raise ValueError(f"{path}: time_column {time_column!r} not in {labels_all}.")
    rows = []
    line_nos = []
    n_exp = len(labels_all)
    for k, fields in enumerate(reader):
        line_no = header_line_no + 1 + k
        if not fields or all(f.strip() == "" for f in fields) and len(fields) <= 1:
            continue
        if len(fields) != n_exp:
            raise _ragged_error(path, line_no, labels_all, len(fields))
        rows.append([_to_float(f, path, line_no, labels_all[c]) for c, f in enumerate(fields)])
        line_nos.append(line_no)
    arr = np.array(rows, dtype=float).reshape(len(rows), n_exp)
    in_deg = None
    for k, v in meta.items():
        if k.lower() == "indegrees":
            in_deg = _parse_bool(v)
    keep = [c for c in range(n_exp) if c != tcol]
    return StorageData(
        time=arr[:, tcol],
        labels=[labels_all[c] for c in keep],
        data=arr[:, keep],
        in_degrees=in_deg,
        name=str(meta.get("name", "")),
        header=meta,
        path=path,
        time_label=labels_all[tcol],
        first_data_line=line_nos[0] if line_nos else 0,
        line_numbers=np.asarray(line_nos, dtype=np.int64),
    )


def write_csv(
    path,
    data: StorageData | None = None,
    *,
    time=None,
    columns: Mapping[str, Sequence[float]] | None = None,
    in_degrees: bool | None = None,
    metadata: Mapping[str, str] | None = None,
    delimiter: str = ",",
    precision: int = 17,
) -> None:
    """Write a CSV table: optional ``# key=value`` lines, a header row, then rows.

    ``in_degrees`` (default ``data.in_degrees``) is written as ``# inDegrees=yes/no``
    when known, so that :func:`read_csv` restores it.
    """
    path = os.fspath(path)
    d = _coerce(data, time, columns, in_degrees, None)
    if in_degrees is None:
        in_degrees = d.in_degrees
    meta = dict(metadata or {})
    if in_degrees is not None and not any(k.lower() == "indegrees" for k in meta):
        meta["inDegrees"] = "yes" if in_degrees else "no"
    buf = _io.StringIO()
    for k, v in meta.items():
        buf.write(f"# {k}={v}\n")
    w = csv.writer(buf, delimiter=delimiter, lineterminator="\n")
    w.writerow([d.time_label] + d.labels)
    full = np.column_stack([d.time, d.data]) if d.data.size else d.time[:, None]
    for row in full:
        w.writerow([_format(float(v), precision) for v in row])
    with open(path, "w", encoding="utf-8", newline="") as fh:
        fh.write(buf.getvalue())


# ----------------------------------------------------------------------------- dispatch
_STORAGE_EXT = (".sto", ".mot")
_CSV_EXT = (".csv",)


def read_table(path, **kwargs) -> StorageData:
    """Read ``.sto``/``.mot`` (:func:`read_storage`) or ``.csv`` (:func:`read_csv`) by extension."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext in _STORAGE_EXT:
        if kwargs:
            raise TypeError(f"read_storage takes no options, got {sorted(kwargs)}.")
        return read_storage(path)
    if ext in _CSV_EXT:
        return read_csv(path, **kwargs)
    raise ValueError(
        f"{path}: unknown extension {ext!r}; expected one of {_STORAGE_EXT + _CSV_EXT}."
    )


def write_table(path, data: StorageData | None = None, **kwargs) -> None:
    """Write ``.sto``/``.mot`` (:func:`write_storage`) or ``.csv`` (:func:`write_csv`) by extension."""
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext in _STORAGE_EXT:
        return write_storage(path, data, **kwargs)
    if ext in _CSV_EXT:
        return write_csv(path, data, **kwargs)
    raise ValueError(
        f"{path}: unknown extension {ext!r}; expected one of {_STORAGE_EXT + _CSV_EXT}."
    )
