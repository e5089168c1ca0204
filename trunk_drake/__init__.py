"""trunk-drake: neuromusculoskeletal simulation of the seated human lumbar spine on Drake."""

from trunk_drake.model.trunk_model import TrunkModel, load_model

__all__ = ["TrunkModel", "load_model"]
