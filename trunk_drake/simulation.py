"""Forward simulation of the seated trunk under pelvis perturbation: `simulate` and its result."""

from __future__ import annotations

import dataclasses
import json
import time as _time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import EventStatus

from trunk_drake.diagram import MUSCLE_LOGS, SLIDING_PELVIS, TrunkDiagram, TrunkOptions, build_trunk_diagram, release
from trunk_drake.metadata import run_metadata
from trunk_drake.parallel import caused_by_interrupt

STIFF_INTEGRATOR = "radau3"  # L-stable: independent vertebrae's damping modes reach ~4000 1/s; compliant tendons
DEFAULT_ACCURACY = 1e-2  # radau3's target accuracy
MAX_STEP = 0.0125  # s, radau3's; longer steps make Newton fail at the reflexes' kinks (measured: 14 ms ok, 20 ms not)
NONSTIFF_INTEGRATOR = "runge_kutta3"  # the rhythm with rigid tendons: no vertebra of its own, its fastest modes are
#   activation dynamics (~-64 1/s); error-controlled explicit steps need no Newton iterations at the kinks
NONSTIFF_ACCURACY = 1e-3
NONSTIFF_MAX_STEP = 0.025  # s; 20 s main job: 2649 evaluations and 0.0014 deg RMS from the 1e-6 reference
#   (radau3 at its settings: 16,305 and 0.0026 deg; benchmarks/simulate.py)
SEQUENCE_ACCURACY = 1e-4  # runge_kutta3's accuracy for the step sequences the fits replay. Reflex-gain finite-difference
#   columns on it against those on a 1e-6 sequence (benchmarks/differentiable_steps.py): within 2 %, except psoas at
#   11 % at 1 Hz (a column near zero: psoas barely moves the rhythm); at 3e-4 and 1e-3 up to 100 % and 1000 % off.
#   Per 24 s trial: 1343 steps at 1 Hz, 3210 at 3 Hz; runge_kutta2 at 5 ms (within 1 %) takes 2.7x and 1.4x the time
MIN_DELAY_STEP = 1e-3  # s: a shorter delay does not shorten the steps further (held within one step, it lags < 1 ms)
DEFAULT_LOG_RATE = 100.0  # Hz, uniform output grid (step-wise logs are resampled onto it)
FIXED_STEP_INTEGRATORS = ("explicit_euler", "semi_explicit_euler", "runge_kutta2")
DIVERGENCE_ANGLE = 1.6  # rad; a lumbar joint beyond this has left any physiological range
DIVERGENCE_SPEED = 50.0  # rad/s
UPRIGHT_DEG = 10.0


class SimulationError(RuntimeError):
    """A simulation that diverged or failed; the message names time, coordinates and muscles."""


@dataclass
class SimulationResult:
    """Time histories of one simulation (SI units, rows = time samples)."""

    time: np.ndarray
    coordinates: list[str]
    q: np.ndarray  # (n, n_coords); pelvis_tx is the prescribed platform motion in "prescribed" mode
    v: np.ndarray
    lumbar_rotation: np.ndarray  # rad, sum of the five FE angles = S1-L1 link to the vertical, flexion +
    muscles: list[str]
    activation: np.ndarray | None  # (n, n_muscles); this and the muscle histories below: None unless logged (`log`)
    excitation: np.ndarray | None
    muscle_force: np.ndarray | None  # tendon force, N
    normalized_fiber_length: np.ndarray | None
    normalized_fiber_velocity: np.ndarray | None
    fiber_length: np.ndarray | None  # m
    platform: np.ndarray  # (n, 3) platform displacement, velocity, acceleration (zeros without perturbation)
    stats: dict  # integrator statistics
    wall_time_s: float
    options: dict
    metadata: dict = field(default_factory=dict)
    levels: dict = field(default_factory=dict)  # level angle (rad) by name, L5_S1_FE ... L1_L2_FE (any configuration)
    step_times: np.ndarray | None = None  # s, 0 and the end of every integrator step: `simulate(steps=...)` replays them

    @property
    def sim_time_s(self) -> float:
        return float(self.time[-1] - self.time[0])

    @property
    def real_time_factor(self) -> float:
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else float("inf")

    def coordinate(self, name: str) -> np.ndarray:
        """A coordinate's trajectory, or a level angle's (also in a coupled configuration, e.g. the rhythm)."""
        if name in self.coordinates:
            return self.q[:, self.coordinates.index(name)]
        if name in self.levels:
            return self.levels[name]
        raise KeyError(f"no coordinate or level {name!r}; coordinates: {self.coordinates}, levels: {list(self.levels)}")

    def summary(self) -> dict:
        """Numbers a user checks first (JSON-friendly), with a warning when the trunk left the
        upright posture (more than UPRIGHT_DEG of mean rotation over the last second)."""
        rot = np.degrees(self.lumbar_rotation - self.lumbar_rotation[0])
        settled = float(np.mean(rot[self.time >= self.time[-1] - 1.0]))
        warning = None
        if abs(settled) > UPRIGHT_DEG:
            warning = (f"the trunk left the upright posture ({settled:+.1f} deg of lumbar {'flexion' if settled > 0 else 'extension'} "
                       "over the last second): with these bushings, co-activation and gains MyoTorso does not hold itself "
                       "upright (about 300 Nm/rad per level are needed without active stabilisation; see README)")
        return {
            "wall_time_s": self.wall_time_s,
            "sim_time_s": self.sim_time_s,
            "steps": self.stats["steps"],
            "real_time_factor": self.real_time_factor,
            "derivative_evaluations": self.stats["derivative_evaluations"],
            "integrator": self.stats["integrator"],
            "lumbar_rotation_deg": {"final": float(rot[-1]), "min": float(rot.min()), "max": float(rot.max()),
                                    "rms": float(np.sqrt(np.mean(rot**2)))},
            "platform_peak_m": float(np.abs(self.platform[:, 0]).max()),
            "warning": warning,
        }

    def write(self, out_dir, plot: bool = True) -> dict[str, Path]:
        """Write OpenSim storage (.sto: the .osim's coordinate names and signs, see
        `opensim_states`), CSV (trunk-drake's names, flexion +, units in the column names),
        JSON summary and (optionally) a PNG plot."""
        from trunk_drake.io.storage import write_csv, write_storage
        from trunk_drake.metadata import json_default

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        states, header = self.opensim_states()
        forces = {m: self.muscle_force[:, i] for i, m in enumerate(self.muscles)}
        units = {"slide": "m", "hinge": "rad"}
        kinematics = {"lumbar_rotation_rad": self.lumbar_rotation, "platform_x_m": self.platform[:, 0],
                      "platform_v_m_per_s": self.platform[:, 1], "platform_a_m_per_s2": self.platform[:, 2]}
        kinematics.update({f"{c}_{units['slide' if c == 'pelvis_tx' else 'hinge']}": self.q[:, i]
                           for i, c in enumerate(self.coordinates)})
        kinematics.update({f"{name}_rad": angle for name, angle in self.levels.items() if name not in self.coordinates})  # coupled levels
        paths = {
            "states": out / "states.sto",
            "muscle_forces": out / "muscle_forces.sto",
            "kinematics": out / "kinematics.csv",
            "summary": out / "summary.json",
        }
        write_storage(paths["states"], time=self.time, columns=states, in_degrees=False, name="trunk-drake states",
                      extra_header=header)
        write_storage(paths["muscle_forces"], time=self.time, columns=forces, in_degrees=False,
                      name="trunk-drake tendon forces", extra_header={"units": "N"})
        write_csv(paths["kinematics"], time=self.time, columns=kinematics, in_degrees=False,
                  metadata={"convention": "trunk-drake coordinates, flexion positive; pelvis_tx anterior"})
        paths["summary"].write_text(json.dumps({**self.summary(), "options": self.options, "metadata": self.metadata}, indent=2,
                                               default=lambda o: json_default(o) if isinstance(o, (np.ndarray, np.generic)) else str(o)))
        if plot:
            from trunk_drake.plots import plot_simulation

            paths["plot"] = plot_simulation(self, out / "simulation.png")
        return paths

    def opensim_states(self) -> tuple[dict[str, np.ndarray], dict[str, str]]:
        """Columns and header lines of states.sto in Lumbar_C_210.osim's conventions: its
        coordinate names (L5-S1 is ``flex_extension``) and signs (flexion negative), radians and
        rad/s (``<name>_u``), then ``<muscle>.activation`` and, with compliant tendons,
        ``<muscle>.fiber_length`` (m). ``pelvis_tx`` (m, anterior) is kept although the .osim
        has no such coordinate."""
        from trunk_drake.model.plant import RHYTHM_COORDINATE, opensim_coordinate

        names, signs = [], []
        for c in self.coordinates:
            name, sign = opensim_coordinate(c) or (c, 1.0)
            names.append(name)
            signs.append(sign)
        states = {n: s * self.q[:, i] for i, (n, s) in enumerate(zip(names, signs))}
        states.update({f"{n}_u": s * self.v[:, i] for i, (n, s) in enumerate(zip(names, signs))})
        states.update({f"{m}.activation": self.activation[:, i] for i, m in enumerate(self.muscles)})
        if self.options.get("tendon") == "compliant":
            states.update({f"{m}.fiber_length": self.fiber_length[:, i] for i, m in enumerate(self.muscles)})
        coupled = RHYTHM_COORDINATE in self.coordinates
        header = {"convention": "Lumbar_C_210.osim coordinate names and signs: flex_extension is "
                                + ("the lumbar rhythm's coordinate (minus trunk-drake's lumbar_FE)" if coupled else "L5-S1")
                                + ", flexion is negative (trunk-drake's kinematics.csv: flexion positive); angles in rad, "
                                "speeds (_u) in rad/s",
                  "coupling": ("the .osim's couplers give L4_L5_FE..L1_L2_FE from flex_extension, as trunk-drake's rhythm does"
                               if coupled else "the .osim couples L4_L5_FE..L1_L2_FE to flex_extension; here every level moves on its own"),
                  "pelvis_tx": "anterior pelvis (platform) translation in m; not a coordinate of the .osim, whose sacrum is welded"}
        return states, header


def _monitor(td: TrunkDiagram):
    """Stop a diverging run with a message naming time, coordinates and muscles."""
    plant, names = td.plant, td.names("coordinates")
    nq = plant.num_positions()

    def monitor(root_context):
        x = plant.GetMyContextFromRoot(root_context).get_continuous_state_vector().CopyToVector()
        q, v = x[:nq], x[nq:]
        angles = np.abs(q[td.fe_indices])
        if np.all(np.isfinite(x)) and angles.max() < DIVERGENCE_ANGLE and np.abs(v).max() < DIVERGENCE_SPEED:
            return EventStatus.Succeeded()
        return EventStatus.Failed(td.diagram, divergence_message(td, root_context, q, v, names))

    return monitor


def divergence_message(td: TrunkDiagram, root_context, q, v, names) -> str:
    """What blew up: the worst coordinates and the muscles with the most extreme fiber states."""
    t = root_context.get_time()
    order = np.argsort(-np.nan_to_num(np.abs(v), nan=np.inf))
    coords = ", ".join(f"{names[i]} (q={q[i]:.3g}, v={v[i]:.3g})" for i in order[:3])
    muscles_ctx = td.muscles.GetMyContextFromRoot(root_context)
    a = muscles_ctx.get_continuous_state_vector().CopyToVector()[: td.muscles.n]
    try:
        vn = td.muscles.GetOutputPort("normalized_fiber_velocity").Eval(muscles_ctx)
        worst = np.argsort(-np.nan_to_num(np.abs(vn), nan=np.inf))[:5]
        fibers = ", ".join(f"{td.names('muscles')[i]} (v/vmax={vn[i]:.3g}, a={a[i]:.3g})" for i in worst)
    except Exception as err:  # the state may be too broken to evaluate fibers
        fibers = f"(fiber states not computable: {err})"
    return (
        f"simulation diverged at t={t:.4f} s: coordinates {coords}; most extreme muscles {fibers}. "
        "Try a smaller --accuracy, lower reflex gains, or check the feed-forward excitation."
    )


def default_integrator(model, options: TrunkOptions) -> str:
    """The integrator `simulate` uses unless told: explicit Runge-Kutta 3 (error-controlled) for the rhythm
    with rigid tendons, radau3 where the model is stiff (independent vertebrae, compliant tendons)."""
    return NONSTIFF_INTEGRATOR if model.coupling is not None and options.tendon == "rigid" else STIFF_INTEGRATOR


def replay_key(point: tuple, on: tuple | None) -> tuple:
    """Cache key of the run of `point` (a tuple) on the step sequences of the run keyed `on` (None: on its
    own): keyed as the run `on` itself when that is the point's own run, which its replay reproduces
    (5e-12 deg apart, tests/test_accuracy.py), so that the fits do not simulate it again."""
    own = (*point, None)
    return own if on is None or on == own else (*point, on)


def differentiable_settings(model, options: TrunkOptions, steps: np.ndarray | None = None) -> dict:
    """`simulate` keywords for simulations that are differentiated by finite differences (the fits): the result must
    be a smooth function of the parameters. An error-controlled step sequence changes with them, and its switching
    then enters the Jacobian as information the data do not hold (runge_kutta3 at 1e-3 on the reference data: the
    columns of the psoas gains 100-500x their size). Where `default_integrator` is runge_kutta3, a fit therefore
    simulates its base point with error control at `SEQUENCE_ACCURACY` (`steps` None) and every finite-difference
    point around it on that run's step sequence (`steps`: its `step_times`); radau3 already runs at its maximum
    step, which binds, and ignores `steps`."""
    if default_integrator(model, options) != NONSTIFF_INTEGRATOR:
        return {}
    if steps is None:
        return {"integrator": NONSTIFF_INTEGRATOR, "accuracy": SEQUENCE_ACCURACY}
    return {"integrator": NONSTIFF_INTEGRATOR, "steps": steps}


def simulate(model, duration: float | None = None, perturbation="multisine", bandwidth: float = 1.0, seed: int = 0,
             lowpass_hz: float | None = None,
             options: TrunkOptions | None = None, integrator: str | None = None, accuracy: float | None = None,
             log_rate: float = DEFAULT_LOG_RATE, max_step: float | None = None, progress: bool = False,
             steps: np.ndarray | None = None, log: tuple[str, ...] = MUSCLE_LOGS, **option_overrides) -> SimulationResult:
    """Simulate the trunk model (pelvis perturbation, muscles, reflexes, bushings).

    `perturbation`: "multisine" (default: 20 s period, 0.2 Hz to `bandwidth` Hz, 2 s fades,
    seeded, optionally low-passed at `lowpass_hz` as the thesis' 2 Hz filter), None (no perturbation: settling under gravity), or any object with
    ``evaluate(t) -> (x, v, a)`` and a ``duration``. `duration` defaults to the signal's
    duration (or 5 s without perturbation). Every integrator step is logged and the
    histories are resampled (shape-preserving cubic, as the thesis did) onto a uniform grid
    of `log_rate` Hz. `integrator` defaults to `default_integrator`; `accuracy` and `max_step` to
    that integrator's (radau3: 1e-2, 12.5 ms; runge_kutta3: 1e-3, 25 ms), the step also at most
    1 / (10 * bandwidth) and the shortest reflex delay. `steps` (a previous run's `step_times`) replays
    that run's step sequence with the same integrator, error control off: finite differences
    between runs on one sequence are smooth, where each run's own error-controlled sequence would
    add its switching to the difference. `log`: the muscle histories to record (of `diagram.MUSCLE_LOGS`; the
    result's others are None), fewer for the fits' many runs. Other keyword arguments override fields of
    `TrunkOptions` (e.g. ``kp=0.2, tendon="compliant"``).
    """
    return _simulate(model, None, duration, perturbation, bandwidth, seed, lowpass_hz, options, integrator, accuracy, log_rate,
                     max_step, progress, steps, log, option_overrides)[0]


def simulate_copies(model, variants: list[dict], steps: np.ndarray, duration: float | None = None, perturbation="multisine",
                    options: TrunkOptions | None = None, log_rate: float = DEFAULT_LOG_RATE,
                    log: tuple[str, ...] = MUSCLE_LOGS) -> list[SimulationResult]:
    """`simulate` once per variant of `options` (a dict of `diagram.VARIANT_FIELDS`: reflex gains {"kp": ..., "kv": ...}
    as `TrunkOptions.kp`, bushing stiffness, damping and stiffening, strength scale, activation time scale, reflex
    delay, seat stiffness and damping), all on the replayed step sequence `steps`, as copies of the model in one diagram (`build_trunk_diagram`'s
    `variants`: the rhythm on the prescribed pelvis or the seat, rigid tendons, no other feedback). Each result equals its own
    `simulate` on `steps` to round-off, at a fraction of the cost: the copies share every evaluation's fixed cost
    (the points of a finite-difference Jacobian). A copy that diverges or leaves the tabulated range fails them all
    (SimulationError)."""
    return _simulate(model, list(variants), duration, perturbation, 1.0, 0, None, options, None, None, log_rate, None, False,
                     steps, log, {})


def _simulate(model, variants, duration, perturbation, bandwidth, seed, lowpass_hz, options, integrator, accuracy, log_rate,
              max_step, progress, steps, log, option_overrides) -> list[SimulationResult]:
    """`simulate` (`variants` None: one result) or `simulate_copies` (one result per variant)."""
    opts = dataclasses.replace(options or TrunkOptions(), **option_overrides)
    integrator = integrator or default_integrator(model, opts)
    nonstiff = integrator == NONSTIFF_INTEGRATOR
    if accuracy is None:
        accuracy = NONSTIFF_ACCURACY if nonstiff else DEFAULT_ACCURACY
    signal = _perturbation(perturbation, bandwidth, seed, lowpass_hz)
    if duration is None:
        duration = signal.duration if signal is not None else 5.0
    if not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive number of seconds, got {duration!r}")
    if log_rate <= 0:
        raise ValueError(f"log_rate must be positive (Hz), got {log_rate!r}")
    if integrator not in FIXED_STEP_INTEGRATORS and not 0 < accuracy < 1:
        raise ValueError(f"accuracy must lie in (0, 1), got {accuracy!r}")
    if steps is not None:
        steps = _replayable(steps, duration)
        max_step = 1.001 * float(np.max(np.diff(steps)))  # every replayed step within it: one step per boundary
    elif max_step is None:
        delays = [max(d, MIN_DELAY_STEP) for d in (opts.reflex_delay, opts.vestibular_delay) if d > 0]
        max_step = min(NONSTIFF_MAX_STEP if nonstiff else MAX_STEP, 0.1 / bandwidth, *delays)
    if variants is not None and steps is None:
        raise ValueError("simulate_copies replays a step sequence: give `steps` (a previous run's step_times)")
    td = build_trunk_diagram(model, opts, signal, log=tuple(log), variants=variants)
    simulator = Simulator(td.diagram)
    ResetIntegratorFromFlags(simulator, integrator, max_step)
    integ = simulator.get_mutable_integrator()
    if steps is not None:
        integ.set_fixed_step_mode(True)
    elif integrator not in FIXED_STEP_INTEGRATORS:
        integ.set_target_accuracy(accuracy)
    _set_initial_muscle_state(td, simulator.get_mutable_context())
    simulator.set_monitor(_monitor(td))

    try:
        wall = _time.perf_counter()
        _run(simulator, duration, steps, progress)
        wall = _time.perf_counter() - wall
        return [_collect(td, simulator, wall / td.copies, integrator, accuracy, signal, seed, bandwidth, duration, log_rate, b)
                for b in range(td.copies)]
    finally:
        release(td.diagram)


def _replayable(steps, duration: float) -> np.ndarray:
    """`steps` checked as a step sequence of a run of `duration`: increasing times from 0 to it."""
    steps = np.asarray(steps, float)
    if steps.ndim != 1 or steps.size < 2 or steps[0] != 0.0 or np.any(np.diff(steps) <= 0) or abs(steps[-1] - duration) > 1e-9:
        raise ValueError(f"steps must be increasing times from 0 to the duration ({duration} s), as a previous run's "
                         f"step_times; got {steps.size} times from {steps[:1]} to {steps[-1:]}")
    return steps


def _set_initial_muscle_state(td: TrunkDiagram, root_context) -> None:
    """Start at rest: activations equal to the feed-forward excitation (no stretch at q = 0),
    compliant fibers in static force equilibrium with their tendons (MuscleSystem.steady_state)."""
    muscles = td.muscles
    path = td.paths.GetOutputPort("path_state").Eval(td.paths.GetMyContextFromRoot(root_context))
    activation = np.clip(td.feedforward, td.options.constants.minimum_activation, 1.0)
    muscles.GetMyMutableContextFromRoot(root_context).SetContinuousState(muscles.steady_state(activation, path))


def _perturbation(perturbation, bandwidth, seed, lowpass_hz=None):
    if perturbation is None:
        return None
    if isinstance(perturbation, str):
        if perturbation != "multisine":
            raise ValueError(f"perturbation={perturbation!r}; expected 'multisine', None or a signal object")
        from trunk_drake.signals import make_multisine

        return make_multisine(f_max=float(bandwidth), seed=seed, fade_shape="quintic",  # continuous acceleration
                              lowpass_hz=lowpass_hz)
    if not hasattr(perturbation, "evaluate"):
        raise ValueError("perturbation must have evaluate(t) -> (x, v, a)")
    return perturbation


def _run(simulator, duration, steps, progress) -> None:
    """Run to `duration`, on the step times `steps` if given; a failure raises SimulationError."""
    try:
        simulator.Initialize()
        if steps is None:
            _advance(simulator, duration, progress)
        else:
            for t in steps[1:]:
                simulator.AdvanceTo(t)
    except RuntimeError as err:
        if caused_by_interrupt(err):  # a Ctrl-C that a Drake callback turned into a RuntimeError
            raise KeyboardInterrupt from err
        raise SimulationError(str(err)) from None


def _advance(simulator, duration, progress):
    if not progress:
        simulator.AdvanceTo(duration)
        return
    from tqdm import tqdm

    with tqdm(total=duration, unit="sim s", bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s [{elapsed}]") as bar:
        t = 0.0
        while t < duration:
            t = min(duration, t + 1.0)
            simulator.AdvanceTo(t)
            bar.update(t - bar.n)


def _collect(td: TrunkDiagram, simulator, wall, integrator, accuracy, signal, seed, bandwidth, duration, log_rate,
             copy: int = 0) -> SimulationResult:
    """The result of copy `copy` of the model (`TrunkDiagram.copies`; its share of the wall time)."""
    from trunk_drake.signals.resample import resample_pchip

    ctx = simulator.get_context()
    t = np.arange(int(np.floor(duration * log_rate + 1e-9)) + 1) / log_rate
    nq, n = td.plant.num_positions() // td.copies, td.model.n_muscles
    rows = {"state": np.r_[copy * nq:(copy + 1) * nq, td.plant.num_positions() + copy * nq:td.plant.num_positions() + (copy + 1) * nq]}
    logs = {}
    for name, sink in td.loggers.items():
        log = sink.FindLog(ctx)
        data = log.data()[rows.get(name, np.s_[copy * n:(copy + 1) * n])]
        logs[name] = resample_pchip(log.sample_times(), data.T, t, drop_duplicates=True)
    step_times = np.unique(td.loggers["state"].FindLog(ctx).sample_times())
    x = logs["state"]
    q, v = x[:, :nq], x[:, nq:]
    coords = list(td.model.coordinates)
    # the platform signal is known analytically: sample it exactly (not from the step-wise log)
    platform = np.column_stack(signal.evaluate(t)) if signal is not None else np.zeros((len(t), 3))
    levels = dict(zip(td.model.levels, (q @ td.model.level_matrix.T).T))
    if td.model.dofs in SLIDING_PELVIS and not td.model.pelvis_free:  # prescribed: the pelvis follows the platform
        coords = ["pelvis_tx", *coords]
        q = np.column_stack([platform[:, 0], q])
        v = np.column_stack([platform[:, 1], v])
    integ = simulator.get_integrator()
    stats = {
        "integrator": integrator,
        "accuracy": None if integrator in FIXED_STEP_INTEGRATORS else accuracy,
        "steps": int(integ.get_num_steps_taken()),
        "derivative_evaluations": int(integ.get_num_derivative_evaluations()),
        "step_shrinkages": int(integ.get_num_step_shrinkages_from_error_control()),
        "largest_step_s": float(integ.get_largest_step_size_taken()),
        "max_step_s": float(integ.get_maximum_step_size()),
    }
    opts = dataclasses.asdict(td.options)
    opts["constants"] = dataclasses.asdict(td.options.constants)
    return SimulationResult(
        time=t, coordinates=coords, q=q, v=v, lumbar_rotation=x[:, td.fe_indices[:len(td.fe_indices) // td.copies]].sum(axis=1), muscles=list(td.model.muscles),
        activation=logs.get("activation"), excitation=logs.get("excitation"), muscle_force=logs.get("tendon_force"),
        normalized_fiber_length=logs.get("normalized_fiber_length"),
        normalized_fiber_velocity=logs.get("normalized_fiber_velocity"), fiber_length=logs.get("fiber_length"),
        platform=platform, stats=stats, wall_time_s=wall, options=opts, levels=levels, step_times=step_times,
        metadata=run_metadata(td.model, seed=seed, bandwidth=bandwidth, perturbation=getattr(signal, "to_dict", lambda: None)()),
    )


def load_reflex_gains(path) -> dict[str, dict[str, float]]:
    """Per-group reflex gains from a TOML or JSON file with tables/objects ``kp`` and ``kv``.

    A file may hold several named sets (like models/reflex_gains_thesis.toml): ``FILE#name``
    picks one, e.g. ``models/reflex_gains_thesis.toml#car_passenger``; without a name the
    file's first set is used (with a warning naming the others). A group missing from a table
    gets gain 0 (its reflex is off), with a warning naming it.
    """
    import tomllib

    from trunk_drake.data import load_toml

    path, _, name = str(path).partition("#")
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"reflex gains file {p} does not exist" if not p.exists() else f"reflex gains file {p} is a folder")
    try:
        data = tomllib.loads(p.read_text()) if p.suffix == ".toml" else json.loads(p.read_text())
    except (tomllib.TOMLDecodeError, json.JSONDecodeError) as err:
        raise ValueError(f"{p} is not valid {'TOML' if p.suffix == '.toml' else 'JSON'}: {err}") from None
    sets = [k for k, v in data.items() if isinstance(v, dict) and ("kp" in v or "kv" in v)]
    if name:
        if name not in sets:
            raise ValueError(f"{p} has no gain set {name!r}; its sets: {sets or 'none (use the file without #NAME)'}")
        data = data[name]
    elif "kp" not in data and "kv" not in data and sets:
        name, data = sets[0], data[sets[0]]
        if len(sets) > 1:
            warnings.warn(f"{p} holds the gain sets {', '.join(sets)}: using {name} ({p}#NAME picks another)", stacklevel=2)
    where = f"{p}{'#' + name if name else ''}"
    missing = [k for k in ("kp", "kv") if k not in data]
    if missing:
        raise ValueError(f"{where} lacks the {missing} table(s); expected [kp] and [kv] per muscle group"
                         + (f", or FILE#NAME for one of its sets {sets}" if sets else ""))
    groups = list(load_toml("muscle_groups.toml")["groups"])
    gains = {}
    for kind in ("kp", "kv"):
        table = data[kind]
        unknown = sorted(set(table) - set(groups))
        if unknown:
            raise ValueError(f"{where}: [{kind}] names unknown muscle group(s) {unknown}; groups: {groups}")
        for group, value in table.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
                raise ValueError(f"{where}: [{kind}] {group} = {value!r} is not a gain: write a number >= 0, "
                                 f"e.g. {group} = 0.1")
        absent = [g for g in groups if g not in table]
        if absent:
            warnings.warn(f"{where}: [{kind}] gives no gain for {', '.join(absent)}: their {kind} is 0", stacklevel=2)
        gains[kind] = {g: float(v) for g, v in table.items()}
    return gains


DEFAULT_GAINS = "reflex_gains_thesis.toml#car_passenger"
