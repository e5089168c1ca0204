"""Shared test fixtures: the oracle files of ../shared (present in CI, maybe absent elsewhere)."""

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[1].parent / "shared"
LUMBAR_C_210 = SHARED / "reference" / "lumbar_c_210" / "Lumbar_C_210.osim"


@pytest.fixture(scope="session")
def lumbar_c210_path():
    """Path of the original OpenSim lumbar model; skips when absent or opensim is missing."""
    pytest.importorskip("opensim", reason="OpenSim 4.6 (pip opensim) is needed for this oracle test")
    if not LUMBAR_C_210.exists():
        pytest.skip(f"oracle model not found at {LUMBAR_C_210} (the repository's ../shared folder)")
    return LUMBAR_C_210
