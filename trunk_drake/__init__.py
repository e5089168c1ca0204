"""trunk-drake: neuromusculoskeletal simulation of the seated human lumbar spine on Drake.

The names below are imported on first use, so that `trunk-drake` (and any submodule) starts
without loading Drake until it needs it.
"""

from importlib import import_module

_API = {
    "TrunkModel": "trunk_drake.model.trunk_model",
    "load_model": "trunk_drake.model.trunk_model",
    "simulate": "trunk_drake.simulation",
    "SimulationResult": "trunk_drake.simulation",
    "static_optimization": "trunk_drake.optim.static",
    "coactivation": "trunk_drake.optim.static",
    "isometric_strength": "trunk_drake.optim.strength",
    "fit_reflex_gains": "trunk_drake.optim.fit",
    "stability": "trunk_drake.optim.stability",
    "StabilityResult": "trunk_drake.optim.stability",
    "animate": "trunk_drake.visual",
    "load_preset": "trunk_drake.presets",
    "Preset": "trunk_drake.presets",
}

__all__ = list(_API)


def __getattr__(name: str):
    if name not in _API:
        raise AttributeError(f"module 'trunk_drake' has no attribute {name!r}")
    return getattr(import_module(_API[name]), name)


def __dir__():
    return sorted([*globals(), *_API])
