"""MusclePathSystem: muscle-tendon lengths, velocities and moment arms from the plant state."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from trunk_drake.model.paths import PathState
from trunk_drake.systems.memo import declare_memo
from trunk_drake.systems.weak import weak


class MusclePathSystem(LeafSystem):
    """Input ``plant_state`` [q; v]; output ``path_state`` (abstract PathState).

    The path kinematics (compiled body kinematics and paths, `TrunkModel.path_state_from_q`)
    are computed once per plant state and kept in the Context (a memo entry: implicit
    integrators perturb muscle states with the plant state unchanged), and shared by every consumer.
    With a `table` (`model.tables.CoordinateTable`, one coordinate) they come from it inside its grid; with
    `copies` > 1 (a table needed) the input holds that many copies' coordinates, the output their muscles in turn.
    """

    def __init__(self, model, table=None, copies: int = 1):
        super().__init__()
        if copies > 1 and table is None:
            raise ValueError("copies of a model need its one-coordinate table (model.tables)")
        self._model, self._table, self._copies = model, table, copies
        self._nq = model.plant.num_positions() * copies
        self._state = self.DeclareVectorInputPort("plant_state", self._nq + model.plant.num_velocities() * copies)
        self._memo = declare_memo(self, "path kinematics", self._eval_state, self._compute, {self._state.ticket()})
        n = model.n_muscles * copies
        empty = PathState(np.zeros(n), np.zeros((n, self._nq)), np.zeros(n))
        self.DeclareAbstractOutputPort("path_state", lambda: AbstractValue.Make(empty),
                                       weak(self._calc_path_state), prerequisites_of_calc={self._memo.ticket()})

    def _eval_state(self, context):
        return self._state.Eval(context)

    def _calc_path_state(self, context, output):
        output.set_value(self._memo.Eval(context))

    def _compute(self, context, x) -> PathState:
        if not np.isfinite(x.sum()):  # any NaN or inf; Drake would abort on non-finite positions
            raise RuntimeError(f"non-finite plant state at t={context.get_time():.6g} s: {x}")
        table, nq = self._table, self._nq
        if self._copies > 1:  # TabulatedPlant checks the range
            w = table.width
            return table.paths(x[w - 1:nq:w], x[nq + w - 1::w])
        if table is not None and table.covers(x[nq - 1]):  # the tabulated coordinate is the last (after a pelvis slide)
            return table.paths(x[nq - 1], x[-1])
        return self._model.path_state_from_q(x[:nq], x[nq:])
