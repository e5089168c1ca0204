"""Locate the project's data folder `models/` (citations, groups, architecture inputs)."""

from __future__ import annotations

import os
import tomllib
from functools import lru_cache
from pathlib import Path


def models_dir() -> Path:
    """The `models/` folder: $TRUNK_DRAKE_MODELS, else the one beside the package (source checkout)."""
    env = os.environ.get("TRUNK_DRAKE_MODELS")
    path = Path(env) if env else Path(__file__).resolve().parents[1] / "models"
    if not path.is_dir():
        raise FileNotFoundError(
            f"trunk-drake data folder not found at {path}. Install from a source checkout "
            "(pip install -e .) or set TRUNK_DRAKE_MODELS to the repository's models/ folder."
        )
    return path


@lru_cache(maxsize=None)
def load_toml(name: str) -> dict:
    """Parse `models/<name>` (cached)."""
    with open(models_dir() / name, "rb") as f:
        return tomllib.load(f)
