"""ModelSpec: a plain-data description of a musculoskeletal trunk model.

No Drake or MuJoCo objects live here: every engine (the Drake plant, the MuJoCo
oracle, an OpenSim export) is built from these dataclasses. Frames follow MuJoCo's
conventions: a body's pose is given relative to its parent at zero joint angles,
joints act about axes expressed in the child body frame, and "up" is minus `gravity`
(z for MyoTorso, y for OpenSim files).
Inside each body the OpenSim lumbar-model axes are kept: x anterior, y superior,
z to the right.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trunk_drake.model.functions import Function


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
    """A one-degree-of-freedom joint of `body` relative to its parent (MuJoCo hinge or slide).

    A body's joints act in order (each about an axis fixed in the body frame). For OpenSim
    models each joint is one transform axis of a CustomJoint: its displacement is
    ``function(value of coordinate)`` (a constant when `coordinate` is None); for MuJoCo
    models the joint is its own coordinate (`function` None).
    """

    name: str
    body: str
    kind: str  # "hinge" or "slide"
    axis: np.ndarray  # (3,) unit axis in the body frame
    anchor: np.ndarray  # (3,) point on the axis in the body frame, m
    range: tuple[float, float]  # rad or m
    coordinate: str | None = None  # source-model coordinate driving the joint (OpenSim)
    function: Function | None = None  # displacement as a function of that coordinate (OpenSim)


@dataclass(frozen=True)
class CoordinateSpec:
    """A generalized coordinate of an OpenSim model (values in its own units: rad or m)."""

    name: str
    kind: str  # OpenSim's motion type: "rotational", "translational" or "coupled" (see osim._motion_type)
    default: float
    range: tuple[float, float]
    locked: bool = False


@dataclass(frozen=True)
class CouplerSpec:
    """An OpenSim CoordinateCouplerConstraint: ``dependent = scale * function(independent)``."""

    name: str
    dependent: str
    independent: str
    function: Function
    scale: float = 1.0


@dataclass(frozen=True)
class SiteSpec:
    """A point fixed to a body (muscle path point or wrap side-site)."""

    name: str
    body: str
    pos: np.ndarray  # (3,) in the body frame, m
    condition: tuple[str, float, float] | None = None  # OpenSim conditional point: (coordinate, low, high)
    motion: tuple[tuple[str | None, Function], ...] | None = None  # OpenSim moving point: per axis (coordinate, function)


@dataclass(frozen=True)
class WrapSpec:
    """A wrapping surface: sphere, cylinder (axis = local z) or ellipsoid.

    MuJoCo models: sphere and infinite cylinder. OpenSim models add the cylinder `length`,
    ellipsoid `radii` and the `quadrant` ("all", "x", "-x", ... "-z") wrapping is kept on.
    """

    name: str
    body: str
    kind: str  # "sphere", "cylinder" or "ellipsoid"
    radius: float  # m (ellipsoid: largest radius)
    pos: np.ndarray  # (3,) centre in the body frame, m
    quat: np.ndarray  # (4,) w, x, y, z orientation in the body frame
    length: float = float("inf")  # cylinder length, m
    radii: np.ndarray | None = None  # ellipsoid semi-axes, m
    quadrant: str = "all"


@dataclass(frozen=True)
class PathElement:
    """One element of a muscle path: a site, or a wrap surface with an optional side-site."""

    kind: str  # "site" or "wrap"
    index: int  # into ModelSpec.sites or ModelSpec.wraps
    side_site: int = -1  # into ModelSpec.sites; -1 when none (wraps only)


@dataclass(frozen=True)
class PathWrapSpec:
    """An OpenSim path wrap: a wrap surface tried on the path segments between two points.

    `start`, `end`: 1-based indices of the path points that bound the range (-1: first/last);
    `method`: the ellipsoid plane-finding method ("hybrid", "midpoint" or "axial").
    """

    wrap: int  # into ModelSpec.wraps
    start: int = -1
    end: int = -1
    method: str = "hybrid"


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
    path_wraps: tuple[PathWrapSpec, ...] = ()  # OpenSim wrapping (then `path` holds its points only)
    source_type: str = ""  # e.g. "Thelen2003Muscle" for OpenSim muscles


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
    coordinates: tuple[CoordinateSpec, ...] = ()  # OpenSim models: the source coordinates
    couplers: tuple[CouplerSpec, ...] = ()  # OpenSim models: coordinate coupler constraints
    path_semantics: str = "mujoco"  # "mujoco" or "opensim": how `MuscleSpec.path` wraps
    pelvis: str = "sacrum"  # the body carrying the lowest lumbar joint (root of the spine)
    level_bodies: tuple[str, ...] = ()  # OpenSim models: child vertebra of each lumbar level, L5/S1 first
    muscle_constants: dict = field(default_factory=dict)  # shared Thelen constants read from the source

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

    def coordinate(self, name: str) -> CoordinateSpec:
        for c in self.coordinates:
            if c.name == name:
                return c
        raise KeyError(f"no coordinate named {name!r}; coordinates: {[c.name for c in self.coordinates]}")

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
