"""Provenance attached to every result: versions, model fingerprint, options, time."""

from __future__ import annotations

import datetime
import hashlib
import platform
from importlib.metadata import PackageNotFoundError, version

import numpy as np

PACKAGES = ("trunk-drake", "drake", "numpy", "scipy", "myo-sim", "numba")


def json_default(obj):
    """`default=` for json.dumps: numpy arrays and scalars as plain lists and numbers."""
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"not JSON serialisable: {type(obj)}")


def package_versions() -> dict[str, str]:
    out = {}
    for name in PACKAGES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


def model_fingerprint(model) -> str:
    """SHA-256 (16 hex digits) of the model's source, configuration and muscle parameters."""
    h = hashlib.sha256()
    h.update(f"{model.spec.source}|{model.dofs}|{model.pelvis_free}|{model.pelvis_mass}".encode())
    for attr in ("max_isometric_force", "optimal_fiber_length", "tendon_slack_length", "pennation_angle"):
        h.update(np.ascontiguousarray(model.muscle_array(attr)).tobytes())
    return h.hexdigest()[:16]


def run_metadata(model, **extra) -> dict:
    """Metadata for a result produced with `model` (extra keys are added as given)."""
    return {
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "machine": platform.machine(),
        "versions": package_versions(),
        "model": {"source": model.spec.source, "dofs": model.dofs, "fingerprint": model_fingerprint(model)},
        **extra,
    }
