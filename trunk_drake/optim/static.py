"""Static optimisation (seed chapter 2.2, OpenSim's Static Optimization Tool) with MathematicalProgram.

At a state (q, v, vdot) the muscles, their passive forces, the intervertebral bushings and the
external loads must produce the inverse-dynamics generalized force of every free coordinate:

    R^T (a * F_active + F_passive) + reserves = M vdot + C v - tau_g - tau_bushing - J^T F_ext

(R: moment arms = -dL/dq; F_active = f_AL f_V F_max cos(phi) and F_passive = f_PE F_max cos(phi)
of a rigid tendon, so the tendon force is linear in activation; the bushings act on the level
angles ``L q`` of ``model.level_matrix``, i.e. as ``L^T`` of their moments). With a deflection
tolerance, each level's bushing may also carry up to ``k * tolerance`` beyond that: the level may
deflect within the tolerated angle instead of balancing exactly (geometry and gravity stay those of
the posture: a first-order model). Among the activations in
[min_activation, max_activation] that satisfy it, the one minimising sum(a^p) is chosen:
p = 1 is a linear program, p = 2 a quadratic program (both Clarabel, an interior-point conic
solver: exact bounds, no tuning), any other p >= 1 goes to IPOPT with an analytic gradient.

`MomentBalance` is that linear balance as plain arrays; `solve_balance` solves it, so
synthetic problems (e.g. one joint, two antagonists) go through the same code as the model.
"""

from __future__ import annotations

import fnmatch
import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, ExtractValue
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.solvers import ClarabelSolver, IpoptSolver, MathematicalProgram, SolverOptions

from trunk_drake.model.levels import LEVELS
from trunk_drake.muscle import thelen
from trunk_drake.systems.bushing import DEFAULT_DAMPING, DEFAULT_STIFFNESS
from trunk_drake.systems.muscles import muscle_parameters

UPPER_BOUND_TOL = 1e-3  # an activation within this of max_activation counts as "at the upper bound"
COACTIVATION_LEVELS = (0.010, 0.011, 0.020, 0.070)  # seed 3.2.3 and 4.4.2
COACTIVATION_RESERVE = 0.01  # Nm: optimal force of the last-resort reserve actuators of `coactivation`


class StaticInfeasibleError(ValueError):
    """No activations in bounds balance the required generalized forces.

    ``shortfall`` maps each coordinate the muscles cannot balance to the missing generalized
    force (Nm or N, signed: what a reserve would have to add); ``saturated`` lists the muscles
    at their upper bound in the closest attempt (an L1-relaxed balance).
    """

    def __init__(self, message: str, shortfall: dict[str, float], saturated: list[str]):
        super().__init__(message)
        self.shortfall = shortfall
        self.saturated = saturated


@dataclass(frozen=True)
class PointLoad:
    """An external force (N, world frame) at `point` (m, in the frame of `body`).

    The world frame is MyoTorso's: z up, -y anterior (forwards), +x to the subject's left, so a
    forward push is ``(0, -F, 0)``, not ``(F, 0, 0)`` (that bends the trunk sideways). The body
    frames are the OpenSim lumbar model's: x anterior, y superior, z right.
    """

    body: str
    point: tuple[float, float, float]
    force: tuple[float, float, float]


@dataclass
class MomentBalance:
    """The linear balance ``R^T (a * active + passive) + D d + reserves = required`` over `coordinates`.

    `moment_arms` (n_muscles, n_coordinates), `active`/`passive` (n_muscles,) in N, `required`
    (n_coordinates,) in Nm (N for translations). `deflection` D (n_coordinates, n_levels) and
    `deflection_limit` (n_levels,): extra bushing moments d, |d| <= limit (Nm), that deflecting
    levels may supply (none by default: exact balance).
    """

    moment_arms: np.ndarray
    active: np.ndarray
    passive: np.ndarray
    required: np.ndarray
    coordinates: tuple[str, ...]
    muscles: tuple[str, ...]
    deflection: np.ndarray | None = None
    deflection_limit: np.ndarray | None = None

    def __post_init__(self):
        self.moment_arms = np.atleast_2d(np.asarray(self.moment_arms, dtype=float))
        n, m = self.moment_arms.shape
        for name, size in (("active", n), ("passive", n), ("required", m)):
            arr = np.broadcast_to(np.asarray(getattr(self, name), dtype=float), (size,)).copy()
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"MomentBalance.{name} contains NaN or inf")
            setattr(self, name, arr)
        if len(self.coordinates) != m or len(self.muscles) != n:
            raise ValueError(f"MomentBalance: {len(self.muscles)} muscle and {len(self.coordinates)} coordinate "
                             f"names for a moment-arm matrix of shape {self.moment_arms.shape}")
        self.deflection = np.zeros((m, 0)) if self.deflection is None else np.asarray(self.deflection, float).reshape(m, -1)
        limit = np.zeros(0) if self.deflection_limit is None else np.asarray(self.deflection_limit, float)
        self.deflection_limit = np.broadcast_to(limit, (self.deflection.shape[1],)).copy()
        if np.any(self.deflection_limit < 0) or not np.all(np.isfinite(self.deflection_limit)):
            raise ValueError("MomentBalance.deflection_limit must be finite and >= 0")

    def with_deflection(self, A: np.ndarray) -> np.ndarray:
        """`A` (n_coordinates, k) with the deflection moments' columns appended."""
        return np.hstack([A, self.deflection])

    @property
    def activation_matrix(self) -> np.ndarray:
        """d(muscle generalized force)/d(activation), (n_coordinates, n_muscles)."""
        return self.moment_arms.T * self.active

    @property
    def target(self) -> np.ndarray:
        """What the active muscle forces and reserves must supply: required - R^T passive."""
        return self.required - self.moment_arms.T @ self.passive


@dataclass
class StaticResult:
    """Solution of one static-optimisation frame."""

    activations: np.ndarray      # (n_muscles,)
    forces: np.ndarray           # tendon forces a*active + passive, N
    reserve_forces: np.ndarray   # generalized force of the reserve actuators per coordinate
    residuals: np.ndarray        # achieved - required generalized force per coordinate
    required: np.ndarray         # required generalized force of the muscles (+ reserves)
    coordinates: tuple[str, ...]
    muscles: tuple[str, ...]
    status: str
    solver: str
    p: float
    min_activation: float
    max_activation: float
    cost: float                  # sum(a^p) (+ reserve terms)
    solve_time: float            # s, solver only
    options: dict = field(default_factory=dict)
    deflection_moments: np.ndarray = field(default_factory=lambda: np.zeros(0))  # Nm carried by deflecting levels

    @property
    def success(self) -> bool:
        return self.status == "solved"

    @property
    def at_upper_bound(self) -> list[str]:
        """Muscles whose activation is within UPPER_BOUND_TOL of max_activation."""
        return [self.muscles[i] for i in np.flatnonzero(self.activations >= self.max_activation - UPPER_BOUND_TOL)]

    @property
    def reserves_used(self) -> dict[str, float]:
        """Reserve generalized forces above 1e-6 (Nm or N), by coordinate."""
        return {c: float(f) for c, f in zip(self.coordinates, self.reserve_forces) if abs(f) > 1e-6}


# ----------------------------------------------------------------------------- the solver

def _check_bounds(p: float, min_activation: float, max_activation: float) -> None:
    if not (np.isfinite(p) and p >= 1.0):
        raise ValueError(f"p={p!r}: the activation exponent must be a finite number >= 1")
    if not (0.0 <= min_activation < max_activation <= 1.0):
        raise ValueError(f"activation bounds [{min_activation}, {max_activation}] must satisfy "
                         "0 <= min_activation < max_activation <= 1")


def _power_cost(p: float):
    """sum(|z|^p) with an analytic gradient (Drake passes AutoDiffXd arrays to IPOPT, which may
    step slightly outside the bounds, so |z| keeps non-integer powers real)."""
    def cost(z):
        if z.dtype == object:
            v = ExtractValue(z).ravel()
            grad = p * np.abs(v) ** (p - 1.0) * np.sign(v)
            return AutoDiffXd(float(np.sum(np.abs(v) ** p)), grad @ ExtractGradient(z))
        return np.sum(np.abs(z) ** p)
    return cost


class ActivationProgram:
    """A MathematicalProgram for one problem size, built once and re-solved with new data.

    Decision variables: activations (n); if `reserve_strength` is given (m,), reserve
    excitations split into positive and negative parts (both >= 0, each costing r^p, so the
    reserve's generalized force is ``strength * (r+ - r-)``); `n_deflection` bushing moments of
    deflecting levels (free of cost, bounded by the balance's deflection_limit).
    """

    def __init__(self, n_muscles: int, n_coordinates: int, p: float = 2.0, reserve_strength=None, n_deflection: int = 0):
        self.n, self.m, self.p = n_muscles, n_coordinates, float(p)
        self.reserve_strength = None if reserve_strength is None else np.broadcast_to(
            np.asarray(reserve_strength, dtype=float), (n_coordinates,)).copy()
        if self.reserve_strength is not None and np.any(self.reserve_strength <= 0):
            raise ValueError("reserve actuator strengths (optimal forces) must be > 0")
        nr = 0 if self.reserve_strength is None else 2 * n_coordinates
        prog = MathematicalProgram()
        self.a = prog.NewContinuousVariables(n_muscles, "a")
        self.r = prog.NewContinuousVariables(nr, "r")
        self.d = prog.NewContinuousVariables(n_deflection, "d")
        self.x = np.concatenate([self.a, self.r, self.d])
        paid = np.concatenate([self.a, self.r])
        self._bounds = prog.AddBoundingBoxConstraint(np.zeros(len(self.x)), np.full(len(self.x), np.inf), self.x)
        self._balance = prog.AddLinearEqualityConstraint(np.zeros((n_coordinates, len(self.x))), np.zeros(n_coordinates), self.x)
        if self.p == 1.0:
            prog.AddLinearCost(np.ones(len(paid)), paid)
            self.solver = ClarabelSolver()
        elif self.p == 2.0:
            prog.AddQuadraticCost(2.0 * np.eye(len(paid)), np.zeros(len(paid)), paid, is_convex=True)
            self.solver = ClarabelSolver()
        else:
            prog.AddCost(_power_cost(self.p), paid)
            self.solver = IpoptSolver()
        self.options = SolverOptions()
        if isinstance(self.solver, IpoptSolver):
            for key, value in (("tol", 1e-10), ("constr_viol_tol", 1e-10), ("print_level", 0)):
                self.options.SetOption(IpoptSolver.id(), key, value)
        self.prog = prog

    def solve(self, balance: MomentBalance, min_activation: float, max_activation: float):
        """(status, activations, reserve generalized forces, deflection moments, cost, solve time)."""
        nd = len(self.d)
        if balance.moment_arms.shape != (self.n, self.m) or balance.deflection.shape[1] != nd:
            raise ValueError(f"balance has shape {balance.moment_arms.shape} with {balance.deflection.shape[1]} deflecting "
                             f"levels, this program was built for {(self.n, self.m)} with {nd}")
        A = balance.activation_matrix
        nr = len(self.r)
        if nr:
            S = np.diag(self.reserve_strength)
            A = np.hstack([A, S, -S])
        A = balance.with_deflection(A)
        b = balance.target
        self._balance.evaluator().UpdateCoefficients(A, b)
        lower = np.concatenate([np.full(self.n, min_activation), np.zeros(nr), -balance.deflection_limit])
        upper = np.concatenate([np.full(self.n, max_activation), np.full(nr, np.inf), balance.deflection_limit])
        self._bounds.evaluator().set_bounds(lower, upper)
        if isinstance(self.solver, IpoptSolver):
            self.prog.SetInitialGuessForAllVariables(np.concatenate([np.full(self.n, 0.5 * (min_activation + max_activation)), np.zeros(nr + nd)]))
        start = time.perf_counter()
        result = self.solver.Solve(self.prog, None, self.options)
        elapsed = time.perf_counter() - start
        if not result.is_success():
            return str(result.get_solution_result()).split(".")[-1], None, None, None, np.nan, elapsed
        x = _polish(result.GetSolution(self.x), A, b, lower, upper)
        a = x[: self.n]
        reserve = np.zeros(self.m) if not nr else self.reserve_strength * (x[self.n : self.n + self.m] - x[self.n + self.m : self.n + nr])
        cost = float(np.sum(np.abs(x[: self.n + nr]) ** self.p))
        return "solved", a, reserve, x[self.n + nr:], cost, elapsed


def _polish(x, A, b, lower, upper):
    """Remove the solver's tolerance-level balance error by a least-norm step on free variables."""
    err = b - A @ x
    if np.max(np.abs(err), initial=0.0) < 1e-12:
        return x
    free = (x > lower + 1e-9) & (x < upper - 1e-9)
    step = np.zeros_like(x)
    step[free] = np.linalg.lstsq(A[:, free], err, rcond=None)[0]
    polished = np.clip(x + step, lower, upper)
    return polished if np.max(np.abs(b - A @ polished)) < np.max(np.abs(err)) else x


def diagnose_infeasible(balance: MomentBalance, min_activation: float, max_activation: float,
                        tol: float = 1e-6) -> tuple[dict[str, float], list[str]]:
    """The closest the muscles get: minimise sum |shortfall| (an LP with unbounded reserves).

    Returns the shortfall per coordinate (only those above `tol`) and the muscles at their
    upper bound in that solution.
    """
    n, m = balance.moment_arms.shape
    prog = MathematicalProgram()
    a = prog.NewContinuousVariables(n, "a")
    s = prog.NewContinuousVariables(2 * m, "s")
    d = prog.NewContinuousVariables(balance.deflection.shape[1], "d")
    prog.AddBoundingBoxConstraint(min_activation, max_activation, a)
    prog.AddBoundingBoxConstraint(0.0, np.inf, s)
    prog.AddBoundingBoxConstraint(-balance.deflection_limit, balance.deflection_limit, d)
    prog.AddLinearEqualityConstraint(balance.with_deflection(np.hstack([balance.activation_matrix, np.eye(m), -np.eye(m)])),
                                     balance.target, np.concatenate([a, s, d]))
    prog.AddLinearCost(np.concatenate([np.zeros(n), np.ones(2 * m)]), np.concatenate([a, s]))
    result = ClarabelSolver().Solve(prog)
    if not result.is_success():
        return {}, []
    short = result.GetSolution(s)
    short = short[:m] - short[m:]
    act = result.GetSolution(a)
    shortfall = {c: float(v) for c, v in zip(balance.coordinates, short) if abs(v) > tol}
    saturated = [balance.muscles[i] for i in np.flatnonzero(act >= max_activation - UPPER_BOUND_TOL)]
    return shortfall, saturated


def infeasible_error(balance: MomentBalance, min_activation: float, max_activation: float, status: str,
                     where: str = "") -> StaticInfeasibleError:
    """A StaticInfeasibleError that names the unbalanced coordinates and saturated muscles."""
    shortfall, saturated = diagnose_infeasible(balance, min_activation, max_activation)
    unit = {c: ("N" if c == "pelvis_tx" else "Nm") for c in balance.coordinates}
    if shortfall:
        missing = ", ".join(f"{c} (short by {v:+.4g} {unit[c]})" for c, v in sorted(shortfall.items(), key=lambda kv: -abs(kv[1])))
        what = f"the muscles cannot produce the required generalized force at {missing}"
    else:
        what = f"the solver reported {status} although an L1 relaxation balances exactly (numerical trouble)"
    sat = ", ".join(saturated[:20]) + (f" and {len(saturated) - 20} more" if len(saturated) > 20 else "") or "none"
    message = (f"static optimisation infeasible{where}: {what}; muscles at their upper bound: {sat}. "
               "Reduce the load, raise strength_scale or max_activation, lower min_activation, "
               "or add reserve actuators (reserves=...).")
    return StaticInfeasibleError(message, shortfall, saturated)


def solve_balance(balance: MomentBalance, p: float = 2.0, min_activation: float = 0.01, max_activation: float = 1.0,
                  reserves=None, program: ActivationProgram | None = None, where: str = "") -> StaticResult:
    """Minimise sum(a^p) subject to `balance`; raise StaticInfeasibleError if no activations fit.

    `reserves`: optimal force of a reserve actuator on every balanced coordinate (scalar or
    per coordinate), or None. Pass `program` (an ActivationProgram of matching size) to reuse it.
    """
    _check_bounds(p, min_activation, max_activation)
    n, m = balance.moment_arms.shape
    prog = program or ActivationProgram(n, m, p, reserves, balance.deflection.shape[1])
    status, a, reserve, deflection, cost, elapsed = prog.solve(balance, min_activation, max_activation)
    if a is None:
        raise infeasible_error(balance, min_activation, max_activation, status, where)
    forces = a * balance.active + balance.passive
    residuals = balance.moment_arms.T @ forces + reserve + balance.deflection @ deflection - balance.required
    return StaticResult(
        activations=a, forces=forces, reserve_forces=reserve, residuals=residuals, required=balance.required,
        coordinates=balance.coordinates, muscles=balance.muscles, status=status, solver=prog.solver.solver_id().name(),
        p=float(p), min_activation=float(min_activation), max_activation=float(max_activation), cost=cost, solve_time=elapsed,
        deflection_moments=deflection,
    )


# ------------------------------------------------------------------------ model problems

def select_coordinates(coordinates, patterns) -> list[str]:
    """Coordinates matching any of `patterns` (exact names or fnmatch globs); error if one matches nothing."""
    chosen = []
    for pattern in patterns:
        hits = [c for c in coordinates if fnmatch.fnmatchcase(c, pattern)]
        if not hits:
            raise ValueError(f"coordinate pattern {pattern!r} matches none of {list(coordinates)}")
        chosen += [c for c in hits if c not in chosen]
    return chosen


class StaticOptimizer:
    """Static optimisation of one model, its program built once and reused frame after frame.

    Options (keywords, SI units): `p` (>= 1), `min_activation`, `max_activation`,
    `include_passive` (muscle passive force; OpenSim's tool ignores it: False to compare),
    `reserves` (optimal force of reserve actuators on every balanced coordinate, or None),
    `locked` (coordinate names or globs whose equilibrium is not required: held by a lock),
    `strength_scale` (multiplies F_max), `constants` (thelen.ThelenConstants),
    `bushing_stiffness`/`bushing_damping` (per lumbar flexion-extension level, as the diagram;
    0 disables), `deflection_tolerance` (rad: each level may deflect on its bushing up to this
    angle instead of balancing exactly; independent levels only). Velocity enters the
    force-velocity curve at full activation (as OpenSim).
    """

    def __init__(self, model, *, p: float = 2.0, min_activation: float = 0.01, max_activation: float = 1.0,
                 include_passive: bool = True, reserves=None, locked=(), strength_scale: float = 1.0,
                 constants: thelen.ThelenConstants | None = None, bushing_stiffness=DEFAULT_STIFFNESS,
                 bushing_damping=DEFAULT_DAMPING, deflection_tolerance: float = 0.0):
        _check_bounds(p, min_activation, max_activation)
        if not strength_scale > 0:
            raise ValueError(f"strength_scale={strength_scale!r} must be > 0")
        if not (np.isfinite(deflection_tolerance) and deflection_tolerance >= 0):
            raise ValueError(f"deflection_tolerance={deflection_tolerance!r} must be an angle >= 0 (rad)")
        if deflection_tolerance and model.coupling is not None:
            raise ValueError(f"deflection_tolerance applies to independent levels ('sagittal', 'spine3d'); in the "
                             f"{model.dofs!r} configuration the levels cannot deflect on their own")
        self.model = model
        self.p, self.min_activation, self.max_activation = float(p), float(min_activation), float(max_activation)
        self.include_passive = include_passive
        self.constants = constants or thelen.ThelenConstants()
        self.params = muscle_parameters(model, strength_scale)
        self.plant = model.plant
        self.context = self.plant.CreateDefaultContext()
        coords = model.coordinates
        self.locked = select_coordinates(coords, locked)
        self.free = np.array([i for i, c in enumerate(coords) if c not in self.locked], dtype=int)
        if not len(self.free):
            raise ValueError("every coordinate is locked: nothing to balance")
        self.coordinates = tuple(coords[i] for i in self.free)
        self.levels = model.level_matrix  # level angles = levels @ q
        n_levels = len(self.levels)
        self.k = np.broadcast_to(np.asarray(bushing_stiffness, float), (n_levels,)).copy()
        self.c = np.broadcast_to(np.asarray(bushing_damping, float), (n_levels,)).copy()
        self.deflection_tolerance = float(deflection_tolerance)
        deflecting = np.flatnonzero(self.k * self.deflection_tolerance > 0)
        self.deflection = self.levels[deflecting][:, self.free].T
        self.deflection_limit = self.k[deflecting] * self.deflection_tolerance
        self.options = {"p": self.p, "min_activation": self.min_activation, "max_activation": self.max_activation,
                        "include_passive": include_passive, "reserves": reserves, "locked": self.locked,
                        "strength_scale": float(strength_scale), "bushing_stiffness": self.k.tolist(),
                        "bushing_damping": self.c.tolist(), "deflection_tolerance": self.deflection_tolerance}
        self.program = ActivationProgram(model.n_muscles, len(self.free), self.p, reserves, len(deflecting))

    def set_state(self, q, v=None, vdot=None):
        """Put (q, v) into the optimizer's plant context; returns checked (q, v, vdot)."""
        nv = self.plant.num_velocities()
        q = self.model.check_q(q)
        v = np.zeros(nv) if v is None else self.model.check_q(v, "v", check_range=False)
        vdot = np.zeros(nv) if vdot is None else self.model.check_q(vdot, "vdot", check_range=False)
        self.plant.SetPositions(self.context, q)
        self.plant.SetVelocities(self.context, v)
        return q, v, vdot

    def generalized_load(self, loads) -> np.ndarray:
        """Generalized force J^T F of point loads at the current state (all coordinates)."""
        tau = np.zeros(self.plant.num_velocities())
        world = self.plant.world_frame()
        for load in loads:
            frame = self.plant.GetBodyByName(load.body).body_frame()
            J = self.plant.CalcJacobianTranslationalVelocity(self.context, JacobianWrtVariable.kV, frame,
                                                             np.asarray(load.point, float), world, world)
            tau += J.T @ np.asarray(load.force, float)
        return tau

    def balance(self, q, v=None, vdot=None, external_loads=()) -> MomentBalance:
        """The linear balance at state (q, v, vdot) with `external_loads` (PointLoads)."""
        q, v, vdot = self.set_state(q, v, vdot)
        plant, ctx = self.plant, self.context
        inverse_dynamics = plant.CalcMassMatrix(ctx) @ vdot + plant.CalcBiasTerm(ctx) - plant.CalcGravityGeneralizedForces(ctx)
        L = self.levels
        bushing = L.T @ (-self.k * (L @ q) - self.c * (L @ v))
        required = inverse_dynamics - bushing - self.generalized_load(external_loads)
        path = self.model.path_state(q, v)
        split = thelen.rigid_tendon_force_split(path.lengths, path.velocities, self.params, self.constants)
        passive = split.passive if self.include_passive else np.zeros_like(split.passive)
        return MomentBalance(path.moment_arms[:, self.free], split.active, passive, required[self.free],
                             self.coordinates, tuple(self.model.muscles), self.deflection, self.deflection_limit)

    def solve_balance(self, balance: MomentBalance, where: str = "") -> StaticResult:
        result = solve_balance(balance, self.p, self.min_activation, self.max_activation, program=self.program, where=where)
        result.options = dict(self.options)
        return result

    def solve(self, q, v=None, vdot=None, external_loads=()) -> StaticResult:
        """One static-optimisation frame; StaticInfeasibleError if the muscles cannot hold it."""
        return self.solve_balance(self.balance(q, v, vdot, external_loads), where=f" at q={np.round(np.asarray(q, float), 4).tolist()}")


def static_optimization(model, q, v=None, vdot=None, external_loads=(), **options) -> StaticResult:
    """Minimise sum(a^p) subject to the generalized-force balance of every free coordinate.

    `q`, `v`, `vdot` follow ``model.coordinates`` (v, vdot default to zero); `external_loads`
    is a sequence of PointLoad. Options as StaticOptimizer (p=2, min_activation=0.01,
    include_passive=True, reserves=None, locked=(), ...). For many frames build one
    StaticOptimizer and call its ``solve``.
    """
    return StaticOptimizer(model, **options).solve(q, v, vdot, external_loads)


def coactivation(model, min_activation: float = 0.020, q=None, reserves: float = COACTIVATION_RESERVE,
                 return_result: bool = False, **options):
    """Feed-forward excitation (n_muscles,) that holds the upright posture under gravity.

    Static optimisation of the lumbar flexion-extension coordinates (seed 3.2.3: the level
    angles, or the rhythm's lumbar_FE; every other coordinate, e.g. pelvis_tx, is locked) with activations >= `min_activation`; at steady
    state excitation equals activation, so the result feeds ``TrunkOptions(feedforward=...)``.
    The thesis used 0.010, 0.011, 0.020 and 0.070 (COACTIVATION_LEVELS) and kept 0.020.

    MyoTorso's muscles cannot always balance the small, level-alternating gravity moments
    exactly once every muscle is held above `min_activation`. Then reserve actuators of
    `reserves` Nm optimal force (a last resort: 0.01 Nm costs as much as a fully active
    muscle) take the remainder, and a warning names it with the settling of the bushings that
    would carry it. With ``return_result`` the StaticResult comes too: ``(excitation, result)``.
    """
    free = [model.coordinates[i] for i in np.flatnonzero(np.abs(model.level_matrix).sum(axis=0) > 0)]
    locked = [c for c in model.coordinates if c not in free]
    q = np.zeros(len(model.coordinates)) if q is None else q
    try:
        result = StaticOptimizer(model, min_activation=min_activation, locked=locked, **options).solve(q)
    except StaticInfeasibleError:
        optimizer = StaticOptimizer(model, min_activation=min_activation, locked=locked, reserves=reserves, **options)
        result = optimizer.solve(q)
        L = model.level_matrix[:, [model.coordinates.index(c) for c in free]]
        k = dict(zip(free, L.T**2 @ optimizer.k))  # stiffness of each balanced coordinate through the bushings
        detail = ", ".join(f"{c} {f:+.3g} Nm (~{np.degrees(abs(f) / k[c]) if k[c] > 0 else np.inf:.2g} deg on the bushing)"
                           for c, f in result.reserves_used.items() if abs(f) > 1e-3)
        warnings.warn(f"co-activation at min_activation={min_activation}: the muscles leave {detail} unbalanced; "
                      "the reserves carry it here; in a simulation the trunk drifts from upright (with MyoTorso it can fall into extension)", stacklevel=2)
    return (result.activations, result) if return_result else result.activations


def with_required(balance: MomentBalance, extra) -> MomentBalance:
    """`balance` with `extra` generalized force (same coordinates) added to what must be supplied."""
    return replace(balance, required=balance.required + np.asarray(extra, float))


VERTEBRAE = ("L5", "L4", "L3", "L2", "L1")  # the body above each level of LEVELS (L1 carries the upper body)


def vertebra_balances(balance: MomentBalance, min_activation: float = 0.0, max_activation: float = 1.0,
                      per_newton=None, top: int = 4) -> list[dict]:
    """Each lumbar vertebra's own moment balance in a model with independent flexion levels.

    The body above level k sits between level k and level k+1, so its equilibrium is the
    difference of the two level balances: each muscle contributes the difference of its moment
    arms at the two levels (one inserting on the vertebra crosses only level k; one passing it
    contributes through the change of its lever arm from one joint centre to the other), and
    together they must supply ``need`` (Nm, flexion of the vertebra relative to its neighbours;
    beyond passive force and activation floor) plus ``per_newton`` times the load. ``capacity`` is the largest flexing and extending moment those
    muscles give within the activation bounds; ``load_limit`` the load at which this vertebra
    alone runs out (N; None without a load or if it never does).
    """
    names = [f"{lvl}_FE" for lvl in LEVELS]
    index = [balance.coordinates.index(n) for n in names if n in balance.coordinates]
    if len(index) != len(LEVELS):
        raise ValueError(f"vertebra balances need the independent flexion levels {names}; the balance has {balance.coordinates}")
    A = balance.activation_matrix
    floor = balance.target - A @ np.full(A.shape[1], min_activation)
    out = []
    for k, vertebra in enumerate(VERTEBRAE):
        row = np.zeros(len(balance.coordinates))
        row[index[k]] = 1.0
        if k + 1 < len(index):
            row[index[k + 1]] = -1.0
        moment = row @ A * (max_activation - min_activation)  # per muscle, from its floor to full activation
        need = float(row @ floor)
        capacity = (float(moment[moment < 0].sum()), float(moment[moment > 0].sum()))
        entry = {"vertebra": vertebra, "between": [names[k], names[k + 1] if k + 1 < len(names) else None], "need_Nm": need,
                 "capacity_Nm": capacity, "flexing": [(balance.muscles[i], float(moment[i])) for i in np.argsort(-moment)[:top] if moment[i] > 0],
                 "extending": [(balance.muscles[i], float(moment[i])) for i in np.argsort(moment)[:top] if moment[i] < 0]}
        if per_newton is not None:
            step = float(-(row @ np.asarray(per_newton, float)))
            entry["need_per_newton_m"] = step
            room = capacity[1] - need if step > 0 else need - capacity[0]
            entry["load_limit_N"] = float(room / abs(step)) if step and room > 0 else (0.0 if step else None)
        out.append(entry)
    return out
