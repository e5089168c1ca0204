"""IntervertebralBushings: rotational spring-dampers at the lumbar joints (seed section 3.1.1)."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem
from trunk_drake.systems.weak import weak

DEFAULT_STIFFNESS = 100.0  # Nm/rad, seed Table 3.1 (Markolf), see models/reference_values.toml
DEFAULT_DAMPING = 7.5  # Nms/rad, seed Table 3.1


class IntervertebralBushings(LeafSystem):
    """Moments -k(dq - q0) - c dq' at each lumbar level, applied as generalized forces.

    Input ``plant_state`` [q; v]; output ``generalized_force`` (n_v). `coordinates` are the
    indices (into q and v) of the level angles, or a matrix L (n_levels, n_q) with level angles
    ``L q`` (a coupled configuration, e.g. ``model.level_matrix`` of the rhythm); the generalized
    force is ``L^T`` of the level moments. With ``cubic > 0`` the moment-angle law stiffens:
    M = -k (dq + cubic * dq^3) - c v, with `cubic` in 1/rad^2. Stiffness, damping, rest angle and cubic
    coefficient are each one value or one per level.
    """

    def __init__(self, nq: int, nv: int, coordinates, stiffness=DEFAULT_STIFFNESS, damping=DEFAULT_DAMPING,
                 rest_angle=0.0, cubic=0.0):
        super().__init__()
        levels = np.asarray(coordinates)
        self.L = levels.astype(float) if levels.ndim == 2 else np.eye(nq)[levels.astype(int)]
        if self.L.shape[1] != nq or nq != nv:
            raise ValueError(f"bushings need level angles over the {nq} positions (= velocities, got {nv}); got {self.L.shape}")
        m = len(self.L)
        self.k = np.broadcast_to(np.asarray(stiffness, float), (m,)).copy()
        self.c = np.broadcast_to(np.asarray(damping, float), (m,)).copy()
        self.q0 = np.broadcast_to(np.asarray(rest_angle, float), (m,)).copy()
        self.cubic = np.broadcast_to(np.asarray(cubic, float), (m,)).copy()
        if np.any(self.k < 0) or np.any(self.c < 0) or np.any(self.cubic < 0):
            raise ValueError("bushing stiffness, damping and cubic coefficient must be >= 0")
        self._nq = nq
        self.DeclareVectorInputPort("plant_state", nq + nv)
        self.DeclareVectorOutputPort("generalized_force", nv, weak(self._calc))

    def moment(self, q, v) -> np.ndarray:
        """The moment of each level's bushing (Nm) at state (q, v)."""
        dq = self.L @ q - self.q0
        return -self.k * (dq + self.cubic * dq**3) - self.c * (self.L @ v)

    def _calc(self, context, output):
        x = self.get_input_port(0).Eval(context)
        output.SetFromVector(self.L.T @ self.moment(x[: self._nq], x[self._nq :]))
