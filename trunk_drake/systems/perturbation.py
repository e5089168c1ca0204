"""Pelvis perturbation: platform motion applied (a) exactly, as prescribed pelvis motion, or
(b) as in the thesis, as a force M * a_platform on a heavy pelvis free to slide."""

from __future__ import annotations

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import LeafSystem


class PrescribedPelvisMotion(LeafSystem):
    """Pelvis welded to a frame that moves with the platform: the plant is simulated in that
    translating frame, where every body feels the inertial force -m_i a_platform(t).

    Their sum is the generalized force ``-a(t) M J_com^T d`` (M total mass, J_com the
    centre-of-mass Jacobian, d the world direction of motion). Input ``plant_state``;
    outputs ``generalized_force`` and ``platform`` [x, v, a] (m, m/s, m/s^2).
    """

    def __init__(self, plant, signal, direction):
        super().__init__()
        self._plant, self._signal = plant, signal
        self._dir = np.asarray(direction, dtype=float)
        self._scratch = plant.CreateDefaultContext()
        self._mass = plant.CalcTotalMass(self._scratch)
        self._last_q, self._com_dir = None, None
        self._nq, nv = plant.num_positions(), plant.num_velocities()
        self.DeclareVectorInputPort("plant_state", self._nq + nv)
        self.DeclareVectorOutputPort("generalized_force", nv, self._calc_force)
        self.DeclareVectorOutputPort("platform", 3, self._calc_platform, prerequisites_of_calc={self.time_ticket()})

    def _calc_force(self, context, output):
        q = self.get_input_port(0).Eval(context)[: self._nq]
        if self._last_q is None or not np.array_equal(q, self._last_q):  # memo over muscle-only changes
            if not np.all(np.isfinite(q)):  # Drake would abort on non-finite positions
                raise RuntimeError(f"non-finite pelvis-frame positions at t={context.get_time():.6g} s: {q}")
            plant, scratch, world = self._plant, self._scratch, self._plant.world_frame()
            plant.SetPositions(scratch, q)
            J = plant.CalcJacobianCenterOfMassTranslationalVelocity(scratch, JacobianWrtVariable.kV, world, world)
            self._last_q, self._com_dir = q.copy(), self._mass * (J.T @ self._dir)
        output.SetFromVector(-self._signal.evaluate(context.get_time())[2] * self._com_dir)

    def _calc_platform(self, context, output):
        output.SetFromVector(np.asarray(self._signal.evaluate(context.get_time()), dtype=float))


class PelvisForcePerturbation(LeafSystem):
    """The thesis' force disturbance: generalized force ``pelvis_mass * a_platform(t)`` on the
    pelvis slide (coordinate index `pelvis_index`). Outputs ``generalized_force`` and ``platform``."""

    def __init__(self, nv: int, pelvis_index: int, signal, pelvis_mass: float):
        super().__init__()
        self._signal, self._nv, self._i, self._mass = signal, nv, pelvis_index, float(pelvis_mass)
        self.DeclareVectorOutputPort("generalized_force", nv, self._calc_force)
        self.DeclareVectorOutputPort("platform", 3, self._calc_platform, prerequisites_of_calc={self.time_ticket()})

    def _calc_force(self, context, output):
        tau = np.zeros(self._nv)
        tau[self._i] = self._mass * self._signal.evaluate(context.get_time())[2]
        output.SetFromVector(tau)

    def _calc_platform(self, context, output):
        output.SetFromVector(np.asarray(self._signal.evaluate(context.get_time()), dtype=float))

