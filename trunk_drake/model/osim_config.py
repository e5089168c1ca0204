"""trunk-drake's configurations on an OpenSim model, and the model's coordinates as functions of q.

A plant coordinate is the displacement of one transform axis (a `JointSpec` of the .osim
spec) times a sign: for ``"sagittal"`` and ``"spine3d"`` the lumbar levels' rotation axes
(flexion = rotation about -z of the vertebra, lateral bending about +x, axial rotation about
+y, the OpenSim lumbar-model axes; ``"rhythm"`` couples the flexion axes by the file's couplers,
`level_rhythm`), for ``"all"`` one axis per unlocked coordinate. The
model's own coordinate then follows from the axis' (affine) function. Its other coordinates
are either held (locked, or unrelated to the plant's coordinates: at their default) or follow
through the file's coordinate couplers; couplers whose dependent coordinate is itself a plant
coordinate are dropped (the configuration makes the levels independent).

Transform axes whose displacement moves with q but is no plant coordinate (coupled routing
bodies such as Lumbar_C_210's `LB_wrap` and `Abdomen`, or a translation that is a spline of a
rotation's coordinate) are *followers*. Drake has no joint whose displacement is an arbitrary
function of another joint's coordinate, so in the MultibodyPlant a follower is welded at its
displacement at q = 0 (its mass and inertia are there; a follower's motion is left out of the
dynamics), while the muscle geometry moves it exactly: the path kinematics re-pose follower
bodies from q and add their axes to the moment arms by the chain rule.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from trunk_drake.model.spec import JointSpec, ModelSpec

# suffix: (body axis, sign so that the plant coordinate is flexion / bend to the right / turn to the left)
LEVEL_AXES = {"FE": (2, -1.0), "LB": (0, 1.0), "AR": (1, 1.0)}
_HUGE_RANGE = 2.0 * np.pi  # wider coordinate ranges than this are taken as "unbounded" in the file


@dataclass(frozen=True)
class AxisChoice:
    """A plant coordinate on an OpenSim model: transform axis `joint`, q = sign * displacement."""

    name: str
    joint: JointSpec
    sign: float


def level_axes(spec: ModelSpec, levels: tuple[str, ...], suffixes: tuple[str, ...]) -> list[AxisChoice]:
    """The lumbar level coordinates of `spec` (ValueError naming what is missing)."""
    if len(spec.level_bodies) != len(levels):
        raise ValueError(f"model {spec.name!r} names no lumbar level bodies; give a mapping file with a [levels] table "
                         f"({', '.join(levels)} -> child vertebra body) or use dofs='all'")
    out = []
    for level, body in zip(levels, spec.level_bodies):
        for suffix in suffixes:
            index, sign = LEVEL_AXES[suffix]
            found = [j for j in spec.joints if j.body == body and j.kind == "hinge" and j.coordinate is not None
                     and abs(j.axis[index]) > 0.999]
            if not found:
                raise ValueError(
                    f"model {spec.name!r} has no coordinate for {level}_{suffix}: no rotation of body {body!r} about its "
                    f"{'xyz'[index]} axis is driven by a coordinate; this configuration needs one (use dofs='all' or "
                    "a model with lumbar level joints)")
            j = found[0]
            if _affine(j) is None or _affine(j)[0] == 0.0:
                raise ValueError(f"{level}_{suffix}: transform axis {j.name} is not a linear function of coordinate "
                                 f"{j.coordinate}; trunk-drake needs linear level joints")
            out.append(AxisChoice(f"{level}_{suffix}", j, sign * float(np.sign(j.axis[index]))))
    return out


def level_rhythm(spec: ModelSpec, levels: list[AxisChoice]) -> tuple[str, np.ndarray]:
    """The file's lumbar rhythm: (driver coordinate, d level q / d driver per level).

    Each level's coordinate must be the driver itself or follow it through a chain of the file's
    coordinate couplers, every link linear with zero offset (ValueError naming the first that is not).
    """
    drivers, slopes = set(), []
    for ch in levels:
        name, (slope, offset) = ch.joint.coordinate, _affine(ch.joint)
        slope, offset = ch.sign * slope, ch.sign * offset
        while (cp := next((c for c in spec.couplers if c.dependent == name), None)) is not None:
            form = cp.function.linear_form()
            if form is None or abs(cp.scale * form[1]) > 1e-12:
                raise ValueError(f"coordinate coupler {cp.name!r} ({cp.dependent} from {cp.independent}) is not linear with zero "
                                 f"offset, so {ch.name} does not follow {cp.independent} in a constant ratio; "
                                 "dofs='rhythm' needs linear couplers (use dofs='sagittal')")
            slope, name = slope * cp.scale * form[0], cp.independent
        if abs(offset) > 1e-12:
            raise ValueError(f"{ch.name}: transform axis {ch.joint.name} is offset by {offset:g} at {name} = 0; "
                             "dofs='rhythm' needs level axes through zero")
        drivers.add(name)
        slopes.append(slope)
    if len(drivers) != 1:
        raise ValueError(f"model {spec.name!r}: the lumbar levels follow {sorted(drivers)} through its coordinate couplers, "
                         "not one coordinate; dofs='rhythm' needs one (use dofs='sagittal')")
    slopes = np.array(slopes)
    if slopes.sum() == 0.0:
        raise ValueError(f"model {spec.name!r}: its couplers move the lumbar levels by a total of zero per unit of "
                         f"{drivers.pop()}; dofs='rhythm' cannot scale lumbar_FE to the lumbar flexion")
    return drivers.pop(), slopes


def free_axes(spec: ModelSpec) -> list[AxisChoice]:
    """``dofs="all"``: per unlocked coordinate one transform axis it drives (q = that axis' displacement).

    A linear axis is preferred; otherwise an axis monotonic in the coordinate over its range
    (the coordinate then follows by inverting the function).
    """
    out = []
    for c in spec.coordinates:
        if c.locked:
            continue
        axes = [j for j in spec.joints if j.coordinate == c.name and not j.function.is_constant]
        axes.sort(key=lambda j: _affine(j) is None)
        if axes and (_affine(axes[0]) is not None or _monotonic(axes[0], c.range)):
            out.append(AxisChoice(c.name, axes[0], 1.0))
    return out


def _monotonic(joint: JointSpec, rng) -> bool:
    lo, hi = max(rng[0], -_HUGE_RANGE), min(rng[1], _HUGE_RANGE)
    slope = joint.function.derivative(np.linspace(lo, hi, 401))
    return bool(np.all(slope > 0) or np.all(slope < 0))


def _inverse(function, value: float, lo: float, hi: float) -> float:
    """x with function(x) = value for a monotonic function (bisection refined by Newton)."""
    f_lo, f_hi = float(function.value(lo)) - value, float(function.value(hi)) - value
    while f_lo * f_hi > 0:  # widen the bracket (the functions extrapolate linearly)
        width = hi - lo
        lo, hi = lo - width, hi + width
        f_lo, f_hi = float(function.value(lo)) - value, float(function.value(hi)) - value
    x = 0.5 * (lo + hi)
    for _ in range(200):
        fx = float(function.value(x)) - value
        if fx == 0.0 or hi - lo < 1e-15 * max(1.0, abs(x)):
            break
        if (fx < 0) == (f_lo < 0):
            lo, f_lo = x, fx
        else:
            hi = x
        slope = float(function.derivative(x))
        newton = x - fx / slope if slope != 0.0 else np.nan
        x = newton if lo < newton < hi else 0.5 * (lo + hi)
    return x


def _affine(joint: JointSpec):
    return joint.function.linear_form()


class SourceCoordinates:
    """The model's coordinates c(q) and dc/dq for a set of plant coordinates (AxisChoices, None for pelvis_tx)."""

    def __init__(self, spec: ModelSpec, choices: list[AxisChoice | None]):
        self.spec = spec
        self.names = [c.name for c in spec.coordinates]
        self.index = {n: i for i, n in enumerate(self.names)}
        self.nq = len(choices)
        self.default = np.array([c.default for c in spec.coordinates], dtype=float)
        # free coordinates: c = (sign * q - intercept) / slope  (q = sign * (slope c + intercept))
        self.free = {ch.joint.coordinate: (k, ch) for k, ch in enumerate(choices) if ch is not None}
        self.couplers = self._coupler_order()
        self.moving = self._moving_coordinates()

    def _coupler_order(self):
        """Couplers that apply (dependent not free, independent moving or fixed), in evaluation order."""
        pending = [c for c in self.spec.couplers if c.dependent not in self.free]
        done, order = set(self.free), []
        while pending:
            ready = [c for c in pending if c.independent in done or not any(p.dependent == c.independent for p in pending)]
            if not ready:
                raise ValueError(f"coordinate couplers form a cycle: {[c.name for c in pending]}")
            for c in ready:
                order.append(c)
                done.add(c.dependent)
                pending.remove(c)
        return order

    def _moving_coordinates(self) -> set[str]:
        moving = set(self.free)
        for c in self.couplers:
            if c.independent in moving:
                moving.add(c.dependent)
        return moving

    def values(self, q) -> tuple[np.ndarray, np.ndarray]:
        """c (n_coordinates,) and dc/dq (n_coordinates, nq) at plant positions q."""
        q = np.asarray(q, dtype=float)
        c = self.default.copy()
        dc = np.zeros((len(self.names), self.nq))
        for name, (k, ch) in self.free.items():
            i = self.index[name]
            form = _affine(ch.joint)
            if form is not None:
                c[i] = (ch.sign * q[k] - form[1]) / form[0]
                dc[i, k] = ch.sign / form[0]
            else:
                lo, hi = self.spec.coordinate(name).range
                c[i] = _inverse(ch.joint.function, ch.sign * q[k], max(lo, -_HUGE_RANGE), min(hi, _HUGE_RANGE))
                dc[i, k] = ch.sign / float(ch.joint.function.derivative(c[i]))
        for cp in self.couplers:
            i, j = self.index[cp.dependent], self.index[cp.independent]
            c[i] = cp.scale * cp.function.at(c[j])
            dc[i] = cp.scale * cp.function.at(c[j], 1) * dc[j]
        return c, dc

    def coordinate_range(self, choice: AxisChoice) -> tuple[float, float]:
        """Range of a plant coordinate from its model coordinate's range (or its coupler's image)."""
        coord = self.spec.coordinate(choice.joint.coordinate)
        lo, hi = coord.range
        if hi - lo > _HUGE_RANGE:
            for cp in self.spec.couplers:
                if cp.dependent == coord.name:
                    ind = self.spec.coordinate(cp.independent).range
                    image = cp.scale * cp.function.value(np.linspace(ind[0], ind[1], 201))
                    lo, hi = float(image.min()), float(image.max())
        values = choice.sign * choice.joint.function.value(np.array([lo, hi]))
        return float(values.min()), float(values.max())

    def followers(self, plant_joints: set[str]) -> list[JointSpec]:
        """Transform axes that move with q but are no plant coordinate."""
        return [j for j in self.spec.joints if j.coordinate in self.moving and j.name not in plant_joints]

    def fixed_values(self, plant_joints: set[str]) -> dict[str, float]:
        """Displacement of every other transform axis at q = 0 (followers included)."""
        c, _ = self.values(np.zeros(self.nq))
        out = {}
        for j in self.spec.joints:
            if j.name in plant_joints:
                continue
            out[j.name] = float(j.function.value(c[self.index[j.coordinate]] if j.coordinate else 0.0))
        return out
