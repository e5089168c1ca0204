"""Static optimisation (seed chapter 2.2, OpenSim's Static Optimization Tool) with MathematicalProgram.

At a state (q, v, vdot) the muscles, their passive forces, the intervertebral bushings and the
external loads must produce the inverse-dynamics generalized force of every free coordinate:

    R^T (a * F_active + F_passive) + reserves = M vdot + C v - tau_g - tau_bushing - J^T F_ext

(R: moment arms = -dL/dq; F_active = f_AL f_V F_max cos(phi) and F_passive = f_PE F_max cos(phi)
of a rigid tendon, so the tendon force is linear in activation). Among the activations in
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
    """An external force (N, world frame) at `point` (m, in the frame of `body`)."""

    body: str
    point: tuple[float, float, float]
    force: tuple[float, float, float]


@dataclass
class MomentBalance:
    """The linear balance ``R^T (a * active + passive) + reserves = required`` over `coordinates`.

    `moment_arms` (n_muscles, n_coordinates), `active`/`passive` (n_muscles,) in N, `required`
    (n_coordinates,) in Nm (N for translations).
    """

    moment_arms: np.ndarray
    active: np.ndarray
    passive: np.ndarray
    required: np.ndarray
    coordinates: tuple[str, ...]
    muscles: tuple[str, ...]

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

    Decision variables: activations (n) and, if `reserve_strength` is given (m,), reserve
    excitations split into positive and negative parts (both >= 0, each costing r^p, so the
    reserve's generalized force is ``strength * (r+ - r-)``).
    """

    def __init__(self, n_muscles: int, n_coordinates: int, p: float = 2.0, reserve_strength=None):
        self.n, self.m, self.p = n_muscles, n_coordinates, float(p)
        self.reserve_strength = None if reserve_strength is None else np.broadcast_to(
            np.asarray(reserve_strength, dtype=float), (n_coordinates,)).copy()
        if self.reserve_strength is not None and np.any(self.reserve_strength <= 0):
            raise ValueError("reserve actuator strengths (optimal forces) must be > 0")
        nr = 0 if self.reserve_strength is None else 2 * n_coordinates
        prog = MathematicalProgram()
        self.a = prog.NewContinuousVariables(n_muscles, "a")
        self.r = prog.NewContinuousVariables(nr, "r")
        self.x = np.concatenate([self.a, self.r])
        self._bounds = prog.AddBoundingBoxConstraint(np.zeros(len(self.x)), np.full(len(self.x), np.inf), self.x)
        self._balance = prog.AddLinearEqualityConstraint(np.zeros((n_coordinates, len(self.x))), np.zeros(n_coordinates), self.x)
        if self.p == 1.0:
            prog.AddLinearCost(np.ones(len(self.x)), self.x)
            self.solver = ClarabelSolver()
        elif self.p == 2.0:
            prog.AddQuadraticCost(2.0 * np.eye(len(self.x)), np.zeros(len(self.x)), self.x, is_convex=True)
            self.solver = ClarabelSolver()
        else:
            prog.AddCost(_power_cost(self.p), self.x)
            self.solver = IpoptSolver()
        self.options = SolverOptions()
        if isinstance(self.solver, IpoptSolver):
            for key, value in (("tol", 1e-10), ("constr_viol_tol", 1e-10), ("print_level", 0)):
                self.options.SetOption(IpoptSolver.id(), key, value)
        self.prog = prog

    def solve(self, balance: MomentBalance, min_activation: float, max_activation: float):
        """(status, activations, reserve generalized forces, cost, solve time)."""
        if balance.moment_arms.shape != (self.n, self.m):
            raise ValueError(f"balance has shape {balance.moment_arms.shape}, this program was built for {(self.n, self.m)}")
        A = balance.activation_matrix
        nr = len(self.r)
        if nr:
            S = np.diag(self.reserve_strength)
            A = np.hstack([A, S, -S])
        b = balance.target
        self._balance.evaluator().UpdateCoefficients(A, b)
        lower = np.concatenate([np.full(self.n, min_activation), np.zeros(nr)])
        upper = np.concatenate([np.full(self.n, max_activation), np.full(nr, np.inf)])
        self._bounds.evaluator().set_bounds(lower, upper)
        if isinstance(self.solver, IpoptSolver):
            self.prog.SetInitialGuessForAllVariables(np.concatenate([np.full(self.n, 0.5 * (min_activation + max_activation)), np.zeros(nr)]))
        start = time.perf_counter()
        result = self.solver.Solve(self.prog, None, self.options)
        elapsed = time.perf_counter() - start
        if not result.is_success():
            return str(result.get_solution_result()).split(".")[-1], None, None, np.nan, elapsed
        x = _polish(result.GetSolution(self.x), A, b, lower, upper)
        a = x[: self.n]
        reserve = np.zeros(self.m) if not nr else self.reserve_strength * (x[self.n : self.n + self.m] - x[self.n + self.m :])
        cost = float(np.sum(np.abs(x) ** self.p))
        return "solved", a, reserve, cost, elapsed


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
    prog.AddBoundingBoxConstraint(min_activation, max_activation, a)
    prog.AddBoundingBoxConstraint(0.0, np.inf, s)
    prog.AddLinearEqualityConstraint(np.hstack([balance.activation_matrix, np.eye(m), -np.eye(m)]), balance.target, np.concatenate([a, s]))
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
    prog = program or ActivationProgram(n, m, p, reserves)
    status, a, reserve, cost, elapsed = prog.solve(balance, min_activation, max_activation)
    if a is None:
        raise infeasible_error(balance, min_activation, max_activation, status, where)
    forces = a * balance.active + balance.passive
    residuals = balance.moment_arms.T @ forces + reserve - balance.required
    return StaticResult(
        activations=a, forces=forces, reserve_forces=reserve, residuals=residuals, required=balance.required,
        coordinates=balance.coordinates, muscles=balance.muscles, status=status, solver=prog.solver.solver_id().name(),
        p=float(p), min_activation=float(min_activation), max_activation=float(max_activation), cost=cost, solve_time=elapsed,
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
    0 disables). Velocity enters the force-velocity curve at full activation (as OpenSim).
    """

    def __init__(self, model, *, p: float = 2.0, min_activation: float = 0.01, max_activation: float = 1.0,
                 include_passive: bool = True, reserves=None, locked=(), strength_scale: float = 1.0,
                 constants: thelen.ThelenConstants | None = None, bushing_stiffness=DEFAULT_STIFFNESS,
                 bushing_damping=DEFAULT_DAMPING):
        _check_bounds(p, min_activation, max_activation)
        if not strength_scale > 0:
            raise ValueError(f"strength_scale={strength_scale!r} must be > 0")
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
        self.fe = np.array([coords.index(f"{lvl}_FE") for lvl in LEVELS])
        self.k = np.broadcast_to(np.asarray(bushing_stiffness, float), (len(LEVELS),)).copy()
        self.c = np.broadcast_to(np.asarray(bushing_damping, float), (len(LEVELS),)).copy()
        self.options = {"p": self.p, "min_activation": self.min_activation, "max_activation": self.max_activation,
                        "include_passive": include_passive, "reserves": reserves, "locked": self.locked,
                        "strength_scale": float(strength_scale), "bushing_stiffness": self.k.tolist(),
                        "bushing_damping": self.c.tolist()}
        self.program = ActivationProgram(model.n_muscles, len(self.free), self.p, reserves)

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
        bushing = np.zeros_like(inverse_dynamics)
        bushing[self.fe] = -self.k * q[self.fe] - self.c * v[self.fe]
        required = inverse_dynamics - bushing - self.generalized_load(external_loads)
        path = self.model.path_state(q, v)
        split = thelen.rigid_tendon_force_split(path.lengths, path.velocities, self.params, self.constants)
        passive = split.passive if self.include_passive else np.zeros_like(split.passive)
        return MomentBalance(path.moment_arms[:, self.free], split.active, passive, required[self.free],
                             self.coordinates, tuple(self.model.muscles))

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

    Static optimisation of the lumbar flexion-extension coordinates (seed 3.2.3; every other
    coordinate, e.g. pelvis_tx, is locked) with activations >= `min_activation`; at steady
    state excitation equals activation, so the result feeds ``TrunkOptions(feedforward=...)``.
    The thesis used 0.010, 0.011, 0.020 and 0.070 (COACTIVATION_LEVELS) and kept 0.020.

    MyoTorso's muscles cannot always balance the small, level-alternating gravity moments
    exactly once every muscle is held above `min_activation`. Then reserve actuators of
    `reserves` Nm optimal force (a last resort: 0.01 Nm costs as much as a fully active
    muscle) take the remainder, and a warning names it with the settling of the bushings that
    would carry it. With ``return_result`` the StaticResult comes too: ``(excitation, result)``.
    """
    fe = [f"{lvl}_FE" for lvl in LEVELS]
    locked = [c for c in model.coordinates if c not in fe]
    q = np.zeros(len(model.coordinates)) if q is None else q
    try:
        result = StaticOptimizer(model, min_activation=min_activation, locked=locked, **options).solve(q)
    except StaticInfeasibleError:
        optimizer = StaticOptimizer(model, min_activation=min_activation, locked=locked, reserves=reserves, **options)
        result = optimizer.solve(q)
        k = dict(zip(fe, optimizer.k))
        detail = ", ".join(f"{c} {f:+.3g} Nm (~{np.degrees(abs(f) / k[c]) if k[c] > 0 else np.inf:.2g} deg on the bushing)"
                           for c, f in result.reserves_used.items() if abs(f) > 1e-3)
        warnings.warn(f"co-activation at min_activation={min_activation}: the muscles leave {detail} unbalanced; "
                      "the reserves carry it here; in a simulation the trunk drifts from upright (with MyoTorso it can fall into extension)", stacklevel=2)
    return (result.activations, result) if return_result else result.activations


def with_required(balance: MomentBalance, extra) -> MomentBalance:
    """`balance` with `extra` generalized force (same coordinates) added to what must be supplied."""
    return replace(balance, required=balance.required + np.asarray(extra, float))
