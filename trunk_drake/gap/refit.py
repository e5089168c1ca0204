"""Nonlinear refits: candidate models fitted and scored with full time-domain simulations
(training on the first halves, scoring on the held-out second halves)."""

from __future__ import annotations

import dataclasses
import pickle
import threading

import numpy as np

from trunk_drake.diagram import VARIANT_FIELDS, CopiesUnsupported, TrunkOptions, copies_unsupported
from trunk_drake.gap.checkpoint import SimulationLog
from trunk_drake.gap.linear import OPERATING_POINT_LOGS, OperatingPoint
from trunk_drake.gap.measures import segment_chi2
from trunk_drake.gap.space import Fit, SearchSpace
from trunk_drake.gap.trials import half
from trunk_drake.optim.least_squares import finite_difference_jacobian, levenberg_marquardt
from trunk_drake.parallel import WorkerPool
from trunk_drake.optim.fit import point_jobs
from trunk_drake.simulation import SimulationError, differentiable_settings, replay_key, simulate, simulate_copies

DIVERGED = 1e12  # chi-square of a simulation that diverged


def simulate_outputs(model, options: TrunkOptions, trial, outputs, steps=None,
                     until: float | None = None) -> tuple[np.ndarray, OperatingPoint | None, np.ndarray]:
    """The outputs of one trial's simulation in its steady window (means removed), the operating point
    there and the run's step times; on the step sequence `steps` of an earlier run if given. With `until`
    (s) and `steps`, the run stops one replayed step after the first at or after `until` (a refit's training
    half needs no more): the outputs up to `until` are those of the whole run on the same steps (the
    resampling's end slopes reach only into the last step), and there is no operating point."""
    steps, duration = _truncated(trial, steps, until)
    result = simulate(model, duration=duration, perturbation=trial.signal, options=options, log_rate=trial.fs,
                      log=OPERATING_POINT_LOGS, **differentiable_settings(model, options, steps))  # the refits difference these
    return _trial_outputs(result, trial, outputs, duration)


def _truncated(trial, steps, until):
    """(steps, duration) of a run that stops one replayed step after `until` (None: the whole trial)."""
    if until is not None and steps is not None and until < trial.duration:
        steps = steps[: int(np.searchsorted(steps, until)) + 2]
        return steps, float(steps[-1])
    return steps, trial.duration


def _trial_outputs(result, trial, outputs, duration):
    columns = [result.lumbar_rotation if o == "lumbar_rotation" else result.coordinate(o) for o in outputs]
    y = np.column_stack(columns)[trial.steady]
    point = OperatingPoint.of(result, trial.steady) if duration == trial.duration else None
    return y - y.mean(axis=0), point, result.step_times


def simulate_outputs_many(model, options: list[TrunkOptions], trial, outputs, steps, until=None) -> list:
    """`simulate_outputs` (or its SimulationError) for each of `options`, which differ in `VARIANT_FIELDS` only, on
    the replayed step sequence `steps`: as copies of the model in one simulation (`simulate_copies`) where the
    diagram allows, else (or when a copy fails) one by one."""
    run_steps, duration = _truncated(trial, steps, until)
    try:
        results = simulate_copies(model, [{f: getattr(o, f) for f in VARIANT_FIELDS} for o in options], run_steps,
                                  duration=duration, perturbation=trial.signal, options=options[0], log_rate=trial.fs,
                                  log=OPERATING_POINT_LOGS)
    except (CopiesUnsupported, SimulationError):
        return [simulation_job(model, (o, trial, outputs, steps, until)) for o in options]
    return [_trial_outputs(result, trial, outputs, duration) for result in results]


def train_end(trial) -> float:
    """Time (s) of the sample after the training half of `trial`'s steady window: a run to it covers the half."""
    return (trial.steady.start + half(trial, "train").stop) / trial.fs


def simulation_job(model, job):
    """Worker job (options, trial, outputs, steps or None, until or None): `simulate_outputs`, or the
    SimulationError of a diverging run; with a list of options (gains apart, the same), a list of those
    (`simulate_outputs_many`)."""
    options, trial, outputs, steps, until = job
    if isinstance(options, list):
        return simulate_outputs_many(model, options, trial, outputs, steps, until)
    try:
        return simulate_outputs(model, options, trial, outputs, steps, until)
    except SimulationError as err:
        return err


def _diagram(options: TrunkOptions) -> tuple:
    """What `options` set beyond `VARIANT_FIELDS`, and whether the reflex is delayed: options alike in it build
    copies of one diagram (`diagram.build_trunk_diagram`'s `variants`; all delayed or none)."""
    return pickle.dumps(dataclasses.replace(options, **{f: None for f in VARIANT_FIELDS})), options.reflex_delay > 0


class TimeDomainFitter:
    """Refit and score models with full nonlinear simulations (first halves train, second test) on
    the worker pool `simulator`: secant Levenberg-Marquardt over the `free` coordinates of x (others
    held). A fit simulates every point on the step sequences of its start's own run
    (`differentiable_settings`), so its finite differences are smooth."""

    def __init__(self, simulator: WorkerPool, space: SearchSpace, trials, noise, outputs, counter: dict | None = None,
                 log: SimulationLog | None = None):
        self.simulator, self.space, self.trials, self.noise, self.outputs = simulator, space, trials, noise, outputs
        self.counter = counter if counter is not None else {"simulations": 0}  # shared with whoever reports progress
        self.counter.setdefault("replayed", 0)  # of them, taken from `log` (an earlier, interrupted run's)
        self.log = log  # where the simulations are written as they finish, and read from when resuming
        self.cache: dict = {}  # `key` (the model simulated, the run replayed or None) -> (outputs, steps)
        self._counting = threading.Lock()  # fits may run concurrently (`WorkerPool.concurrently`)

    @property
    def simulations(self) -> int:
        return self.counter["simulations"]

    def concurrently(self, calls) -> list:
        """The results of independent fits (zero-argument calls of this fitter), run at once on its pool."""
        return self.simulator.concurrently(calls)

    def key(self, x, effects, on=None, space: SearchSpace | None = None, train_only: bool = False) -> tuple:
        """The cache key of x simulated on the step sequences of the run keyed `on` (`replay_key`), over the
        training halves only if `train_only`."""
        space = space or self.space  # keyed by the model simulated: its gains (rounded far below any fit's step) and effects,
        #   so a point of a wider space with its further coordinates at 0 is the narrower point's run, not a new one
        x = np.asarray(x, float)
        gains = np.round(space.log_gains(x[:space.rank]), 12) + 0.0  # + 0.0: no -0.0
        key = replay_key((tuple(e.name for e in effects), gains.tobytes(), x[space.rank:].tobytes()), on)
        return (*key, "train") if train_only else key

    def outputs_of(self, points, effects, on=None, space: SearchSpace | None = None, train_only: bool = False) -> list:
        """Each point's simulated outputs (None where a simulation diverged), simulated once and cached;
        `effects`: one tuple of effects for every point, or a list of one tuple per point; `on`: the
        key of a run whose step sequences the simulations replay (None: each its own); `space`: the
        points' space if not the fitter's; `train_only`: each trial simulated to the end of its training
        half only (the outputs hold no held-out half: for the refits' own steps). Simulations in the fitter's `log`
        are taken from it (and counted as run); those run are added to it."""
        space = space or self.space
        each = effects if isinstance(effects, list) else [effects] * len(points)
        keys = [self.key(p, fx, on, space, train_only) for p, fx in zip(points, each)]
        todo = {k: (p, fx) for k, p, fx in zip(keys, points, each) if k not in self.cache}
        if self.log is not None and todo:
            logged = self.log.take(todo)
            with self._counting:
                self.cache.update(logged)
                self.counter["simulations"] += len(logged) * len(self.trials)
                self.counter["replayed"] += len(logged) * len(self.trials)
            todo = {k: v for k, v in todo.items() if k not in logged}
        steps = self.cache[on][1] if on is not None else [None] * len(self.trials)
        options = [space.options_for(p, fx) for p, fx in todo.values()]
        plan = self._plan(options, steps)
        jobs = [([options[i] for i in group] if len(group) > 1 else options[group[0]],
                 self.trials[k], self.outputs, steps[k], train_end(self.trials[k]) if train_only else None)  # stops on replays
                for group, k in plan]
        sims = [[None] * len(self.trials) for _ in options]
        for (group, k), result in zip(plan, self.simulator.map(simulation_job, jobs)):
            for i, one in zip(group, result if len(group) > 1 else [result]):
                sims[i][k] = one
        with self._counting:
            self.counter["simulations"] += len(options) * len(self.trials)
        for k, chunk in zip(todo, sims):
            diverged = any(isinstance(c, Exception) for c in chunk)
            self.cache[k] = (None, None) if diverged else ([c[0] for c in chunk], [c[2] for c in chunk])
        if self.log is not None and todo:
            self.log.add({k: self.cache[k] for k in todo})
        return [self.cache[k][0] for k in keys]

    def outputs_near(self, x, effects, points, each) -> tuple[list, list]:
        """`outputs_of` the `points` (with `each`'s effects) near the model (x, `effects`): where a point's diagram is that
        model's up to `VARIANT_FIELDS` (and its reflex delay no shorter: the steps follow the shortest delay), on the
        step sequences of the model's own run, as copies of the model; every other point on its own steps. Also the
        key of the run each point replayed (None: its own steps), for a refit from it (`fit`'s `on`)."""
        base = self.space.options_for(x, effects)
        own = self.key(x, effects)
        near = self.outputs_of([x], effects)[0] is not None
        options = [self.space.options_for(p, fx) for p, fx in zip(points, each)]
        same = _diagram(base)
        replay = [near and _diagram(o) == same and o.reflex_delay >= base.reflex_delay for o in options]
        out = [None] * len(points)
        for flag in (True, False):
            chosen = [i for i, r in enumerate(replay) if r == flag]
            if chosen:
                found = self.outputs_of([points[i] for i in chosen], [each[i] for i in chosen], own if flag else None)
                for i, o in zip(chosen, found):
                    out[i] = o
        return out, [own if r else None for r in replay]

    def _plan(self, options: list[TrunkOptions], steps) -> list[tuple[list[int], int]]:
        """Worker jobs for the points simulated with `options` x trials: (indices of points, trial). On replayed
        steps the points whose options differ only in `VARIANT_FIELDS` (gains, and effects that only set those
        fields: a Jacobian's columns) run as groups (`point_jobs`) where the diagram can hold copies of the model
        (`copies_unsupported`), every other point alone."""
        workers = self.simulator.capacity
        alike: dict = {}
        for i, o in enumerate(options):
            alike.setdefault(_diagram(o), []).append(i)
        return [([members[j] for j in group], k) for members in alike.values()
                for group, k in point_jobs(members, len(self.trials), steps, workers,
                                           not copies_unsupported(self.simulator.model, options[members[0]]))]

    def seed(self, x, effects, outputs, steps) -> None:
        """Register an existing simulation (e.g. the nominal one) for parameter vector x: outputs and step times per trial."""
        self.cache[self.key(x, effects)] = (outputs, steps)

    def chi2(self, outputs, which: str) -> float:
        if outputs is None:
            return DIVERGED
        return sum(segment_chi2(t.steady_outputs, o, self.noise, half(t, which)) for t, o in zip(self.trials, outputs))

    def residual(self, outputs) -> np.ndarray:
        if outputs is None:
            return np.full(sum(t.steady_outputs[half(t, "train")].size for t in self.trials), np.sqrt(DIVERGED / 1e3))
        parts = []
        for t, o in zip(self.trials, outputs):
            part = half(t, "train")
            r = t.steady_outputs[part] - o[part]
            parts.append(((r - r.mean(axis=0)) / self.noise).ravel())
        return np.concatenate(parts)

    def fit(self, effects, x0, free, max_iterations: int = 2, space: SearchSpace | None = None, on=None) -> Fit:
        """`effects` fitted from x0 on the coordinates `free` of x (in `space`, default the fitter's), every point on the
        step sequences of x0's own run, or of the run keyed `on` where x0 was simulated on them (`outputs_near`)."""
        space = space or self.space
        lo, hi, _ = space.bounds(effects)
        x_full = np.clip(np.asarray(x0, float), lo, hi)
        free = np.asarray(free, int)

        def expand(z):
            x = x_full.copy()
            x[free] = z
            return x

        if on is None or self.outputs_of([x_full], effects, on, space)[0] is None:
            own = self.key(x_full, effects, space=space)
            self.outputs_of([x_full], effects, space=space)
            on = own if self.cache[own][0] is not None else None  # a diverging start: each point on its own steps

        def fun(z):  # the training halves only: the simulations stop there (the fitted point is run whole below)
            return self.residual(self.outputs_of([expand(z)], effects, on, space, train_only=True)[0])

        def jac(z):
            return finite_difference_jacobian(
                lambda points: [self.residual(o) for o in self.outputs_of([expand(p) for p in points], effects, on, space,
                                                                          train_only=True)],
                z, 0.02 * (hi[free] - lo[free]), upper=hi[free], r0=fun(z))

        z = x_full[free]
        if z.size:
            z, *_ = levenberg_marquardt(fun, jac, z, lo[free], hi[free], max_iterations=max_iterations, tolerance=1e-3,
                                        refresh_every=max_iterations + 1, scale=hi[free] - lo[free])
        x = expand(z)
        outputs = self.outputs_of([x], effects, on, space)[0]
        return Fit(tuple(e.name for e in effects), x, self.chi2(outputs, "train"), self.chi2(outputs, "test"),
                   {e.name: v for e, v in zip(effects, space.values(x, effects))}, outputs)
