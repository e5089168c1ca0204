"""MuscleSystem: all muscles of the model as Thelen 2003 Hill units, vectorised."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem

from trunk_drake.model.paths import PathState
from trunk_drake.muscle import thelen
from trunk_drake.muscle.short_range import ShortRangeStiffness
from trunk_drake.muscle.thelen import MuscleParameters, ThelenConstants
from trunk_drake.systems.memo import declare_memo
from trunk_drake.systems.weak import weak

TENDON_MODES = ("rigid", "compliant")


def muscle_parameters(model, strength_scale: float = 1.0) -> MuscleParameters:
    """The model's Hill parameters as a thelen.MuscleParameters (forces scaled by `strength_scale`)."""
    return MuscleParameters(
        max_isometric_force=model.muscle_array("max_isometric_force") * strength_scale,
        optimal_fiber_length=model.muscle_array("optimal_fiber_length"),
        tendon_slack_length=model.muscle_array("tendon_slack_length"),
        pennation_angle_at_optimal=model.muscle_array("pennation_angle"),
    )


def empty_path_state(model, copies: int = 1) -> PathState:
    n, nv = model.n_muscles * copies, model.plant.num_velocities() * copies
    return PathState(np.zeros(n), np.zeros((n, nv)), np.zeros(n))


class MuscleSystem(LeafSystem):
    """Activation dynamics and Hill force of every muscle, vectorised over muscles.

    Inputs: ``excitation`` (n_muscles), ``path_state`` (abstract PathState).
    State: activations; with ``tendon="compliant"`` also fiber lengths (as OpenSim's
    Thelen2003Muscle). Outputs: ``muscle_state`` (abstract thelen.MuscleState, computed
    once per context), ``activation``, ``tendon_force`` (N), ``normalized_fiber_length``,
    ``normalized_fiber_velocity``, ``fiber_length`` (m), ``generalized_force``
    (moment arms^T tendon force, one entry per plant velocity). An optional 0/1 `mask`
    switches muscles off (their tendon force is zeroed), for studies that add groups one by one.
    With `srs` (rigid tendons) the short-range stiffness force is added along every fiber and the
    reference normalised fiber lengths it acts about are further states (muscle.short_range).
    With `copies` > 1 it holds the muscles of that many copies of the model in turn (`params` per muscle of
    all of them), and the path state has their coordinates (`MusclePathSystem` with copies); `time_scale`
    (one per muscle, or None) multiplies the activation time constants where copies differ in them.
    """

    def __init__(self, model, constants: ThelenConstants | None = None, tendon: str = "rigid",
                 params: MuscleParameters | None = None, mask=None, srs: ShortRangeStiffness | None = None,
                 copies: int = 1, time_scale=None):
        super().__init__()
        if tendon not in TENDON_MODES:
            raise ValueError(f"tendon={tendon!r}; expected one of {TENDON_MODES}")
        if srs is not None and tendon != "rigid":
            raise ValueError("short-range stiffness is implemented for rigid tendons only; use tendon='rigid' or srs=None")
        self.srs = srs
        self.constants = constants or ThelenConstants()
        self.params = params or muscle_parameters(model)
        self.tendon = tendon
        self.n = n = model.n_muscles * copies
        self.time_scale = None if time_scale is None else np.broadcast_to(np.asarray(time_scale, float), (n,)).copy()
        nv = model.plant.num_velocities() * copies
        self.mask = None if mask is None else np.asarray(mask, dtype=float)
        if self.mask is not None and self.mask.shape != (n,):
            raise ValueError(f"muscle mask must have {n} entries, got shape {self.mask.shape}")
        x0 = np.full(n, self.constants.minimum_activation)
        if tendon == "compliant":
            x0 = np.concatenate([x0, self.params.optimal_fiber_length])
        if srs is not None:
            x0 = np.concatenate([x0, np.ones(n)])  # placed at the fiber lengths by steady_state()
        self.DeclareContinuousState(len(x0))
        self._x0 = x0
        self._u = self.DeclareVectorInputPort("excitation", n)
        self._path = self.DeclareAbstractInputPort("path_state", AbstractValue.Make(empty_path_state(model, copies)))
        self._kin = declare_memo(self, "rigid-tendon fiber kinematics", self._eval_path,  # the path object: by identity
                                 self._rigid_kinematics, {self._path.ticket()})
        state_and_path = {self.all_state_ticket(), self._path.ticket()}
        template = thelen.rigid_tendon(self._x0[:n], self.params.tendon_slack_length + self.params.optimal_fiber_length, 0.0, self.params, self.constants)
        self._state_port = self.DeclareAbstractOutputPort(
            "muscle_state", lambda: AbstractValue.Make(template), weak(self._calc_state), prerequisites_of_calc=state_and_path
        )
        self.DeclareVectorOutputPort(
            "activation", n, lambda c, o: o.SetFromVector(c.get_continuous_state_vector().CopyToVector()[:n]),  # no self
            prerequisites_of_calc={self.all_state_ticket()},
        )
        self.DeclareVectorOutputPort("tendon_force", n, weak(self._calc_tendon_force), prerequisites_of_calc=state_and_path)
        for name in ("normalized_fiber_length", "normalized_fiber_velocity", "fiber_length"):
            self.DeclareVectorOutputPort(name, n, self._field(name), prerequisites_of_calc=state_and_path)
        self.DeclareVectorOutputPort("generalized_force", nv, weak(self._calc_generalized_force), prerequisites_of_calc=state_and_path)

    @property
    def default_state(self) -> np.ndarray:
        """Initial state: minimum activation (and optimal fiber lengths for compliant tendons)."""
        return self._x0.copy()

    def steady_state(self, activation, path) -> np.ndarray:
        """State at rest at `path` with `activation`: compliant fibers in force equilibrium with
        their tendons, SRS reference lengths at the fiber lengths."""
        x = self.default_state
        n = self.n
        x[:n] = activation
        if self.tendon == "compliant":
            x[n:2 * n] = thelen.equilibrium_fiber_length(activation, path.lengths, self.params, self.constants).fiber_length
        if self.srs is not None:
            x[-n:] = thelen.rigid_kinematics(path.lengths, path.velocities, self.params, self.constants).normalized_fiber_length
        return x

    def SetDefaultState(self, context, state):  # noqa: N802 (Drake API)
        state.get_mutable_continuous_state().SetFromVector(self._x0)

    def muscle_state(self, context) -> thelen.MuscleState:
        return self._state_port.Eval(context)

    def _tendon_force(self, context) -> np.ndarray:
        if self.tendon == "compliant":
            return self.muscle_state(context).tendon_force
        x = context.get_continuous_state_vector().CopyToVector()
        kin = self._kin.Eval(context)
        force = thelen.rigid_tendon_force(x[: self.n], kin, self.params, self.constants) + self._srs_force(x, kin)
        return force if self.mask is None else force * self.mask

    def _srs_force(self, x, kin: thelen.RigidKinematics):
        """Short-range stiffness force along the tendon (N), 0 without SRS or at a clamped fiber."""
        if self.srs is None:
            return 0.0
        a = thelen.clamp_activation(x[: self.n], self.constants)
        force = self.srs.fiber_force(a, kin.active_force_length, self.params.max_isometric_force,
                                     kin.normalized_fiber_length - x[-self.n:])
        return np.where(kin.clamped, 0.0, force * kin.cos_pennation)

    def _calc_state(self, context, output):
        x = context.get_continuous_state_vector().CopyToVector()
        path = self._path.Eval(context)
        if self.tendon == "rigid":
            kin = self._kin.Eval(context)
            value = thelen.rigid_tendon(x[: self.n], path.lengths, path.velocities, self.params, self.constants, kin)
            value.tendon_force = value.tendon_force + self._srs_force(x, kin)
        else:
            value = thelen.compliant_tendon(x[: self.n], x[self.n :], path.lengths, self.params, self.constants)
        if self.mask is not None:
            value.tendon_force = value.tendon_force * self.mask
        output.set_value(value)

    def _field(self, name):
        """Fiber kinematics: from the path alone with rigid tendons, else from the full state."""
        source = weak(self._rigid_fiber if self.tendon == "rigid" and name != "fiber_length" else self.muscle_state)
        return lambda c, o: o.SetFromVector(getattr(source(c), name))

    def _eval_path(self, context):
        return self._path.Eval(context)

    def _rigid_kinematics(self, context, path):
        return thelen.rigid_kinematics(path.lengths, path.velocities, self.params, self.constants)

    def _rigid_fiber(self, context):
        return self._kin.Eval(context)

    def _calc_tendon_force(self, context, output):
        output.SetFromVector(self._tendon_force(context))

    def _calc_generalized_force(self, context, output):
        output.SetFromVector(self._path.Eval(context).moment_arms.T @ self._tendon_force(context))

    def DoCalcTimeDerivatives(self, context, derivatives):  # noqa: N802 (Drake API)
        x = context.get_continuous_state_vector().CopyToVector()
        da = thelen.activation_derivative(self._u.Eval(context), x[: self.n], self.constants, self.time_scale)
        if self.tendon == "compliant":
            da = np.concatenate([da, self.muscle_state(context).fiber_velocity])
        if self.srs is not None:
            ln = self._kin.Eval(context).normalized_fiber_length
            da = np.concatenate([da, self.srs.reference_rate(ln, x[-self.n:])])
        derivatives.get_mutable_vector().SetFromVector(da)
