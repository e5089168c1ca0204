"""MusclePathSystem: muscle-tendon lengths, velocities and moment arms from the plant state."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, LeafSystem

from trunk_drake.model.paths import PathState


class MusclePathSystem(LeafSystem):
    """Input ``plant_state`` [q; v]; outputs ``path_state`` (abstract PathState), ``lengths``, ``velocities``.

    The path kinematics are computed once per context (Drake caches the abstract output)
    and shared by every consumer.
    """

    def __init__(self, model):
        super().__init__()
        self._model = model
        self._nq = model.plant.num_positions()
        self._scratch = model.plant.CreateDefaultContext()
        self._last_x, self._last = None, None
        n_state = self._nq + model.plant.num_velocities()
        self.DeclareVectorInputPort("plant_state", n_state)
        empty = PathState(np.zeros(model.n_muscles), np.zeros((model.n_muscles, self._nq)), np.zeros(model.n_muscles))
        self._path_port = self.DeclareAbstractOutputPort("path_state", lambda: AbstractValue.Make(empty), self._calc_path)
        self.DeclareVectorOutputPort("lengths", model.n_muscles, lambda c, o: o.SetFromVector(self._path(c).lengths))
        self.DeclareVectorOutputPort("velocities", model.n_muscles, lambda c, o: o.SetFromVector(self._path(c).velocities))

    def _path(self, context) -> PathState:
        return self._path_port.Eval(context)

    def _calc_path(self, context, output):
        x = self.get_input_port(0).Eval(context)
        if self._last_x is None or not np.array_equal(x, self._last_x):
            # memo: implicit integrators perturb muscle states with the plant state unchanged
            if not np.all(np.isfinite(x)):  # Drake would abort on non-finite positions
                raise RuntimeError(f"non-finite plant state at t={context.get_time():.6g} s: {x}")
            self._model.plant.SetPositions(self._scratch, x[: self._nq])
            self._last = self._model.path_state_from_context(self._scratch, x[self._nq :])
            self._last_x = x.copy()
        output.set_value(self._last)
