"""Tables of a one-coordinate model's posture-dependent terms, for the diagram's per-step evaluations.

With one coordinate q (the lumbar rhythm on a welded pelvis, the default passenger) every term the
equations of motion need at a posture is a function of one number: each muscle's length L(q) and moment
arm -dL/dq, the generalized mass M(q), the gravity force g(q), the velocity-product term c(q) v^2 (one
coordinate: c = M'/2) and the inertial load of a unit platform acceleration (``M J_com^T``, per world
axis). A `CoordinateTable` holds them as piecewise cubics on a uniform grid, so a step's evaluations
cost a few vector operations instead of the body kinematics, 210 paths and three multibody calls:

* lengths by cubic Hermite interpolation with the exact moment arms as slopes; the moment arm is the
  interpolant's own derivative, so muscle work stays the derivative of length (no energy leak);
* the rigid-body terms by not-a-knot cubic splines of their exact values.

The rhythm on a sliding pelvis (``pelvis_tx``, the seat or the thesis' force perturbation) uses the welded
model's table: the slide translates every body, so the paths, M, g and c of the lumbar coordinate are unchanged; the
slide's own terms are the total mass, gravity along it (constants, `Slide`) and the coupling ``M J_com^T d`` already
tabulated, whose slope gives the slide's velocity-product term (`CoordinateTable.accelerations`).

OpenSim 4.5's FunctionBasedPath does the same for muscle paths (fitted polynomials of the coordinates).
The grid spans the coordinate's range (where the geometry was verified). A wrapping surface that a path
starts or stops touching gives the exact moment arm a jump, which no cubic follows: an interval whose
midpoint misses the exact lengths or moment arms by more than TOLERANCE is left out of the table. Outside
the table (out of range, or such an interval) the callers use the exact computation. `tests/test_tables.py` bounds the table's error
against the exact kernel; `tests/test_accuracy.py` checks the trials against the stored accurate reference.
"""

from __future__ import annotations

import hashlib
import pickle
from dataclasses import dataclass, replace

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable
from scipy.interpolate import CubicHermiteSpline, CubicSpline

from trunk_drake.model.paths import PathState

STEP = np.radians(0.125)  # grid spacing (rad)
TOLERANCE = {"length": 1e-8, "moment_arm": 1e-6}  # m: an interval's largest error at its midpoint, else left out
_CACHE: dict = {}  # (hash of the spec, load options) -> table: built once per process and model


@dataclass(frozen=True)
class Slide:
    """The pelvis slide under a tabulated coordinate (coordinates ``pelvis_tx`` then it): its world direction,
    the total mass it carries and gravity's force along it. Kinetic energy ``m x'^2/2 + b(q) x' q' + M(q) q'^2/2``
    with ``b(q) = M J_com^T d``, so ``m x'' + b q'' + b' q'^2 = f_x + gravity`` and ``b x'' + M q'' + c q'^2 = g + tau``."""

    direction: np.ndarray
    mass: float
    gravity: float


@dataclass(frozen=True)
class CoordinateTable:
    """Piecewise cubics in q on ``lo + step * k``: `coefficients` (4, intervals, columns), highest power first,
    columns = lengths of the n muscles, then M, g, c and the three axes of ``M J_com^T``."""

    lo: float
    step: float
    coefficients: np.ndarray
    slopes: np.ndarray  # (3, intervals, n): derivative coefficients of the length columns
    n_muscles: int
    exact: np.ndarray  # (intervals,) bool: intervals left out (a moment-arm jump inside)
    slide: Slide | None = None  # the model's pelvis slide (its first coordinate), or None (the tabulated one only)

    @property
    def width(self) -> int:
        """Coordinates per copy of the model: the tabulated one last, after the slide if there is one."""
        return 1 if self.slide is None else 2

    @property
    def hi(self) -> float:
        return self.lo + self.step * self.coefficients.shape[1]

    def covers(self, q) -> bool:
        """Whether q (a number, or an array of one per copy) lies in tabulated intervals only."""
        if np.ndim(q) == 0:  # one copy, every evaluation: plain numbers
            return self.lo <= q <= self.hi and not self.exact[self._locate(q)[0]]
        return bool(np.all((q >= self.lo) & (q <= self.hi)) and not self.exact[self._locate(q)[0]].any())

    def _locate(self, q):
        """Interval and offset in it: numbers for a number q, arrays (copies,) and (copies, 1) for an array."""
        if np.ndim(q) == 0:
            k = min(int((q - self.lo) / self.step), self.exact.size - 1)
            return k, q - (self.lo + k * self.step)
        k = np.minimum(((q - self.lo) / self.step).astype(int), self.exact.size - 1)
        return k, (q - (self.lo + k * self.step))[:, None]

    def _values(self, q, columns: slice) -> np.ndarray:
        """The columns at q: (columns,) for a number, (copies, columns) for an array."""
        return self._cubic(self.coefficients, *self._locate(q), columns)

    @staticmethod
    def _cubic(coefficients, k, t, columns=slice(None)) -> np.ndarray:
        c = coefficients[:, k, columns]
        return ((c[0] * t + c[1]) * t + c[2]) * t + c[3]

    def paths(self, q, v=None) -> PathState:
        """Lengths, moment arms and (with v) lengthening velocities at q. For an array q (one value per copy)
        the muscles of copy b are rows b*n ... b*n+n-1, and the moment arms (copies * n, copies) are
        block-diagonal (copy b's muscles act on its own coordinate only), as one model with `copies` coordinates. With a
        `slide` each copy has two coordinates (the slide first), and the slide's moment arms are zero."""
        n = self.n_muscles
        k, t = self._locate(q)
        lengths = self._cubic(self.coefficients, k, t, slice(0, n))
        s = self.slopes[:, k]
        slope = (s[0] * t + s[1]) * t + s[2]  # dL/dq: (n,) or (copies, n)
        w = self.width
        if np.ndim(q) == 0:
            arms = -slope[:, None] if w == 1 else np.column_stack([np.zeros(n), -slope])
            return PathState(lengths=lengths, moment_arms=arms, velocities=None if v is None else slope * v)
        copies = q.size
        arms = np.zeros((copies, n, copies * w))
        arms[np.arange(copies), :, w * np.arange(copies) + w - 1] = -slope
        return PathState(lengths=lengths.reshape(-1), moment_arms=arms.reshape(copies * n, copies * w),
                         velocities=None if v is None else (slope * v[:, None]).reshape(-1))

    def dynamics(self, q):
        """M(q), g(q) and c(q) (numbers, or one per copy): the equation of motion is M v' + c v^2 = g + tau."""
        values = self._values(q, slice(self.n_muscles, self.n_muscles + 3))
        return values[..., 0], values[..., 1], values[..., 2]

    def com_load(self, q, direction):
        """``M J_com^T d`` at q (a number, or one per copy; `TrunkModel.mass_weighted_com_jacobian`)."""
        return self._values(q, slice(self.n_muscles + 3, None)) @ direction

    def accelerations(self, q, v, applied) -> np.ndarray:
        """Generalized accelerations of copies of the model (arrays of `width` coordinates per copy, in turn) under
        the generalized forces `applied`: ``M q'' + c q'^2 = g + tau``, with a `slide` the 2x2 system of `Slide`."""
        w = self.width
        angle, rate, torque = q[w - 1::w], v[w - 1::w], applied[w - 1::w]
        k, t = self._locate(angle)
        mass, gravity, bias = self._cubic(self.coefficients, k, t, slice(self.n_muscles, self.n_muscles + 3)).T
        rotation = gravity - bias * rate**2 + torque
        if self.slide is None:
            return rotation / mass
        s, load = self.slide, slice(self.n_muscles + 3, None)
        coupling = self._cubic(self.coefficients, k, t, load) @ s.direction
        c = self.coefficients[:3, k, load]
        slope = ((3 * c[0] * t + 2 * c[1]) * t + c[2]) @ s.direction  # d(M J_com^T d)/dq
        translation = applied[0::2] + s.gravity - slope * rate**2
        det = s.mass * mass - coupling**2
        out = np.empty(q.size)
        out[0::2] = (mass * translation - coupling * rotation) / det
        out[1::2] = (s.mass * rotation - coupling * translation) / det
        return out


def coordinate_table(model) -> CoordinateTable | None:
    """The table of `model` (built once per spec and configuration), or None where it has none: more than
    one coordinate (besides the pelvis slide: then the welded model's table with its `Slide`), or paths without
    compiled kinematics (OpenSim files)."""
    sliding = model.coordinates[:1] == ["pelvis_tx"]
    if model.plant.num_positions() != 1 + sliding or model._kinematics is None:
        return None
    key = (hashlib.sha256(pickle.dumps(model.spec)).hexdigest(), *model.load_options.values())
    if key not in _CACHE:
        if len(_CACHE) >= 8:
            _CACHE.pop(next(iter(_CACHE)))
        _CACHE[key] = replace(coordinate_table(model.variant(pelvis_free=False)), slide=_slide(model)) if sliding else _build(model)
    return _CACHE[key]


def _slide(model) -> Slide:
    """The pelvis slide of `model` (coordinate 0): the pelvis' velocity per unit slide rate, and the slide's constant
    mass-matrix entry and gravity force."""
    plant = model.plant
    context = plant.CreateDefaultContext()
    pelvis = plant.GetBodyByName(model.spec.pelvis).body_frame()
    jacobian = plant.CalcJacobianTranslationalVelocity(context, JacobianWrtVariable.kV, pelvis, np.zeros(3),
                                                       plant.world_frame(), plant.world_frame())
    return Slide(jacobian[:, 0].copy(), float(plant.CalcMassMatrix(context)[0, 0]),
                 float(plant.CalcGravityGeneralizedForces(context)[0]))


def _build(model) -> CoordinateTable:
    lo, hi = model.coordinate_info[0].range
    q = lo + STEP * np.arange(int(np.ceil((hi - lo) / STEP)) + 1)
    lengths, slopes, rigid = [], [], []
    plant, context = model.plant, model.plant.CreateDefaultContext()
    for value in q:
        state = model.path_state_from_q(np.array([value]))
        lengths.append(state.lengths)
        slopes.append(-state.moment_arms[:, 0])
        plant.SetPositionsAndVelocities(context, [value, 1.0])  # at v = 1 the bias term is c
        load = [model.mass_weighted_com_jacobian(np.array([value]), axis)[0] for axis in np.eye(3)]
        rigid.append([plant.CalcMassMatrix(context)[0, 0], plant.CalcGravityGeneralizedForces(context)[0],
                      plant.CalcBiasTerm(context)[0], *load])
    hermite = CubicHermiteSpline(q, np.array(lengths), np.array(slopes))
    spline = CubicSpline(q, np.array(rigid))
    coefficients = np.concatenate([hermite.c, spline.c], axis=2)
    table = CoordinateTable(float(q[0]), STEP, np.ascontiguousarray(coefficients),
                            np.ascontiguousarray(hermite.derivative().c), model.n_muscles, np.zeros(q.size - 1, bool))
    for k, middle in enumerate(q[:-1] + STEP / 2):
        exact, approximate = model.path_state_from_q(np.array([middle])), table.paths(middle)
        table.exact[k] = (np.abs(approximate.lengths - exact.lengths).max() > TOLERANCE["length"]
                          or np.abs(approximate.moment_arms - exact.moment_arms).max() > TOLERANCE["moment_arm"])
    return table
