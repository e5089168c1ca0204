"""Isometric trunk strength with the pelvis locked (seed 2.2, 4.1-4.2, appendix A).

The thesis re-ran OpenSim's Static Optimization Tool with the load raised in 10 N steps from
0 to 700 N until it failed. Here the maximal strength is solved for directly: a linear program
maximises the load F over (activations, F) subject to the same generalized-force balance, so
it equals the sweep's answer to within the step. The sweep is kept for parity.

Load points (MyoTorso lumps thorax, arms and head into one body "torso"; the points are the
model's own landmarks, trunk_drake.model.myotorso):
* extension / flexion: a horizontal force along the pelvis' anterior (resp. posterior)
  direction, half at the T6 and half at the T7 vertebral-body centre (seed Fig. 2.3). The
  subject pushes backwards (extension) against a pad, so the pad pushes the trunk forwards.
* lateral: a vertical force at the left shoulder site (seed Fig. 2.4), upwards: the subject
  bends to the left against it, so the left-side muscles work (seed 4.1). MyoTorso's shoulder
  site lies 0.07 m lateral of the midline; a real acromion is about 0.20 m lateral (half the
  biacromial breadth in models/reference_values.toml), so with the model's site the same
  lateral-bending moment needs ~2.9x the force. ``shoulder="acromion"`` moves the point
  laterally to the cited half-breadth (keeping the site's height and depth). The site is also
  ~0.11 m posterior of the spine's axis, so the vertical force flexes the trunk as well.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.solvers import Binding, ClarabelSolver, EvaluatorBase, MathematicalProgram

from trunk_drake.data import load_toml
from trunk_drake.model.plant import rhythm_spec
from trunk_drake.optim.static import (
    MomentBalance, PointLoad, StaticInfeasibleError, StaticOptimizer, StaticResult, infeasible_error, with_required,
)

DIRECTIONS = ("extension", "flexion", "lateral")
THESIS_STEP = 10.0          # N, seed 2.2.1
THESIS_RANGE = (0.0, 700.0)  # N, seed 2.2.1
SWEEP_LIMIT = 5000.0        # N: our sweep continues past the thesis' 700 N until it fails (or this)
FORCE_CAP = 1.0e5           # N: a maximum at this bound means the load is not resisted by muscles
PRIMARY_REFERENCE = {       # the thesis' in vivo sources (seed 4.2)
    "extension": "paalanne2009_young_men", "flexion": "paalanne2009_young_men", "lateral": "thomas",
}


@dataclass(frozen=True)
class LoadCase:
    """Where and in which direction the external force acts (per newton of total load)."""

    direction: str
    body: str
    points: tuple[tuple[float, float, float], ...]  # in the body frame, m
    shares: tuple[float, ...]                        # fraction of the load at each point
    unit_force: tuple[float, float, float]           # world frame
    description: str

    def point_loads(self, magnitude: float) -> list[PointLoad]:
        f = np.asarray(self.unit_force) * magnitude
        return [PointLoad(self.body, tuple(p), tuple(s * f)) for p, s in zip(self.points, self.shares)]


def acromion_half_breadth() -> float:
    """Half the biacromial breadth of models/reference_values.toml (m)."""
    entry = load_toml("reference_values.toml")["anthropometry"]["cityu_online"]["biacromial_breadth_british_men"]
    return 0.5 * float(entry["value"])


def load_case(model, direction: str, level=("T6", "T7"), shoulder: str = "model", context=None) -> LoadCase:
    """The load of one strength test on `model` (see the module docstring).

    `level`: thoracic landmarks sharing the sagittal load equally; `shoulder`: "model" (the
    shoulder_l site) or "acromion" (moved to the cited acromion half-breadth).
    """
    if direction not in DIRECTIONS:
        raise ValueError(f"unknown strength direction {direction!r}; expected one of {DIRECTIONS}")
    plant = model.plant
    context = context or plant.CreateDefaultContext()
    if direction == "lateral":
        if not any(c.endswith("_LB") for c in model.coordinates):
            raise ValueError(f"lateral strength needs lateral bending coordinates: load_model(dofs='spine3d'), not {model.dofs!r}")
        if shoulder not in ("model", "acromion"):
            raise ValueError(f"shoulder={shoulder!r}; expected 'model' or 'acromion'")
        site = model.spec.landmark("shoulder_l")
        point = np.array(site.pos, dtype=float)
        if shoulder == "acromion":
            point[2] = -acromion_half_breadth()  # body z points right: left is negative
        up = -np.asarray(model.spec.gravity, float) / np.linalg.norm(model.spec.gravity)
        where = "model shoulder site" if shoulder == "model" else f"acromion, {abs(point[2]):.3f} m left of the midline"
        return LoadCase(direction, site.body, (tuple(point),), (1.0,), tuple(up), f"vertical upward force at the left shoulder ({where})")
    sites = [model.spec.landmark(name) for name in level]
    bodies = {s.body for s in sites}
    if len(bodies) != 1:
        raise ValueError(f"load landmarks {list(level)} lie on several bodies {sorted(bodies)}")
    pelvis = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(model.spec.pelvis)).rotation().matrix()[:, 0]
    up = -np.asarray(model.spec.gravity, float) / np.linalg.norm(model.spec.gravity)
    anterior = pelvis - (pelvis @ up) * up
    anterior /= np.linalg.norm(anterior)
    sign, word = (1.0, "anterior") if direction == "extension" else (-1.0, "posterior")
    share = 1.0 / len(sites)
    return LoadCase(direction, bodies.pop(), tuple(tuple(s.pos) for s in sites), (share,) * len(sites), tuple(sign * anterior),
                    f"horizontal {word} force split equally over {' and '.join(level)}")


@dataclass
class StrengthResult:
    """Maximal isometric strength of one direction."""

    direction: str
    max_force: float                      # N, solved directly (LP)
    min_force: float                      # N, smallest feasible load: > 0 if the unloaded posture is infeasible
    limiting_coordinate: str
    sensitivity: dict[str, float]         # dF_max / d(extra generalized force), N per Nm (or N/N)
    muscles_at_upper_bound: list[str]     # static optimisation just below the maximum
    activations: np.ndarray               # of that frame
    load: LoadCase
    sweep_force: float | None = None      # last feasible load of the sweep (None: not run / none feasible)
    sweep_first_failure: float | None = None
    sweep_solves: int = 0
    sweep_step: float = THESIS_STEP
    in_vivo: list[dict] = field(default_factory=list)
    variants: dict = field(default_factory=dict)
    time: float = 0.0

    @property
    def parity(self) -> bool | None:
        """Does the direct maximum lie within one step above the sweep's last feasible load?"""
        if self.sweep_force is None:
            return None
        return self.sweep_force - 1e-6 <= self.max_force < self.sweep_force + self.sweep_step + 1e-6

    def summary(self) -> dict:
        out = {
            "direction": self.direction, "max_force_N": self.max_force, "min_feasible_force_N": self.min_force,
            "load": self.load.description,
            "limiting_coordinate": self.limiting_coordinate,
            "sensitivity_N_per_Nm": self.sensitivity,
            "muscles_at_upper_bound": self.muscles_at_upper_bound,
            "sweep": {"step_N": self.sweep_step, "last_feasible_N": self.sweep_force,
                      "first_failure_N": self.sweep_first_failure, "solves": self.sweep_solves,
                      "direct_within_one_step": self.parity},
            "in_vivo": self.in_vivo, "time_s": self.time,
        }
        if self.variants:
            out["variants"] = self.variants
        return out


def _load_lp(balance: MomentBalance, per_newton, min_activation: float, max_activation: float, maximise: bool):
    per_newton = np.asarray(per_newton, float)
    n = balance.moment_arms.shape[0]
    prog = MathematicalProgram()
    a = prog.NewContinuousVariables(n, "a")
    force = prog.NewContinuousVariables(1, "F")
    d = prog.NewContinuousVariables(balance.deflection.shape[1], "d")
    prog.AddBoundingBoxConstraint(min_activation, max_activation, a)
    prog.AddBoundingBoxConstraint(0.0, FORCE_CAP, force)
    prog.AddBoundingBoxConstraint(-balance.deflection_limit, balance.deflection_limit, d)
    constraint = prog.AddLinearEqualityConstraint(balance.with_deflection(np.hstack([balance.activation_matrix, per_newton[:, None]])),
                                                  balance.target, np.concatenate([a, force, d]))
    prog.AddLinearCost(-np.ones(1) if maximise else np.ones(1), force)
    return ClarabelSolver().Solve(prog), force, constraint


def max_load(balance: MomentBalance, per_newton, min_activation: float = 0.01, max_activation: float = 1.0,
             where: str = "") -> tuple[float, np.ndarray]:
    """Largest load F with activations in bounds such that R^T (a active + passive) + per_newton F = required.

    A linear program over (activations, F). Returns F (N) and the sensitivity of F to extra
    generalized force made available at each coordinate (N per Nm). Raises
    StaticInfeasibleError if no load F >= 0 is feasible, ValueError if the load meets no
    resistance.
    """
    result, force, constraint = _load_lp(balance, per_newton, min_activation, max_activation, maximise=True)
    if not result.is_success():
        raise infeasible_error(balance, min_activation, max_activation, str(result.get_solution_result()),
                               f" for every load{where}; without load")
    f_max = float(result.GetSolution(force)[0])
    if f_max >= FORCE_CAP * (1 - 1e-6):
        raise ValueError(f"the load meets no muscular resistance{where} (maximum hit {FORCE_CAP:g} N): its generalized "
                         f"force per N {dict(zip(balance.coordinates, np.round(per_newton, 4)))} is zero or acts only on locked coordinates")
    # Drake's dual is d(cost)/d(rhs) with cost = -F; extra generalized force h enters as rhs - h. The binding
    # is up-cast explicitly: pybind11's implicit conversion is not thread-safe (Dask thread workers).
    base = Binding[EvaluatorBase](constraint.evaluator(), constraint.variables())
    return f_max, np.asarray(result.GetDualSolution(base), float)


def min_load(balance: MomentBalance, per_newton, min_activation: float = 0.01, max_activation: float = 1.0) -> float:
    """Smallest feasible load F >= 0 (N): above 0 when the unloaded posture cannot be held (call after max_load)."""
    result, force, _ = _load_lp(balance, per_newton, min_activation, max_activation, maximise=False)
    return float(result.GetSolution(force)[0]) if result.is_success() else float("nan")


class StrengthProblem:
    """One strength test at one posture: the load-free balance and the load's generalized force."""

    def __init__(self, optimizer: StaticOptimizer, case: LoadCase, q=None, balance: MomentBalance | None = None):
        model = optimizer.model
        self.optimizer, self.case = optimizer, case
        self.q = np.zeros(len(model.coordinates)) if q is None else np.asarray(q, float)
        self.balance = balance if balance is not None else optimizer.balance(self.q)
        optimizer.set_state(self.q, None, None)
        self.per_newton = optimizer.generalized_load(case.point_loads(1.0))[optimizer.free]
        self.coordinates = self.balance.coordinates

    def at(self, force: float) -> MomentBalance:
        """The balance with `force` newtons applied (the load is supplied, so less is required)."""
        return with_required(self.balance, -self.per_newton * force)

    def solve(self, force: float) -> StaticResult:
        return self.optimizer.solve_balance(self.at(force), where=f" with a {force:.6g} N {self.case.direction} load")

    def maximum(self) -> tuple[float, np.ndarray]:
        """(largest feasible load in N, dF_max/d(extra generalized force) per coordinate)."""
        opt = self.optimizer
        return max_load(self.balance, self.per_newton, opt.min_activation, opt.max_activation,
                        where=f" ({self.case.direction} test)")

    def minimum(self) -> float:
        """Smallest feasible load (N); > 0 if the posture cannot be held without the load."""
        return min_load(self.balance, self.per_newton, self.optimizer.min_activation, self.optimizer.max_activation)

    def sweep(self, step: float = THESIS_STEP, limit: float = SWEEP_LIMIT):
        """The thesis' search: static optimisation at 0, step, 2 step, ... until it fails.

        Returns (last feasible load or None, first failing load or None, number of solves,
        result of the last feasible frame or None).
        """
        if not step > 0:
            raise ValueError(f"sweep step must be > 0, got {step}")
        last, last_result, solves = None, None, 0
        for force in np.arange(0.0, limit + 0.5 * step, step):
            solves += 1
            try:
                last_result = self.solve(float(force))
            except StaticInfeasibleError:
                return last, float(force), solves, last_result
            last = float(force)
        return last, None, solves, last_result


def _limiting(coordinates, sensitivity) -> tuple[str, dict[str, float]]:
    mags = np.abs(sensitivity)
    keep = mags >= 0.01 * mags.max() if mags.max() > 0 else mags > 0
    order = np.argsort(-mags)
    ranked = {coordinates[i]: float(sensitivity[i]) for i in order if keep[i]}
    return coordinates[int(order[0])], ranked


def _near_maximum(problem: StrengthProblem, f_max: float) -> StaticResult:
    """Static optimisation just below the maximum (the boundary itself is degenerate)."""
    for shrink in (1e-6, 1e-4, 1e-2):
        try:
            return problem.solve(f_max * (1 - shrink))
        except StaticInfeasibleError:
            continue
    return problem.solve(f_max)


def strength(problem: StrengthProblem, sweep: bool = True, step: float = THESIS_STEP, limit: float = SWEEP_LIMIT) -> StrengthResult:
    """Direct maximum (and optionally the sweep) of one StrengthProblem."""
    start = time.perf_counter()
    f_max, sensitivity = problem.maximum()
    frame = _near_maximum(problem, f_max)
    limiting, ranked = _limiting(problem.coordinates, sensitivity)
    result = StrengthResult(problem.case.direction, f_max, problem.minimum(), limiting, ranked, frame.at_upper_bound,
                            frame.activations, problem.case, sweep_step=step)
    if sweep:
        result.sweep_force, result.sweep_first_failure, result.sweep_solves, _ = problem.sweep(step, limit)
    result.in_vivo = in_vivo_comparison(problem.case.direction, f_max)
    result.time = time.perf_counter() - start
    return result


def supported_directions(model) -> tuple[str, ...]:
    """The strength tests `model` can do: lateral bending needs lateral-bending coordinates."""
    return tuple(d for d in DIRECTIONS if d != "lateral" or any(c.endswith("_LB") for c in model.coordinates))


def isometric_strength(model=None, directions=None, *, q=None, level=("T6", "T7"), shoulder: str = "model",
                       sweep: bool = True, step: float = THESIS_STEP, sweep_limit: float = SWEEP_LIMIT,
                       locked=(), min_activation: float = 0.0, include_passive: bool = True,
                       **options) -> dict[str, StrengthResult]:
    """Maximal isometric extension, flexion and lateral-bending strength with the pelvis locked.

    `model` defaults to ``load_model("spine3d")`` (pelvis welded); ``pelvis_tx`` is locked where
    it exists (sagittal, rhythm). `directions` defaults to those the model supports. The maxima
    use a lower activation bound of 0 (the thesis' 0.01 floor forces every muscle, antagonists
    included, to work). `options` go to StaticOptimizer (p, strength_scale, deflection_tolerance,
    ...); the direct maximum does not depend on p, the sweep and the muscles at their upper bound
    do. Every result carries the maximum with the other passive-force choice under ``variants``
    (``without_passive`` or ``with_passive``), and the lateral result the acromion variant
    (shoulder moved to the cited half-breadth) when `shoulder` is "model".
    """
    from trunk_drake.model.trunk_model import load_model

    model = model if model is not None else load_model(dofs="spine3d")
    directions = supported_directions(model) if directions is None else directions
    locked = list(locked) + (["pelvis_tx"] if "pelvis_tx" in model.coordinates and "pelvis_tx" not in locked else [])
    optimizer = StaticOptimizer(model, locked=locked, min_activation=min_activation, include_passive=include_passive, **options)
    q = np.zeros(len(model.coordinates)) if q is None else model.check_q(q)
    balance = optimizer.balance(q)
    other = replace(balance, passive=np.zeros_like(balance.passive)) if include_passive else \
        StaticOptimizer(model, locked=locked, min_activation=min_activation, include_passive=True, **options).balance(q)
    optimizer.set_state(q, None, None)
    results = {}
    for direction in directions:
        case = load_case(model, direction, level=level, shoulder=shoulder, context=optimizer.context)
        results[direction] = strength(StrengthProblem(optimizer, case, q, balance), sweep, step, sweep_limit)
        flipped = StrengthProblem(optimizer, case, q, other)
        f_other, sens = flipped.maximum()
        results[direction].variants["without_passive" if include_passive else "with_passive"] = {
            "load": case.description, "max_force_N": f_other, "limiting_coordinate": _limiting(flipped.coordinates, sens)[0],
            "include_passive": not include_passive,
        }
        if direction == "lateral" and shoulder == "model":
            variant = StrengthProblem(optimizer, load_case(model, "lateral", shoulder="acromion", context=optimizer.context), q, balance)
            f_var, sens = variant.maximum()
            results[direction].variants["acromion"] = {
                "load": variant.case.description, "max_force_N": f_var,
                "limiting_coordinate": _limiting(variant.coordinates, sens)[0],
                "source": "models/reference_values.toml anthropometry.cityu_online.biacromial_breadth_british_men",
            }
    return results


DEFLECTION_TOLERANCE_DEG = 2.0  # the tolerated-deflection variant (issue 10): each level within 2 deg of upright
VARIANTS = {  # name: (configuration, StaticOptimizer options) of the in vivo comparison (README, reproduction Fig. 4.2)
    "rhythm": ("rhythm", {}),
    f"independent levels, {DEFLECTION_TOLERANCE_DEG:g} deg deflection": ("spine3d", {"deflection_tolerance": np.radians(DEFLECTION_TOLERANCE_DEG)}),
    "independent levels, exact": ("spine3d", {}),
    "independent levels, exact, activation floor 0.01 (thesis)": ("spine3d", {"min_activation": 0.01}),
}


def strength_variants(spec=None, directions=("extension", "flexion"), variants=VARIANTS) -> dict[str, dict[str, StrengthResult]]:
    """Direct maxima of every variant (with passive force; each result carries the without-passive maximum).

    `spec`: a ModelSpec (default MyoTorso). Returns {variant: {direction: StrengthResult}}.
    """
    from trunk_drake.model.trunk_model import load_model

    models = {dofs: load_model(dofs, spec=spec) for dofs in {d for d, _ in variants.values()}}
    return {name: isometric_strength(models[dofs], directions, sweep=False, **options) for name, (dofs, options) in variants.items()}


# ------------------------------------------------------------------------- in vivo

def _describe_source(key: str) -> str:
    src = load_toml("reference_values.toml")["sources"].get(key, {})
    return f"{src.get('authors', key)} ({src.get('year', 'year not read')})"


def in_vivo_comparison(direction: str, force: float) -> list[dict]:
    """Model force vs the reference values of models/reference_values.toml for `direction`.

    The thesis' own in vivo source comes first (Paalanne et al. 2009 for extension/flexion,
    Thomas et al. for lateral bending); other in vivo comparators and model predictions
    (Schmid et al. 2020, the thesis) follow. A value that could not be sourced is reported as
    "no reference": nothing is filled in.
    """
    strength_refs = load_toml("reference_values.toml")["strength"]
    rows = []
    in_vivo = strength_refs.get(direction, {})
    keys = sorted(in_vivo, key=lambda k: (k != PRIMARY_REFERENCE[direction], k))
    for key in keys:
        rows.append(_compare(f"strength.{direction}.{key}", in_vivo[key], force, "in vivo", key == PRIMARY_REFERENCE[direction]))
    for group in ("schmid2020", "thesis"):
        for key, entry in strength_refs.get(group, {}).items():
            if key.startswith(direction):
                rows.append(_compare(f"strength.{group}.{key}", entry, force, "model", False))
    return rows


def _compare(path: str, entry: dict, force: float, kind: str, primary: bool) -> dict:
    mean = entry.get("mean", entry.get("value"))
    sd = entry.get("sd", "no reference")
    row = {"reference": path, "kind": kind, "thesis_source": primary, "source": _describe_source(entry["source"]),
           "population": entry.get("population", "not stated"), "mean_N": mean, "sd_N": sd}
    if isinstance(mean, (int, float)):
        row["ratio_model_to_reference"] = force / mean
        row["within_one_sd"] = bool(abs(force - mean) <= sd) if isinstance(sd, (int, float)) else "no reference"
    else:
        row["ratio_model_to_reference"] = "no reference"
        row["within_one_sd"] = "no reference"
    return row


# ------------------------------------------------------------------------------ report

NOTES = (
    "Maximum = largest load for which static optimisation is feasible, solved directly as a linear program; "
    f"the sweep repeats the thesis' {THESIS_STEP:g} N search (the thesis stopped at {THESIS_RANGE[1]:g} N; ours continues until it fails).",
    "Load points are MyoTorso's own landmarks on its lumped upper body: T6/T7 vertebral-body centres and the left shoulder site.",
    "sensitivity_N_per_Nm: how much the maximum rises per Nm of extra moment available at a coordinate; "
    "the limiting coordinate has the largest magnitude.",
    "MyoTorso has no latissimus dorsi and no transversus abdominis (thesis: 9 muscle groups, here 7).",
)


def strength_report(results: dict, model, options: dict) -> dict:
    """JSON-ready report of `isometric_strength` results (a value may be an error message instead)."""
    return {
        "model": model.spec.name, "dofs": model.dofs, "configuration": describe_configuration(model, options),
        "posture": "upright (q = 0), pelvis locked",
        "options": options,
        "results": {d: r.summary() if isinstance(r, StrengthResult) else {"direction": d, "error": str(r)} for d, r in results.items()},
        "total_time_s": sum(r.time for r in results.values() if isinstance(r, StrengthResult)), "notes": list(NOTES),
    }


def describe_configuration(model, options: dict) -> str:
    """How the levels are held in a strength test, in words."""
    tolerance = options.get("deflection_tolerance", 0.0) or 0.0
    if model.coupling is not None:
        how = f"lumbar rhythm ({rhythm_spec(model.spec).source}): one coordinate, the levels balance together"
    elif tolerance > 0:
        how = f"independent levels, each may deflect up to {np.degrees(tolerance):g} deg on its bushing"
    else:
        how = "independent levels, each balanced exactly"
    passive = "with" if options.get("include_passive", True) else "without"
    return f"{how}; activations in [{options.get('min_activation', 0.0):g}, 1], {passive} passive muscle force"


def format_strength(report: dict) -> str:
    lines = [f"isometric strength, {report['model']} ({report['dofs']}), {report['posture']}", f"  {report['configuration']}"]
    for d, r in report["results"].items():
        if "error" in r:
            lines.append(f"{d:9s} failed: {r['error']}")
            continue
        sweep = r["sweep"]
        if not sweep["solves"]:
            swept = "sweep not run"
        elif sweep["last_feasible_N"] is None:
            swept = "sweep fails at 0 N"
        else:
            swept = f"sweep {sweep['last_feasible_N']:.0f} N ({sweep['solves']} solves)"
        lines.append(f"{d:9s} {r['max_force_N']:8.1f} N direct, {swept}; limited at {r['limiting_coordinate']}; "
                     f"{len(r['muscles_at_upper_bound'])} muscles at the upper bound")
        lines.append(f"          load: {r['load']}")
        if r["min_feasible_force_N"] > 1e-6:
            lines.append(f"          the unloaded posture is infeasible: loads below {r['min_feasible_force_N']:.1f} N fail too")
        for name, v in r.get("variants", {}).items():
            lines.append(f"          {name.replace('_', ' ')}: {v['max_force_N']:.1f} N, limited at {v['limiting_coordinate']}"
                         + (f" ({v['load']})" if name == "acromion" else ""))
        for row in r["in_vivo"]:
            ratio = row["ratio_model_to_reference"]
            value = (f"{row['mean_N']} N; model/ref {ratio:.2f}, within 1 SD: {row['within_one_sd']}"
                     if isinstance(ratio, float) else "no reference")
            tag = " (thesis' source)" if row["thesis_source"] else ""
            lines.append(f"          vs {row['reference']}{tag}: {value}")
    lines.append(f"total {report['total_time_s']:.2f} s")
    return "\n".join(lines)
