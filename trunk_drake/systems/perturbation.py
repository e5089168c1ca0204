"""Pelvis perturbation: platform motion applied (a) exactly, as prescribed pelvis motion, or
(b) as in the thesis, as a force M * a_platform on a heavy pelvis free to slide."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import LeafSystem

from trunk_drake.systems.memo import declare_memo


class PrescribedPelvisMotion(LeafSystem):
    """Pelvis welded to a frame that moves with the platform: the plant is simulated in that
    translating frame, where every body feels the inertial force -m_i a_platform(t).

    Their sum is the generalized force ``-a(t) M J_com^T d`` (M total mass, J_com the
    centre-of-mass Jacobian, d the world direction of motion). Input ``plant_state``;
    output ``generalized_force``.
    """

    def __init__(self, plant, signal, direction):
        super().__init__()
        self._plant, self._signal = plant, signal
        self._dir = np.asarray(direction, dtype=float)
        self._scratch = plant.CreateDefaultContext()  # a workspace, fully set before every use
        self._mass = plant.CalcTotalMass(self._scratch)
        self._nq, nv = plant.num_positions(), plant.num_velocities()
        self._state = self.DeclareVectorInputPort("plant_state", self._nq + nv)
        self._com_dir = declare_memo(self, "M J_com^T d", lambda c: self._state.Eval(c)[: self._nq], self._calc_com_dir,
                                     {self._state.ticket()})
        self.DeclareVectorOutputPort("generalized_force", nv, self._calc_force,
                                     prerequisites_of_calc={self.time_ticket(), self._com_dir.ticket()})

    def _calc_com_dir(self, context) -> np.ndarray:
        q = self._state.Eval(context)[: self._nq]
        if not np.all(np.isfinite(q)):  # Drake would abort on non-finite positions
            raise RuntimeError(f"non-finite pelvis-frame positions at t={context.get_time():.6g} s: {q}")
        plant, scratch, world = self._plant, self._scratch, self._plant.world_frame()
        plant.SetPositions(scratch, q)
        J = plant.CalcJacobianCenterOfMassTranslationalVelocity(scratch, JacobianWrtVariable.kV, world, world)
        return self._mass * (J.T @ self._dir)

    def _calc_force(self, context, output):
        output.SetFromVector(-self._signal.evaluate(context.get_time())[2] * self._com_dir.Eval(context))


class PelvisForcePerturbation(LeafSystem):
    """The thesis' force disturbance: generalized force ``pelvis_mass * a_platform(t)`` on the
    pelvis slide (coordinate index `pelvis_index`). Output ``generalized_force``."""

    def __init__(self, nv: int, pelvis_index: int, signal, pelvis_mass: float):
        super().__init__()
        self._signal, self._nv, self._i, self._mass = signal, nv, pelvis_index, float(pelvis_mass)
        self.DeclareVectorOutputPort("generalized_force", nv, self._calc_force, prerequisites_of_calc={self.time_ticket()})

    def _calc_force(self, context, output):
        tau = np.zeros(self._nv)
        tau[self._i] = self._mass * self._signal.evaluate(context.get_time())[2]
        output.SetFromVector(tau)

