"""TabulatedPlant: independent copies of a one-coordinate plant, their dynamics from its table."""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import LeafSystem

from trunk_drake.systems.weak import weak


class TabulatedPlant(LeafSystem):
    """`copies` copies of a one-coordinate model (the rhythm on a welded pelvis), each ``M v' + c v^2 = g + tau``
    with M, g and c from its `model.tables.CoordinateTable`: a finite-difference Jacobian's points simulated as
    one diagram (`simulation.simulate_copies`). State [q (copies); v (copies)]; input
    ``applied_generalized_force`` (copies); output ``state``. A copy leaving the table raises: the caller runs
    the copies one by one instead (the single-copy diagram falls back to the exact dynamics there)."""

    def __init__(self, table, copies: int):
        super().__init__()
        self.table, self.copies = table, int(copies)
        self.DeclareContinuousState(self.copies, self.copies, 0)
        self._applied = self.DeclareVectorInputPort("applied_generalized_force", self.copies)
        self._state = self.DeclareVectorOutputPort("state", 2 * self.copies, weak(self._copy_state),
                                                   prerequisites_of_calc={self.xc_ticket()})
        self.set_name("tabulated_plant")

    def num_positions(self) -> int:
        return self.copies

    def num_velocities(self) -> int:
        return self.copies

    def get_state_output_port(self):
        return self._state

    def get_applied_generalized_force_input_port(self):
        return self._applied

    def _copy_state(self, context, output):
        output.SetFromVector(context.get_continuous_state_vector().CopyToVector())

    def DoCalcTimeDerivatives(self, context, derivatives):  # noqa: N802 (Drake API)
        x = context.get_continuous_state_vector().CopyToVector()
        q, v = x[: self.copies], x[self.copies:]
        if not (np.all(np.isfinite(x)) and self.table.covers(q)):
            raise RuntimeError(f"a copy left the tabulated range [{self.table.lo:.4g}, {self.table.hi:.4g}] rad "
                               f"at t={context.get_time():.6g} s: q = {q}")
        mass, gravity, bias = self.table.dynamics(q)
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([v, (gravity - bias * v**2 + self._applied.Eval(context)) / mass]))
