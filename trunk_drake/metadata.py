"""Provenance attached to every result: versions, model fingerprint, options, time."""

from __future__ import annotations

import ast
import datetime
import hashlib
import platform
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

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


def source_fingerprint(root: Path | None = None) -> str:
    """SHA-256 (16 hex digits) of trunk-drake's own Python code (`root`: the package folder): the code a
    result was computed with. Docstrings, comments and layout do not count, so editing them keeps a
    long run resumable."""
    root = Path(__file__).parent if root is None else Path(root)
    h = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        h.update(str(path.relative_to(root)).encode())
        h.update(ast.dump(_without_docstrings(ast.parse(path.read_bytes()))).encode())
    return h.hexdigest()[:16]


def _without_docstrings(tree: ast.AST) -> ast.AST:
    """`tree` with the docstring of every module, class and function removed."""
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
                node.body = node.body[1:] or [ast.Pass()]
    return tree


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
