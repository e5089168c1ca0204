"""Compare MyoTorso with the original OpenSim Lumbar_C_210 model (test oracle; needs `opensim`).

MyoTorso was converted from Christophy et al.'s Lumbar_C_210.osim. This module loads that
file with OpenSim, reads its musculotendon lengths at the neutral posture and its Thelen
parameters, and compares them with ours. The .osim file itself is never copied.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from trunk_drake.model.architecture import derive_hill_lengths


@dataclass
class OsimMuscles:
    """Per-muscle values read from an .osim model (arrays in the order of `names`)."""

    names: list[str]
    neutral_length: np.ndarray
    optimal_fiber_length: np.ndarray
    tendon_slack_length: np.ndarray
    pennation_angle: np.ndarray
    max_isometric_force: np.ndarray


def read_osim_muscles(path: str) -> OsimMuscles:
    """Musculotendon lengths at the default (neutral) pose and Hill parameters, via OpenSim."""
    import opensim

    opensim.Logger.setLevelString("error")
    model = opensim.Model(str(path))
    state = model.initSystem()
    model.realizePosition(state)
    muscles = model.getMuscles()
    rows = [muscles.get(i) for i in range(muscles.getSize())]
    return OsimMuscles(
        names=[m.getName() for m in rows],
        neutral_length=np.array([m.getLength(state) for m in rows]),
        optimal_fiber_length=np.array([m.getOptimalFiberLength() for m in rows]),
        tendon_slack_length=np.array([m.getTendonSlackLength() for m in rows]),
        pennation_angle=np.array([m.getPennationAngleAtOptimalFiberLength() for m in rows]),
        max_isometric_force=np.array([m.getMaxIsometricForce() for m in rows]),
    )


@dataclass
class HillComparison:
    """Relative differences, ours vs the .osim, per muscle (model order)."""

    muscles: list[str]
    groups: list[str]
    neutral_length: np.ndarray
    optimal_fiber_length: np.ndarray
    tendon_slack_length: np.ndarray
    osim_follows_method: np.ndarray  # the .osim values equal the published method applied to OpenSim's own lengths (1 %)

    def by_group(self) -> dict[str, dict[str, float]]:
        """Largest relative difference per group: all muscles, and muscles whose .osim follows the method."""
        out = {}
        for g in dict.fromkeys(self.groups):
            sel = np.array([x == g for x in self.groups])
            follow = sel & self.osim_follows_method
            out[g] = {
                "n": int(sel.sum()),
                "neutral_length": float(self.neutral_length[sel].max()),
                "optimal_fiber_length": float(self.optimal_fiber_length[sel].max()),
                "tendon_slack_length": float(self.tendon_slack_length[sel].max()),
                "n_osim_follows_method": int(follow.sum()),
                "optimal_fiber_length_where_followed": float(self.optimal_fiber_length[follow].max()) if follow.any() else math.nan,
                "tendon_slack_length_where_followed": float(self.tendon_slack_length[follow].max()) if follow.any() else math.nan,
            }
        return out


def compare_hill_parameters(model, osim_path: str, tolerance: float = 0.01) -> HillComparison:
    """Our neutral lengths and derived Hill lengths against Lumbar_C_210.osim."""
    osim = read_osim_muscles(osim_path)
    index = {n: i for i, n in enumerate(osim.names)}
    missing = [n for n in model.muscles if n not in index]
    if missing:
        raise ValueError(f"{osim_path} lacks muscles {missing[:5]}... of the model")
    order = [index[n] for n in model.muscles]
    lmt = osim.neutral_length[order]
    ours_lmt = model.muscle_lengths(np.zeros(len(model.coordinates)))
    lopt = model.muscle_array("optimal_fiber_length")
    lslack = model.muscle_array("tendon_slack_length")
    # the published method applied to OpenSim's own neutral lengths
    method = derive_hill_lengths(model.muscles, lmt)
    o_lopt, o_lslack = osim.optimal_fiber_length[order], osim.tendon_slack_length[order]
    follows = (np.abs(method.optimal_fiber_length / o_lopt - 1) < tolerance) & (
        np.abs(method.tendon_slack_length / o_lslack - 1) < tolerance
    )
    return HillComparison(
        muscles=list(model.muscles),
        groups=[m.group for m in model.spec.muscles],
        neutral_length=np.abs(ours_lmt / lmt - 1),
        optimal_fiber_length=np.abs(lopt / o_lopt - 1),
        tendon_slack_length=np.abs(lslack / o_lslack - 1),
        osim_follows_method=follows,
    )

