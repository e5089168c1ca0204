"""TabulatedPlant: independent copies of a one-coordinate plant (on a pelvis slide or not), their dynamics from its table."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem

from trunk_drake.systems.weak import weak


class TabulatedPlant(LeafSystem):
    """`copies` copies of a one-coordinate model (the rhythm on a welded pelvis, or on the pelvis slide: the table's
    `width` coordinates per copy), each ``M v' + c v^2 = g + tau`` (`CoordinateTable.accelerations`) with M, g and c
    from its `model.tables.CoordinateTable`: a finite-difference Jacobian's points simulated as one diagram
    (`simulation.simulate_copies`). State [q (copies * width); v (copies * width)], each copy's coordinates in turn;
    input ``applied_generalized_force``; output ``state``. A copy leaving the table raises: the caller runs the
    copies one by one instead (the single-copy diagram falls back to the exact dynamics there)."""

    def __init__(self, table, copies: int):
        super().__init__()
        self.table, self.copies = table, int(copies)
        self._n = self.copies * table.width
        self.DeclareContinuousState(self._n, self._n, 0)
        self._applied = self.DeclareVectorInputPort("applied_generalized_force", self._n)
        self._state = self.DeclareVectorOutputPort("state", 2 * self._n, weak(self._copy_state),
                                                   prerequisites_of_calc={self.xc_ticket()})
        self.set_name("tabulated_plant")

    def num_positions(self) -> int:
        return self._n

    def num_velocities(self) -> int:
        return self._n

    def get_state_output_port(self):
        return self._state

    def get_applied_generalized_force_input_port(self):
        return self._applied

    def _copy_state(self, context, output):
        output.SetFromVector(context.get_continuous_state_vector().CopyToVector())

    def DoCalcTimeDerivatives(self, context, derivatives):  # noqa: N802 (Drake API)
        x = context.get_continuous_state_vector().CopyToVector()
        q, v, w = x[: self._n], x[self._n:], self.table.width
        if not (np.all(np.isfinite(x)) and self.table.covers(q[w - 1::w])):
            raise RuntimeError(f"a copy left the tabulated range [{self.table.lo:.4g}, {self.table.hi:.4g}] rad "
                               f"at t={context.get_time():.6g} s: q = {q}")
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([v, self.table.accelerations(q, v, self._applied.Eval(context))]))
