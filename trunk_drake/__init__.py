"""trunk-drake: neuromusculoskeletal simulation of the seated human lumbar spine on Drake."""

from trunk_drake.model.trunk_model import TrunkModel, load_model
from trunk_drake.optim.fit import fit_reflex_gains
from trunk_drake.optim.stability import StabilityResult, stability
from trunk_drake.optim.static import coactivation, static_optimization
from trunk_drake.optim.strength import isometric_strength
from trunk_drake.simulation import SimulationResult, simulate

__all__ = [
    "TrunkModel",
    "load_model",
    "simulate",
    "SimulationResult",
    "static_optimization",
    "coactivation",
    "isometric_strength",
    "fit_reflex_gains",
    "stability",
    "StabilityResult",
]

