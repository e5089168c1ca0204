"""The passenger's missing segments: arms and the rest of the head, lumped on the thorax.

MyoTorso's upper body is the thoracic spine and rib cage (18.6 kg) with a light head and neck
(2.4 kg) and no arms. A seated passenger's trunk also carries the whole head and both arms.
`with_passenger` adds them to the ``torso`` body of a ModelSpec as rigidly attached lumped
segments sized by de Leva (1996, Table 4, male) for a stated body mass and stature
(`models/reference_values.toml` [anthropometry.deleva1996]):

* head: MyoTorso's head and neck are completed to de Leva's head-and-neck mass fraction; the
  added mass sits at their own centre of mass;
* arms (``arms="hanging"``): upper arm, forearm and hand hang straight down from each shoulder
  joint centre (MyoArm's glenohumeral centre in MyoTorso's torso frame, as myo-sim attaches it),
  each segment's centre of mass at de Leva's fraction of its length. The arms are rigid with the
  thorax: they tilt with it instead of swinging (a modelling choice, stated in models/).

Body frames keep the lumbar model's axes: x anterior, y superior, z to the right.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from trunk_drake.data import load_toml
from trunk_drake.model.paths import quat_matrix
from trunk_drake.model.spec import BodySpec, ModelSpec

ARM_POSTURES = ("hanging", "none")
ARM_SEGMENTS = ("upper_arm", "forearm", "hand")
THORAX = "torso"
HEAD_BODIES = ("neck", "head")


@dataclass(frozen=True)
class Passenger:
    """Whole-body size of the simulated passenger and which missing segments it carries."""

    body_mass: float = 75.0  # kg
    stature: float = 1.741  # m (de Leva's male reference stature: segment lengths as tabulated)
    arms: str = "hanging"  # "hanging" from the shoulder joint centres, or "none"
    complete_head: bool = True  # raise MyoTorso's head and neck to de Leva's mass

    def __post_init__(self):
        if not (np.isfinite(self.body_mass) and 30.0 <= self.body_mass <= 200.0):
            raise ValueError(f"passenger body_mass={self.body_mass!r} kg; expected an adult's mass between 30 and 200 kg")
        if not (np.isfinite(self.stature) and 1.2 <= self.stature <= 2.3):
            raise ValueError(f"passenger stature={self.stature!r} m; expected an adult's stature between 1.2 and 2.3 m")
        if self.arms not in ARM_POSTURES:
            raise ValueError(f"passenger arms={self.arms!r}; expected one of {ARM_POSTURES}")


@dataclass(frozen=True)
class LumpedSegment:
    """A rigid segment added to the thorax: mass (kg), centre of mass and inertia about it (torso frame)."""

    name: str
    mass: float
    com: np.ndarray
    inertia: np.ndarray


def _table() -> dict:
    return load_toml("reference_values.toml")["anthropometry"]


def _segment(name: str, passenger: Passenger) -> tuple[float, float, float, np.ndarray]:
    """(mass kg, length m, centre-of-mass fraction from the proximal end, radii (x, y, z) in m)."""
    deleva = _table()["deleva1996"]
    mass_fraction, com_fraction, r_sag, r_trans, r_long = deleva[f"male_{name}"]["value"]
    length = deleva[f"male_{name}_length"]["value"] * passenger.stature / deleva["reference_stature_male"]["value"]
    # anatomical axes: the sagittal axis is antero-posterior (x), the transverse axis medio-lateral (z)
    radii = np.array([r_sag, r_long, r_trans]) * length
    return mass_fraction * passenger.body_mass, length, com_fraction, radii


def _pose_in(spec: ModelSpec, body: str, frame: str) -> tuple[np.ndarray, np.ndarray]:
    """Rotation and origin of `body` in `frame` at zero joint angles (body must descend from frame by welds)."""
    R, p = np.eye(3), np.zeros(3)
    name = body
    while name != frame:
        b = spec.body(name)
        if b.parent is None:
            raise ValueError(f"body {body!r} does not descend from {frame!r}")
        Rb = quat_matrix(b.quat)
        R, p = Rb @ R, Rb @ p + np.asarray(b.pos, float)
        name = b.parent
    return R, p


def _head_completion(spec: ModelSpec, passenger: Passenger) -> list[LumpedSegment]:
    mass, length, _, radii = _segment("head", passenger)
    present = [b for b in spec.bodies if b.name in HEAD_BODIES]
    have = sum(b.mass for b in present)
    if not passenger.complete_head or mass <= have:
        return []
    coms = [(lambda R, p: R @ np.asarray(b.com, float) + p)(*_pose_in(spec, b.name, THORAX)) for b in present]
    com = np.average(coms, axis=0, weights=[b.mass for b in present]) if have > 0 else np.zeros(3)
    extra = mass - have
    return [LumpedSegment("head_completion", extra, com, np.diag(extra * radii**2))]


def _arms(spec: ModelSpec, passenger: Passenger) -> list[LumpedSegment]:
    if passenger.arms == "none":
        return []
    shoulder = np.asarray(_table()["myoarm_shoulder_joint_centre"]["value"], dtype=float)
    out = []
    for side, sign in (("r", 1.0), ("l", -1.0)):
        joint = shoulder * np.array([1.0, 1.0, sign])
        drop = 0.0
        for name in ARM_SEGMENTS:
            mass, length, com_fraction, radii = _segment(name, passenger)
            com = joint - np.array([0.0, drop + com_fraction * length, 0.0])
            out.append(LumpedSegment(f"{name}_{side}", mass, com, np.diag(mass * radii**2)))
            drop += length
    return out


def lumped_segments(spec: ModelSpec, passenger: Passenger) -> list[LumpedSegment]:
    """The segments `with_passenger` adds to the thorax, in the torso frame."""
    return _head_completion(spec, passenger) + _arms(spec, passenger)


def _combine(body: BodySpec, segments: list[LumpedSegment]) -> BodySpec:
    """The body with the segments rigidly added (parallel-axis theorem)."""
    parts = [(body.mass, np.asarray(body.com, float), np.asarray(body.inertia, float))]
    parts += [(s.mass, s.com, s.inertia) for s in segments]
    mass = sum(m for m, _, _ in parts)
    com = sum(m * c for m, c, _ in parts) / mass
    inertia = np.zeros((3, 3))
    for m, c, I in parts:
        d = c - com
        inertia += I + m * (d @ d * np.eye(3) - np.outer(d, d))
    return replace(body, mass=mass, com=com, inertia=inertia)


def with_upper_body_mass(spec: ModelSpec, scale: float) -> ModelSpec:
    """`spec` with its thorax body's mass and inertia scaled by `scale` (an upper-body mass error)."""
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"upper-body mass scale must be a number > 0, got {scale!r}")
    bodies = tuple(replace(b, mass=b.mass * scale, inertia=np.asarray(b.inertia, float) * scale) if b.name == THORAX else b
                   for b in spec.bodies)
    return replace(spec, bodies=bodies, source=f"{spec.source} + thorax mass x{scale:g}")


def with_passenger(spec: ModelSpec, passenger: Passenger) -> ModelSpec:
    """`spec` with the passenger's missing segments lumped on its thorax body."""
    segments = lumped_segments(spec, passenger)
    if not segments:
        return spec
    bodies = tuple(_combine(b, segments) if b.name == THORAX else b for b in spec.bodies)
    return replace(spec, bodies=bodies, source=f"{spec.source} + passenger {passenger}")
