"""Build a Drake MultibodyPlant from a ModelSpec in one of two joint configurations.

``"sagittal"`` (dynamic analysis, thesis section 3.3.2): the sacrum slides on a prismatic
anterior-posterior joint ``pelvis_tx`` and the five lumbar levels are independent revolute
flexion-extension joints ``L5_S1_FE`` ... ``L1_L2_FE``; lateral bending and axial rotation
are welded at zero.

``"spine3d"`` (static analysis): the pelvis is welded to the ground and every lumbar level
has flexion-extension (``*_FE``), lateral bending (``*_LB``) and axial rotation (``*_AR``).

``"all"``: every joint of the spec with its own name and sign (for user and test models).

Sign conventions (MyoTorso keeps the OpenSim lumbar-model axes in every body: x anterior,
y superior, z right):

* ``*_FE`` is positive in flexion. MyoTorso's ``flex_extension`` (the L5-S1 joint) and
  ``L?_L?_FE`` rotate about +z, which is extension, so ``*_FE = -MyoTorso angle``.
* ``*_LB`` = MyoTorso angle about +x (anterior): positive tilts the trunk to the right.
* ``*_AR`` = MyoTorso angle about +y (superior): positive turns the trunk to the left.
* ``pelvis_tx`` is positive anteriorly (sacrum x axis), metres.

MyoTorso's coupling constraints (all lumbar levels driven by ``flex_extension`` etc.) are
removed. MyoTorso's ``Abdomen`` routing body is already a child of ``lumbar5`` but was
coupled to ``flex_extension`` (``Abs_r3 = 0.6429 * flex_extension``) with locked
translations; with the couplings removed it is welded to ``lumbar5`` at zero, so it moves
rigidly with L5 during lumbar bending: the equivalent of the thesis' re-parenting of the
abdominal wrap surface from the sacrum to L5 (seed section 3.3.2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    PrismaticJoint,
    RevoluteJoint,
    RotationalInertia,
    SpatialInertia,
)
from pydrake.common.eigen_geometry import Quaternion

from trunk_drake.model.levels import LEVELS
from trunk_drake.model.spec import ModelSpec

# MyoTorso joint names per level: (flexion-extension, lateral bending, axial rotation)
_MYOTORSO_LEVEL_JOINTS = {
    "L5_S1": ("flex_extension", "lat_bending", "axial_rotation"),
    "L4_L5": ("L4_L5_FE", "L4_L5_LB", "L4_L5_AR"),
    "L3_L4": ("L3_L4_FE", "L3_L4_LB", "L3_L4_AR"),
    "L2_L3": ("L2_L3_FE", "L2_L3_LB", "L2_L3_AR"),
    "L1_L2": ("L1_L2_FE", "L1_L2_LB", "L1_L2_AR"),
}
PELVIS_BODY = "sacrum"
PELVIS_AXIS = np.array([1.0, 0.0, 0.0])  # anterior, in the sacrum frame
DOFS = ("sagittal", "spine3d", "all")  # "all": every joint of the spec, as defined there


@dataclass(frozen=True)
class Coordinate:
    """A generalized coordinate of the plant and the source-model joint it stands for."""

    name: str
    body: str  # child body it moves
    kind: str  # "hinge" or "slide"
    axis: np.ndarray  # unit axis in the child body frame, sign already applied
    source_joint: str | None  # MyoTorso joint name (None for pelvis_tx)
    sign: float  # our value = sign * source joint value
    range: tuple[float, float]  # in our sign convention


def coordinates_for(spec: ModelSpec, dofs: str, pelvis_free: bool = True) -> list[Coordinate]:
    """The free coordinates of a configuration, in kinematic order (root to tip)."""
    if dofs not in DOFS:
        raise ValueError(f"unknown configuration dofs={dofs!r}; expected one of {DOFS}")
    if dofs == "all":
        return [Coordinate(j.name, j.body, j.kind, np.asarray(j.axis, float), j.name, 1.0, j.range) for j in spec.joints]
    coords: list[Coordinate] = []
    if dofs == "sagittal" and pelvis_free:
        coords.append(Coordinate("pelvis_tx", PELVIS_BODY, "slide", PELVIS_AXIS.copy(), None, 1.0, (-1.0, 1.0)))
    suffixes = ("FE",) if dofs == "sagittal" else ("FE", "LB", "AR")
    for level in LEVELS:
        for suffix, source in zip(("FE", "LB", "AR"), _MYOTORSO_LEVEL_JOINTS[level]):
            if suffix not in suffixes:
                continue
            j = spec.joint(source)
            sign = -1.0 if suffix == "FE" else 1.0
            lo, hi = sorted((sign * j.range[0], sign * j.range[1]))
            coords.append(Coordinate(f"{level}_{suffix}", j.body, j.kind, sign * j.axis, source, sign, (lo, hi)))
    return coords


def _transform(pos, quat) -> RigidTransform:
    q = np.asarray(quat, dtype=float)
    return RigidTransform(RotationMatrix(Quaternion(q / np.linalg.norm(q))), np.asarray(pos, dtype=float))


def _spatial_inertia(body) -> SpatialInertia:
    if body.mass <= 0.0:
        return SpatialInertia.Zero()
    i = body.inertia
    central = RotationalInertia(i[0, 0], i[1, 1], i[2, 2], i[0, 1], i[0, 2], i[1, 2])
    return SpatialInertia.MakeFromCentralInertia(body.mass, np.asarray(body.com, dtype=float), central)


def build_plant(spec: ModelSpec, dofs: str = "sagittal", pelvis_mass: float | None = None,
                pelvis_free: bool = True) -> tuple[MultibodyPlant, list[Coordinate]]:
    """A finalized continuous-time MultibodyPlant of `spec` and its coordinates (in q order).

    Body frames equal the source model's body frames, so path sites and wrap surfaces
    keep their local coordinates. Bodies with several free coordinates are reached
    through massless intermediate bodies (one revolute joint each), which reproduces
    MuJoCo's sequential joint composition. `pelvis_mass` overrides the sacrum mass (the
    thesis used 10,000 kg for its force-driven perturbation). With ``pelvis_free=False``
    the sagittal model has no ``pelvis_tx`` (pelvis welded, e.g. to a moving frame).
    """
    coords = coordinates_for(spec, dofs, pelvis_free)
    by_body: dict[str, list[Coordinate]] = {}
    for c in coords:
        by_body.setdefault(c.body, []).append(c)

    plant = MultibodyPlant(time_step=0.0)
    plant.mutable_gravity_field().set_gravity_vector(np.asarray(spec.gravity, dtype=float))
    drake_bodies = {}
    for b in spec.bodies:
        if b.name == PELVIS_BODY and pelvis_mass is not None:
            b = type(b)(b.name, b.parent, b.pos, b.quat, float(pelvis_mass), b.com, b.inertia * pelvis_mass / b.mass)
        drake_bodies[b.name] = plant.AddRigidBody(b.name, _spatial_inertia(b))

    for b in spec.bodies:
        parent = plant.world_body() if b.parent is None else drake_bodies[b.parent]
        X_PB0 = _transform(b.pos, b.quat) if b.parent is not None else _transform(spec.root_pos, spec.root_quat).multiply(_transform(b.pos, b.quat))
        child = drake_bodies[b.name]
        chain = by_body.get(b.name, [])
        if not chain:
            plant.WeldFrames(parent.body_frame(), child.body_frame(), X_PB0)
            continue
        # each coordinate turns (or slides) the body about an anchor fixed in the body frame
        frame_on_parent = plant.AddFrame(_fixed_frame(f"{b.name}_{chain[0].name}_F", parent.body_frame(), X_PB0.multiply(_anchor(spec, chain[0]))))
        for k, c in enumerate(chain):
            last = k == len(chain) - 1
            if last:
                inboard_child = plant.AddFrame(_fixed_frame(f"{b.name}_{c.name}_M", child.body_frame(), _anchor(spec, c)))
                target = inboard_child
            else:
                dummy = plant.AddRigidBody(f"{b.name}_{c.name}_gimbal", SpatialInertia.Zero())
                target = dummy.body_frame()
            if c.kind == "hinge":
                plant.AddJoint(RevoluteJoint(c.name, frame_on_parent, target, c.axis, damping=0.0))
            else:
                plant.AddJoint(PrismaticJoint(c.name, frame_on_parent, target, c.axis, damping=0.0))
            if not last:
                # next joint's anchor, expressed from this joint's anchor
                offset = _anchor(spec, c).inverse().multiply(_anchor(spec, chain[k + 1]))
                frame_on_parent = plant.AddFrame(_fixed_frame(f"{b.name}_{chain[k + 1].name}_F", dummy.body_frame(), offset))
    plant.Finalize()
    order = sorted(coords, key=lambda c: plant.GetJointByName(c.name).position_start())
    return plant, order


def _anchor(spec: ModelSpec, c: Coordinate) -> RigidTransform:
    if c.source_joint is None:
        return RigidTransform()
    return RigidTransform(np.asarray(spec.joint(c.source_joint).anchor, dtype=float))


def _fixed_frame(name, parent_frame, X):
    return FixedOffsetFrame(name, parent_frame, X)
