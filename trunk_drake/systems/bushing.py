"""IntervertebralBushings: rotational spring-dampers at the lumbar joints (seed section 3.1.1)."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem

DEFAULT_STIFFNESS = 100.0  # Nm/rad, seed Table 3.1 (Markolf), see models/reference_values.toml
DEFAULT_DAMPING = 7.5  # Nms/rad, seed Table 3.1


class IntervertebralBushings(LeafSystem):
    """Generalized force -k(q - q0) - c v on each lumbar rotation coordinate.

    Input ``plant_state`` [q; v]; output ``generalized_force`` (n_v). `coordinates` are the
    indices (into q and v) of the lumbar rotations. With ``cubic > 0`` the moment-angle law
    stiffens: M = -k (dq + cubic * dq^3) - c v, with `cubic` in 1/rad^2.
    """

    def __init__(self, nq: int, nv: int, coordinates, stiffness=DEFAULT_STIFFNESS, damping=DEFAULT_DAMPING,
                 rest_angle=0.0, cubic: float = 0.0):
        super().__init__()
        self.idx = np.asarray(coordinates, dtype=int)
        m = len(self.idx)
        self.k = np.broadcast_to(np.asarray(stiffness, float), (m,)).copy()
        self.c = np.broadcast_to(np.asarray(damping, float), (m,)).copy()
        self.q0 = np.broadcast_to(np.asarray(rest_angle, float), (m,)).copy()
        self.cubic = float(cubic)
        if np.any(self.k < 0) or np.any(self.c < 0) or self.cubic < 0:
            raise ValueError("bushing stiffness, damping and cubic coefficient must be >= 0")
        self._nq, self._nv = nq, nv
        self._tau = np.zeros(nv)
        self.DeclareVectorInputPort("plant_state", nq + nv)
        self.DeclareVectorOutputPort("generalized_force", nv, self._calc)

    def moment(self, q, v) -> np.ndarray:
        dq = q[self.idx] - self.q0
        return -self.k * (dq + self.cubic * dq**3) - self.c * v[self.idx]

    def _calc(self, context, output):
        x = self.get_input_port(0).Eval(context)
        self._tau[self.idx] = self.moment(x[: self._nq], x[self._nq :])
        output.SetFromVector(self._tau)
