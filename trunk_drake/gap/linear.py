"""Linearised trunk model for fast frequency-domain evaluation of candidate effects.

The diagram is linearised at an operating point (mean posture, activation and excitation of a
nominal simulation) with the feedback loops *open*: the mechanics (d v/dt with respect to
q, v and the activations) by central differences of the diagram itself, the muscle sensors
(normalised fiber length and velocity, tendon force) analytically from the moment arms and
the Thelen derivatives. The loops - stretch reflex, Golgi tendon organs, trunk-in-space
feedback, each with its own transport delay exp(-s tau) - and the activation dynamics are
closed per frequency. Activations are eliminated muscle by muscle (each is a first-order lag
of its own excitation), so every frequency needs only a 5x5 (6x6 with a seat) solve.

Kinks are linearised by central differences or their describing function for small
symmetric oscillation: (v)+ of the velocity reflex and each side of the trunk-in-space
feedback count half, the activation rate is the mean of the activating and deactivating
rates, excitations at their lower bound pass only half of a two-sided (Golgi) signal.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from trunk_drake.diagram import EXTENSOR_GROUPS, FLEXOR_GROUPS, TrunkOptions, _group_mask, build_trunk_diagram
from trunk_drake.muscle import thelen
from trunk_drake.systems.muscles import muscle_parameters


class ConstantAcceleration:
    """A platform 'signal' with a settable constant acceleration (for linearisation)."""

    duration = np.inf

    def __init__(self, acceleration: float = 0.0):
        self.acceleration = acceleration

    def evaluate(self, t):
        return 0.0, 0.0, self.acceleration


@dataclass
class LinearParams:
    """Parameters of the closed loops and candidate effects (arrays over muscles/levels)."""

    kp: np.ndarray
    kv: np.ndarray
    reflex_delay: float = 0.0
    gto_gain: float = 0.0
    vestibular_gain: float = 0.0
    vestibular_delay: float = 0.0
    activation_scale: float = 1.0
    extra_damping: float = 0.0  # Nms/rad on every level
    extra_stiffness: np.ndarray | float = 0.0  # Nm/rad per level (e.g. equivalent of a stiffening law)
    seat_stiffness: float | None = None  # N/m; None: pelvis prescribed
    seat_damping: float = 0.0


@dataclass
class LinearTrunk:
    """Open-loop linearisation (see module docstring). Coordinates q = the mechanical model's."""

    coordinates: list[str]
    levels: np.ndarray  # (n_levels, n): level angles = levels @ q (model.level_matrix)
    dvdq: np.ndarray  # (n, n)
    dvdv: np.ndarray  # (n, n)
    dvda: np.ndarray  # (n, m)
    m_inv: np.ndarray  # (n, n)
    b_acc: np.ndarray | None  # (n,) d v/dt per platform acceleration (prescribed pelvis)
    pelvis: int | None  # index of pelvis_tx (seat model)
    rate: np.ndarray  # (m,) activation rate 1/tau
    dln_dq: np.ndarray  # (m, n) normalised fiber length
    dvn_dv: np.ndarray  # (m, n) normalised fiber velocity
    df_dq: np.ndarray  # (m, n) tendon force / F_max
    df_dv: np.ndarray
    df_da: np.ndarray  # (m,)
    stretch_active: np.ndarray  # (m,) l_n above the set point at the operating point
    headroom: np.ndarray  # (m,) 1, or 0.5 where the excitation sits at its lower bound
    extensors: np.ndarray
    flexors: np.ndarray

    def frf(self, freqs, p: LinearParams) -> np.ndarray:
        """Rotation per platform displacement (rad/m) at `freqs` (Hz): (n_f, 6) complex,
        columns total lumbar rotation then L5_S1 ... L1_L2."""
        freqs = np.atleast_1d(np.asarray(freqs, float))
        n = len(self.coordinates)
        L = self.levels
        out = np.empty((freqs.size, 1 + len(L)), dtype=complex)
        select = L.sum(axis=0)  # the lumbar rotation as a function of q
        dvdq, dvdv = self.dvdq.copy(), self.dvdv.copy()
        k_extra = np.broadcast_to(np.asarray(p.extra_stiffness, float), (len(L),))
        c_extra = np.broadcast_to(np.asarray(p.extra_damping, float), (len(L),))
        dvdq -= self.m_inv @ (L.T * k_extra) @ L
        dvdv -= self.m_inv @ (L.T * c_extra) @ L
        rate = self.rate / p.activation_scale
        stretch_q = (p.kp * self.stretch_active)[:, None] * self.dln_dq
        stretch_v = (0.5 * p.kv)[:, None] * self.dvn_dv
        gto = p.gto_gain * self.headroom
        vest = (0.5 * p.vestibular_gain * (self.extensors - self.flexors))[:, None] * select[None, :]
        for i, f in enumerate(freqs):
            s = 2j * np.pi * f
            er, ev = np.exp(-s * p.reflex_delay), np.exp(-s * p.vestibular_delay)
            k_q = er * (stretch_q - gto[:, None] * self.df_dq) + ev * vest
            k_v = er * (stretch_v - gto[:, None] * self.df_dv)
            k_a = -er * gto * self.df_da
            g = rate / (s + rate)
            w = g / (1.0 - g * k_a)  # a = w * (k_q q + k_v v)
            aq = dvdq + self.dvda @ (w[:, None] * k_q)
            av = dvdv + self.dvda @ (w[:, None] * k_v)
            Z = s * s * np.eye(n) - s * av - aq
            if p.seat_stiffness is not None:
                spring = self.m_inv[:, self.pelvis] * (p.seat_stiffness + s * p.seat_damping)
                Z[:, self.pelvis] += spring
                rhs = spring
            else:
                rhs = self.b_acc * s * s
            q = np.linalg.solve(Z, rhs)
            out[i, 0] = select @ q
            out[i, 1:] = L @ q
        return out


def linearize(model, options: TrunkOptions, q0, a0, u0, seat: bool = False, h: float = 1e-6) -> LinearTrunk:
    """Open-loop linearisation of `model` with the non-feedback parts of `options` at the
    operating point: posture q0 (the model's lumbar rotation coordinates, `rotation_coordinates`),
    activations a0, excitations u0.
    With ``seat=True`` the pelvis slides freely (for the pelvis-seat compliance candidate)."""
    open_loop = dataclasses.replace(options, kp=0.0, kv=0.0, gto_gain=0.0, vestibular_gain=0.0, reflex_delay=0.0,
                                    vestibular_delay=0.0, feedforward=np.asarray(u0, float),
                                    pelvis="force" if seat else "prescribed", pelvis_mass=_sacrum_mass(model))
    signal = ConstantAcceleration()
    td = build_trunk_diagram(model, open_loop, signal)
    base, plant, n_m = td.model, td.plant, td.muscles.n
    nq = plant.num_positions()
    q = np.zeros(nq)
    q[td.fe_indices] = np.asarray(q0, float)
    x0 = np.concatenate([q, np.zeros(nq), np.asarray(a0, float)])
    context = td.diagram.CreateDefaultContext()

    def f(x):
        return time_derivatives(td, context, x)

    jac = state_jacobian(td, x0, h, context)
    vrows = slice(nq, 2 * nq)
    arows = slice(2 * nq, 2 * nq + n_m)
    b_acc = None
    if not seat:
        context.SetContinuousState(x0)
        signal.acceleration = 1.0
        plus = td.diagram.EvalTimeDerivatives(context).CopyToVector()
        signal.acceleration = 0.0
        context.SetContinuousState(x0 + 0.0)  # invalidate caches that depend on the signal
        b_acc = plus[vrows] - f(x0)[vrows]

    plant_ctx = plant.CreateDefaultContext()
    plant.SetPositions(plant_ctx, q)
    params = muscle_parameters(base, options.strength_scale)
    path = base.path_state(q, np.zeros(nq))
    R = path.moment_arms
    kin = thelen.rigid_kinematics(path.lengths, path.velocities, params, td.muscles.constants)
    deriv = thelen.rigid_tendon_derivatives(a0, path.lengths, path.velocities, params, td.muscles.constants)
    vmax = td.muscles.constants.max_contraction_velocity
    f_max = params.max_isometric_force
    l_set = td.reflex.l_desired
    u0 = np.asarray(u0, float)
    return LinearTrunk(
        coordinates=list(base.coordinates), levels=base.level_matrix, dvdq=jac[vrows, :nq], dvdv=jac[vrows, nq:2 * nq],
        dvda=jac[vrows, arows], m_inv=np.linalg.inv(plant.CalcMassMatrix(plant_ctx)), b_acc=b_acc,
        pelvis=base.coordinates.index("pelvis_tx") if seat else None, rate=-np.diag(jac[arows, arows]),
        dln_dq=-(kin.cos_pennation / params.optimal_fiber_length)[:, None] * R,
        dvn_dv=-(kin.cos_pennation / (vmax * params.optimal_fiber_length))[:, None] * R,
        df_dq=-(deriv.d_length / f_max)[:, None] * R, df_dv=-(deriv.d_velocity / f_max)[:, None] * R,
        df_da=deriv.d_activation / f_max, stretch_active=(kin.normalized_fiber_length > l_set).astype(float),
        headroom=np.where(u0 <= options.constants.minimum_activation * (1 + 1e-9), 0.5, 1.0),
        extensors=_group_mask(base, EXTENSOR_GROUPS), flexors=_group_mask(base, FLEXOR_GROUPS),
    )


def state_jacobian(td, x0, h: float = 1e-6, context=None) -> np.ndarray:
    """Central-difference Jacobian of the built diagram's time derivatives at continuous state `x0`
    (a kink, e.g. a one-sided reflex exactly at its threshold, gives the mean of its two slopes)."""
    context = context or td.diagram.CreateDefaultContext()
    x0 = np.asarray(x0, float)
    jac = np.empty((x0.size, x0.size))
    for j in range(x0.size):
        dx = np.zeros_like(x0)
        dx[j] = h
        jac[:, j] = (time_derivatives(td, context, x0 + dx) - time_derivatives(td, context, x0 - dx)) / (2 * h)
    context.SetContinuousState(x0)
    return jac


def time_derivatives(td, context, x) -> np.ndarray:
    """The diagram's continuous-state time derivatives at state `x` (set into `context`)."""
    context.SetContinuousState(x)
    return td.diagram.EvalTimeDerivatives(context).CopyToVector()


def _sacrum_mass(model) -> float:
    return model.spec.body("sacrum").mass
