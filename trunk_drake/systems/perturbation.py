"""Pelvis perturbation: platform motion applied (a) exactly, as prescribed pelvis motion, or
(b) as in the thesis, as a force M * a_platform on a heavy pelvis free to slide."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem
from trunk_drake.systems.weak import weak


class PrescribedPelvisMotion(LeafSystem):
    """Pelvis welded to a frame that moves with the platform: the plant is simulated in that
    translating frame, where every body feels the inertial force -m_i a_platform(t).

    Their sum is the generalized force ``-a(t) M J_com^T d`` (M total mass, J_com the
    centre-of-mass Jacobian, d the world direction of motion; compiled, from the model's body
    kinematics, or a `table`'s for one coordinate, also for `copies` of it). Input ``plant_state``; output
    ``generalized_force``.
    """

    def __init__(self, model, signal, direction, table=None, copies: int = 1):
        super().__init__()
        self._model, self._signal, self._table, self._copies = model, signal, table, copies
        self._dir = np.asarray(direction, dtype=float)
        self._nq, nv = model.plant.num_positions() * copies, model.plant.num_velocities() * copies
        self._state = self.DeclareVectorInputPort("plant_state", self._nq + nv)
        self.DeclareVectorOutputPort("generalized_force", nv, weak(self._calc_force))

    def _calc_force(self, context, output):
        q = self._state.Eval(context)[: self._nq]
        if not np.isfinite(q.sum()):  # any NaN or inf
            raise RuntimeError(f"non-finite pelvis-frame positions at t={context.get_time():.6g} s: {q}")
        acceleration = self._signal.evaluate(context.get_time())[2]
        table = self._table
        if self._copies > 1:
            load = table.com_load(q, self._dir)
        elif table is not None and table.covers(q[0]):
            load = np.array([table.com_load(q[0], self._dir)])
        else:
            load = self._model.mass_weighted_com_jacobian(q, self._dir)
        output.SetFromVector(-acceleration * load)


class PelvisForcePerturbation(LeafSystem):
    """The thesis' force disturbance: generalized force ``pelvis_mass * a_platform(t)`` on the
    pelvis slide (coordinate index `pelvis_index`). Output ``generalized_force``."""

    def __init__(self, nv: int, pelvis_index: int, signal, pelvis_mass: float):
        super().__init__()
        self._signal, self._nv, self._i, self._mass = signal, nv, pelvis_index, float(pelvis_mass)
        self.DeclareVectorOutputPort("generalized_force", nv, weak(self._calc_force))

    def _calc_force(self, context, output):
        tau = np.zeros(self._nv)
        tau[self._i] = self._mass * self._signal.evaluate(context.get_time())[2]
        output.SetFromVector(tau)

