"""Build a Drake MultibodyPlant from a ModelSpec in one of its joint configurations.

``"sagittal"`` (dynamic analysis, thesis section 3.3.2): the sacrum slides on a prismatic
anterior-posterior joint ``pelvis_tx`` and the five lumbar levels are independent revolute
flexion-extension joints ``L5_S1_FE`` ... ``L1_L2_FE``; lateral bending and axial rotation
are welded at zero.

``"spine3d"`` (static analysis): the pelvis is welded to the ground and every lumbar level
has flexion-extension (``*_FE``), lateral bending (``*_LB``) and axial rotation (``*_AR``).

``"rhythm"`` (the configuration the model's authors built it for): ``pelvis_tx`` and one
coordinate ``lumbar_FE``, the lumbar flexion (S1-L1, = the sum of the five level angles), which
turns every level and the routing bodies in the fixed proportions of the spec's rhythm
(`ModelSpec.rhythm`, the constrained source model's couplings). Drake's continuous plant has no
constraints, so the plant is a `CoupledPlant` simulating the chain in that one coordinate.
On an OpenSim model the rhythm is the file's: its level flexion axes following one coordinate
through its linear coordinate couplers (`rhythm_spec`).

``"all"``: every joint of the spec with its own name and sign (for user and test models).

Sign conventions (MyoTorso keeps the OpenSim lumbar-model axes in every body: x anterior,
y superior, z right):

* ``*_FE`` is positive in flexion. MyoTorso's ``flex_extension`` (the L5-S1 joint) and
  ``L?_L?_FE`` rotate about +z, which is extension, so ``*_FE = -MyoTorso angle``.
* ``*_LB`` = MyoTorso angle about +x (anterior): positive tilts the trunk to the right.
* ``*_AR`` = MyoTorso angle about +y (superior): positive turns the trunk to the left.
* ``pelvis_tx`` is positive anteriorly (sacrum x axis), metres.
* ``lumbar_FE`` is positive in flexion: ``lumbar_FE = -rhythm.total * driver``.

In ``sagittal`` and ``spine3d`` MyoTorso's coupling constraints (all lumbar levels driven by
``flex_extension`` etc.) are removed. MyoTorso's ``Abdomen`` routing body is already a child of ``lumbar5`` but was
coupled to ``flex_extension`` (``Abs_r3 = 0.6429 * flex_extension``) with locked
translations; with the couplings removed it is welded to ``lumbar5`` at zero, so it moves
rigidly with L5 during lumbar bending: the equivalent of the thesis' re-parenting of the
abdominal wrap surface from the sacrum to L5 (seed section 3.3.2). In ``rhythm`` it turns with
its coupling.
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
from pydrake.common.eigen_geometry import AngleAxis, Quaternion

from trunk_drake.model.coupled import CoupledPlant
from trunk_drake.model.levels import LEVELS
from trunk_drake.model.osim_config import AxisChoice, SourceCoordinates, free_axes, level_axes, level_rhythm
from trunk_drake.model.spec import ModelSpec, RhythmSpec

# MyoTorso joint names per level: (flexion-extension, lateral bending, axial rotation)
_MYOTORSO_LEVEL_JOINTS = {
    "L5_S1": ("flex_extension", "lat_bending", "axial_rotation"),
    "L4_L5": ("L4_L5_FE", "L4_L5_LB", "L4_L5_AR"),
    "L3_L4": ("L3_L4_FE", "L3_L4_LB", "L3_L4_AR"),
    "L2_L3": ("L2_L3_FE", "L2_L3_LB", "L2_L3_AR"),
    "L1_L2": ("L1_L2_FE", "L1_L2_LB", "L1_L2_AR"),
}
_DOF_KINDS = ("FE", "LB", "AR")


def opensim_coordinate(name: str) -> tuple[str, float] | None:
    """(name, sign) of coordinate `name` in MyoTorso and Lumbar_C_210.osim, which share joint
    names and axes: their value is sign * ours (flexion is negative there). None for a
    coordinate they do not have (``pelvis_tx``: their sacrum is welded to the ground). The rhythm's
    ``lumbar_FE`` is their ``flex_extension`` with its couplers enforced."""
    if name == RHYTHM_COORDINATE:  # the lumbar flexion of the rhythm (Lumbar_C_210's level slopes sum to 1)
        return "flex_extension", -1.0
    level, _, kind = name.rpartition("_")
    if level not in _MYOTORSO_LEVEL_JOINTS or kind not in _DOF_KINDS:
        return None
    return _MYOTORSO_LEVEL_JOINTS[level][_DOF_KINDS.index(kind)], (-1.0 if kind == "FE" else 1.0)


PELVIS_AXIS = np.array([1.0, 0.0, 0.0])  # anterior, in the sacrum frame
DOFS = ("sagittal", "spine3d", "rhythm", "all")  # "all": every joint of the spec, as defined there
RHYTHM_COORDINATE = "lumbar_FE"


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
    if spec.path_semantics == "opensim":
        return _osim_coordinates(spec, dofs, pelvis_free)
    if dofs == "all":
        return [_signed(spec, j.name, j.name, 1.0) for j in spec.joints]
    coords: list[Coordinate] = []
    if dofs in ("sagittal", "rhythm") and pelvis_free:
        coords.append(_pelvis_coordinate(spec))
    if dofs == "rhythm":
        rhythm = _rhythm(spec)
        coords += [_signed(spec, f"{level}_FE", joint, -1.0) for level, joint in zip(LEVELS, rhythm.levels)]
        return coords + [_signed(spec, j, j, 1.0) for j in rhythm.routing]
    suffixes = ("FE",) if dofs == "sagittal" else _DOF_KINDS
    for level in LEVELS:
        for suffix in suffixes:
            coords.append(_signed(spec, f"{level}_{suffix}", *opensim_coordinate(f"{level}_{suffix}")))
    return coords


def _signed(spec: ModelSpec, name: str, source: str, sign: float) -> Coordinate:
    """Coordinate `name` = sign * the spec's joint `source` (flexion: -1, MyoTorso turns about +z in extension)."""
    j = spec.joint(source)
    lo, hi = sorted((sign * j.range[0], sign * j.range[1]))
    return Coordinate(name, j.body, j.kind, sign * np.asarray(j.axis, float), source, sign, (lo, hi))


def _rhythm(spec: ModelSpec):
    rhythm = spec.rhythm
    if rhythm is None:
        raise ValueError(f"model {spec.name!r} defines no lumbar rhythm (ModelSpec.rhythm): use dofs='sagittal' or 'spine3d'")
    if len(rhythm.levels) != len(LEVELS) or not rhythm.total > 0:
        raise ValueError(f"the rhythm of {spec.name!r} must turn {len(LEVELS)} levels ({', '.join(LEVELS)}) with a positive "
                         f"total ratio; it has levels {list(rhythm.levels)} with ratios {list(rhythm.level_ratios)}")
    return rhythm


def rhythm_coupling(spec: ModelSpec, joints: list[Coordinate]) -> tuple[np.ndarray, list[Coordinate]]:
    """The coupling matrix G (joints x coordinates, ``q_joints = G q``) and the rhythm's coordinates.

    ``lumbar_FE`` is scaled to the sum of the level angles (the lumbar rotation): each level turns
    ``level_ratio / total`` of it; a routing joint turns ``-routing_ratio / total`` of it in its
    source sign (the levels' flexion is minus the source angle). Its range keeps every coupled
    joint within its own range. OpenSim models: see `_osim_rhythm_coupling`.
    """
    if spec.path_semantics == "opensim":
        return _osim_rhythm_coupling(spec, joints)
    rhythm = _rhythm(spec)
    share = {f"{level}_FE": r / rhythm.total for level, r in zip(LEVELS, rhythm.level_ratios)}
    share.update({j: -r / rhythm.total for j, r in zip(rhythm.routing, rhythm.routing_ratios)})
    G, coords, rng = _coupling_matrix(joints, share)
    driver = spec.joint(rhythm.levels[0])
    coords.append(Coordinate(RHYTHM_COORDINATE, driver.body, "hinge", -np.asarray(driver.axis, float), rhythm.driver,
                             -rhythm.total, rng))
    return G, coords


def _osim_rhythm_coupling(spec: ModelSpec, joints: list[Coordinate]) -> tuple[np.ndarray, list[Coordinate]]:
    """`rhythm_coupling` of an OpenSim model (levels as in `rhythm_spec`); ``lumbar_FE`` stands for the
    first level's transform axis scaled by its share, so the file's driver maps to it. The routing
    bodies stay followers (trunk_drake.model.osim_config)."""
    levels = [c for c in joints if c.source_joint is not None]
    slopes = np.array(rhythm_spec(spec).level_ratios) * [c.sign for c in levels]  # flexion per unit of the driver
    share = dict(zip((c.name for c in levels), slopes / slopes.sum()))
    G, coords, rng = _coupling_matrix(joints, share)
    first = levels[0]
    coords.append(Coordinate(RHYTHM_COORDINATE, first.body, "hinge", first.axis, first.source_joint,
                             float(first.sign / share[first.name]), rng))
    return G, coords


def rhythm_spec(spec: ModelSpec) -> RhythmSpec:
    """The lumbar rhythm of `spec`: `ModelSpec.rhythm`, or for an OpenSim model its level flexion axes
    following one coordinate through the file's linear couplers (`level_rhythm`; ratios: axis
    displacement per unit of that coordinate)."""
    if spec.path_semantics != "opensim":
        return _rhythm(spec)
    choices = osim_choices(spec, "rhythm")
    driver, slopes = level_rhythm(spec, choices)
    return RhythmSpec(driver, tuple(c.joint.name for c in choices), tuple(float(s * c.sign) for s, c in zip(slopes, choices)),
                      source=f"coordinate couplers of {spec.name}")


def _coupling_matrix(joints: list[Coordinate], share: dict[str, float]):
    """G for ``pelvis_tx`` (if among `joints`) and one rhythm coordinate turning joint j by ``share[j]``
    of it, the coordinates before the rhythm's, and the rhythm coordinate's range (every joint in range)."""
    coords = [c for c in joints if c.name == "pelvis_tx"]
    G = np.zeros((len(joints), len(coords) + 1))
    lo, hi = -np.inf, np.inf
    for i, c in enumerate(joints):
        if c.name == "pelvis_tx":
            G[i, 0] = 1.0
            continue
        G[i, -1] = share[c.name]
        if share[c.name]:
            bounds = np.asarray(c.range) / share[c.name]
            lo, hi = max(lo, bounds.min()), min(hi, bounds.max())
    return G, coords, (float(lo), float(hi))


def _pelvis_coordinate(spec: ModelSpec) -> Coordinate:
    return Coordinate("pelvis_tx", spec.pelvis, "slide", PELVIS_AXIS.copy(), None, 1.0, (-1.0, 1.0))


def _osim_coordinates(spec: ModelSpec, dofs: str, pelvis_free: bool) -> list[Coordinate]:
    """Coordinates of an OpenSim spec: the chosen transform axes (see trunk_drake.model.osim_config)."""
    choices = osim_choices(spec, dofs)
    source = SourceCoordinates(spec, choices)
    coords = [_pelvis_coordinate(spec)] if dofs in ("sagittal", "rhythm") and pelvis_free else []
    for ch in choices:
        j = ch.joint
        coords.append(Coordinate(ch.name, j.body, j.kind, ch.sign * np.asarray(j.axis, float), j.name, ch.sign,
                                 source.coordinate_range(ch)))
    return coords


def osim_choices(spec: ModelSpec, dofs: str) -> list[AxisChoice]:
    """The transform axes that are the plant coordinates of configuration `dofs` (no pelvis_tx)."""
    if dofs == "all":
        return free_axes(spec)
    return level_axes(spec, LEVELS, ("FE", "LB", "AR") if dofs == "spine3d" else ("FE",))


def fixed_joint_values(spec: ModelSpec, coords: list[Coordinate]) -> dict[str, float]:
    """Displacements of the spec's joints that are no plant coordinate (MuJoCo specs: none, all zero)."""
    if spec.path_semantics != "opensim":
        return {}
    choices = [None if c.source_joint is None else AxisChoice(c.name, spec.joint(c.source_joint), c.sign) for c in coords]
    return SourceCoordinates(spec, choices).fixed_values({c.source_joint for c in coords})


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
    the sagittal and rhythm models have no ``pelvis_tx`` (pelvis welded, e.g. to a moving frame).
    For ``"rhythm"`` the plant is a `CoupledPlant` around the plant of the coupled joints
    (its `joints`), and the coordinates are ``pelvis_tx`` and ``lumbar_FE``.
    """
    joints = coordinates_for(spec, dofs, pelvis_free)
    plant = MultibodyPlant(time_step=0.0)
    add_to_plant(plant, spec, joints, pelvis_mass)
    plant.Finalize()
    joints = sorted(joints, key=lambda c: plant.GetJointByName(c.name).position_start())
    if dofs != "rhythm":
        return plant, joints
    G, coords = rhythm_coupling(spec, joints)
    return CoupledPlant(plant, G, [c.name for c in coords], joints), coords


def add_to_plant(plant: MultibodyPlant, spec: ModelSpec, coords: list[Coordinate], pelvis_mass: float | None = None) -> None:
    """Add the bodies of `spec` to an unfinalized `plant`, movable on `coords` and welded elsewhere."""
    by_body: dict[str, list[Coordinate]] = {}
    for c in coords:
        by_body.setdefault(c.body, []).append(c)
    fixed = fixed_joint_values(spec, coords)

    plant.mutable_gravity_field().set_gravity_vector(np.asarray(spec.gravity, dtype=float))
    drake_bodies = {}
    for b in spec.bodies:
        if b.name == spec.pelvis and pelvis_mass is not None:
            if b.mass <= 0.0:
                raise ValueError(f"the pelvis body {b.name!r} of model {spec.name!r} has no mass, so its inertia cannot be "
                                 f"scaled to the {pelvis_mass:g} kg of a force-driven or seated pelvis; give it a mass and "
                                 "inertia in the model file")
            b = type(b)(b.name, b.parent, b.pos, b.quat, float(pelvis_mass), b.com, b.inertia * pelvis_mass / b.mass)
        drake_bodies[b.name] = plant.AddRigidBody(b.name, _spatial_inertia(b))

    for b in spec.bodies:
        parent = plant.world_body() if b.parent is None else drake_bodies[b.parent]
        X_PB0 = _transform(b.pos, b.quat) if b.parent is not None else _transform(spec.root_pos, spec.root_quat).multiply(_transform(b.pos, b.quat))
        child = drake_bodies[b.name]
        steps = _body_steps(spec, b.name, by_body.get(b.name, []), fixed)
        chain = [s for s in steps if isinstance(s, Coordinate)]
        # X_PB = X_PB0 * (each step: A D(q) A^-1 for a coordinate, a fixed transform otherwise), A = anchor
        acc, k = X_PB0, 0
        for i, step in enumerate(steps):
            if not isinstance(step, Coordinate):
                acc = acc.multiply(step)
                continue
            frame_on_parent = plant.AddFrame(_fixed_frame(f"{b.name}_{step.name}_F", parent.body_frame() if k == 0 else dummy.body_frame(), acc.multiply(_anchor(spec, step))))
            last = k == len(chain) - 1
            if last:
                rest = _product(steps[i + 1:])
                X_BM = _anchor(spec, step) if rest is None else rest.inverse().multiply(_anchor(spec, step))
                target = plant.AddFrame(_fixed_frame(f"{b.name}_{step.name}_M", child.body_frame(), X_BM))
            else:
                dummy = plant.AddRigidBody(f"{b.name}_{step.name}_gimbal", SpatialInertia.Zero())
                target = dummy.body_frame()
            joint_type = RevoluteJoint if step.kind == "hinge" else PrismaticJoint
            plant.AddJoint(joint_type(step.name, frame_on_parent, target, step.axis, damping=0.0))
            acc = _anchor(spec, step).inverse()
            k += 1
        if not chain:
            plant.WeldFrames(parent.body_frame(), child.body_frame(), acc)


def _anchor(spec: ModelSpec, c: Coordinate) -> RigidTransform:
    if c.source_joint is None:
        return RigidTransform()
    return RigidTransform(np.asarray(spec.joint(c.source_joint).anchor, dtype=float))


def _body_steps(spec: ModelSpec, body: str, coords: list[Coordinate], fixed: dict[str, float]) -> list:
    """The motion steps of a body in order: coordinates (pelvis slide first) and fixed transforms."""
    selected = {c.source_joint: c for c in coords if c.source_joint is not None}
    steps: list = [c for c in coords if c.source_joint is None]
    if spec.path_semantics != "opensim":
        return steps + [c for c in coords if c.source_joint is not None]
    for j in spec.joints:
        if j.body != body:
            continue
        if j.name in selected:
            steps.append(selected[j.name])
        elif fixed.get(j.name, 0.0) != 0.0:
            steps.append(joint_transform(j, fixed[j.name]))
    return steps


def joint_transform(joint, value: float) -> RigidTransform:
    """Pose change of a body by a displacement of one of its joints (in the body frame before it)."""
    axis = np.asarray(joint.axis, dtype=float)
    if joint.kind == "slide":
        return RigidTransform(axis * value)
    R = RotationMatrix(AngleAxis(value, axis / np.linalg.norm(axis)))
    anchor = np.asarray(joint.anchor, dtype=float)
    return RigidTransform(R, anchor - R.matrix() @ anchor)


def _product(transforms) -> RigidTransform | None:
    out = None
    for X in transforms:
        out = X if out is None else out.multiply(X)
    return out


def _fixed_frame(name, parent_frame, X):
    return FixedOffsetFrame(name, parent_frame, X)
