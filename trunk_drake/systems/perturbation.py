"""Pelvis perturbation: platform motion applied (a) exactly, as prescribed pelvis motion, or
(b) as in the thesis, as a force M * a_platform on a heavy pelvis free to slide."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce
from pydrake.systems.framework import LeafSystem


class PrescribedPelvisMotion(LeafSystem):
    """Pelvis welded to a frame that moves with the platform: the plant is simulated in that
    translating frame, where every body feels the inertial force -m_i a_platform(t).

    Output ``spatial_forces`` (for the plant's applied-spatial-force input) and ``platform``
    [x, v, a] (m, m/s, m/s^2) along `direction` (world unit vector, anterior).
    """

    def __init__(self, plant, signal, direction):
        super().__init__()
        self._signal = signal
        self._dir = np.asarray(direction, dtype=float)
        self._bodies = []
        for i in range(plant.num_bodies()):
            body = plant.get_body(_body_index(i))
            mass = body.default_mass()
            if mass > 0:
                self._bodies.append((body.index(), mass, body.default_com()))
        self.DeclareAbstractOutputPort(
            "spatial_forces", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]), self._calc_forces
        )
        self.DeclareVectorOutputPort("platform", 3, self._calc_platform)

    def _calc_forces(self, context, output):
        _, _, acc = self._signal.evaluate(context.get_time())
        forces = []
        for index, mass, com in self._bodies:
            f = ExternallyAppliedSpatialForce()
            f.body_index = index
            f.p_BoBq_B = com
            f.F_Bq_W = SpatialForce(np.zeros(3), -mass * acc * self._dir)
            forces.append(f)
        output.set_value(forces)

    def _calc_platform(self, context, output):
        output.SetFromVector(np.asarray(self._signal.evaluate(context.get_time()), dtype=float))


class PelvisForcePerturbation(LeafSystem):
    """The thesis' force disturbance: generalized force ``pelvis_mass * a_platform(t)`` on the
    pelvis slide (coordinate index `pelvis_index`). Outputs ``generalized_force`` and ``platform``."""

    def __init__(self, nv: int, pelvis_index: int, signal, pelvis_mass: float):
        super().__init__()
        self._signal, self._nv, self._i, self._mass = signal, nv, pelvis_index, float(pelvis_mass)
        self.DeclareVectorOutputPort("generalized_force", nv, self._calc_force)
        self.DeclareVectorOutputPort("platform", 3, self._calc_platform)

    def _calc_force(self, context, output):
        tau = np.zeros(self._nv)
        tau[self._i] = self._mass * self._signal.evaluate(context.get_time())[2]
        output.SetFromVector(tau)

    def _calc_platform(self, context, output):
        output.SetFromVector(np.asarray(self._signal.evaluate(context.get_time()), dtype=float))


def _body_index(i):
    from pydrake.multibody.tree import BodyIndex

    return BodyIndex(i)
