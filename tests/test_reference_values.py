"""Consistency checks for models/reference_values.toml.

The file holds literature/thesis reference numbers with their sources. These
tests check the bookkeeping, not the numbers: every entry names a known source
and an allowed unit, numbers are numbers (or the explicit string "no
reference"), unsourced values say why, and strength means are positive.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import pytest

TOML_PATH = Path(__file__).resolve().parents[1] / "models" / "reference_values.toml"

NO_REFERENCE = "no reference"

ALLOWED_UNITS = {
    "N",  # force
    "Nm/rad",  # rotational stiffness
    "Nms/rad",  # rotational damping
    "s",
    "1/s",
    "Hz",
    "m",
    "kg",
    "rad",
    "percent",
    "1",  # dimensionless
    "count",
}

# Keys whose values are reference quantities: number, list of numbers, or "no reference".
QUANTITY_KEYS = {
    "value",
    "mean",
    "sd",
    "kv",
    "kp",
    "kv_initial",
    "kp_initial",
    "step",
}

# Bookkeeping keys allowed on an entry besides the quantity keys.
TEXT_KEYS = {"unit", "population", "n", "source", "where", "quote", "note", "value_as_printed"}

REQUIRED_SOURCE_FIELDS = ("authors", "year", "title", "journal", "verified")


def _load() -> dict:
    with TOML_PATH.open("rb") as fh:
        return tomllib.load(fh)


def _is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _has_numeric(x) -> bool:
    if _is_number(x):
        return True
    if isinstance(x, list):
        return any(_has_numeric(v) for v in x)
    return False


def _entries(node: dict, path: tuple[str, ...] = ()):
    """Yield (dotted_path, table) for every entry: a table with a 'unit' or 'source' key."""
    for key, val in node.items():
        if not isinstance(val, dict):
            continue
        sub = path + (key,)
        if "unit" in val or "source" in val:
            yield ".".join(sub), val
        else:
            yield from _entries(val, sub)


DATA = _load()
SOURCES = DATA.get("sources", {})
ENTRIES = list(_entries({k: v for k, v in DATA.items() if k != "sources"}))
ENTRY_IDS = [p for p, _ in ENTRIES]


def test_file_parses_and_has_sections():
    for section in ("sources", "strength", "intervertebral", "reflex", "perturbation", "muscle", "anthropometry"):
        assert section in DATA, f"missing section [{section}]"
    assert DATA.get("schema_version") == 1
    assert len(ENTRIES) > 0


@pytest.mark.parametrize("key", sorted(SOURCES))
def test_sources_are_complete(key):
    src = SOURCES[key]
    for field in REQUIRED_SOURCE_FIELDS:
        assert field in src, f"sources.{key} lacks '{field}'"
        assert str(src[field]).strip(), f"sources.{key}.{field} is empty"


@pytest.mark.parametrize("path,entry", ENTRIES, ids=ENTRY_IDS)
def test_entry_has_known_source_and_allowed_unit(path, entry):
    source = entry.get("source")
    assert isinstance(source, str) and source.strip(), f"{path}: empty source"
    assert source in SOURCES, f"{path}: source '{source}' not in [sources]"
    unit = entry.get("unit")
    assert unit in ALLOWED_UNITS, f"{path}: unit {unit!r} not in {sorted(ALLOWED_UNITS)}"


@pytest.mark.parametrize("path,entry", ENTRIES, ids=ENTRY_IDS)
def test_entry_keys_and_quantity_types(path, entry):
    unknown = set(entry) - QUANTITY_KEYS - TEXT_KEYS
    assert not unknown, f"{path}: unexpected keys {sorted(unknown)}"
    quantities = {k: v for k, v in entry.items() if k in QUANTITY_KEYS}
    assert quantities, f"{path}: no quantity (value/mean/kv/kp...)"
    for k, v in quantities.items():
        if isinstance(v, str):
            assert v == NO_REFERENCE, f"{path}.{k}: string quantity must be '{NO_REFERENCE}', got {v!r}"
        elif isinstance(v, list):
            assert v and all(_is_number(x) for x in v), f"{path}.{k}: list must hold numbers"
        else:
            assert _is_number(v), f"{path}.{k}: not a finite number: {v!r}"
    n = entry.get("n")
    if n is not None and not isinstance(n, str):
        assert isinstance(n, int) and n > 0, f"{path}.n must be a positive integer"
    elif isinstance(n, str):
        assert n == NO_REFERENCE, f"{path}.n: string must be '{NO_REFERENCE}'"


@pytest.mark.parametrize("path,entry", ENTRIES, ids=ENTRY_IDS)
def test_numeric_entries_are_located_in_their_source(path, entry):
    if any(_has_numeric(entry.get(k)) for k in QUANTITY_KEYS):
        where = entry.get("where", "")
        assert isinstance(where, str) and where.strip() and where != NO_REFERENCE, (
            f"{path}: numeric entry must say where in the source it was read"
        )


@pytest.mark.parametrize("path,entry", ENTRIES, ids=ENTRY_IDS)
def test_unsourced_values_explain_why(path, entry):
    if any(entry.get(k) == NO_REFERENCE for k in QUANTITY_KEYS):
        note = entry.get("note", "")
        assert isinstance(note, str) and len(note.strip()) > 20, f"{path}: 'no reference' needs a note on what was searched"


def test_strength_means_are_positive():
    checked = 0
    for path, entry in ENTRIES:
        if not path.startswith("strength.") or entry.get("unit") != "N":
            continue
        for k in ("mean", "value"):
            v = entry.get(k)
            values = v if isinstance(v, list) else [v]
            for x in values:
                if _is_number(x):
                    assert x >= 0, f"{path}.{k} must be non-negative"
                    if k == "mean":
                        assert x > 0, f"{path}.mean must be positive"
                        checked += 1
        sd = entry.get("sd")
        if _is_number(sd):
            assert sd > 0, f"{path}.sd must be positive"
    assert checked > 0, "expected at least one numeric strength mean"


def test_reflex_gains_within_thesis_bounds():
    lo, hi = DATA["reflex"]["thesis"]["gain_bounds"]["value"]
    for table in ("thesis_table_4_2", "thesis_table_4_3"):
        groups = DATA["reflex"][table]
        assert len(groups) == 9, f"{table}: the thesis has 9 muscle groups"
        for group, entry in groups.items():
            for k in ("kv", "kp"):
                assert lo <= entry[k] <= hi, f"reflex.{table}.{group}.{k} outside [{lo}, {hi}]"
