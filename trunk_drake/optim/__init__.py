"""Optimisation: static optimisation, co-activation and isometric strength (seed chapter 2, 3.2.3)."""

from trunk_drake.optim.static import (
    COACTIVATION_LEVELS, ActivationProgram, MomentBalance, PointLoad, StaticInfeasibleError, StaticOptimizer,
    StaticResult, coactivation, solve_balance, static_optimization,
)
from trunk_drake.optim.strength import (
    DIRECTIONS, LoadCase, StrengthProblem, StrengthResult, in_vivo_comparison, isometric_strength, load_case,
)

__all__ = [
    "COACTIVATION_LEVELS", "ActivationProgram", "MomentBalance", "PointLoad", "StaticInfeasibleError",
    "StaticOptimizer", "StaticResult", "coactivation", "solve_balance", "static_optimization",
    "DIRECTIONS", "LoadCase", "StrengthProblem", "StrengthResult", "in_vivo_comparison", "isometric_strength", "load_case",
]
