"""TrunkModel: the plant, its coordinates, the muscles and their path kinematics together."""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from pydrake.multibody.tree import BodyIndex, JointIndex

from trunk_drake.model.anthropometry import Passenger, with_passenger
from trunk_drake.model.architecture import with_hill_parameters
from trunk_drake.model.myotorso import read_myotorso
from trunk_drake.model.paths import MusclePaths, PathState
from trunk_drake.model.plant import DOFS, Coordinate, build_plant
from trunk_drake.model.spec import ModelSpec


@dataclass
class TrunkModel:
    """A finalized plant with named coordinates and vectorised muscle path kinematics.

    Build it with `load_model`. `path_state(q, v)` evaluates all 210 muscle paths at once;
    every system and optimiser uses it (or `path_state_from_context`).
    """

    spec: ModelSpec
    dofs: str
    pelvis_free: bool
    pelvis_mass: float | None
    plant: object
    coordinate_info: list[Coordinate]
    _paths: MusclePaths = field(repr=False)
    _context: object = field(repr=False)
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

    def variant(self, **changes) -> "TrunkModel":
        """The same model (same spec) rebuilt with other options of `load_model`."""
        options = {"spec": self.spec, "dofs": self.dofs, "pelvis_free": self.pelvis_free, "pelvis_mass": self.pelvis_mass}
        options.update(changes)
        return load_model(**options)

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

    def path_state_from_context(self, context, v=None) -> PathState:
        """Muscle path kinematics for a plant context (body poses read from the plant)."""
        plant = self.plant
        all_poses = plant.get_body_poses_output_port().Eval(context)
        poses = np.zeros((len(all_poses), 3, 4))
        for i in self._pose_bodies:  # only bodies that carry sites, wraps or joint frames
            poses[i] = all_poses[i].GetAsMatrix34()
        R, p = poses[:, :, :3], poses[:, :, 3]
        Rj = R[self._joint_body]
        axes = (Rj @ self._joint_axis[:, :, None])[:, :, 0]
        origins = (Rj @ self._joint_anchor[:, :, None])[:, :, 0] + p[self._joint_body]
        return self._paths.compute(R, p, axes, origins, v)

    def path_state(self, q, v=None) -> PathState:
        """Lengths (m), moment arms (m or m/rad, = -dL/dq) and, with v, lengthening velocities."""
        q = self.check_q(q)
        self.plant.SetPositions(self._context, q)
        if v is not None:
            v = self.check_q(v, "v", check_range=False)
        return self.path_state_from_context(self._context, v)

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
    def _init_joints(self):
        """Per coordinate: the body carrying its child frame, axis and anchor in that body."""
        body, axis, anchor = [], [], []
        for c in self.coordinate_info:
            joint = self.plant.GetJointByName(c.name)
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
    n_bodies = plant.num_bodies()
    moves = np.zeros((n_bodies, len(coords)))
    for k, c in enumerate(coords):
        joint = plant.GetJointByName(c.name)
        for b in plant.GetBodiesKinematicallyAffectedBy([JointIndex(int(joint.index()))]):
            moves[int(b), k] = 1.0
    names = [plant.get_body(_body_index(i)).name() for i in range(n_bodies)]
    paths = MusclePaths(spec, names, [c.kind for c in coords], moves)
    model = TrunkModel(spec=spec, dofs=dofs, pelvis_free=pelvis_free, pelvis_mass=pelvis_mass, plant=plant, coordinate_info=coords, _paths=paths, _context=plant.CreateDefaultContext())
    model._init_joints()
    return model


def _body_index(i: int) -> BodyIndex:
    return BodyIndex(i)


def load_model(dofs: str = "sagittal", spec: ModelSpec | None = None, pelvis_mass: float | None = None,
               pelvis_free: bool = True, passenger: Passenger | None = None) -> TrunkModel:
    """The default MyoTorso trunk model in configuration `dofs` ("sagittal" or "spine3d").

    Hill fiber and tendon lengths are derived from the neutral-posture musculotendon lengths
    by Christophy et al.'s method unless `spec` already carries them. `pelvis_mass` replaces
    the sacrum's mass; ``pelvis_free=False`` welds the sagittal pelvis (no ``pelvis_tx``).
    `passenger` adds the arms and the rest of the head to the thorax (model/anthropometry.py).
    """
    if dofs not in DOFS:
        raise ValueError(f"unknown configuration dofs={dofs!r}; expected one of {DOFS}")
    spec = spec or read_myotorso()
    if any(np.isnan(m.optimal_fiber_length) for m in spec.muscles):
        geometric = _build(spec, "spine3d", None, False)
        neutral = geometric.path_state(np.zeros(len(geometric.coordinate_info))).lengths
        spec = with_hill_parameters(spec, neutral)
    if passenger is not None:
        spec = with_passenger(spec, passenger)
    return _build(spec, dofs, pelvis_mass, pelvis_free)
