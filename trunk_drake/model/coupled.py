"""CoupledPlant: a MultibodyPlant whose joints follow fewer independent coordinates, as one Drake system.

A lumbar rhythm moves five intervertebral joints (and a wrapping body) in fixed proportion to one
coordinate. Drake's continuous-time MultibodyPlant does not support constraints (its coupler
constraint needs a discrete SAP plant), so the coupled chain is simulated in its independent
coordinates q: the joints of the full plant follow ``q_full = G q`` with a constant coupling matrix
G, hence ``v_full = G v`` and, the couplings being ideal (workless) constraints, the equations of
motion are those of the constrained system projected on its free motions:

    G^T M(G q) G vdot = G^T (tau_g(G q) - C(G q, G v)) + tau_applied

`tau_applied` (the input port) is already a generalized force on q: muscles give moment arms
``-dL/dq = -(dL/dq_full) G``; bushings and external loads give ``G^T`` of their joint-space forces.

The class offers the part of MultibodyPlant's interface the package uses (ports, positions,
mass matrix, bias and gravity terms, Jacobians, body poses, energies), each in the coupled
coordinates; ``full_context(context)`` gives the full plant's context for anything else.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem
from trunk_drake.systems.weak import weak


class CoupledPlant(LeafSystem):
    """The multibody system of `plant` (finalized, continuous) restricted to ``q_full = coupling @ q``.

    `coordinates`: names of the independent coordinates (columns of `coupling`); `joints`: the
    caller's descriptions of the full plant's coordinates (rows of `coupling`), kept for it.
    """

    def __init__(self, plant, coupling, coordinates, joints=()):
        super().__init__()
        G = np.asarray(coupling, dtype=float)
        if G.ndim != 2 or G.shape[0] != plant.num_positions() or plant.num_positions() != plant.num_velocities():
            raise ValueError(f"coupling of shape {G.shape} does not fit a plant with {plant.num_positions()} positions "
                             f"and {plant.num_velocities()} velocities (needs one column per independent coordinate)")
        if len(coordinates) != G.shape[1]:
            raise ValueError(f"{len(coordinates)} coordinate names for {G.shape[1]} coupling columns")
        self.full = plant
        self.coupling = G
        self.coordinate_names = list(coordinates)
        self.joints = list(joints)
        self._n = G.shape[1]
        self._scratch = plant.CreateDefaultContext()
        self._synced = None  # the state last written into the scratch context
        self._free_motion = None  # (state, M^-1, M^-1 (tau_g - C)) at the last state: implicit integrators
        #                         perturb the other systems' states many times at one plant state
        self._table = None  # a CoordinateTable (one coordinate): M, g and c from it inside its grid
        self.DeclareContinuousState(self._n, self._n, 0)
        self._applied = self.DeclareVectorInputPort("applied_generalized_force", self._n)
        self._state = self.DeclareVectorOutputPort("state", 2 * self._n, weak(self._copy_state),
                                                   prerequisites_of_calc={self.xc_ticket()})
        n_bodies = plant.num_bodies()
        self._poses = self.DeclareAbstractOutputPort(
            "body_poses", lambda: AbstractValue.Make([RigidTransform()] * n_bodies), weak(self._calc_poses),
            prerequisites_of_calc={self.xc_ticket()})
        self.set_name("coupled_plant")

    # ---- ports --------------------------------------------------------------------
    def get_state_output_port(self):
        return self._state

    def get_applied_generalized_force_input_port(self):
        return self._applied

    def get_body_poses_output_port(self):
        return self._poses

    # ---- state ----------------------------------------------------------------------
    def num_positions(self) -> int:
        return self._n

    def num_velocities(self) -> int:
        return self._n

    def num_bodies(self) -> int:
        return self.full.num_bodies()

    def _state_vector(self, context):
        return context.get_continuous_state_vector()

    def SetPositions(self, context, q) -> None:
        x = context.get_mutable_continuous_state_vector()
        x.SetFromVector(np.concatenate([np.asarray(q, float), x.CopyToVector()[self._n:]]))

    def SetVelocities(self, context, v) -> None:
        x = context.get_mutable_continuous_state_vector()
        x.SetFromVector(np.concatenate([x.CopyToVector()[: self._n], np.asarray(v, float)]))

    def SetPositionsAndVelocities(self, context, x) -> None:
        context.get_mutable_continuous_state_vector().SetFromVector(np.asarray(x, float))

    def GetPositions(self, context) -> np.ndarray:
        return self._state_vector(context).CopyToVector()[: self._n]

    def GetVelocities(self, context) -> np.ndarray:
        return self._state_vector(context).CopyToVector()[self._n:]

    def full_context(self, context):
        """The full plant's context at this state (a shared scratch context: use it at once)."""
        return self._scratch_at(self._state_vector(context).CopyToVector())

    def _scratch_at(self, x):
        """The scratch context of the full plant at coupled state x."""
        if self._synced is None or not np.array_equal(x, self._synced):
            G = self.coupling
            self.full.SetPositionsAndVelocities(self._scratch, np.concatenate([G @ x[: self._n], G @ x[self._n:]]))
            self._synced = x
        return self._scratch

    def use_table(self, table) -> None:
        """Take M, gravity and the bias term from `table` (a `model.tables.CoordinateTable` of this plant: its one
        coordinate, or the pelvis slide and it) where it covers q; None: always from the full plant."""
        self._table = table
        self._free_motion = None

    # ---- dynamics in the coupled coordinates ------------------------------------------
    def CalcMassMatrix(self, context) -> np.ndarray:
        return self._mass(self.full_context(context))

    def _mass(self, scratch) -> np.ndarray:
        return self.coupling.T @ self.full.CalcMassMatrix(scratch) @ self.coupling

    def CalcBiasTerm(self, context) -> np.ndarray:
        return self.coupling.T @ self.full.CalcBiasTerm(self.full_context(context))

    def CalcGravityGeneralizedForces(self, context) -> np.ndarray:
        return self.coupling.T @ self.full.CalcGravityGeneralizedForces(self.full_context(context))

    def CalcJacobianTranslationalVelocity(self, context, with_respect_to, frame_B, p_BoBi_B, frame_A, frame_E) -> np.ndarray:
        J = self.full.CalcJacobianTranslationalVelocity(self.full_context(context), with_respect_to, frame_B, p_BoBi_B,
                                                        frame_A, frame_E)
        return J @ self.coupling

    def CalcJacobianCenterOfMassTranslationalVelocity(self, context, with_respect_to, frame_A, frame_E) -> np.ndarray:
        J = self.full.CalcJacobianCenterOfMassTranslationalVelocity(self.full_context(context), with_respect_to, frame_A, frame_E)
        return J @ self.coupling

    def DoCalcTimeDerivatives(self, context, derivatives):
        x = self._state_vector(context).CopyToVector()
        table = self._table
        if table is not None and table.slide is not None and table.covers(x[1]):  # the rhythm on the pelvis slide
            applied = self._applied.Eval(context) if self._applied.HasValue(context) else np.zeros(2)
            derivatives.get_mutable_vector().SetFromVector(np.concatenate([x[2:], table.accelerations(x[:2], x[2:], applied)]))
            return
        if table is not None and table.slide is None and table.covers(x[0]):
            mass, gravity, bias = table.dynamics(x[0])
            applied = self._applied.Eval(context)[0] if self._applied.HasValue(context) else 0.0
            vdot = (gravity - bias * x[1] ** 2 + applied) / mass
            derivatives.get_mutable_vector().SetFromVector([x[1], vdot])
            return
        if self._free_motion is None or not np.array_equal(x, self._free_motion[0]):
            scratch = self._scratch_at(x)  # the state read once, for all three terms
            mass = self._mass(scratch)
            m_inv = 1.0 / mass if self._n == 1 else np.linalg.inv(mass)  # one coordinate (the rhythm): no LAPACK call
            free = m_inv @ (self.coupling.T @ (self.full.CalcGravityGeneralizedForces(scratch) - self.full.CalcBiasTerm(scratch)))
            self._free_motion = (x, m_inv, free)
        _, m_inv, free = self._free_motion
        vdot = free + m_inv @ self._applied.Eval(context) if self._applied.HasValue(context) else free
        derivatives.get_mutable_vector().SetFromVector(np.concatenate([x[self._n:], vdot]))

    # ---- kinematics and energies (full plant at this state) ----------------------------
    def EvalBodyPoseInWorld(self, context, body):
        return self.full.EvalBodyPoseInWorld(self.full_context(context), body)

    def CalcCenterOfMassPositionInWorld(self, context):
        return self.full.CalcCenterOfMassPositionInWorld(self.full_context(context))

    def CalcTotalMass(self, context) -> float:
        return self.full.CalcTotalMass(self.full_context(context))

    def CalcKineticEnergy(self, context) -> float:
        return self.full.CalcKineticEnergy(self.full_context(context))

    def CalcPotentialEnergy(self, context) -> float:
        return self.full.CalcPotentialEnergy(self.full_context(context))

    # ---- structure (no context) ------------------------------------------------------
    def GetBodyByName(self, name):
        return self.full.GetBodyByName(name)

    def get_body(self, index):
        return self.full.get_body(index)

    def world_frame(self):
        return self.full.world_frame()

    def world_body(self):
        return self.full.world_body()

    def gravity_field(self):
        return self.full.gravity_field()

    def _copy_state(self, context, output):
        output.SetFromVector(self._state_vector(context).CopyToVector())

    def _calc_poses(self, context, value):
        poses = self.full.get_body_poses_output_port().Eval(self.full_context(context))
        value.set_value(list(poses))
