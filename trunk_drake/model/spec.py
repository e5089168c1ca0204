"""ModelSpec: a plain-data description of a musculoskeletal trunk model.

No Drake or MuJoCo objects live here: every engine (the Drake plant, the MuJoCo
oracle, an OpenSim export) is built from these dataclasses. Frames follow MuJoCo's
conventions: a body's pose is given relative to its parent at zero joint angles,
joints act about axes expressed in the child body frame, and the world is z-up.
Inside each body the OpenSim lumbar-model axes are kept: x anterior, y superior,
z to the right.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class BodySpec:
    """A rigid body: inertial properties and its pose in the parent at zero joint angles."""

    name: str
    parent: str | None  # None for the root (attached to the world)
    pos: np.ndarray  # (3,) body origin in the parent frame, m
    quat: np.ndarray  # (4,) w, x, y, z: body orientation in the parent frame
    mass: float  # kg
    com: np.ndarray  # (3,) centre of mass in the body frame, m
    inertia: np.ndarray  # (3, 3) rotational inertia about the COM in the body frame, kg m^2


@dataclass(frozen=True)
class JointSpec:
    """A one-degree-of-freedom joint of `body` relative to its parent (MuJoCo hinge or slide)."""

    name: str
    body: str
    kind: str  # "hinge" or "slide"
    axis: np.ndarray  # (3,) unit axis in the body frame
    anchor: np.ndarray  # (3,) point on the axis in the body frame, m
    range: tuple[float, float]  # rad or m


@dataclass(frozen=True)
class SiteSpec:
    """A point fixed to a body (muscle path point or wrap side-site)."""

    name: str
    body: str
    pos: np.ndarray  # (3,) in the body frame, m


@dataclass(frozen=True)
class WrapSpec:
    """A wrapping surface: sphere or infinite cylinder (axis = local z), MuJoCo-style."""

    name: str
    body: str
    kind: str  # "sphere" or "cylinder"
    radius: float  # m
    pos: np.ndarray  # (3,) centre in the body frame, m
    quat: np.ndarray  # (4,) w, x, y, z orientation in the body frame


@dataclass(frozen=True)
class PathElement:
    """One element of a muscle path: a site, or a wrap surface with an optional side-site."""

    kind: str  # "site" or "wrap"
    index: int  # into ModelSpec.sites or ModelSpec.wraps
    side_site: int = -1  # into ModelSpec.sites; -1 when none (wraps only)


@dataclass(frozen=True)
class MuscleSpec:
    """A muscle-tendon unit: Hill parameters and its path.

    The Hill parameters (optimal fiber length, tendon slack length, pennation) are
    filled in by `trunk_drake.model.architecture`; NaN until then.
    """

    name: str
    path: tuple[PathElement, ...]
    max_isometric_force: float  # N
    optimal_fiber_length: float = float("nan")  # m
    tendon_slack_length: float = float("nan")  # m
    pennation_angle: float = float("nan")  # rad, at optimal fiber length
    group: str = ""


@dataclass(frozen=True)
class CouplingSpec:
    """A source-model equality constraint `joint = sum_k coef[k] * driver**k` (kept for reference)."""

    name: str
    joint: str
    driver: str | None
    coef: tuple[float, ...]


@dataclass(frozen=True)
class RhythmSpec:
    """A one-coordinate lumbar rhythm: every listed joint moves in proportion to one coordinate.

    ``joint value = ratio * driver value`` in the source's own joint signs and units, where
    `driver` names the source's independent coordinate (e.g. Lumbar_C_210's ``flex_extension``,
    the whole lumbar spine's flexion-extension). `levels` are the intervertebral joints (root
    to tip); `routing` are other coupled joints (e.g. a wrapping body turning with the spine).
    """

    driver: str
    levels: tuple[str, ...]
    level_ratios: tuple[float, ...]
    routing: tuple[str, ...] = ()
    routing_ratios: tuple[float, ...] = ()
    source: str = ""

    @property
    def total(self) -> float:
        """Sum of the level ratios: how far the levels turn in total per unit of the driver."""
        return float(sum(self.level_ratios))


@dataclass(frozen=True)
class ModelSpec:
    """Everything needed to build the plant and the muscle paths of one model."""

    name: str
    bodies: tuple[BodySpec, ...]
    joints: tuple[JointSpec, ...]
    sites: tuple[SiteSpec, ...]
    wraps: tuple[WrapSpec, ...]
    muscles: tuple[MuscleSpec, ...]
    couplings: tuple[CouplingSpec, ...] = ()
    rhythm: RhythmSpec | None = None  # the flexion-extension rhythm of the constrained source model
    landmarks: tuple[SiteSpec, ...] = ()  # named anatomical points (e.g. vertebral body centres)
    root_pos: np.ndarray = field(default_factory=lambda: np.zeros(3))  # root body origin in world
    root_quat: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, -9.81]))
    source: str = ""  # provenance, e.g. "myo-sim 0.2.4 myotorso"

    def body(self, name: str) -> BodySpec:
        for b in self.bodies:
            if b.name == name:
                return b
        raise KeyError(f"no body named {name!r}; bodies: {[b.name for b in self.bodies]}")

    def joint(self, name: str) -> JointSpec:
        for j in self.joints:
            if j.name == name:
                return j
        raise KeyError(f"no joint named {name!r}; joints: {[j.name for j in self.joints]}")

    def landmark(self, name: str) -> SiteSpec:
        for s in self.landmarks:
            if s.name == name:
                return s
        raise KeyError(f"no landmark named {name!r}; landmarks: {[s.name for s in self.landmarks]}")

    @property
    def muscle_names(self) -> list[str]:
        return [m.name for m in self.muscles]

    def groups(self) -> dict[str, list[str]]:
        """Muscle names per group, in model order."""
        out: dict[str, list[str]] = {}
        for m in self.muscles:
            out.setdefault(m.group, []).append(m.name)
        return out

    def children(self, name: str) -> list[str]:
        return [b.name for b in self.bodies if b.parent == name]
