"""TrunkModel: the plant, its coordinates, the muscles and their path kinematics together."""

from __future__ import annotations

import os
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.multibody.tree import BodyIndex, JacobianWrtVariable, JointIndex

from trunk_drake.model.anthropometry import Passenger, with_passenger
from trunk_drake.model.architecture import with_hill_parameters
from trunk_drake.model.coupled import CoupledPlant
from trunk_drake.model.kinematics import TreeKinematics
from trunk_drake.model.levels import LEVELS
from trunk_drake.model.myotorso import read_myotorso
from trunk_drake.model.osim import load_osim_spec
from trunk_drake.model.osim_kinematics import OsimKinematics
from trunk_drake.model.paths import MusclePaths, PathLayout, PathPoints, PathState
from trunk_drake.model.plant import DOFS, Coordinate, build_plant
from trunk_drake.model.spec import ModelSpec


@dataclass
class TrunkModel:
    """A finalized plant with named coordinates and vectorised muscle path kinematics.

    Build it with `load_model`. `path_state(q, v)` evaluates all 210 muscle paths at once;
    every system and optimiser uses it (the diagram its unchecked form `path_state_from_q`). In the
    ``"rhythm"`` configuration the plant is a `CoupledPlant`: `joint_info` lists the joints it couples
    and `coupling` maps the coordinates onto them (``q_joints = coupling @ q``); otherwise the joints
    are the coordinates and `coupling` is None.
    """

    spec: ModelSpec
    dofs: str
    pelvis_free: bool
    pelvis_mass: float | None
    plant: object
    coordinate_info: list[Coordinate]
    joint_info: list[Coordinate]
    coupling: np.ndarray | None
    _paths: MusclePaths | OsimKinematics = field(repr=False)
    _context: object = field(repr=False)
    _kinematics: TreeKinematics | None = field(default=None, repr=False)  # compiled body kinematics (MyoTorso paths)
    _warned: set = field(default_factory=set, repr=False)

    # ---- names -------------------------------------------------------------------
    @property
    def coordinates(self) -> list[str]:
        """Coordinate names in the order of q (and v)."""
        return [c.name for c in self.coordinate_info]

    @property
    def muscles(self) -> list[str]:
        return self.spec.muscle_names

    @property
    def groups(self) -> dict[str, list[str]]:
        return self.spec.groups()

    @property
    def n_muscles(self) -> int:
        return len(self.spec.muscles)

    @property
    def levels(self) -> list[str]:
        """The intervertebral flexion-extension angles (where bushings act), root to tip."""
        names = [c.name for c in self.joint_info]
        return [f"{lvl}_FE" for lvl in LEVELS if f"{lvl}_FE" in names] or [c.name for c in self.joint_info if c.kind == "hinge"]

    @property
    def level_matrix(self) -> np.ndarray:
        """(n_levels, n_coordinates): level angles = level_matrix @ q; its sum over levels is the lumbar rotation."""
        names = [c.name for c in self.joint_info]
        rows = np.eye(len(names))[[names.index(n) for n in self.levels]]
        return rows if self.coupling is None else rows @ self.coupling

    def posture(self, lumbar_flexion: float) -> np.ndarray:
        """q with the given total lumbar flexion (rad, the sum of the level angles): shared equally by
        independent levels, along the rhythm when coupled (the least-norm q); other coordinates 0."""
        s = self.level_matrix.sum(axis=0)
        return s * (float(lumbar_flexion) / (s @ s))

    @property
    def load_options(self) -> dict:
        """The options of `load_model` that, with `spec`, rebuild this model (worker processes do)."""
        return {"dofs": self.dofs, "pelvis_free": self.pelvis_free, "pelvis_mass": self.pelvis_mass}

    def variant(self, **changes) -> "TrunkModel":
        """The same model rebuilt with other options of `load_model` (`spec` among them)."""
        return load_model(**{"spec": self.spec, **self.load_options, **changes})

    def muscle_array(self, attribute: str) -> np.ndarray:
        """A per-muscle parameter as an array, e.g. ``muscle_array("max_isometric_force")``."""
        return np.array([getattr(m, attribute) for m in self.spec.muscles], dtype=float)

    # ---- kinematics ----------------------------------------------------------------
    def check_q(self, q, name: str = "q", check_range: bool = True) -> np.ndarray:
        """q as a float array; ValueError on wrong length or NaN, a one-time warning out of range."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape != (len(self.coordinate_info),):
            raise ValueError(
                f"{name} has {q.size} values but the {self.dofs!r} model has {len(self.coordinate_info)} "
                f"coordinates: {self.coordinates}"
            )
        bad = [f"{c.name}={v}" for c, v in zip(self.coordinate_info, q) if not np.isfinite(v)]
        if bad:
            raise ValueError(f"{name} contains non-finite values: {', '.join(bad)} (coordinates {self.coordinates})")
        for c, v in zip(self.coordinate_info, q if check_range else ()):
            if c.source_joint is not None and not (c.range[0] <= v <= c.range[1]) and c.name not in self._warned:
                self._warned.add(c.name)
                warnings.warn(
                    f"{c.name}={v:.4g} is outside the joint range [{c.range[0]:.4g}, {c.range[1]:.4g}] "
                    "where the muscle geometry was verified; results there are extrapolated",
                    stacklevel=3,
                )
        return q

    def body_poses(self, context, bodies=None) -> tuple[np.ndarray, np.ndarray]:
        """World rotations (n_bodies, 3, 3) and positions (n_bodies, 3) of the plant's bodies,
        filled for `bodies` (indices; default: those carrying sites, wraps or joint frames)."""
        all_poses = self.plant.get_body_poses_output_port().Eval(context)
        poses = np.zeros((len(all_poses), 3, 4))
        for i in self._pose_bodies if bodies is None else bodies:
            poses[i] = all_poses[i].GetAsMatrix34()
        return poses[:, :, :3], poses[:, :, 3]

    def path_state_from_context(self, context, v=None) -> PathState:
        """Muscle path kinematics for a plant context (body poses read from the plant)."""
        R, p = self.body_poses(context)
        if isinstance(self._paths, OsimKinematics):
            q = self.plant.GetPositions(context)
            state = self._paths.path_state(R, p, self._joint_q(q), self._joint_frames(), None if v is None else self._joint_q(v))
            if self.coupling is not None:
                state.moment_arms = state.moment_arms @ self.coupling
            return state
        axes, origins = self._joint_frames()(R, p)
        return self._joint_paths(R, p, axes, origins, v)

    def _joint_q(self, q) -> np.ndarray:
        """Positions (or velocities) of the plant's joints: q, or ``coupling @ q`` in the rhythm."""
        return np.asarray(q, float) if self.coupling is None else self.coupling @ np.asarray(q, float)

    def _joint_paths(self, R, p, axes, origins, v) -> PathState:
        """MyoTorso path kinematics from the joints' frames, moment arms and velocities in the coordinates
        (through `coupling` in the rhythm: -dL/dq = -(dL/dq_joints) G, v_joints = G v)."""
        if self.coupling is None:
            return self._paths.compute(R, p, axes, origins, v)
        state = self._paths.compute(R, p, axes, origins, None if v is None else self.coupling @ np.asarray(v, float))
        state.moment_arms = state.moment_arms @ self.coupling
        return state

    def _joint_frames(self):
        """Function of body poses (R, p) giving the world axis and a point of every coordinate's joint."""
        def frames(R, p):
            Rj = R[self._joint_body]
            axes = (Rj @ self._joint_axis[:, :, None])[:, :, 0]
            return axes, (Rj @ self._joint_anchor[:, :, None])[:, :, 0] + p[self._joint_body]
        return frames

    # ---- OpenSim models: the file's own coordinates --------------------------------------
    def _osim(self) -> OsimKinematics:
        if not isinstance(self._paths, OsimKinematics):
            raise ValueError(f"model {self.spec.name!r} was not read from an OpenSim file; it has no source coordinates")
        return self._paths

    def source_coordinates(self, q) -> dict[str, float]:
        """The OpenSim model's own coordinates (its names, signs and units: rad, m) at q."""
        values = self._osim().coordinate_values(self._joint_q(self.check_q(q, check_range=False)))
        return dict(zip(self._osim().source.names, map(float, values)))

    def q_from_source(self, values: dict[str, float]) -> np.ndarray:
        """Plant positions q from the OpenSim model's coordinate values (missing ones: defaults)."""
        osim = self._osim()
        q = np.zeros(len(self.coordinate_info))
        for k, c in enumerate(self.coordinate_info):
            if c.source_joint is None:
                q[k] = values.get(c.name, 0.0)
                continue
            joint = self.spec.joint(c.source_joint)
            value = values.get(joint.coordinate, osim.source.default[osim.source.index[joint.coordinate]])
            q[k] = c.sign * float(joint.function.value(value))
        return q

    def source_moment_arms(self, q) -> dict[str, np.ndarray]:
        """Moment arms (n_muscles,) about each plant coordinate's OpenSim coordinate (m or m/rad of it)."""
        q = self.check_q(q)
        values = self.source_coordinates(q)
        arms = self.moment_arms(q)
        out = {}
        for k, c in enumerate(self.coordinate_info):
            if c.source_joint is not None:
                joint = self.spec.joint(c.source_joint)
                out[joint.coordinate] = arms[:, k] * c.sign * float(joint.function.derivative(values[joint.coordinate]))
        return out

    def path_state(self, q, v=None) -> PathState:
        """Lengths (m), moment arms (m or m/rad, = -dL/dq) and, with v, lengthening velocities."""
        q = self.check_q(q)
        if v is not None:
            v = self.check_q(v, "v", check_range=False)
        return self.path_state_from_q(q, v)

    def path_state_from_q(self, q, v=None) -> PathState:
        """`path_state` without input checks (the per-step path: q and v float arrays of the right size);
        compiled body kinematics where the model has them, else the plant's poses."""
        if self._kinematics is not None:
            R, p, axes, origins = self._kinematics.frames(self._joint_q(q))
            return self._joint_paths(R, p, axes, origins, v)
        self.plant.SetPositions(self._context, q)
        return self.path_state_from_context(self._context, v)

    def mass_weighted_com_jacobian(self, q, direction) -> np.ndarray:
        """``M J_com^T d`` at q (unchecked): the generalized force of a unit acceleration field along
        world direction d, negated."""
        if self._kinematics is not None:
            if self.coupling is None:
                return self._kinematics.mass_weighted_com_jacobian(q, direction)
            return self.coupling.T @ self._kinematics.mass_weighted_com_jacobian(self.coupling @ q, direction)
        plant, world = self.plant, self.plant.world_frame()
        plant.SetPositions(self._context, q)
        J = plant.CalcJacobianCenterOfMassTranslationalVelocity(self._context, JacobianWrtVariable.kV, world, world)
        return plant.CalcTotalMass(self._context) * (J.T @ np.asarray(direction, dtype=float))

    def path_points(self, q) -> PathPoints:
        """World points of all muscle paths (sites, wrap tangent points) at q, for drawing;
        `path_layout` tells which belong to which muscle. No joint-range warning: drawing only."""
        self._mujoco_paths()
        self.plant.SetPositions(self._context, self.check_q(q, check_range=False))
        return self._paths.points(*self.body_poses(self._context))

    @property
    def path_layout(self) -> PathLayout:
        return self._mujoco_paths().layout

    def _mujoco_paths(self) -> MusclePaths:
        if isinstance(self._paths, OsimKinematics):
            raise ValueError(f"model {self.spec.name!r} has OpenSim muscle paths: drawing them (path points) is only "
                             "implemented for MyoTorso's paths; use the default model")
        return self._paths

    @property
    def body_names(self) -> list[str]:
        """Names of the plant's bodies in body-index order (the order of `body_poses`)."""
        return [self.plant.get_body(BodyIndex(i)).name() for i in range(self.plant.num_bodies())]

    def center_of_mass(self, q) -> np.ndarray:
        """Whole-model centre of mass in the world at q (follower bodies at their true poses), m.

        Equals the plant's own unless an OpenSim model has follower bodies with mass (see
        trunk_drake.model.osim_config): the plant holds those at their q = 0 displacement.
        """
        q = self.check_q(q, check_range=False)
        self.plant.SetPositions(self._context, q)
        all_poses = self.plant.get_body_poses_output_port().Eval(self._context)
        poses = np.array([X.GetAsMatrix34() for X in all_poses])
        R, p = poses[:, :, :3], poses[:, :, 3]
        if isinstance(self._paths, OsimKinematics):
            R, p = self._paths.repose(R, p, self._joint_q(q))
        index = [int(self.plant.GetBodyByName(b.name).index()) for b in self.spec.bodies]
        mass = np.array([b.mass for b in self.spec.bodies])
        points = np.array([R[i] @ b.com + p[i] for i, b in zip(index, self.spec.bodies)])
        return mass @ points / mass.sum()

    def muscle_lengths(self, q) -> np.ndarray:
        """Musculotendon lengths (n_muscles,), m."""
        return self.path_state(q).lengths

    def moment_arms(self, q) -> np.ndarray:
        """Moment-arm matrix (n_muscles, n_coordinates) = -dL/dq."""
        return self.path_state(q).moment_arms

    def muscle_velocities(self, q, v) -> np.ndarray:
        """Musculotendon lengthening velocities (n_muscles,), m/s."""
        return self.path_state(q, v).velocities

    # ---- set-up --------------------------------------------------------------------
    def _init_joints(self, plant):
        """Per joint of `plant` (the MultibodyPlant): the body carrying its child frame, axis and anchor in that body."""
        body, axis, anchor = [], [], []
        for c in self.joint_info:
            joint = plant.GetJointByName(c.name)
            frame = joint.frame_on_child()
            X_BM = frame.GetFixedPoseInBodyFrame()
            axis_M = joint.revolute_axis() if c.kind == "hinge" else joint.translation_axis()
            body.append(int(frame.body().index()))
            axis.append(X_BM.rotation().matrix() @ np.asarray(axis_M))
            anchor.append(X_BM.translation())
        self._joint_body = np.array(body, dtype=int)
        self._pose_bodies = sorted(set(body) | self._paths.bodies_used())
        self._joint_axis = np.array(axis, dtype=float).reshape(-1, 3)
        self._joint_anchor = np.array(anchor, dtype=float).reshape(-1, 3)


def _build(spec: ModelSpec, dofs: str, pelvis_mass: float | None, pelvis_free: bool) -> TrunkModel:
    plant, coords = build_plant(spec, dofs, pelvis_mass=pelvis_mass, pelvis_free=pelvis_free)
    coupled = isinstance(plant, CoupledPlant)
    bodies, joints = (plant.full, plant.joints) if coupled else (plant, coords)
    n_bodies = bodies.num_bodies()
    moves = np.zeros((n_bodies, len(joints)))
    for k, c in enumerate(joints):
        joint = bodies.GetJointByName(c.name)
        for b in bodies.GetBodiesKinematicallyAffectedBy([JointIndex(int(joint.index()))]):
            moves[int(b), k] = 1.0
    names = [bodies.get_body(BodyIndex(i)).name() for i in range(n_bodies)]
    kinematics = None
    if spec.path_semantics == "opensim":
        paths = OsimKinematics(spec, joints, names, moves)
    else:
        paths = MusclePaths(spec, names, [c.kind for c in joints], moves)
        kinematics = TreeKinematics(bodies, [c.name for c in joints])
    model = TrunkModel(spec=spec, dofs=dofs, pelvis_free=pelvis_free, pelvis_mass=pelvis_mass, plant=plant, coordinate_info=coords,
                       joint_info=joints, coupling=plant.coupling if coupled else None, _paths=paths,
                       _context=plant.CreateDefaultContext(), _kinematics=kinematics)
    model._init_joints(bodies)
    return model


MODEL_ENV = "TRUNK_DRAKE_MODEL"  # an .osim path: the model `load_model()` loads when none is given


@contextmanager
def model_source(path: str | Path | None):
    """Within the block, `load_model()` without a model loads `path` (worker processes inherit it)."""
    if path is None:
        yield
        return
    previous = os.environ.get(MODEL_ENV)
    os.environ[MODEL_ENV] = str(path)
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(MODEL_ENV, None)
        else:
            os.environ[MODEL_ENV] = previous


def load_model(model: str | Path | None = None, dofs: str | None = None, spec: ModelSpec | None = None,
               pelvis_mass: float | None = None, pelvis_free: bool = True, passenger: Passenger | None = None) -> TrunkModel:
    """A trunk model in configuration `dofs` ("sagittal", "spine3d", "rhythm" or "all"; default "sagittal").

    `model`: None or "myotorso" for the default MyoTorso model (None: $TRUNK_DRAKE_MODEL if set,
    see `model_source`), or the path of an OpenSim ``.osim`` file (read by
    `trunk_drake.model.osim`, mapped with its file in ``models/osim/``);
    a configuration name in its place is read as `dofs` (``load_model("spine3d")``). Hill
    fiber and tendon lengths are derived from the neutral-posture musculotendon lengths by
    Christophy et al.'s method unless the spec carries them (OpenSim files do).
    `pelvis_mass` replaces the pelvis' mass; ``pelvis_free=False`` welds the sagittal pelvis
    (no ``pelvis_tx``). `passenger` adds the arms and the rest of the head to the thorax
    (model/anthropometry.py).
    """
    if model is not None and str(model) in DOFS:
        if dofs is not None:
            raise ValueError(f"load_model got configuration {model!r} and dofs={dofs!r}; give one")
        model, dofs = None, str(model)
    dofs = dofs or "sagittal"
    if dofs not in DOFS:
        raise ValueError(f"unknown configuration dofs={dofs!r}; expected one of {DOFS}")
    if spec is None:
        model = model if model is not None else os.environ.get(MODEL_ENV)
        spec = read_myotorso() if model is None or str(model).lower() == "myotorso" else load_osim_spec(model)
    if any(np.isnan(m.optimal_fiber_length) for m in spec.muscles):
        geometric = _build(spec, "spine3d", None, False)
        neutral = geometric.path_state(np.zeros(len(geometric.coordinate_info))).lengths
        spec = with_hill_parameters(spec, neutral)
    if passenger is not None:
        spec = with_passenger(spec, passenger)
    return _build(spec, dofs, pelvis_mass, pelvis_free)
