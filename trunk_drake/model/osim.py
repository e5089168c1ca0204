"""Read an OpenSim model file (.osim) into a ModelSpec: plain XML parsing, no OpenSim needed.

Both document generations are read: OpenSim 1.x-3.x (joints inside bodies, `location_in_parent`)
and 4.x (a JointSet with PhysicalOffsetFrames). Values the file leaves out come from its own
`<defaults>` block, then from OpenSim 4.6's class defaults, as OpenSim does.

What is read, in OpenSim's semantics:

* bodies (mass, centre of mass, inertia about it); `WeldJoint`, `PinJoint`, `SliderJoint`,
  `GimbalJoint`, `UniversalJoint` and `CustomJoint` with its `SpatialTransform`: the three
  translations act first along the parent-side joint frame's axes, then the three rotations
  in order, each about its axis in the frame the previous rotations produced; every transform
  axis becomes one `JointSpec` whose displacement is its function of its coordinate;
* coordinates (range, default, lock) and `CoordinateCouplerConstraint`s;
* wrap objects `WrapSphere`, `WrapCylinder`, `WrapEllipsoid` (pose, size, quadrant, active);
* muscles (`Thelen2003Muscle`, `Millard2012EquilibriumMuscle`): Hill parameters, the shared
  Thelen constants, path points (fixed, conditional, moving) and path wraps (range, method).

Anything else (other joints, constraints, forces, wrap objects) is reported with one warning
per element type saying what was done instead. Frames: the world is OpenSim's ground (y up);
a body's pose is given relative to its parent at zero joint displacements, and bodies welded to
the ground are re-attached, welded, to the pelvis when the pelvis is welded to the ground too
(so a pelvis motion moves every pelvic body).
"""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from collections import defaultdict
from dataclasses import dataclass, field, replace
from functools import lru_cache
from pathlib import Path

import numpy as np

from trunk_drake.model.functions import Function, constant
from trunk_drake.model.levels import LEVEL_BODIES, LEVELS
from trunk_drake.model.paths import quat_matrix
from trunk_drake.model.spec import (
    BodySpec, CoordinateSpec, CouplerSpec, JointSpec, ModelSpec, MuscleSpec, PathElement, PathWrapSpec, SiteSpec,
    WrapSpec,
)

MUSCLE_TYPES = ("Thelen2003Muscle", "Millard2012EquilibriumMuscle")
# Thelen constants: (spec key, 4.x property, older property) and OpenSim 4.6's class defaults
_THELEN_PROPERTIES = {
    "tendon_strain_at_fmax": (("FmaxTendonStrain",), 0.04),
    "passive_strain_at_fmax": (("FmaxMuscleStrain",), 0.6),
    "gamma": (("KshapeActive",), 0.45),
    "k_passive": (("KshapePassive",), 5.0),
    "af": (("Af",), 0.25),
    "flen": (("Flen",), 1.4),
    "fv_extrapolation_threshold": (("fv_linear_extrap_threshold",), 0.95),
    "max_contraction_velocity": (("max_contraction_velocity", "Vmax"), 10.0),
    "activation_time_constant": (("activation_time_constant",), 0.015),
    "deactivation_time_constant": (("deactivation_time_constant",), 0.05),
    "minimum_activation": (("minimum_activation",), 0.01),
    "maximum_pennation_angle": (("maximum_pennation_angle",), math.acos(0.1)),
}
_FUNCTION_TAGS = ("Constant", "LinearFunction", "PolynomialFunction", "PiecewiseLinearFunction", "SimmSpline",
                  "NaturalCubicSpline", "MultiplierFunction", "GCVSpline")
_JOINT_TAGS = ("WeldJoint", "PinJoint", "SliderJoint", "GimbalJoint", "UniversalJoint", "CustomJoint")


class OsimError(ValueError):
    """An .osim file that cannot be read (the message says where and what to do)."""


# ------------------------------------------------------------------------------ XML helpers

def _text(el, tag, default=None):
    child = el.find(tag) if el is not None else None
    if child is None or child.text is None or not child.text.strip():
        return default
    return child.text.strip()


def _floats(text) -> np.ndarray:
    return np.array([float(v) for v in text.split()], dtype=float) if text else np.zeros(0)


def _vec(el, tag, default=(0.0, 0.0, 0.0)) -> np.ndarray:
    text = _text(el, tag)
    return np.array(default, dtype=float) if text is None else _floats(text)


def _bool(text, default=False) -> bool:
    return default if text is None else text.strip().lower() == "true"


def _last(path: str | None) -> str | None:
    """The component name a socket path ends in (``/bodyset/pelvis`` -> ``pelvis``)."""
    return None if path is None else path.strip().rstrip("/").split("/")[-1]


def xyz_body_fixed(angles) -> np.ndarray:
    """Rotation matrix of a body-fixed x-y-z rotation sequence (OpenSim orientations)."""
    a, b, c = np.asarray(angles, dtype=float)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    ry = np.array([[math.cos(b), 0, math.sin(b)], [0, 1, 0], [-math.sin(b), 0, math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    return rx @ ry @ rz


def matrix_quat(r) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix."""
    r = np.asarray(r, dtype=float)
    t = np.trace(r)
    if t > 0:
        s = 2.0 * math.sqrt(1.0 + t)
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0] * 4
        q[0] = (r[k, j] - r[j, k]) / s
        q[1 + i] = 0.25 * s
        q[1 + j] = (r[j, i] + r[i, j]) / s
        q[1 + k] = (r[k, i] + r[i, k]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)


@dataclass
class _Pose:
    """A rigid transform: rotation R and translation p (x_parent = R x + p)."""

    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    p: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __mul__(self, other: "_Pose") -> "_Pose":
        return _Pose(self.R @ other.R, self.R @ other.p + self.p)

    def inverse(self) -> "_Pose":
        return _Pose(self.R.T, -self.R.T @ self.p)


class _Warnings:
    """Collects unsupported elements; one warning per (element type, action)."""

    def __init__(self, path):
        self.path = path
        self.items: dict[tuple[str, str], list[str]] = defaultdict(list)

    def add(self, element: str, name: str, instead: str):
        self.items[(element, instead)].append(name)

    def emit(self):
        for (element, instead), names in self.items.items():
            shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
            warnings.warn(f"{self.path}: {element} not supported ({len(names)}: {shown}); {instead}", stacklevel=3)


# ------------------------------------------------------------------------------ the reader

def read_osim(path) -> ModelSpec:
    """The ModelSpec of an .osim file (muscle groups empty; see `trunk_drake.model.osim_config`)."""
    path = Path(path)
    if not path.is_file():
        raise OsimError(f"OpenSim model file not found: {path} (give the path of an existing .osim file)")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as err:
        raise OsimError(f"{path} is not valid XML ({err}); is it an OpenSim .osim model file?") from None
    model = root.find("Model") if root.tag == "OpenSimDocument" else (root if root.tag == "Model" else None)
    if model is None:
        raise OsimError(f"{path} has no <Model> element; is it an OpenSim .osim model file?")
    return _Reader(path, model, int(root.get("Version", "40000"))).spec()


class _Reader:
    def __init__(self, path, model, version):
        self.path, self.model, self.version = path, model, version
        self.warn = _Warnings(path)
        defaults = model.find("defaults")
        self.defaults = {el.tag: el for el in (defaults if defaults is not None else [])}
        self.frames: dict[str, tuple[str, _Pose]] = {"ground": ("ground", _Pose())}
        self.body_els = {b.get("name"): b for b in model.findall("BodySet/objects/Body")}
        for name in self.body_els:
            self.frames[name] = (name, _Pose())
        ground = model.find("Ground") if model.find("Ground") is not None else model.find("ground")
        if ground is not None:
            self.frames[ground.get("name", "ground")] = ("ground", _Pose())

    # ---- structure ---------------------------------------------------------------------
    def spec(self) -> ModelSpec:
        joints_el = self._joint_elements()
        self._offset_frames(joints_el)
        coords, joint_specs, parents, poses = [], [], {}, {}
        for el in joints_el:
            parsed = self._joint(el)
            if parsed is None:
                continue
            child, parent, X_PB0, axes, joint_coords = parsed
            if child in parents:
                raise OsimError(f"{self.path}: body {child} has two joints (closed kinematic loops are not supported)")
            parents[child], poses[child] = parent, X_PB0
            joint_specs.extend(axes)
            coords.extend(joint_coords)
        bodies = self._bodies(parents, poses)
        wraps, wrap_index = self._wraps()
        sites, muscles, constants = self._muscles(wrap_index, wraps)
        couplers = self._couplers({c.name for c in coords})
        self.warn.emit()
        return ModelSpec(
            name=self.model.get("name", self.path.stem),
            bodies=bodies,
            joints=tuple(joint_specs),
            sites=tuple(sites),
            wraps=tuple(wraps),
            muscles=tuple(muscles),
            coordinates=tuple(coords),
            couplers=tuple(couplers),
            gravity=_vec(self.model, "gravity", (0.0, -9.80665, 0.0)),
            path_semantics="opensim",
            muscle_constants=constants,
            source=f"{self.path.name} (OpenSim document version {self.version})",
        )

    def _joint_elements(self):
        if self.model.find("JointSet") is not None:
            els = list(self.model.findall("JointSet/objects/*"))
        else:
            els = [j for b in self.body_els.values() for j in b.findall("Joint/*")]
        for el in els:
            if el.tag not in _JOINT_TAGS:
                self.warn.add(el.tag, el.get("name", "?"), "welded with its joint frames aligned (zero displacement)")
        return els

    def _offset_frames(self, joints_el):
        """PhysicalOffsetFrames of the model's and bodies' components and of 4.x joints.

        Joint frames are known by their path ``jointset/<joint>/<frame>`` (frame names repeat
        across joints); the others by their name.
        """
        pending = [(f.get("name"), f) for f in self.model.findall("components/PhysicalOffsetFrame")]
        for body in self.body_els.values():
            pending += [(f.get("name"), f) for f in body.findall("components/PhysicalOffsetFrame")]
        for el in joints_el:
            pending += [(f"jointset/{el.get('name')}/{f.get('name')}", f) for f in el.findall("frames/PhysicalOffsetFrame")]
        for _ in range(len(pending) + 1):
            left = []
            for key, f in pending:
                parent = _last(_text(f, "socket_parent"))
                if parent not in self.frames:
                    left.append((key, f))
                    continue
                body, X = self.frames[parent]
                self.frames[key] = (body, X * _Pose(xyz_body_fixed(_vec(f, "orientation")), _vec(f, "translation")))
            pending = left
        for key, _ in pending:
            self.warn.add("PhysicalOffsetFrame without a known parent", key, "ignored")

    def _frame(self, name, where) -> tuple[str, _Pose]:
        if name not in self.frames:
            raise OsimError(f"{self.path}: {where} refers to frame {name!r}, which the model does not define")
        return self.frames[name]

    def _socket_frame(self, path: str | None, joint: str | None, where: str) -> tuple[str, _Pose]:
        """The frame a socket path names: a joint's own frame, a body, ground or a named frame."""
        if path is None:
            raise OsimError(f"{self.path}: {where} has no frame")
        parts = [p for p in path.strip().split("/") if p not in ("", ".", "..")]
        if joint is not None and len(parts) == 1 and f"jointset/{joint}/{parts[0]}" in self.frames:
            return self.frames[f"jointset/{joint}/{parts[0]}"]
        if len(parts) >= 3 and parts[-3] == "jointset":
            return self._frame("/".join(parts[-3:]), where)
        return self._frame(parts[-1], where)

    def _joint(self, el):
        """(child, parent, X_PB at zero displacements, axis JointSpecs, CoordinateSpecs) or None."""
        name = el.get("name", "?")
        if self.version >= 30000 and el.find("socket_parent_frame") is not None:
            parent, X_PF = self._socket_frame(_text(el, "socket_parent_frame"), name, f"joint {name}")
            child, X_BM = self._socket_frame(_text(el, "socket_child_frame"), name, f"joint {name}")
        else:
            parent = _last(_text(el, "parent_body"))
            child = self._owner_body(el)
            X_PF = _Pose(xyz_body_fixed(_vec(el, "orientation_in_parent")), _vec(el, "location_in_parent"))
            X_BM = _Pose(xyz_body_fixed(_vec(el, "orientation")), _vec(el, "location"))
            if parent not in self.frames:
                raise OsimError(f"{self.path}: joint {name} has parent body {parent!r}, which the model does not define")
        if _bool(_text(el, "reverse")):
            self.warn.add("reversed joint", name, "read parent to child as written")
        coords = self._coordinates(el)
        X_PB0 = X_PF * X_BM.inverse()
        if el.tag not in _JOINT_TAGS:
            return child, parent, X_PB0, [], []
        axes = []
        for kind, axis, coord_names, function, axis_name in self._transform_axes(el, coords):
            if len(coord_names) > 1:
                self.warn.add("transform axis with several coordinates", f"{name}/{axis_name}", "held at its value at the default pose")
                function = constant(0.0)
                coord_names = []
            coord = coord_names[0] if coord_names else None
            if coord is None and function.kind != "constant":
                function = constant(float(function.value(0.0)))
            if coord is None and function.coefficients[0] == 0.0:
                continue
            unit = X_BM.R @ (axis / np.linalg.norm(axis))
            axes.append(JointSpec(
                name=f"{name}/{axis_name}", body=child, kind="hinge" if kind == "rotation" else "slide",
                axis=unit, anchor=X_BM.p.copy(), range=(-math.inf, math.inf), coordinate=coord, function=function,
            ))
        # translations act before rotations (the child-side frame translates in the parent-side frame)
        axes.sort(key=lambda j: j.kind == "hinge")
        return child, parent, X_PB0, axes, [replace(c, kind=_motion_type(c.name, axes)) for c in coords]

    def _owner_body(self, joint_el):
        for name, body in self.body_els.items():
            if any(j is joint_el for j in body.findall("Joint/*")):
                return name
        raise OsimError(f"{self.path}: joint {joint_el.get('name')} is not inside a body")

    def _coordinates(self, el) -> list[CoordinateSpec]:
        out = []
        for c in el.findall("coordinates/Coordinate") + el.findall("CoordinateSet/objects/Coordinate"):
            rng = _floats(_text(c, "range", "-1e10 1e10"))
            out.append(CoordinateSpec(
                name=c.get("name"), kind="rotational",
                default=float(_text(c, "default_value", "0")), range=(float(rng[0]), float(rng[1])),
                locked=_bool(_text(c, "locked")),
            ))
        return out

    def _transform_axes(self, el, coords):
        """(kind, axis in the joint frame, coordinate names, function, name) of each transform axis."""
        names = [c.name for c in coords]
        if el.tag == "CustomJoint":
            st = el.find("SpatialTransform")
            for ta in (st if st is not None else []):
                axis_name = ta.get("name", "")
                coord_names = (_text(ta, "coordinates") or "").split()
                function = self._function_of(ta, "function") or (
                    Function("linear", (1.0, 0.0)) if len(coord_names) == 1 else constant(0.0))
                yield ("rotation" if axis_name.startswith("rotation") else "translation"), _vec(ta, "axis"), coord_names, function, axis_name
            return
        identity = Function("linear", (1.0, 0.0))
        basis = np.eye(3)
        if el.tag == "PinJoint":
            yield "rotation", basis[2], names[:1], identity, "rotation1"
        elif el.tag == "SliderJoint":
            yield "translation", basis[0], names[:1], identity, "translation1"
        elif el.tag in ("GimbalJoint", "UniversalJoint"):
            for k, coord in enumerate(names):
                yield "rotation", basis[k], [coord], identity, f"rotation{k + 1}"

    # ---- functions ---------------------------------------------------------------------
    def _function_of(self, el, wrapper) -> Function | None:
        """The function inside `el` (4.x: a direct child; older: inside <wrapper>)."""
        holder = el.find(wrapper)
        for parent in ((holder,) if holder is not None else ()) + (el,):
            for child in parent:
                if child.tag in _FUNCTION_TAGS:
                    return self._function(child)
                if child.tag.endswith(("Function", "Spline")) and child.tag != wrapper:
                    self.warn.add(f"function {child.tag}", el.get("name") or el.tag, "replaced by the constant 0")
                    return constant(0.0)
        return None

    def _function(self, el) -> Function:
        tag = el.tag
        if tag == "Constant":
            return constant(float(_text(el, "value", "0")))
        if tag == "LinearFunction":
            return Function("linear", tuple(_floats(_text(el, "coefficients", "1 0"))))
        if tag == "PolynomialFunction":
            return Function("polynomial", tuple(_floats(_text(el, "coefficients", "0"))))
        if tag == "MultiplierFunction":
            inner = self._function_of(el, "function")
            return Function("multiplier", scale=float(_text(el, "scale", "1")), inner=inner or constant(0.0))
        x, y = tuple(_floats(_text(el, "x"))), tuple(_floats(_text(el, "y")))
        if tag == "PiecewiseLinearFunction":
            return Function("piecewise_linear", x=x, y=y)
        if tag == "GCVSpline":
            self.warn.add("GCVSpline", el.get("name") or "function", "interpolated by a cubic spline through its knots")
        return Function("spline", x=x, y=y)

    # ---- bodies, wraps, constraints --------------------------------------------------------
    def _bodies(self, parents, poses) -> tuple[BodySpec, ...]:
        order, seen = [], set()

        def visit(name):
            if name in seen or name == "ground":
                return
            parent = parents.get(name)
            if parent is not None and parent != "ground":
                visit(parent)
            seen.add(name)
            order.append(name)

        for name in self.body_els:
            if name != "ground":
                visit(name)
        bodies = []
        for name in order:
            el = self.body_els[name]
            X = poses.get(name)
            if X is None:
                self.warn.add("body without a joint", name, "welded to the ground at its origin")
                X = _Pose()
            parent = parents.get(name)
            bodies.append(BodySpec(
                name=name, parent=None if parent in (None, "ground") else parent, pos=X.p.copy(), quat=matrix_quat(X.R),
                mass=float(_text(el, "mass", "0")), com=_vec(el, "mass_center"), inertia=self._inertia(el),
            ))
        return tuple(bodies)

    @staticmethod
    def _inertia(el) -> np.ndarray:
        text = _text(el, "inertia")
        if text is not None:
            xx, yy, zz, xy, xz, yz = _floats(text)
        else:
            xx, yy, zz, xy, xz, yz = (float(_text(el, f"inertia_{k}", "0")) for k in ("xx", "yy", "zz", "xy", "xz", "yz"))
        return np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])

    def _wraps(self):
        wraps, index = [], {}
        for body, el in self.body_els.items():
            for w in el.findall("WrapObjectSet/objects/*"):
                name = w.get("name")
                if w.tag not in ("WrapSphere", "WrapCylinder", "WrapEllipsoid"):
                    self.warn.add(w.tag, name, "paths do not wrap over it")
                    continue
                if not _bool(_text(w, "active"), True):
                    continue
                radii = _vec(w, "dimensions", (0.05, 0.05, 0.05)) if w.tag == "WrapEllipsoid" else None
                radius = float(_text(w, "radius", "0.05")) if radii is None else float(radii.max())
                index[name] = len(wraps)
                wraps.append(WrapSpec(
                    name=name, body=body, kind=w.tag[4:].lower(), radius=radius,
                    pos=_vec(w, "translation"), quat=matrix_quat(xyz_body_fixed(_vec(w, "xyz_body_rotation"))),
                    length=float(_text(w, "length", "1.0")) if w.tag == "WrapCylinder" else math.inf,
                    radii=radii, quadrant=_quadrant(_text(w, "quadrant", "all"), self.path, name),
                ))
        return wraps, index

    def _couplers(self, coordinate_names) -> list[CouplerSpec]:
        out = []
        for el in self.model.findall("ConstraintSet/objects/*"):
            name = el.get("name", "?")
            if el.tag != "CoordinateCouplerConstraint":
                self.warn.add(el.tag, name, "ignored")
                continue
            if _bool(_text(el, "isDisabled")) or not _bool(_text(el, "isEnforced"), True):
                continue
            independent = (_text(el, "independent_coordinate_names") or "").split()
            dependent = _text(el, "dependent_coordinate_name")
            function = self._function_of(el, "coupled_coordinates_function")
            if len(independent) != 1 or function is None:
                self.warn.add("coordinate coupler with several independent coordinates", name, "ignored")
                continue
            for c in independent + [dependent]:
                if c not in coordinate_names:
                    raise OsimError(f"{self.path}: constraint {name} refers to coordinate {c!r}, which no joint defines")
            out.append(CouplerSpec(name, dependent, independent[0], function, float(_text(el, "scale_factor", "1"))))
        return out

    # ---- muscles ---------------------------------------------------------------------------
    def _property(self, el, names, default):
        for source in (el, self.defaults.get(el.tag)):
            for n in names:
                value = _text(source, n)
                if value is not None:
                    return float(value)
        return default

    def _muscles(self, wrap_index, wraps):
        sites, muscles, constants = [], [], defaultdict(set)
        for el in self.model.findall("ForceSet/objects/*"):
            name = el.get("name", "?")
            path_el = el.find("GeometryPath")
            if el.tag not in MUSCLE_TYPES:
                if path_el is None:
                    self.warn.add(el.tag, name, "ignored (trunk-drake models muscles, bushings and reflexes itself)")
                    continue
                self.warn.add(el.tag, name, "read as a Thelen 2003 muscle with its Hill parameters")
            elif el.tag != "Thelen2003Muscle":
                self.warn.add(f"{el.tag} force-length-velocity curves", name, "simulated with Thelen 2003 curves and its parameters")
            if _bool(_text(el, "isDisabled")) or not _bool(_text(el, "appliesForce"), True):
                self.warn.add("disabled muscle", name, "left out, as OpenSim does")
                continue
            first = len(sites)
            for p in path_el.findall("PathPointSet/objects/*"):
                sites.append(self._path_point(p, f"muscle {name}"))
            path_wraps = []
            for w in path_el.findall("PathWrapSet/objects/PathWrap"):
                target = _text(w, "wrap_object")
                if target not in wrap_index:
                    self.warn.add("path wrap over a missing, inactive or unsupported wrap object", f"{name}/{target}", "not wrapped")
                    continue
                rng = _floats(_text(w, "range", "-1 -1")).astype(int)
                method = (_text(w, "method", "hybrid") or "hybrid").lower()
                path_wraps.append(PathWrapSpec(wrap_index[target], int(rng[0]), int(rng[1]), method if method in ("hybrid", "midpoint", "axial") else "hybrid"))
            if len(sites) - first < 2:
                raise OsimError(f"{self.path}: muscle {name} has fewer than two path points")
            if el.tag == "Thelen2003Muscle":
                for key, (props, default) in _THELEN_PROPERTIES.items():
                    constants[key].add(self._property(el, props, default))
            muscles.append(MuscleSpec(
                name=name,
                path=tuple(PathElement("site", i) for i in range(first, len(sites))),
                max_isometric_force=self._property(el, ("max_isometric_force",), 1000.0),
                optimal_fiber_length=self._property(el, ("optimal_fiber_length",), 0.1),
                tendon_slack_length=self._property(el, ("tendon_slack_length",), 0.2),
                pennation_angle=self._property(el, ("pennation_angle_at_optimal", "pennation_angle"), 0.0),
                path_wraps=tuple(path_wraps),
                source_type=el.tag,
            ))
        shared = {}
        for key, values in constants.items():
            if len(values) > 1:
                self.warn.add(f"per-muscle Thelen constant {key}", ", ".join(f"{v:g}" for v in sorted(values)),
                              f"every muscle uses the smallest, {sorted(values)[0]:g}")
            shared[key] = sorted(values)[0]
        return sites, muscles, shared or {key: default for key, (_, default) in _THELEN_PROPERTIES.items()}

    def _path_point(self, p, where) -> SiteSpec:
        name = p.get("name", "")
        socket = _text(p, "socket_parent_frame")
        where = f"{where} path point {name}"
        body, X = self._socket_frame(socket, None, where) if socket else self._frame(_last(_text(p, "body")), where)
        condition = motion = None
        if p.tag == "ConditionalPathPoint":
            rng = _floats(_text(p, "range", "0 0"))
            coord = _last(_text(p, "socket_coordinate") or _text(p, "coordinate"))
            condition = (coord, float(rng[0]), float(rng[1]))
        elif p.tag == "MovingPathPoint":
            motion = []
            for axis in "xyz":
                coord = _last(_text(p, f"socket_{axis}_coordinate") or _text(p, f"{axis}_coordinate"))
                f = self._function_of(p, f"{axis}_location") or self._function_of(p, f"{axis.upper()}Attachment")
                motion.append((coord, f or constant(0.0)))
            if X.p.any() or not np.allclose(X.R, np.eye(3)):
                raise OsimError(f"{self.path}: {where} moving point {name} sits on an offset frame (not supported)")
            motion = tuple(motion)
        elif p.tag != "PathPoint":
            self.warn.add(p.tag, f"{where}/{name}", "read as a fixed path point")
        location = X.R @ _vec(p, "location") + X.p
        return SiteSpec(name=name, body=body, pos=location, condition=condition, motion=motion)


def _motion_type(coordinate: str, axes: list[JointSpec]) -> str:
    """OpenSim's motion type: "rotational" / "translational" where the coordinate is an axis'
    displacement (a linear function of slope +-1), else "coupled" (OpenSim then keeps the
    coordinate in its own units in degree-valued motion files)."""
    kind = None
    for j in axes:
        if j.coordinate != coordinate:
            continue
        form = j.function.linear_form() if j.function.kind == "linear" else None
        if form is not None and abs(form[0]) == 1.0:
            kind = "rotational" if j.kind == "hinge" else "translational"
        elif kind is None:
            kind = "coupled"
    return kind or "rotational"


def _quadrant(text, path, name) -> str:
    q = (text or "all").strip().lower().lstrip("+")
    if q in ("all", "unassigned"):
        return "all"
    if q not in ("x", "-x", "y", "-y", "z", "-z"):
        raise OsimError(f"{path}: wrap object {name} has quadrant {text!r}; expected all, x, -x, y, -y, z or -z")
    return q


def attach_fixed_roots(spec: ModelSpec, pelvis: str) -> ModelSpec:
    """Weld every other ground-welded body to `pelvis` when the pelvis is welded to ground too."""
    jointed = {j.body for j in spec.joints}
    by_name = {b.name: b for b in spec.bodies}
    if by_name[pelvis].parent is not None or pelvis in jointed:
        return replace(spec, pelvis=pelvis)
    X_WP = _Pose(quat_matrix(by_name[pelvis].quat), np.asarray(by_name[pelvis].pos))
    bodies = []
    for b in spec.bodies:
        if b.parent is None and b.name != pelvis and b.name not in jointed:
            X = X_WP.inverse() * _Pose(quat_matrix(b.quat), np.asarray(b.pos))
            b = replace(b, parent=pelvis, pos=X.p, quat=matrix_quat(X.R))
        bodies.append(b)
    return replace(spec, bodies=tuple(bodies), pelvis=pelvis)


# ------------------------------------------------------------------------------ model mapping

def mapping_for(model_name: str) -> dict:
    """The mapping file `models/osim/<model name>.toml`, or {} when there is none."""
    from trunk_drake.data import load_toml, models_dir

    name = f"osim/{model_name}.toml"
    return load_toml(name) if (models_dir() / name).is_file() else {}


def load_osim_spec(path, mapping: dict | None = None) -> ModelSpec:
    """An .osim file as a ModelSpec ready for `load_model`: lumbar levels, pelvis, groups, landmarks.

    `mapping` defaults to the model's file in ``models/osim/`` (see Lumbar_C_210.toml); without
    one, the levels are the bodies lumbar5 ... lumbar1 where they exist, and muscles take the
    thesis' groups by name prefix where one matches (else group "other").
    """
    path = Path(path)
    key = (str(path.resolve()), path.stat().st_mtime_ns if path.is_file() else 0)
    return _load_osim_spec(key, path, None if mapping is None else tuple(sorted(mapping.items())))


@lru_cache(maxsize=8)
def _load_osim_spec(key, path, mapping_items) -> ModelSpec:
    from trunk_drake.data import load_toml
    from trunk_drake.model.architecture import muscle_group_of

    spec = read_osim(path)
    mapping = dict(mapping_items) if mapping_items is not None else mapping_for(spec.name)
    names = {b.name for b in spec.bodies}
    levels = mapping.get("levels", {})
    level_bodies = tuple(levels.get(level, body) for level, body in zip(LEVELS, LEVEL_BODIES))
    if not set(level_bodies) <= names:
        level_bodies = ()
    pelvis = spec.body(level_bodies[0]).parent if level_bodies else next(b.name for b in spec.bodies if b.parent is None)
    spec = replace(attach_fixed_roots(spec, pelvis), level_bodies=level_bodies)
    groups_table = load_toml(mapping.get("groups", {}).get("file", "muscle_groups.toml"))
    muscles = []
    for m in spec.muscles:
        try:
            group = muscle_group_of(m.name, groups_table)
        except ValueError:
            group = "other"
        muscles.append(replace(m, group=group))
    if not mapping and any(m.group == "other" for m in muscles):
        warnings.warn(f"{path}: no mapping file models/osim/{spec.name}.toml; "
                      f"{sum(m.group == 'other' for m in muscles)} muscles match no thesis group and form group 'other'",
                      stacklevel=3)
    landmarks = ()
    if mapping.get("landmarks", {}).get("from") == "myotorso":
        from trunk_drake.model.myotorso import read_myotorso

        landmarks = read_myotorso().landmarks
    return replace(spec, muscles=tuple(muscles), landmarks=landmarks)
