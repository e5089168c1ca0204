"""Candidate effects the thesis' model lacks (switchable blocks for the sim-to-real gap diagnosis).

Each has few parameters; `trunk_drake.gap.catalogue` lists them with physiological bounds.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem
from trunk_drake.systems.weak import weak


class GolgiTendonFeedback(LeafSystem):
    """Autogenic force feedback (Golgi tendon organs): feedback = -gain (F - F0) / F_max.

    Input ``tendon_force`` (n, N); output ``feedback`` (n). F0 is the tendon force at the
    operating point (the tonic part belongs to the feed-forward), so the block acts on
    force changes: inhibitory when force rises.
    """

    def __init__(self, gain: float, max_isometric_force, reference_force):
        super().__init__()
        self.gain = float(gain)
        self._scale = self.gain / np.asarray(max_isometric_force, float)
        self._f0 = np.asarray(reference_force, float)
        n = self._f0.size
        self.DeclareVectorInputPort("tendon_force", n)
        self.DeclareVectorOutputPort("feedback", n, weak(self._calc))

    def _calc(self, context, output):
        output.SetFromVector(-self._scale * (self.get_input_port(0).Eval(context) - self._f0))


class TrunkInSpaceFeedback(LeafSystem):
    """Vestibular/visual trunk-orientation feedback onto the trunk muscles.

    Trunk inclination theta (the sum of the lumbar flexion angles: the pelvis does not
    rotate) drives the back extensors when the trunk flexes and the abdominal flexors when
    it extends: feedback = gain * (theta)+ on `extensors` (0/1 mask), gain * (-theta)+ on
    `flexors`. Input ``plant_state``; output ``feedback`` (n).
    """

    def __init__(self, gain: float, extensors, flexors, angle_indices, n_state: int):
        super().__init__()
        self.gain = float(gain)
        self._ext = np.asarray(extensors, float)
        self._flex = np.asarray(flexors, float)
        self._idx = np.asarray(angle_indices, int)
        self.DeclareVectorInputPort("plant_state", n_state)
        self.DeclareVectorOutputPort("feedback", self._ext.size, weak(self._calc))

    def _calc(self, context, output):
        theta = float(self.get_input_port(0).Eval(context)[self._idx].sum())
        output.SetFromVector(self.gain * (max(theta, 0.0) * self._ext + max(-theta, 0.0) * self._flex))


class SeatCompliance(LeafSystem):
    """Pelvis-seat contact as a spring-damper: the pelvis no longer follows the platform exactly.

    Generalized force on the pelvis slide k (x_platform - x_pelvis) + c (v_platform - v_pelvis). With copies of
    the model, `stiffness`, `damping` and `pelvis_index` hold one value per copy.
    Input ``plant_state``; output ``generalized_force`` (n_v).
    """

    def __init__(self, signal, stiffness, damping, pelvis_index, nq: int, nv: int):
        super().__init__()
        self._k, self._c = np.atleast_1d(np.asarray(stiffness, float)), np.atleast_1d(np.asarray(damping, float))
        if np.any(self._k <= 0) or np.any(self._c < 0):
            raise ValueError(f"seat stiffness must be > 0 and damping >= 0, got {stiffness}, {damping}")
        self._signal, self._i, self._nq = signal, np.atleast_1d(pelvis_index), nq
        self._nv = nv
        self.DeclareVectorInputPort("plant_state", nq + nv)
        self.DeclareVectorOutputPort("generalized_force", nv, weak(self._calc_force))

    def _calc_force(self, context, output):
        x = self.get_input_port(0).Eval(context)
        p, v, _ = self._signal.evaluate(context.get_time()) if self._signal is not None else (0.0, 0.0, 0.0)
        tau = np.zeros(self._nv)
        tau[self._i] = self._k * (p - x[self._i]) + self._c * (v - x[self._nq + self._i])
        output.SetFromVector(tau)
