"""Intervertebral bushings: rotational spring-dampers at the lumbar joints (seed section 3.1.1).

The linear law is a Drake AffineSystem (compiled, no Python per evaluation); the optional cubic
stiffening is a LeafSystem added beside it.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem
from pydrake.systems.primitives import AffineSystem

DEFAULT_STIFFNESS = 100.0  # Nm/rad, seed Table 3.1 (Markolf), see models/reference_values.toml
DEFAULT_DAMPING = 7.5  # Nms/rad, seed Table 3.1


def _per_coordinate(value, m: int, name: str) -> np.ndarray:
    array = np.broadcast_to(np.asarray(value, float), (m,)).copy()
    if np.any(array < 0):
        raise ValueError(f"bushing {name} must be >= 0, got {value}")
    return array


def intervertebral_bushings(nq: int, nv: int, coordinates, stiffness=DEFAULT_STIFFNESS, damping=DEFAULT_DAMPING,
                            rest_angle=0.0) -> AffineSystem:
    """Generalized force -k (q - q0) - c v on each lumbar rotation coordinate.

    Input [q; v]; output the generalized force (n_v). `coordinates` are the indices (into q
    and v) of the lumbar rotations; `stiffness`, `damping` and `rest_angle` are per coordinate
    or scalars.
    """
    idx = np.asarray(coordinates, dtype=int)
    k = _per_coordinate(stiffness, len(idx), "stiffness")
    c = _per_coordinate(damping, len(idx), "damping")
    q0 = np.broadcast_to(np.asarray(rest_angle, float), (len(idx),))
    D = np.zeros((nv, nq + nv))
    D[idx, idx] = -k
    D[idx, nq + idx] = -c
    y0 = np.zeros(nv)
    y0[idx] = k * q0
    return AffineSystem(np.zeros((0, 0)), np.zeros((0, nq + nv)), np.zeros(0), np.zeros((nv, 0)), D, y0)


class BushingStiffening(LeafSystem):
    """The cubic part of a stiffening bushing law M = -k (dq + cubic dq^3) - c v: -k cubic dq^3.

    Input ``plant_state`` [q; v]; output ``generalized_force`` (n_v); `cubic` in 1/rad^2.
    """

    def __init__(self, nq: int, nv: int, coordinates, stiffness, cubic: float, rest_angle=0.0):
        super().__init__()
        self.idx = np.asarray(coordinates, dtype=int)
        self.k = _per_coordinate(stiffness, len(self.idx), "stiffness")
        self.q0 = np.broadcast_to(np.asarray(rest_angle, float), (len(self.idx),)).copy()
        self.cubic = float(cubic)
        if not self.cubic > 0:
            raise ValueError(f"cubic bushing coefficient must be > 0, got {cubic}")
        self._tau = np.zeros(nv)
        self._state = self.DeclareVectorInputPort("plant_state", nq + nv)
        self.DeclareVectorOutputPort("generalized_force", nv, self._calc)

    def _calc(self, context, output):
        dq = self._state.Eval(context)[self.idx] - self.q0
        tau = self._tau.copy()
        tau[self.idx] = -self.k * self.cubic * dq**3
        output.SetFromVector(tau)
