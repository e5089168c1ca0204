"""Drake LeafSystems of the neuromuscular trunk diagram (wired by `trunk_drake.diagram`)."""
