"""Thelen (2003) Hill-type muscle model, vectorised over muscles (numpy; the per-step rigid-tendon
path and the curves are numba-compiled scalar kernels).

Reproduces OpenSim 4.6 ``Thelen2003Muscle`` (with its ``MuscleFixedWidthPennationModel``
and ``MuscleFirstOrderActivationDynamicModel``) formula for formula:

* curves of normalised quantities: Gaussian active force-length, exponential passive
  force-length (zero at and below optimal length), Thelen's activation-dependent
  force-velocity relation with OpenSim's linear extrapolation (below the concentric
  asymptote and above ``fv_extrapolation_threshold * flen``), and OpenSim's tendon curve
  (exponential toe up to 0.33 F_max, then linear; toe strain and slope from the exact
  slope-continuity condition, not the paper's rounded 0.609 e0);
* constant-thickness (parallelogram) pennation, fiber length clamped at the length where
  the pennation angle reaches ``maximum_pennation_angle``;
* rigid tendon (fiber kinematics follow the path), compliant tendon (fiber length is a
  state; its derivative comes from inverting force-velocity) and the static fiber
  equilibrium that OpenSim's ``computeInitialFiberEquilibrium`` solves;
* first-order activation dynamics with activation-dependent time constants.

Units are SI (m, m/s, N, s, rad). Normalised fiber length is divided by the optimal fiber
length, tendon strain is ``l_tendon / l_slack - 1``, and normalised fiber velocity is
divided by ``max_contraction_velocity * optimal_fiber_length`` (positive = lengthening).
Arrays have shape ``(n_muscles,)``; scalars broadcast.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numba
import numpy as np

__all__ = [
    "ThelenConstants", "MuscleParameters", "MuscleState", "ForceSplit", "RigidTendonDerivatives",
    "THESIS_CONSTANTS", "active_force_length", "active_force_length_derivative",
    "passive_force_length", "passive_force_length_derivative", "force_velocity",
    "force_velocity_derivatives", "fiber_velocity_from_force", "tendon_force_length",
    "tendon_force_length_derivative", "parallelogram_height", "minimum_fiber_length",
    "pennation_angle", "clamp_activation", "activation_derivative", "RigidKinematics",
    "rigid_kinematics", "rigid_tendon", "rigid_tendon_force",
    "rigid_tendon_force_split", "rigid_tendon_derivatives", "compliant_tendon",
    "equilibrium_fiber_length",
]

_EPS = float(np.finfo(float).eps)          # SimTK::Eps
_SIGNIFICANT_REAL = _EPS ** 0.875          # SimTK::SignificantReal
_K_TOE = 3.0                               # tendon toe shape factor (thesis k_t = 3)
_F_TOE = 33.0 / 100.0                      # normalised force at the end of the toe region


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"ThelenConstants.{name} must be a finite number > 0, got {value!r}")


@dataclass(frozen=True)
class ThelenConstants:
    """Muscle-independent Thelen 2003 constants (OpenSim property name in brackets).

    Defaults are the thesis' values (seed section 2.1.1); activation constants and the
    limits the thesis does not state are OpenSim 4.6's Thelen2003Muscle defaults.
    """

    tendon_strain_at_fmax: float = 0.033       # [FmaxTendonStrain] e0_T
    passive_strain_at_fmax: float = 0.6        # [FmaxMuscleStrain] e0_M
    k_passive: float = 4.0                     # [KshapePassive] k_PE
    gamma: float = 0.5                         # [KshapeActive] Gaussian width of f_AL
    af: float = 0.3                            # [Af] force-velocity shape factor
    flen: float = 1.8                          # [Flen] max normalised lengthening force
    fv_extrapolation_threshold: float = 0.95   # [fv_linear_extrap_threshold]
    max_contraction_velocity: float = 10.0     # [max_contraction_velocity] l_opt/s
    activation_time_constant: float = 0.015    # [activation_time_constant] s
    deactivation_time_constant: float = 0.050  # [deactivation_time_constant] s
    minimum_activation: float = 0.01           # [minimum_activation]
    maximum_pennation_angle: float = math.acos(0.1)  # [maximum_pennation_angle] rad

    def __post_init__(self):
        for name in ("tendon_strain_at_fmax", "passive_strain_at_fmax", "k_passive", "gamma",
                     "af", "max_contraction_velocity", "activation_time_constant",
                     "deactivation_time_constant"):
            _positive(name, getattr(self, name))
        if not (math.isfinite(self.flen) and self.flen > 1.0):
            raise ValueError(f"ThelenConstants.flen must be > 1, got {self.flen!r}")
        if not (1.0 / self.flen < self.fv_extrapolation_threshold < 1.0):
            raise ValueError("ThelenConstants.fv_extrapolation_threshold must lie in "
                             f"(1/flen, 1) = ({1.0 / self.flen:.4g}, 1), "
                             f"got {self.fv_extrapolation_threshold!r}")
        if not (0.0 < self.minimum_activation < 1.0):
            raise ValueError("ThelenConstants.minimum_activation must lie in (0, 1), "
                             f"got {self.minimum_activation!r}")
        if not (0.0 < self.maximum_pennation_angle <= math.pi / 2):
            raise ValueError("ThelenConstants.maximum_pennation_angle must lie in (0, pi/2], "
                             f"got {self.maximum_pennation_angle!r}")

    @classmethod
    def opensim_defaults(cls) -> "ThelenConstants":
        """OpenSim 4.6 Thelen2003Muscle defaults (0.04, 0.6, 5.0, 0.45, 0.25, 1.4)."""
        return cls(tendon_strain_at_fmax=0.04, passive_strain_at_fmax=0.6, k_passive=5.0,
                   gamma=0.45, af=0.25, flen=1.4)

    @property
    def tendon_toe_strain(self) -> float:
        """Strain where the tendon curve turns linear (OpenSim's exact form of 0.609 e0)."""
        t1 = math.exp(3.0)
        return (99.0 * self.tendon_strain_at_fmax * t1) / (166.0 * t1 - 67.0)

    @property
    def tendon_linear_stiffness(self) -> float:
        """Slope of normalised tendon force vs strain in the linear region (~1.712/e0)."""
        return (67.0 / 100.0) * 1.0 / (self.tendon_strain_at_fmax - self.tendon_toe_strain)


THESIS_CONSTANTS = ThelenConstants()


@dataclass
class MuscleParameters:
    """Per-muscle parameters, arrays of shape (n_muscles,), SI units."""

    max_isometric_force: np.ndarray          # N
    optimal_fiber_length: np.ndarray         # m
    tendon_slack_length: np.ndarray          # m
    pennation_angle_at_optimal: np.ndarray   # rad, in [0, pi/2)

    def __post_init__(self):
        n = None
        for name in ("max_isometric_force", "optimal_fiber_length", "tendon_slack_length",
                     "pennation_angle_at_optimal"):
            try:
                arr = np.array(getattr(self, name), dtype=float)
            except (TypeError, ValueError) as err:
                raise ValueError(f"MuscleParameters.{name} must be numeric: {err}") from None
            arr = np.atleast_1d(arr)
            if arr.ndim != 1:
                raise ValueError(f"MuscleParameters.{name} must be 1-D (n_muscles,), "
                                 f"got shape {arr.shape}")
            if n is None:
                n = arr.shape[0]
            elif arr.shape[0] != n:
                raise ValueError(f"MuscleParameters.{name} has {arr.shape[0]} entries, "
                                 f"expected {n} (length of max_isometric_force)")
            bad = ~np.isfinite(arr)
            if bad.any():
                raise ValueError(f"MuscleParameters.{name} contains NaN/inf at index "
                                 f"{np.flatnonzero(bad).tolist()}")
            if name == "pennation_angle_at_optimal":
                bad = (arr < 0) | (arr >= math.pi / 2)
                rule = "in [0, pi/2)"
            else:
                bad = arr <= 0
                rule = "> 0"
            if bad.any():
                i = np.flatnonzero(bad)
                raise ValueError(f"MuscleParameters.{name} must be {rule}; "
                                 f"index {i.tolist()} has {arr[i].tolist()}")
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)
        if n == 0:
            raise ValueError("MuscleParameters.max_isometric_force is empty (no muscles)")

    @property
    def n_muscles(self) -> int:
        return self.max_isometric_force.shape[0]

    @cached_property
    def parallelogram_height(self) -> np.ndarray:
        """Constant fiber 'thickness' ``l_opt sin(alpha_opt)`` (m), computed once."""
        return self.optimal_fiber_length * np.sin(self.pennation_angle_at_optimal)

    @cached_property
    def packed(self) -> np.ndarray:
        """Rows l_slack, h, alpha_opt, l_opt, F_max: one contiguous array for the compiled kernels."""
        return np.array([self.tendon_slack_length, self.parallelogram_height, self.pennation_angle_at_optimal,
                         self.optimal_fiber_length, self.max_isometric_force])


@dataclass
class MuscleState:
    """Muscle quantities, arrays of shape (n_muscles,). Forces in N, lengths in m."""

    activation: np.ndarray               # clamped to [minimum_activation, 1]
    fiber_length: np.ndarray             # m (clamped at the minimum fiber length)
    normalized_fiber_length: np.ndarray  # l_f / l_opt
    pennation_angle: np.ndarray          # rad
    fiber_velocity: np.ndarray           # m/s; compliant tendon: d(fiber_length)/dt
    normalized_fiber_velocity: np.ndarray  # v_f / (v_max l_opt)
    tendon_length: np.ndarray            # m
    tendon_strain: np.ndarray            # l_t / l_slack - 1
    active_force_length: np.ndarray      # f_AL
    passive_force_length: np.ndarray     # f_PE
    force_velocity: np.ndarray           # f_V
    active_fiber_force: np.ndarray       # a f_AL f_V F_max (along the fiber)
    passive_fiber_force: np.ndarray      # f_PE F_max (along the fiber)
    tendon_force: np.ndarray             # N, the force the muscle applies to its path
    fiber_clamped: np.ndarray            # bool: fiber at its minimum length (no active force)


class ForceSplit(NamedTuple):
    """Rigid-tendon force as ``tendon_force = activation * active + passive`` (N)."""

    active: np.ndarray
    passive: np.ndarray


class RigidTendonDerivatives(NamedTuple):
    """Partial derivatives of the rigid-tendon tendon force."""

    d_activation: np.ndarray  # N
    d_length: np.ndarray      # N/m, w.r.t. musculotendon length at fixed velocity
    d_velocity: np.ndarray    # N s/m, w.r.t. musculotendon lengthening velocity


# ----------------------------------------------------------------------------- curves

_jit = numba.njit(cache=True)
_UFUNC_SIGNATURE = ["float64(float64, float64, float64)"]


@_jit
def _fal(l_n, gamma):
    d = l_n - 1.0
    return math.exp(-(d * d) / gamma)


@_jit
def _fpe(l_n, k, e0):
    if l_n > 1.0:
        return (math.exp(k * (l_n - 1.0) / e0) - 1.0) / (math.exp(k) - 1.0)
    return 0.0


_fal_ufunc = numba.vectorize(["float64(float64, float64)"], cache=True)(_fal)
_fpe_ufunc = numba.vectorize(_UFUNC_SIGNATURE, cache=True)(_fpe)


def active_force_length(norm_fiber_length, constants: ThelenConstants = THESIS_CONSTANTS):
    """Gaussian active force-length multiplier, ``exp(-(l-1)^2 / gamma)``; 1 at l = 1."""
    return _fal_ufunc(np.asarray(norm_fiber_length, dtype=float), constants.gamma)


def active_force_length_derivative(norm_fiber_length,
                                   constants: ThelenConstants = THESIS_CONSTANTS):
    """d f_AL / d (normalised fiber length)."""
    d = np.asarray(norm_fiber_length, dtype=float) - 1.0
    return -2.0 * d / constants.gamma * np.exp(-(d * d) / constants.gamma)


def passive_force_length(norm_fiber_length, constants: ThelenConstants = THESIS_CONSTANTS):
    """Passive multiplier ``(exp(kPE (l-1)/e0) - 1) / (exp(kPE) - 1)`` for l > 1, else 0."""
    return _fpe_ufunc(np.asarray(norm_fiber_length, dtype=float), constants.k_passive, constants.passive_strain_at_fmax)


def passive_force_length_derivative(norm_fiber_length,
                                    constants: ThelenConstants = THESIS_CONSTANTS):
    """d f_PE / d (normalised fiber length); 0 at and below l = 1."""
    l = np.asarray(norm_fiber_length, dtype=float)
    k, e0 = constants.k_passive, constants.passive_strain_at_fmax
    with np.errstate(over="ignore"):
        d = k * (1.0 / e0) * np.exp(k * (l - 1.0) * (1.0 / e0)) / (math.exp(k) - 1.0)
    return np.where(l > 1.0, d, 0.0)


def _fv_shape(activation, constants):
    """Shared terms of the force-velocity relation: c, k, x0, v0, slope at v0."""
    c = 0.25 + 0.75 * np.asarray(activation, dtype=float)  # velocity scale (0.25+0.75a)
    af, flen = constants.af, constants.flen
    k = (2.0 + 2.0 / af) / (flen - 1.0)
    x0 = constants.fv_extrapolation_threshold * flen       # fv where extrapolation starts
    v0 = c * (x0 - 1.0) / (k * (flen - x0))
    s0 = k * (flen - x0) ** 2 / (c * (flen - 1.0))         # d fv / d v beyond v0
    return c, k, x0, v0, s0


@_jit
def _fv(v, activation, af, flen, threshold):
    """Scalar core of :func:`force_velocity`."""
    c = 0.25 + 0.75 * activation
    if v <= -c:
        return 0.0
    if v <= 0.0:
        return (c + v) / (c - v / af)
    k = (2.0 + 2.0 / af) / (flen - 1.0)
    x0 = threshold * flen
    v0 = c * (x0 - 1.0) / (k * (flen - x0))
    if v < v0:
        return (c + v * k * flen) / (c + v * k)
    return x0 + (v - v0) * k * (flen - x0) ** 2 / (c * (flen - 1.0))


_force_velocity = numba.vectorize(["float64(float64, float64, float64, float64, float64)"], cache=True)(_fv)


def force_velocity(norm_fiber_velocity, activation,
                   constants: ThelenConstants = THESIS_CONSTANTS):
    """Force-velocity multiplier f_V(v, a) of OpenSim's Thelen2003Muscle.

    Closed-form inverse of :func:`fiber_velocity_from_force` (OpenSim inverts it by Newton
    iteration, ``calcfvInv``): 0 for ``v <= -(0.25 + 0.75 a)``, Thelen's hyperbolas in
    between, 1 at v = 0, approaching ``flen`` when lengthening, linearly extrapolated
    beyond ``fv_extrapolation_threshold * flen``. ``activation`` is used as given.
    """
    return _force_velocity(np.asarray(norm_fiber_velocity, dtype=float), np.asarray(activation, dtype=float),
                           constants.af, constants.flen, constants.fv_extrapolation_threshold)


def force_velocity_derivatives(norm_fiber_velocity, activation,
                               constants: ThelenConstants = THESIS_CONSTANTS):
    """``(d f_V / d v_norm, d f_V / d activation)`` of :func:`force_velocity`."""
    v = np.asarray(norm_fiber_velocity, dtype=float)
    c, k, x0, v0, s0 = _fv_shape(activation, constants)
    af, flen = constants.af, constants.flen
    with np.errstate(divide="ignore", invalid="ignore"):
        dcon = c - v / af
        decc = c + v * k
        dv = np.where(v <= 0.0, c * (1.0 + 1.0 / af) / dcon ** 2,
                      np.where(v < v0, k * c * (flen - 1.0) / decc ** 2, s0))
        dc = np.where(v <= 0.0, -v * (1.0 + 1.0 / af) / dcon ** 2,
                      np.where(v < v0, v * k * (1.0 - flen) / decc ** 2,
                               -v * k * (flen - x0) ** 2 / (c * c * (flen - 1.0))))
    dead = v <= -c
    return np.where(dead, 0.0, dv), np.where(dead, 0.0, 0.75 * dc)


def fiber_velocity_from_force(activation, active_force_length_value, a_fal_fv,
                              constants: ThelenConstants = THESIS_CONSTANTS):
    """Normalised fiber velocity for active force ``a*f_AL*f_V`` (OpenSim ``calcdlceN``).

    Thelen 2003 eqs. 6-7 between 0 and ``threshold*flen*a*f_AL``, linear extrapolation
    outside. Used by the compliant-tendon state derivative.
    """
    a = np.asarray(activation, dtype=float)
    afl = a * np.asarray(active_force_length_value, dtype=float)
    fm = np.asarray(a_fal_fv, dtype=float)
    af, flen, th = constants.af, constants.flen, constants.fv_extrapolation_threshold
    c = 0.25 + 0.75 * a
    fm_asy_e = afl * flen
    with np.errstate(divide="ignore", invalid="ignore"):
        b = np.where(fm <= afl, afl + fm / af, ((2 + 2 / af) * (afl * flen - fm)) / (flen - 1))
        on_curve = c * (fm - afl) / b
        below = fm <= 0.0
        fm0 = np.where(below, 0.0, th * fm_asy_e)
        b0 = np.where(below, afl + fm0 / af, ((2 + 2 / af) * (afl * flen - fm0)) / (flen - 1))
        db0 = np.where(below, 1 / af, ((2 + 2 / af) * (-1)) / (flen - 1))
        v0 = c * (fm0 - afl) / b0
        slope = c * 1 / b0 - (c * (fm0 - afl) / (b0 * b0)) * db0
        extrapolated = v0 + slope * (fm - fm0)
    return np.where((fm > 0.0) & (fm < fm_asy_e * th), on_curve, extrapolated)


def tendon_force_length(tendon_strain, constants: ThelenConstants = THESIS_CONSTANTS):
    """Normalised tendon force: 0 when slack, exponential toe, linear above the toe strain."""
    x = np.asarray(tendon_strain, dtype=float)
    e_toe, k_lin = constants.tendon_toe_strain, constants.tendon_linear_stiffness
    with np.errstate(over="ignore"):
        toe = (_F_TOE / (math.exp(_K_TOE) - 1.0)) * (np.exp(_K_TOE * x / e_toe) - 1.0)
    return np.where(x > e_toe, k_lin * (x - e_toe) + _F_TOE, np.where(x > 0.0, toe, 0.0))


def tendon_force_length_derivative(tendon_strain,
                                   constants: ThelenConstants = THESIS_CONSTANTS):
    """d (normalised tendon force) / d (tendon strain)."""
    x = np.asarray(tendon_strain, dtype=float)
    e_toe, k_lin = constants.tendon_toe_strain, constants.tendon_linear_stiffness
    with np.errstate(over="ignore"):
        toe = (_F_TOE / (math.exp(_K_TOE) - 1.0)) * (_K_TOE / e_toe) * np.exp(_K_TOE * x / e_toe)
    return np.where(x > e_toe, k_lin, np.where(x > 0.0, toe, 0.0))


# -------------------------------------------------------------------------- pennation

def parallelogram_height(params: MuscleParameters) -> np.ndarray:
    """Constant fiber 'thickness' ``l_opt sin(alpha_opt)`` (m)."""
    return params.parallelogram_height


def minimum_fiber_length(params: MuscleParameters,
                         constants: ThelenConstants = THESIS_CONSTANTS) -> np.ndarray:
    """Fiber length at the maximum pennation angle (0 for unpennated muscles) (m)."""
    return parallelogram_height(params) / math.sin(constants.maximum_pennation_angle)


@_jit
def _pennation(l, h, l_min, alpha_opt, max_pennation):
    """Scalar constant-thickness pennation angle (rad), capped at the maximum."""
    if alpha_opt <= _EPS:
        return 0.0
    sin_phi = h / l if l != 0.0 else math.inf
    if l > l_min and sin_phi < math.sin(max_pennation):
        return math.asin(min(1.0, max(0.0, sin_phi)))
    return max_pennation


_pennation_vectorized = numba.vectorize(["float64(float64, float64, float64, float64, float64)"], cache=True)(_pennation)


def pennation_angle(fiber_length, params: MuscleParameters,
                    constants: ThelenConstants = THESIS_CONSTANTS):
    """Pennation angle (rad) of the constant-thickness model, capped at the maximum."""
    return _pennation_vectorized(np.asarray(fiber_length, dtype=float), parallelogram_height(params),
                                 minimum_fiber_length(params, constants), params.pennation_angle_at_optimal,
                                 constants.maximum_pennation_angle)


def _dcos_dl(l, h, cos_phi):
    """d cos(phi) / d fiber length = h^2 / (l^3 cos(phi)) (0 for unpennated muscles)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(h > 0.0, h * h / (l * l * l * cos_phi), 0.0)


# ------------------------------------------------------------------------- activation

def clamp_activation(activation, constants: ThelenConstants = THESIS_CONSTANTS):
    """Activation clamped to ``[minimum_activation, 1]`` as OpenSim uses it in forces."""
    return np.clip(np.asarray(activation, dtype=float), constants.minimum_activation, 1.0)


def activation_derivative(excitation, activation,
                          constants: ThelenConstants = THESIS_CONSTANTS, time_scale=None):
    """da/dt (1/s) of OpenSim 4.6's first-order activation model.

    Activation is clamped to [minimum_activation, 1], excitation is used as given (as
    OpenSim 4.6 does); ``tau = tau_act (0.5 + 1.5 a)`` when u > a, else
    ``tau_deact / (0.5 + 1.5 a)``. `time_scale` (one value or one per muscle) multiplies both
    time constants.
    """
    tau_act, tau_deact = constants.activation_time_constant, constants.deactivation_time_constant
    if time_scale is not None:
        tau_act, tau_deact = tau_act * time_scale, tau_deact * time_scale
    return _activation_rate(np.asarray(excitation, dtype=float), np.asarray(activation, dtype=float), constants.minimum_activation,
                            tau_act, tau_deact)


@numba.vectorize(["float64(float64, float64, float64, float64, float64)"], cache=True)
def _activation_rate(u, activation, a_min, tau_act, tau_deact):
    a = min(1.0, max(a_min, activation))
    if u > a:
        return (u - a) / (tau_act * (0.5 + 1.5 * a))
    return (u - a) * (0.5 + 1.5 * a) / tau_deact


# ---------------------------------------------------------------------- rigid tendon

def _broadcast(x, n):
    if type(x) is np.ndarray and x.shape == (n,) and x.dtype == np.float64:  # the per-step case, without a copy
        return x
    return np.broadcast_to(np.asarray(x, dtype=float), (n,))


@_jit
def _rigid_fiber(l_mt, v_mt, packed, max_pennation, v_max, gamma, k_pe, e0):
    """Compiled per-muscle loop: rows fiber length, pennation, cos, fiber velocity, normalised length
    and velocity, f_AL, f_PE (see RigidKinematics), and the clamped flags."""
    n = l_mt.shape[0]
    out = np.empty((8, n))
    clamped = np.empty(n, dtype=np.bool_)
    cos_max, sin_max = math.cos(max_pennation), math.sin(max_pennation)
    for i in range(n):
        l_slack, h, alpha_opt, l_opt = packed[0, i], packed[1, i], packed[2, i], packed[3, i]
        l_min = h / sin_max
        l_at = l_mt[i] - l_slack
        l_f = math.sqrt(h * h + l_at * l_at) if l_at >= l_min * cos_max else l_min
        clamped[i] = not (l_f > l_min)
        phi = _pennation(l_f, h, l_min, alpha_opt, max_pennation)
        cos_phi = math.cos(phi)
        v_f = 0.0 if clamped[i] else v_mt[i] * cos_phi
        l_n = l_f / l_opt
        out[0, i], out[1, i], out[2, i], out[3, i] = l_f, phi, cos_phi, v_f
        out[4, i], out[5, i] = l_n, v_f / (v_max * l_opt)
        out[6, i], out[7, i] = _fal(l_n, gamma), _fpe(l_n, k_pe, e0)
    return out, clamped


class RigidKinematics(NamedTuple):
    """Activation-independent part of the rigid-tendon muscle state (arrays over muscles)."""

    fiber_length: np.ndarray
    pennation_angle: np.ndarray
    cos_pennation: np.ndarray
    fiber_velocity: np.ndarray
    normalized_fiber_length: np.ndarray
    normalized_fiber_velocity: np.ndarray
    active_force_length: np.ndarray
    passive_force_length: np.ndarray
    clamped: np.ndarray


def _rigid_kinematics(l_mt, v_mt, params, constants) -> tuple[np.ndarray, np.ndarray, RigidKinematics]:
    """Path length and velocity as arrays over muscles, and the fiber kinematics."""
    n = params.n_muscles
    l_mt = np.ascontiguousarray(_broadcast(l_mt, n))
    v_mt = np.ascontiguousarray(_broadcast(v_mt, n))
    rows, clamped = _rigid_fiber(l_mt, v_mt, params.packed, constants.maximum_pennation_angle,
                                 constants.max_contraction_velocity, constants.gamma, constants.k_passive,
                                 constants.passive_strain_at_fmax)
    return l_mt, v_mt, RigidKinematics(*rows, clamped)


def rigid_kinematics(l_mt, v_mt, params: MuscleParameters,
                     constants: ThelenConstants = THESIS_CONSTANTS) -> RigidKinematics:
    """Fiber kinematics and length multipliers for an inextensible tendon.

    ``l_f cos(phi) = l_mt - l_slack`` and ``v_f = v_mt cos(phi)``; depends only on the path,
    so callers may reuse it for several activations (see :func:`rigid_tendon`).
    """
    return _rigid_kinematics(l_mt, v_mt, params, constants)[2]


@_jit
def _rigid_force(activation, a_min, cos_phi, v_n, fal, fpe, clamped, f_max, af, flen, threshold):
    """Compiled tendon force (N) of every muscle for `activation` (clamped to [a_min, 1] here)."""
    force = np.empty(activation.shape[0])
    for i in range(activation.shape[0]):
        a = min(1.0, max(a_min, activation[i]))
        active = 0.0 if clamped[i] else f_max[i] * a * fal[i] * _fv(v_n[i], a, af, flen, threshold)
        force[i] = (active + fpe[i] * f_max[i]) * cos_phi[i]  # the operation order of rigid_tendon
    return force


def _rigid_fiber_forces(a, k: RigidKinematics, params, constants):
    """f_V and the active and passive fiber forces (N) for clamped activation `a`."""
    fv = np.where(k.clamped, 1.0, force_velocity(k.normalized_fiber_velocity, a, constants))
    f_max = params.max_isometric_force
    active = np.where(k.clamped, 0.0, f_max * a * k.active_force_length * fv)
    return fv, active, k.passive_force_length * f_max


def rigid_tendon_force(activation, kinematics: RigidKinematics, params: MuscleParameters,
                       constants: ThelenConstants = THESIS_CONSTANTS) -> np.ndarray:
    """Tendon force (N) only, the per-step hot path of :func:`rigid_tendon`."""
    k = kinematics
    return _rigid_force(np.ascontiguousarray(_broadcast(activation, params.n_muscles)), constants.minimum_activation,
                        k.cos_pennation, k.normalized_fiber_velocity, k.active_force_length, k.passive_force_length,
                        k.clamped, params.packed[4], constants.af, constants.flen, constants.fv_extrapolation_threshold)


def rigid_tendon(activation, l_mt, v_mt, params: MuscleParameters,
                 constants: ThelenConstants = THESIS_CONSTANTS,
                 kinematics: RigidKinematics | None = None) -> MuscleState:
    """Muscle state for an inextensible tendon of length ``tendon_slack_length``.

    ``l_mt`` (m) and ``v_mt`` (m/s, lengthening positive) are the musculotendon path
    length and velocity. Fiber kinematics follow the path: ``l_f cos(phi) = l_mt - l_slack``
    and ``v_f = v_mt cos(phi)``; tendon force ``(a f_AL f_V + f_PE) F_max cos(phi)``,
    matching OpenSim's ``calcInextensibleTendonActiveFiberForce`` plus passive force
    (no active force when the fiber sits at its minimum length). Pass `kinematics`
    (from :func:`rigid_kinematics` at the same path) to skip recomputing them.
    """
    a = clamp_activation(activation, constants)
    k = kinematics if kinematics is not None else rigid_kinematics(l_mt, v_mt, params, constants)
    fv, active, passive = _rigid_fiber_forces(a, k, params, constants)
    zeros = np.zeros_like(k.fiber_length)
    return MuscleState(
        activation=np.broadcast_to(a, zeros.shape).copy(), fiber_length=k.fiber_length,
        normalized_fiber_length=k.normalized_fiber_length, pennation_angle=k.pennation_angle,
        fiber_velocity=k.fiber_velocity, normalized_fiber_velocity=k.normalized_fiber_velocity,
        tendon_length=params.tendon_slack_length.copy(), tendon_strain=zeros,
        active_force_length=k.active_force_length, passive_force_length=k.passive_force_length,
        force_velocity=fv, active_fiber_force=active, passive_fiber_force=passive,
        tendon_force=(active + passive) * k.cos_pennation, fiber_clamped=k.clamped)


def rigid_tendon_force_split(l_mt, v_mt, params: MuscleParameters,
                             constants: ThelenConstants = THESIS_CONSTANTS,
                             fv_activation=1.0) -> ForceSplit:
    """Rigid-tendon force split as ``F = a * active + passive`` for static optimisation.

    ``active = f_AL f_V F_max cos(phi)``, ``passive = f_PE F_max cos(phi)`` (N). Thelen's
    f_V depends on activation, so the split is exactly linear in ``a`` only when
    ``v_mt = 0``; otherwise f_V is taken at ``fv_activation`` (1, as OpenSim's static
    optimisation does). Activation is not clamped here.
    """
    k = rigid_kinematics(l_mt, v_mt, params, constants)
    f_max, cos_phi = params.max_isometric_force, k.cos_pennation
    fv = force_velocity(k.normalized_fiber_velocity, fv_activation, constants)
    active = np.where(k.clamped, 0.0, k.active_force_length * fv * f_max * cos_phi)
    return ForceSplit(active, k.passive_force_length * f_max * cos_phi)


def rigid_tendon_derivatives(activation, l_mt, v_mt, params: MuscleParameters,
                             constants: ThelenConstants = THESIS_CONSTANTS
                             ) -> RigidTendonDerivatives:
    """Analytic partials of :func:`rigid_tendon`'s tendon force w.r.t. a, l_mt, v_mt.

    ``d_activation`` is 0 where activation is clamped; all are 0 where the fiber is at its
    minimum length (except the passive part, which is 0 there anyway).
    """
    a_raw = np.asarray(activation, dtype=float)
    a = clamp_activation(a_raw, constants)
    l_mt, v_mt, k = _rigid_kinematics(l_mt, v_mt, params, constants)
    l_f, cos_phi, clamped = k.fiber_length, k.cos_pennation, k.clamped
    l_n, v_n, fal, fpe = k.normalized_fiber_length, k.normalized_fiber_velocity, k.active_force_length, k.passive_force_length
    l_opt, f_max, h = params.optimal_fiber_length, params.max_isometric_force, parallelogram_height(params)
    vscale = constants.max_contraction_velocity * l_opt
    fv = force_velocity(v_n, a, constants)
    dfv_dv, dfv_da = force_velocity_derivatives(v_n, a, constants)
    active = np.where(clamped, 0.0, 1.0)
    dcos = _dcos_dl(l_f, h, cos_phi) * cos_phi          # d cos / d l_mt  (dl_f/dl_mt = cos)
    d_len = f_max * (((a * fv * active_force_length_derivative(l_n, constants) * active
                       + passive_force_length_derivative(l_n, constants)) / l_opt)
                     * cos_phi * cos_phi
                     + (a * fal * fv * active + fpe) * dcos
                     + a * fal * dfv_dv * active * cos_phi * v_mt * dcos / vscale)
    d_vel = f_max * a * fal * dfv_dv * active * cos_phi * cos_phi / vscale
    in_range = (a_raw >= constants.minimum_activation) & (a_raw <= 1.0)
    d_act = np.where(in_range, f_max * fal * (fv + a * dfv_da) * active * cos_phi, 0.0)
    return RigidTendonDerivatives(d_act, d_len, d_vel)


# ------------------------------------------------------------------- compliant tendon

def compliant_tendon(activation, fiber_length, l_mt, params: MuscleParameters,
                     constants: ThelenConstants = THESIS_CONSTANTS) -> MuscleState:
    """Muscle state with fiber length as the state (OpenSim ``calcFiberVelocityInfo``).

    ``fiber_velocity`` of the result is the state derivative d(fiber_length)/dt: the
    active force ``a f_AL f_V = F_T / (F_max cos(phi)) - f_PE`` is set by the tendon and
    the force-velocity relation is inverted for the velocity. A fiber at its minimum
    length that would shorten further is held (velocity 0, f_V = 1, no active force).
    """
    a = clamp_activation(activation, constants)
    n = params.n_muscles
    l_state = _broadcast(fiber_length, n)
    l_mt = _broadcast(l_mt, n)
    l_opt, f_max = params.optimal_fiber_length, params.max_isometric_force
    l_f = np.maximum(minimum_fiber_length(params, constants), l_state)
    l_n = l_f / l_opt
    phi = pennation_angle(l_f, params, constants)
    cos_phi = np.cos(phi)
    l_t = l_mt - l_f * cos_phi
    strain = l_t / params.tendon_slack_length - 1.0
    fse = tendon_force_length(strain, constants)
    fal = active_force_length(l_n, constants)
    fpe = passive_force_length(l_n, constants)
    a_fal_fv = (fse / cos_phi) - fpe
    fv = a_fal_fv / (a * fal)
    v_n = fiber_velocity_from_force(a, fal, a_fal_fv, constants)
    clamped = (l_state <= minimum_fiber_length(params, constants)) & (v_n <= 0.0)
    v_n = np.where(clamped, 0.0, v_n)
    fv = np.where(clamped, 1.0, fv)
    return MuscleState(
        activation=np.broadcast_to(a, l_f.shape).copy(), fiber_length=l_f,
        normalized_fiber_length=l_n, pennation_angle=phi,
        fiber_velocity=v_n * constants.max_contraction_velocity * l_opt,
        normalized_fiber_velocity=v_n, tendon_length=l_t, tendon_strain=strain,
        active_force_length=fal, passive_force_length=fpe, force_velocity=fv,
        active_fiber_force=np.where(clamped, 0.0, a * fal * fv * f_max),
        passive_fiber_force=fpe * f_max, tendon_force=fse * f_max, fiber_clamped=clamped)


def _equilibrium_residual(l_f, a, fv, l_mt, params, constants, h):
    """Normalised force error (fiber along tendon - tendon) / F_max and its l_f-slope."""
    l_opt, l_s = params.optimal_fiber_length, params.tendon_slack_length
    l_n = l_f / l_opt
    cos_phi = np.cos(pennation_angle(l_f, params, constants))
    strain = (l_mt - l_f * cos_phi) / l_s - 1.0
    fal = active_force_length(l_n, constants)
    fpe = passive_force_length(l_n, constants)
    fm = a * fal * fv + fpe
    g = fm * cos_phi - tendon_force_length(strain, constants)
    dfm = (a * fv * active_force_length_derivative(l_n, constants)
           + passive_force_length_derivative(l_n, constants)) / l_opt
    with np.errstate(divide="ignore", invalid="ignore"):
        dg = (dfm * cos_phi + fm * _dcos_dl(l_f, h, cos_phi)
              + tendon_force_length_derivative(strain, constants) / (cos_phi * l_s))
    return g, dg


def _velocity_share(l_f, a, fv, l_mt, v_mt, params, constants, h):
    """OpenSim's initialisation heuristic: split v_mt between fiber and tendon by their
    stiffnesses in series, and return f_V at the resulting fiber velocity."""
    l_opt, l_s, f_max = (params.optimal_fiber_length, params.tendon_slack_length,
                         params.max_isometric_force)
    l_n = l_f / l_opt
    cos_phi = np.cos(pennation_angle(l_f, params, constants))
    l_t = l_mt - l_f * cos_phi
    fal = active_force_length(l_n, constants)
    fm = (a * fal * fv + passive_force_length(l_n, constants)) * f_max
    dfm = ((a * fv) * active_force_length_derivative(l_n, constants)
           + passive_force_length_derivative(l_n, constants)) * f_max * (1 / l_opt)
    with np.errstate(divide="ignore", invalid="ignore"):
        dcos = np.where(h > 0.0, h * h / (l_f ** 3 * np.sqrt(1 - h * h / (l_f * l_f))), 0.0)
        k_fiber = (dfm * cos_phi + fm * dcos) * cos_phi
        k_tendon = tendon_force_length_derivative(l_t / l_s - 1.0, constants) * (f_max / l_s)
        shared = (np.abs(k_fiber + k_tendon) > _SIGNIFICANT_REAL) & (l_t > l_s)
        v_t = np.where(shared, (k_fiber / (k_fiber + k_tendon)) * v_mt, v_mt)
    v_n = (v_mt - v_t) * cos_phi / (constants.max_contraction_velocity * l_opt)
    return force_velocity(v_n, a, constants)


def equilibrium_fiber_length(activation, l_mt, params: MuscleParameters,
                             constants: ThelenConstants = THESIS_CONSTANTS,
                             v_mt=0.0, rtol: float = 1e-13, max_iter: int = 200
                             ) -> MuscleState:
    """Static fiber-tendon force equilibrium (OpenSim ``computeInitialFiberEquilibrium``).

    Solves ``(a f_AL f_V + f_PE) cos(phi) = f_T`` for the fiber length of every muscle
    by safeguarded Newton iteration inside the bracket [minimum fiber length, fiber
    length with a slack tendon], to ``rtol`` relative in fiber length. With ``v_mt != 0``
    f_V follows OpenSim's heuristic (v_mt shared between fiber and tendon in proportion
    to their stiffnesses in series), made self-consistent at every iterate. Fibers whose
    force exceeds the tendon's even at the minimum length are returned clamped there
    (OpenSim warns). Returns the :class:`MuscleState` at equilibrium (``.fiber_length``,
    ``.tendon_force``; ``.fiber_velocity`` is then the compliant-tendon state derivative).
    """
    n = params.n_muscles
    a = np.broadcast_to(clamp_activation(activation, constants), (n,))
    l_mt, v_mt = _broadcast(l_mt, n), _broadcast(v_mt, n)
    moving = bool(np.any(v_mt != 0.0))
    h = parallelogram_height(params)

    def residual(l_f, fv):
        if moving:  # fixed-point sweeps: f_V consistent with the stiffness-shared velocity
            for _ in range(max_iter):
                fv_new = _velocity_share(l_f, a, fv, l_mt, v_mt, params, constants, h)
                change = np.max(np.abs(fv_new - fv))
                fv = fv_new
                if change <= 4 * _EPS:
                    break
        g, dg = _equilibrium_residual(l_f, a, fv, l_mt, params, constants, h)
        return g, dg, fv

    l_min = minimum_fiber_length(params, constants)
    l_at_slack = l_mt - params.tendon_slack_length
    hi = np.where(l_at_slack >= l_min * math.cos(constants.maximum_pennation_angle),
                  np.maximum(np.sqrt(h * h + l_at_slack ** 2), l_min), l_min)
    lo = l_min.copy()
    fv = np.ones(n)
    g_lo, _, _ = residual(lo, fv)
    converged = g_lo >= 0.0                          # fiber force wins even at l_min
    l_at_guess = l_mt - 1.01 * params.tendon_slack_length    # OpenSim's starting guess
    l_f = np.where(converged, l_min, np.clip(np.sqrt(h * h + l_at_guess ** 2), lo, hi))
    for _ in range(max_iter):
        if converged.all():
            break
        g, dg, fv = residual(l_f, fv)
        neg = g < 0.0
        lo = np.where(neg & ~converged, l_f, lo)
        hi = np.where(~neg & ~converged, l_f, hi)
        with np.errstate(divide="ignore", invalid="ignore"):
            newton = l_f - g / dg
        ok = (dg > 0.0) & (newton >= lo) & (newton <= hi)
        step_to = np.where(ok, newton, 0.5 * (lo + hi))
        done = ((ok & (np.abs(newton - l_f) <= rtol * l_f)) | (g == 0.0)
                | (hi - lo <= rtol * l_f))
        l_f = np.where(converged | (g == 0.0), l_f, step_to)
        converged |= done
    if not converged.all():
        warnings.warn(f"equilibrium_fiber_length: {np.count_nonzero(~converged)} muscle(s) "
                      "did not converge", RuntimeWarning, stacklevel=2)
    return compliant_tendon(a, l_f, l_mt, params, constants)
