"""Reflex-gain fitting (seed sections 3.2.2 and 4.8): kp and kv per muscle group by
Levenberg-Marquardt nonlinear least squares on time-domain simulations.

The parameters are log10 of the gains, bounded to GAIN_BOUNDS (`trunk_drake.optim.gains`; wider than
the thesis' [0.001, 1] of seed 4.8), fitted by the bounded
secant Levenberg-Marquardt method of `trunk_drake.optim.least_squares`. The Jacobian comes
from forward differences (one simulation per gain, in parallel worker processes, each with
its own model: Drake objects are not picklable) and is kept current between recomputations
by Broyden updates, so an iteration usually costs one simulation per trial. Residuals are model minus measured kinematics divided by the measurement noise, with a
constant offset per output fitted in closed form (the thesis removed offsets; removing the
first, noisy sample instead would bias the fit), so the cost is a chi-square and the
Jacobian gives the gains' covariance. Two
scenarios: trunk settling (no perturbation, target zero rotation) and car-passenger
interaction (measured trials).
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from trunk_drake.diagram import CopiesUnsupported, TrunkOptions, copies_unsupported
from trunk_drake.io.prepared import PreparedTrial, prepare_trials
from trunk_drake.metadata import json_default
from trunk_drake.optim.gains import GAIN_BOUNDS, GainLayout
from trunk_drake.optim.least_squares import finite_difference_jacobian, inverse_or_inf, levenberg_marquardt
from trunk_drake.parallel import WorkerPool
from trunk_drake.signals import DEFAULT_FADE_S, DEFAULT_PERIOD_S, estimate_frf, vaf
from trunk_drake.simulation import SimulationError, differentiable_settings, replay_key, simulate, simulate_copies

# Stop when an accepted step lowers the cost by less than this fraction. The cost is a chi-square/2, about half the
# number of samples at the noise floor (14406 for the two reference trials), and one SD of a gain moves it by 0.5:
# 1e-3 (14 units) stopped the reference fit at 14515 where the truth costs 14483; 1e-5 goes on while steps gain 0.15.
FIT_TOLERANCE = 1e-5
MAX_ITERATIONS = 40  # per start: the 14-gain fit of the reference data stops by FIT_TOLERANCE after 36 (at 20 it was
#   still 15 above the truth's cost: the weakly determined directions converge slowly)
JACOBIAN_REFRESH = 8  # iterations between finite-difference Jacobians (Broyden updates in between). The 14-gain fit of
#   the reference data (benchmarks/fit.py, 2026-12-03): every 4: 350 simulations, cost 14475.52; every 8: 250, 14475.57, the
#   same gains within 1 SD; every 16: 196, 14476.99 (40 iterations, not converged); only after rejections: 128, 14477.44
THESIS_START = {"car": 0.1, "settling": 0.001}  # seed Tables 4.2-4.3: initial values (mostly)


def targets_from_trials(trials, outputs=("lumbar_rotation",), noise: float | dict = np.radians(0.1),
                        lowpass_hz: float | None = None, period: float = DEFAULT_PERIOD_S, steady_start: float = DEFAULT_FADE_S,
                        t_max: float | None = None) -> list[PreparedTrial]:
    """Fit targets from measured trials (see trunk_drake.io.prepared.prepare_trials); `noise`
    (rad, scalar or per output) weights the residuals."""
    return prepare_trials(trials, outputs, noise, period, steady_start, lowpass_hz, t_max)


def settling_target(duration: float = 5.0, fs: float = 50.0, noise: float = np.radians(0.1)) -> PreparedTrial:
    """Trunk settling (seed 4.8.1): no perturbation, the target is zero lumbar rotation."""
    t = np.arange(int(round(duration * fs)) + 1) / fs
    return PreparedTrial("settling", t, fs, {"lumbar_rotation": np.zeros_like(t)}, {"lumbar_rotation": noise})


class Objective:
    """Weighted residuals of all targets for one gain vector (runs the simulations)."""

    def __init__(self, model, targets: list[PreparedTrial], layout: GainLayout, options: TrunkOptions, accuracy: float | None = None):
        self.model, self.targets, self.layout, self.options, self.accuracy = model, targets, layout, options, accuracy

    def simulate(self, x, target: PreparedTrial, steps=None):
        """One target's simulation at x; on the step sequence `steps` of an earlier run if given (finite
        differences need smooth simulations: `differentiable_settings`)."""
        settings = differentiable_settings(self.model, self.options, steps)
        if self.accuracy is not None and "steps" not in settings:
            settings["accuracy"] = self.accuracy
        return simulate(self.model, duration=float(target.time[-1]), perturbation=target.signal, options=self.options,
                        log_rate=target.fs, log=("normalized_fiber_length",), **settings, **self.layout.gains(x))

    def outputs(self, result, target: PreparedTrial) -> dict[str, np.ndarray]:
        out = {}
        for name in target.outputs:
            series = result.lumbar_rotation if name == "lumbar_rotation" else result.coordinate(name)
            series = np.interp(target.time, result.time, series)
            out[name] = series - series[0]
        return out

    def __call__(self, x, steps=None) -> tuple[np.ndarray, np.ndarray, list]:
        """Residuals, per kp parameter whether its length reflex ever engaged, and per target the
        run's step times (None where it diverged); on the step sequences `steps` (per target) if given.

        A group whose fibers never exceed the set point l_d has (l_n - l_d)+ = 0 throughout:
        its kp has no effect near x, so its Jacobian column is exactly zero.
        """
        return combine([self.of_target(x, k, on) for k, on in enumerate(steps or [None] * len(self.targets))])

    def of_target(self, x, k: int, steps=None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """Target k's part of `__call__`: its residuals, the engaged kp parameters and its step times."""
        try:
            result = self.simulate(x, self.targets[k], steps)
        except SimulationError:  # an unstable gain set: a large, finite residual keeps the search going
            result = None
        return self._part(result, self.targets[k])

    def of_target_many(self, points, k: int, steps) -> list[tuple]:
        """`of_target` of each of `points` on the step sequence `steps`: as copies of the model in one simulation
        (`simulate_copies`, the same results to round-off) where the diagram allows, else (or when a copy fails)
        one by one."""
        target = self.targets[k]
        try:
            results = simulate_copies(self.model, [self.layout.gains(x) for x in points], steps, duration=float(target.time[-1]),
                                         perturbation=target.signal, options=self.options, log_rate=target.fs,
                                         log=("normalized_fiber_length",))
        except (CopiesUnsupported, SimulationError):
            return [self.of_target(x, k, steps) for x in points]
        return [self._part(result, target) for result in results]

    def _part(self, result, target: PreparedTrial) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """A target's residuals, engaged kp parameters and step times from its simulation (None: it diverged)."""
        engaged = np.zeros(len(self.layout.groups), dtype=bool)
        if result is None:
            model_out = {n: np.full_like(target.time, np.radians(90.0)) for n in target.outputs}
            engaged[:] = True
            step_times = None
        else:
            step_times = result.step_times
            model_out = self.outputs(result, target)
            stretch = result.normalized_fiber_length.max(axis=0) - self.options.per_muscle(self.model, self.options.l_desired) \
                if not isinstance(self.options.l_desired, str) else np.ones(self.model.n_muscles)
            engaged = np.array([np.any(stretch[m] > 0) for m in self.layout.members(self.model)])
        parts = []
        for name, measured in target.outputs.items():
            difference = model_out[name] - measured
            parts.append((difference - difference.mean()) / target.noise[name])  # offset fitted in closed form
        return np.concatenate(parts), engaged, step_times


def combine(per_target: list[tuple]) -> tuple[np.ndarray, np.ndarray, list]:
    """`Objective.__call__` from the `of_target` parts of every target, in target order."""
    return (np.concatenate([r for r, _, _ in per_target]), np.logical_or.reduce([e for _, e, _ in per_target]),
            [s for _, _, s in per_target])


def _evaluate(model, job):
    """Worker job: one target's part of the objective (targets, layout, options, accuracy) at x, on its step
    sequence `steps` if given (a point's targets run as separate jobs, so both workers share even one point);
    with several points (a list), each one's, on `steps` (`Objective.of_target_many`)."""
    x, problem, k, steps = job
    if isinstance(x, list):
        return Objective(model, *problem).of_target_many(x, k, steps)
    return Objective(model, *problem).of_target(x, k, steps)


def point_jobs(points: list, n_targets: int, steps: list, workers: int, copies: bool = True) -> list[tuple[list[int], int]]:
    """How `evaluate_many` splits points x targets into worker jobs: (indices of points, target). Each point alone
    on its own step sequence (`steps` None) or where the diagram cannot hold copies (`copies` False,
    `diagram.copies_unsupported`); on a replayed one, every target's points in as few groups as keep the workers
    busy (`Objective.of_target_many` runs a group as one simulation)."""
    if steps[0] is None or len(points) <= 1 or not copies:
        return [([i], k) for i in range(len(points)) for k in range(n_targets)]
    groups = np.array_split(np.arange(len(points)), min(len(points), max(1, -(-workers // n_targets))))
    return [(list(g), k) for g in groups for k in range(n_targets)]


@dataclass
class FitStart:
    """One start of the multi-start search."""

    x0: np.ndarray
    x: np.ndarray
    cost: float
    iterations: int
    simulations: int
    status: str


@dataclass
class FitResult:
    """Fitted reflex gains with uncertainty, goodness of fit and convergence history."""

    gains: dict[str, dict[str, float]]  # {"kp": {group: value}, "kv": {...}}
    std: dict[str, dict[str, float]]  # one standard deviation, same layout
    parameter_names: list[str]
    covariance_log10: np.ndarray  # covariance of log10(gains)
    cost: float  # 0.5 * sum of squared weighted residuals
    vaf: dict[str, dict[str, float]]  # per target and output
    frf: dict[str, dict]  # per target: {"frequencies", "data", "model"} (complex gains, rad/m)
    series: dict[str, dict]  # per target: {"time", "data", "model"} lumbar rotation (rad), offsets aligned
    history: list[dict]  # every evaluated point: start, cost, gains
    starts: list[FitStart]
    n_simulations: int
    wall_time_s: float
    options: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        frf = {name: {"frequencies_hz": f["frequencies"].tolist(),
                      "data_gain": np.abs(f["data"]).tolist(), "data_phase_deg": np.degrees(np.angle(f["data"])).tolist(),
                      "model_gain": np.abs(f["model"]).tolist(), "model_phase_deg": np.degrees(np.angle(f["model"])).tolist()}
               for name, f in self.frf.items()}
        return {"gains": self.gains, "std": self.std, "cost": self.cost, "vaf": self.vaf, "frf": frf,
                "n_simulations": self.n_simulations, "wall_time_s": self.wall_time_s,
                "starts": [{"start": 10.0 ** s.x0, "end": 10.0 ** s.x, "cost": s.cost, "iterations": s.iterations,
                            "simulations": s.simulations, "status": s.status} for s in self.starts],
                "history": self.history, "options": self.options}


def start_points(layout: GainLayout, scenario: str, n_starts: int, seed: int = 0, start=None) -> list[np.ndarray]:
    """The first start is `start` (gains dict) or the thesis' initial value; then 0.05 for all
    gains; then log-uniform random points in the bounds."""
    n = len(layout.names)
    first = layout.vector(start) if start is not None else np.full(n, np.log10(THESIS_START[scenario]))
    points = [first, np.full(n, np.log10(0.05))]
    rng = np.random.default_rng(seed)
    lo, hi = np.log10(GAIN_BOUNDS)
    while len(points) < n_starts:
        points.append(rng.uniform(lo + 0.5, hi - 0.3, n))
    return points[:n_starts]


def fit_reflex_gains(model, targets: list[PreparedTrial], *, groups=None, fixed_gains: dict | None = None, scenario: str = "car",
                     options: TrunkOptions | None = None,
                     start=None, n_starts: int = 1, workers: int = 2, cluster: str | None = None, max_iterations: int = MAX_ITERATIONS, fd_step: float = 0.05,
                     tolerance: float = FIT_TOLERANCE, accuracy: float | None = None, seed: int = 0, progress: bool = True) -> FitResult:
    """Fit kp and kv of each muscle group to `targets` (see targets_from_trials / settling_target).

    `options` fixes everything else of the diagram (co-activation, bushings, pelvis mode);
    groups not in `groups` keep `fixed_gains` ({"kp": {group: value}, "kv": {...}}, else 0).
    Bounded secant Levenberg-Marquardt (see the module docstring) with a parallel
    forward-difference Jacobian (`fd_step` in log10 units; on `workers` local processes, or on the Dask cluster at
    `cluster`, split into as many jobs as it runs at once); `n_starts` starts (multi-start),
    the best kept. Each start stops when an accepted step lowers the cost by less than
    `tolerance` (relative) or after `max_iterations`. `accuracy`: the simulations' (None: the
    default integrator's, see `simulate`).
    """
    if scenario not in THESIS_START:
        raise ValueError(f"scenario={scenario!r}; expected one of {sorted(THESIS_START)}")
    if not targets:
        raise ValueError("no fit targets: give measured trials (car) or settling_target()")
    layout = GainLayout.for_groups(tuple(groups or model.groups), fixed_gains)
    unknown = set(layout.groups) - set(model.groups)
    if unknown:
        raise ValueError(f"unknown muscle groups {sorted(unknown)}; groups: {sorted(model.groups)}")
    options = options or TrunkOptions()
    lo, hi = np.log10(GAIN_BOUNDS)
    history: list[dict] = []
    wall = _time.perf_counter()
    cache: dict[tuple, tuple] = {}  # (x, x of the run whose steps are replayed or None) -> (residuals, engaged, steps)
    counter = {"simulations": 0}

    problem = (targets, layout, options, accuracy)
    pool = WorkerPool(model, workers, cluster)
    copies = not copies_unsupported(model, options)  # a Jacobian's points as copies of the model in one simulation

    def evaluate_many(points, what="cost", on=None):
        """Each point's (residuals, engaged, step times), simulated once; `on`: the cache key of a run whose
        step sequences are replayed (None: each point on its own)."""
        keys = [replay_key((p.tobytes(),), on) for p in points]
        todo = [(p, k) for p, k in zip(points, keys) if k not in cache]
        steps = cache[on][2] if on is not None else [None] * len(targets)
        plan = point_jobs([p for p, _ in todo], len(targets), steps, pool.capacity, copies)
        jobs = [([todo[i][0] for i in group] if len(group) > 1 else todo[group[0]][0], problem, k, steps[k]) for group, k in plan]
        parts = [[None] * len(targets) for _ in todo]
        with tqdm(total=len(todo) * len(targets), desc=f"  start {current['start'] + 1}/{n_starts}: {what}", unit="sim",
                  leave=False, disable=not progress or not todo) as bar:
            for j, part, error in pool.completed(_evaluate, jobs):
                if error is not None:
                    raise error
                group, k = plan[j]
                for i, one in zip(group, part if len(group) > 1 else [part]):
                    parts[i][k] = one
                bar.update(len(group))
        for n, (p, k) in enumerate(todo):
            result = combine(parts[n])
            cache[k] = result
            counter["simulations"] += len(targets)
            history.append({"start": current["start"], "cost": float(0.5 * result[0] @ result[0]), "gains": layout.gains(p)})
        return [cache[k] for k in keys]

    def fun(x):
        return evaluate_many([np.asarray(x, float)])[0][0]

    def jac(x):
        """Forward differences around x, every point on the step sequences of x's own run."""
        x = np.asarray(x, float)
        r0, engaged, steps = evaluate_many([x])[0]
        on = replay_key((x.tobytes(),), None) if all(s is not None for s in steps) else None
        active = np.concatenate([engaged, np.ones(len(layout.groups), dtype=bool)])  # kp columns, then kv
        return finite_difference_jacobian(lambda points: [r for r, _, _ in evaluate_many(points, "Jacobian", on)], x, fd_step,
                                          upper=hi, columns=np.flatnonzero(active), r0=r0)

    current = {"start": 0}
    starts = []
    if progress:
        print(f"fitting {len(layout.names)} gains to {len(targets)} target(s) ({sum(t.time.size for t in targets)} samples) "
              f"on {f'the cluster at {cluster}' if cluster else f'{max(1, workers)} worker(s)'}; {n_starts} start(s), at most {max_iterations} iterations each", flush=True)
    with pool:
        for k, x0 in enumerate(start_points(layout, scenario, n_starts, seed, start)):
            current["start"] = k
            before = counter["simulations"]
            x, _, r, iterations, status = levenberg_marquardt(fun, jac, np.clip(x0, lo, hi), lo, hi, max_iterations, tolerance,
                                                              JACOBIAN_REFRESH, progress=progress, label=f"start {k + 1}/{n_starts}")
            starts.append(FitStart(np.asarray(x0), x, float(0.5 * r @ r), iterations, counter["simulations"] - before, status))
        best = min(starts, key=lambda s: s.cost)
        J = jac(best.x)  # a fresh finite-difference Jacobian for the covariance
        r = fun(best.x)

    dof = max(1, r.size - best.x.size)
    cov = float(r @ r) / dof * inverse_or_inf(J.T @ J)
    gains = layout.gains(best.x)  # the fixed groups too: a gains.toml written from it must not zero them
    std_x = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    std_free = dict(zip(layout.names, ((10.0 ** best.x) * np.log(10.0) * std_x).tolist()))
    std = {k: {g: std_free.get(f"{k}.{g}", 0.0) for g in gains[k]} for k in gains}  # fixed gains: 0
    vafs, frfs, series = goodness_of_fit(targets, r)
    return FitResult(gains, std, layout.names, cov, float(0.5 * r @ r), vafs, frfs, series, history, starts,
                     counter["simulations"], _time.perf_counter() - wall,
                     options={"scenario": scenario, "groups": list(layout.groups), "n_starts": n_starts,
                              "fd_step": fd_step, "accuracy": accuracy, "noise": {t.name: t.noise for t in targets}})


def goodness_of_fit(targets: list[PreparedTrial], residuals: np.ndarray):
    """VAF per target/output, the FRF (lumbar rotation / platform) and the time series, from the weighted
    `residuals` of `Objective` at the fitted point (no simulation: with each output's offset fitted in closed
    form, the model's series aligned to the data is the data plus residual times noise)."""
    samples = sum(o.size for t in targets for o in t.outputs.values())
    if residuals.size != samples:
        raise ValueError(f"{residuals.size} residuals for {samples} samples of the targets")
    vafs, frfs, series, k = {}, {}, {}, 0
    for target in targets:
        aligned = {}
        for n, measured in target.outputs.items():
            aligned[n] = measured + residuals[k:k + measured.size] * target.noise[n]
            k += measured.size
        vafs[target.name] = {n: _vaf_or_none(target.outputs[n], aligned[n]) for n in target.outputs}
        name = "lumbar_rotation" if "lumbar_rotation" in target.outputs else next(iter(target.outputs))
        series[target.name] = {"time": target.time, "data": target.outputs[name], "model": aligned[name], "output": name}
        if target.whole_periods >= 1 and name == "lumbar_rotation":
            frfs[target.name] = frf_pair(target, target.outputs[name], aligned[name])
    return vafs, frfs, series


def _vaf_or_none(measured, modelled):
    """VAF about the mean; None for a constant target (e.g. settling: zero rotation)."""
    centred = measured - measured.mean()
    if not np.any(centred):
        return None
    return float(vaf(centred, modelled - measured.mean()))


def frf_pair(target: PreparedTrial, measured, modelled) -> dict:
    """FRF of platform displacement to rotation (rad/m) for data and model over whole periods."""
    if target.whole_periods < 1:
        raise ValueError(f"{target.name}: fewer than one whole {target.period} s period after {target.steady_start} s")
    window, fs = target.steady, target.fs
    u = target.platform[window]
    data = estimate_frf(u, measured[window], fs, target.period)
    model = estimate_frf(u, modelled[window], fs, target.period)
    return {"frequencies": data.frequencies, "data": data.H, "model": model.H,
            "data_lower": data.gain_lower, "data_upper": data.gain_upper, "coherence": data.coherence}


def write_fit(result: FitResult, out_dir) -> dict:
    """fit.json, gains.toml (usable as ``trunk-drake simulate --reflex-gains``) and PNG figures."""
    import json
    from pathlib import Path

    from trunk_drake.plots import plot_fit

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {"json": out / "fit.json", "gains": out / "gains.toml"}
    files["json"].write_text(json.dumps(result.to_dict(), indent=2, default=json_default))
    fitted = set(result.parameter_names)

    def line(kind, group, value):
        note = f"+- {result.std[kind][group]:.3g}" if f"{kind}.{group}" in fitted else "fixed, not fitted"
        return f"{group} = {value:.6g}  # {note}"

    lines = ["# Reflex gains fitted by trunk-drake (1 SD in comments).", "", "[kp]"]
    lines += [line("kp", g, v) for g, v in result.gains["kp"].items()]
    lines += ["", "[kv]"] + [line("kv", g, v) for g, v in result.gains["kv"].items()]
    files["gains"].write_text("\n".join(lines) + "\n")
    files.update(plot_fit(result, out))
    return files
