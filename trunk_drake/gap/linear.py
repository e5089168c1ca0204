"""Linearised trunk model for fast frequency-domain evaluation of candidate effects.

The diagram is linearised at an operating point (mean posture, activation and excitation of a
nominal simulation) with the feedback loops *open*: the mechanics (d v/dt with respect to
q, v and the activations) by central differences of the diagram itself, the muscle sensors
(normalised fiber length and velocity, tendon force) analytically from the moment arms and
the Thelen derivatives. The loops - stretch reflex, Golgi tendon organs, trunk-in-space
feedback, each with its own transport delay exp(-s tau) - and the activation dynamics are
closed per frequency. Activations are eliminated muscle by muscle (each is a first-order lag
of its own excitation), so every frequency needs only an n x n solve (n: the mechanical
coordinates, 5 levels in the sagittal configuration, 1 in the rhythm, +1 with a seat). The
bushings act on the level angles L q (L = `model.level_matrix`), the lumbar rotation is sum(L q).

Kinks are linearised statistically where the operating point carries the nominal simulation's
fiber length and velocity statistics: the length reflex (l_n - l_d)+ and the velocity reflex
(dl_n)+ each count with the share of time they engage (the gain of the best linear
approximation of a one-sided law for a Gaussian-like input, Bussgang's theorem; with the set
point at the neutral length about half); without statistics, the length reflex counts where l_n
exceeds l_d at the operating point and the velocity reflex half. Each side of the trunk-in-space
feedback counts half, the activation rate is the mean of the activating and deactivating
rates, excitations at their lower bound pass only half of a two-sided (Golgi) signal. The
stiffening bushing law M = -k (dq + c dq^3) is linearised statistically over the operating
range: 3 c E[dq^2] dq for a Gaussian-like signal about the rest angle.

The frequency response takes the same `TrunkOptions` as the diagram: the loops and the
candidate effects are read from them, so an effect switched on in the options is switched on
in the linear model too (options the linearisation cannot follow raise an error).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.special import ndtr

from trunk_drake.diagram import EXTENSOR_GROUPS, FLEXOR_GROUPS, TrunkOptions, _group_mask, build_trunk_diagram, release
from trunk_drake.muscle import thelen
from trunk_drake.optim.least_squares import finite_difference_jacobian
from trunk_drake.systems.muscles import muscle_parameters


class ConstantAcceleration:
    """A platform 'signal' with a settable constant acceleration (for linearisation)."""

    duration = np.inf

    def __init__(self, acceleration: float = 0.0):
        self.acceleration = acceleration

    def evaluate(self, t):
        return 0.0, 0.0, self.acceleration


OPERATING_POINT_LOGS = ("activation", "excitation", "normalized_fiber_length", "normalized_fiber_velocity")  # what `of` reads


@dataclass
class OperatingPoint:
    """Where the diagram is linearised: the mean level angles (rad, `model.levels` order: the
    lumbar posture in any configuration), activations a and excitations u (per muscle), and the
    RMS angle of each level about the bushings' rest angle (offset included), the range over
    which amplitude-dependent laws are linearised."""

    angles: np.ndarray
    a: np.ndarray
    u: np.ndarray
    amplitude: np.ndarray
    fiber_length: np.ndarray | None = None  # (2, m) mean and SD of l_n: the share of time each length reflex engages
    fiber_velocity: np.ndarray | None = None  # (2, m) mean and SD of the normalised fiber velocity

    @classmethod
    def of(cls, result, window: slice) -> OperatingPoint:
        """The operating point of a simulation (SimulationResult) over the samples `window`."""
        levels = np.column_stack(list(result.levels.values()))[window]
        ln, vn = result.normalized_fiber_length[window], result.normalized_fiber_velocity[window]
        return cls(levels.mean(axis=0), result.activation[window].mean(axis=0), result.excitation[window].mean(axis=0),
                   np.sqrt(np.mean(levels**2, axis=0)), np.array([ln.mean(axis=0), ln.std(axis=0)]),
                   np.array([vn.mean(axis=0), vn.std(axis=0)]))

    @classmethod
    def mean(cls, points) -> OperatingPoint:
        """The average of several operating points (e.g. one per trial)."""
        values = ([getattr(p, f.name) for p in points] for f in dataclasses.fields(cls))
        return cls(*(None if any(v is None for v in vs) else np.mean(vs, axis=0) for vs in values))

    def share_above(self, set_point: np.ndarray, fallback: np.ndarray) -> np.ndarray:
        """Per muscle, the share of time l_n exceeds `set_point` (Gaussian l_n of the operating point's mean
        and SD): the gain of the best linear approximation of (l_n - l_d)+ (Bussgang). `fallback` without
        the statistics."""
        if self.fiber_length is None:
            return fallback
        mean, sd = self.fiber_length
        return _share_positive(mean - set_point, sd)

    def share_lengthening(self) -> np.ndarray | float:
        """Per muscle, the share of time the fiber lengthens: the best linear gain of (dl_n)+ (1/2 without statistics)."""
        return 0.5 if self.fiber_velocity is None else _share_positive(*self.fiber_velocity)


def _share_positive(mean, sd) -> np.ndarray:
    """P(x > 0) for a Gaussian x of `mean` and `sd` (a step where sd = 0)."""
    mean, sd = np.asarray(mean, float), np.asarray(sd, float)
    return np.where(sd > 0, ndtr(mean / np.where(sd > 0, sd, 1.0)), (mean > 0).astype(float))


# options the linear model follows by re-linearising once with a step (value: the step), linear in between
_PARAMETRIC = {"strength_scale": 0.05, "upper_body_mass_scale": 0.05}
# TrunkOptions fields the linear model follows; every other field must equal the linearised options
_FOLLOWED = {"kp", "kv", "reflex_delay", "gto_gain", "vestibular_gain", "vestibular_delay", "activation_scale",
             "stiffness", "damping", "cubic", "pelvis", "seat_stiffness", "seat_damping", "pelvis_mass", "srs", *_PARAMETRIC}
# the arrays of a linearisation that depend on the _PARAMETRIC options
_BLOCKS = ("dvdq", "dvdv", "dvda", "m_inv", "b_acc", "rate", "dln_dq", "dvn_dv", "df_dq", "df_dv", "df_da", "srs_stiffness")


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
    stretch_active: np.ndarray  # (m,) share of time l_n is above the set point (OperatingPoint.share_above)
    lengthening: np.ndarray  # (m,) share of time the fiber lengthens (the velocity reflex' linear gain)
    headroom: np.ndarray  # (m,) 1, or 0.5 where the excitation sits at its lower bound
    extensors: np.ndarray
    flexors: np.ndarray
    model: object  # the TrunkModel (per-group gains to per-muscle)
    options: TrunkOptions  # the options linearised
    op: OperatingPoint

    srs_stiffness: np.ndarray = None  # (n, n) R^T diag(a f_AL F_max cos^2 / l_opt) R: short-range stiffness per unit gain
    vdot: np.ndarray = None  # (n,) accelerations at the operating point (~0 at a static equilibrium)
    _sensitivities: dict = field(default_factory=dict, repr=False)  # d(blocks)/d(option) of the _PARAMETRIC options

    def frf(self, freqs, options: TrunkOptions, amplitude=None) -> np.ndarray:
        """Rotation per platform displacement (rad/m) at `freqs` (Hz) of the diagram with
        `options`: (n_f, 1 + levels) complex, columns total lumbar rotation then the level angles
        (`model.levels`: L5_S1 ... L1_L2).
        `amplitude` (rad per level, default the operating point's) is the RMS angle over which
        the stiffening law is linearised: give each trial its own."""
        self._check(options)
        amplitude = self.op.amplitude if amplitude is None else np.asarray(amplitude, float)
        b = self._blocks(options)
        freqs = np.atleast_1d(np.asarray(freqs, float))
        n = len(self.coordinates)
        L = self.levels
        out = np.empty((freqs.size, 1 + len(L)), dtype=complex)
        select = L.sum(axis=0)  # the lumbar rotation as a function of q
        dvdq, dvdv = b["dvdq"].copy(), b["dvdv"].copy()
        k_change = self._bushing_stiffness(options, amplitude) - self._bushing_stiffness(self.options, amplitude)
        c_change = self._per_level(options.damping) - self._per_level(self.options.damping)
        dvdq -= b["m_inv"] @ (L.T * k_change) @ L  # the bushings act on the level angles L q
        dvdv -= b["m_inv"] @ (L.T * c_change) @ L
        rate = b["rate"] / options.activation_scale
        reflex_q, vest = self._position_feedback(options, b)
        stretch_v = (self.lengthening * options.per_muscle(self.model, options.kv))[:, None] * b["dvn_dv"]
        gto = options.gto_gain * self.headroom
        srs = b["m_inv"] @ b["srs_stiffness"] * options.srs.gain if options.srs is not None else None
        for i, f in enumerate(freqs):
            s = 2j * np.pi * f
            er, ev = np.exp(-s * options.reflex_delay), np.exp(-s * options.vestibular_delay)
            k_q = er * reflex_q + ev * vest
            k_v = er * (stretch_v - gto[:, None] * b["df_dv"])
            k_a = -er * gto * b["df_da"]
            g = rate / (s + rate)
            w = g / (1.0 - g * k_a)  # a = w * (k_q q + k_v v)
            aq = dvdq + b["dvda"] @ (w[:, None] * k_q)
            av = dvdv + b["dvda"] @ (w[:, None] * k_v)
            if srs is not None:  # the reference length follows l_n with a first-order lag: a high-passed stiffness
                tau = options.srs.time_constant
                aq = aq - srs * (s * tau / (1.0 + s * tau))
            Z = s * s * np.eye(n) - s * av - aq
            if self.pelvis is not None:
                spring = b["m_inv"][:, self.pelvis] * (options.seat_stiffness + s * options.seat_damping)
                Z[:, self.pelvis] += spring
                rhs = spring
            else:
                rhs = b["b_acc"] * s * s
            q = np.linalg.solve(Z, rhs)
            out[i, 0] = select @ q
            out[i, 1:] = L @ q
        return out

    def _blocks(self, options: TrunkOptions) -> dict:
        """The linearised blocks for `options`: those of the linearisation, moved linearly along the
        sensitivities of every _PARAMETRIC option that differs (each computed on first use)."""
        base = {name: getattr(self, name) for name in _BLOCKS if getattr(self, name) is not None}
        blocks = dict(base)
        for name in _PARAMETRIC:
            change = getattr(options, name) - getattr(self.options, name)
            if change:
                if name not in self._sensitivities:
                    self._sensitivities[name] = self._sensitivity(name, base)
                blocks = {k: v + change * self._sensitivities[name][k] for k, v in blocks.items()}
        return blocks

    def _position_feedback(self, options: TrunkOptions, b: dict) -> tuple[np.ndarray, np.ndarray]:
        """Excitation per coordinate (m, n) of the loops through the reflex delay (stretch and Golgi)
        and of the trunk-in-space loop, delays left out."""
        select = self.levels.sum(axis=0)
        stretch = (options.per_muscle(self.model, options.kp) * self.stretch_active)[:, None] * b["dln_dq"]
        golgi = (options.gto_gain * self.headroom)[:, None] * b["df_dq"]
        vest = (0.5 * options.vestibular_gain * (self.extensors - self.flexors))[:, None] * select[None, :]
        return stretch - golgi, vest

    def _sensitivity(self, name: str, base: dict) -> dict:
        """d(blocks)/d(option `name`) by one re-linearisation at a step of the option, at the operating
        point it moves to: the step's unbalanced accelerations at the old point, resolved through the
        static closed loop of the linearised options (the reflexes' tonic response included); with a
        free pelvis (seat) the point is kept."""
        step = _PARAMETRIC[name]
        options = dataclasses.replace(self.options, **{name: getattr(self.options, name) + step})
        seat = self.pelvis is not None
        other = linearize(self.model, options, self.op, seat=seat)
        if not seat:
            reflex_q, vest = self._position_feedback(self.options, base)
            k_q = reflex_q + vest
            w = 1.0 / (1.0 + self.options.gto_gain * self.headroom * self.df_da)  # static activation per feedback
            dq = -np.linalg.solve(self.dvdq + self.dvda @ (w[:, None] * k_q), other.vdot - self.vdot)
            du = k_q @ dq
            moved = dataclasses.replace(self.op, angles=self.op.angles + self.levels @ dq, a=self.op.a + w * du, u=self.op.u + du)
            other = linearize(self.model, options, moved)
        return {k: (getattr(other, k) - base[k]) / step for k in base}

    def _bushing_stiffness(self, options: TrunkOptions, amplitude) -> np.ndarray:
        """Per level: k (1 + 3 c E[dq^2]), the statistical linearisation of M = -k (dq + c dq^3)."""
        return self._per_level(options.stiffness) * (1.0 + 3.0 * options.cubic * amplitude**2)

    def _per_level(self, value) -> np.ndarray:
        return np.broadcast_to(np.asarray(value, float), (len(self.levels),))

    def _check(self, options: TrunkOptions) -> None:
        seat = options.pelvis == "seat"
        if seat != (self.pelvis is not None):
            raise ValueError(f"pelvis={options.pelvis!r} needs the linearisation "
                             f"{'with' if seat else 'without'} the seat (linearize(..., seat={seat}))")
        changed = [f.name for f in dataclasses.fields(TrunkOptions) if f.name not in _FOLLOWED
                   and not _same(getattr(options, f.name), getattr(self.options, f.name))]
        if changed:
            raise ValueError(f"the linear model cannot follow a change of {', '.join(changed)}: linearise with these options")


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return a is not None and b is not None and bool(np.array_equal(a, b))
    return a == b


def linearize(model, options: TrunkOptions, op: OperatingPoint, seat: bool = False, h: float = 1e-6) -> LinearTrunk:
    """Open-loop linearisation of `model` with the non-feedback parts of `options` at the
    operating point `op` (its level angles set as the least-norm q, `model.level_matrix`). With
    ``seat=True`` the pelvis slides freely (for pelvis="seat")."""
    if options.srs is not None:
        raise ValueError("linearise without short-range stiffness (srs=None): the linear model adds it per frequency")
    open_loop = dataclasses.replace(options, kp=0.0, kv=0.0, gto_gain=0.0, vestibular_gain=0.0, reflex_delay=0.0,
                                    vestibular_delay=0.0, feedforward=np.asarray(op.u, float),
                                    pelvis="force" if seat else "prescribed", pelvis_mass=_pelvis_mass(model))
    signal = ConstantAcceleration()
    td = build_trunk_diagram(model, open_loop, signal)
    try:
        return _linear_trunk(td, signal, model, options, op, seat, h)
    finally:
        release(td.diagram)


def _linear_trunk(td, signal, model, options: TrunkOptions, op: OperatingPoint, seat: bool, h: float) -> LinearTrunk:
    """The LinearTrunk of the open-loop diagram `td`, driven by the platform acceleration `signal`."""
    a0, u0 = op.a, op.u
    base, plant, n_m = td.model, td.plant, td.muscles.n
    nq = plant.num_positions()
    q = np.linalg.pinv(base.level_matrix) @ np.asarray(op.angles, float)
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
    srs_unit = np.asarray(a0, float) * kin.active_force_length * f_max * kin.cos_pennation**2 / params.optimal_fiber_length
    return LinearTrunk(
        coordinates=list(base.coordinates), levels=base.level_matrix, dvdq=jac[vrows, :nq], dvdv=jac[vrows, nq:2 * nq],
        dvda=jac[vrows, arows], m_inv=np.linalg.inv(plant.CalcMassMatrix(plant_ctx)), b_acc=b_acc,
        pelvis=base.coordinates.index("pelvis_tx") if seat else None, rate=-np.diag(jac[arows, arows]),
        dln_dq=-(kin.cos_pennation / params.optimal_fiber_length)[:, None] * R,
        dvn_dv=-(kin.cos_pennation / (vmax * params.optimal_fiber_length))[:, None] * R,
        df_dq=-(deriv.d_length / f_max)[:, None] * R, df_dv=-(deriv.d_velocity / f_max)[:, None] * R,
        df_da=deriv.d_activation / f_max, stretch_active=op.share_above(l_set, (kin.normalized_fiber_length > l_set).astype(float)),
        lengthening=np.broadcast_to(op.share_lengthening(), (n_m,)).astype(float),
        headroom=np.where(u0 <= options.constants.minimum_activation * (1 + 1e-9), 0.5, 1.0),
        extensors=_group_mask(base, EXTENSOR_GROUPS), flexors=_group_mask(base, FLEXOR_GROUPS),
        model=model, options=options, op=op, srs_stiffness=R.T @ (srs_unit[:, None] * R), vdot=f(x0)[vrows],
    )


def state_jacobian(td, x0, h: float = 1e-6, context=None) -> np.ndarray:
    """Central-difference Jacobian of the built diagram's time derivatives at continuous state `x0`
    (a kink, e.g. a one-sided reflex exactly at its threshold, gives the mean of its two slopes)."""
    context = context or td.diagram.CreateDefaultContext()
    x0 = np.asarray(x0, float)
    jac = finite_difference_jacobian(lambda points: [time_derivatives(td, context, x) for x in points], x0, h, central=True)
    context.SetContinuousState(x0)
    return jac


def time_derivatives(td, context, x) -> np.ndarray:
    """The diagram's continuous-state time derivatives at state `x` (set into `context`)."""
    context.SetContinuousState(x)
    return td.diagram.EvalTimeDerivatives(context).CopyToVector()


def _pelvis_mass(model) -> float:
    return model.spec.body(model.spec.pelvis).mass
