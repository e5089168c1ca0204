"""Forward simulation of the seated trunk under pelvis perturbation: `simulate` and its result."""

from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import EventStatus

from trunk_drake.diagram import TrunkDiagram, TrunkOptions, build_trunk_diagram
from trunk_drake.metadata import run_metadata

DEFAULT_INTEGRATOR = "radau3"  # L-stable: the vertebral damping modes reach ~4000 1/s
DEFAULT_ACCURACY = 1e-2
DEFAULT_LOG_RATE = 100.0  # Hz, uniform output grid (step-wise logs are resampled onto it)
MAX_STEP = 0.0125  # s; longer steps make Newton fail at the reflexes' kinks (measured: 14 ms ok, 20 ms not)
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
    activation: np.ndarray  # (n, n_muscles)
    excitation: np.ndarray
    muscle_force: np.ndarray  # tendon force, N
    normalized_fiber_length: np.ndarray
    normalized_fiber_velocity: np.ndarray
    fiber_length: np.ndarray  # m
    platform: np.ndarray  # (n, 3) platform displacement, velocity, acceleration (zeros without perturbation)
    stats: dict  # integrator statistics
    wall_time_s: float
    options: dict
    metadata: dict = field(default_factory=dict)

    @property
    def sim_time_s(self) -> float:
        return float(self.time[-1] - self.time[0])

    @property
    def real_time_factor(self) -> float:
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else float("inf")

    def coordinate(self, name: str) -> np.ndarray:
        if name not in self.coordinates:
            raise KeyError(f"no coordinate {name!r}; coordinates: {self.coordinates}")
        return self.q[:, self.coordinates.index(name)]

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
        """Write OpenSim storage (.sto), CSV, JSON summary and (optionally) a PNG plot."""
        from trunk_drake.io.storage import write_csv, write_storage

        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        states = {c: self.q[:, i] for i, c in enumerate(self.coordinates)}
        states.update({f"{c}_u": self.v[:, i] for i, c in enumerate(self.coordinates)})
        states.update({f"{m}.activation": self.activation[:, i] for i, m in enumerate(self.muscles)})
        forces = {m: self.muscle_force[:, i] for i, m in enumerate(self.muscles)}
        kinematics = {"lumbar_rotation": self.lumbar_rotation, "platform_x": self.platform[:, 0],
                      "platform_v": self.platform[:, 1], "platform_a": self.platform[:, 2]}
        kinematics.update({c: self.q[:, i] for i, c in enumerate(self.coordinates)})
        paths = {
            "states": out / "states.sto",
            "muscle_forces": out / "muscle_forces.sto",
            "kinematics": out / "kinematics.csv",
            "summary": out / "summary.json",
        }
        write_storage(paths["states"], time=self.time, columns=states, in_degrees=False, name="trunk-drake states")
        write_storage(paths["muscle_forces"], time=self.time, columns=forces, in_degrees=False, name="trunk-drake tendon forces")
        write_csv(paths["kinematics"], time=self.time, columns=kinematics, in_degrees=False)
        import json

        paths["summary"].write_text(json.dumps({**self.summary(), "options": self.options, "metadata": self.metadata}, indent=2, default=str))
        if plot:
            from trunk_drake.plots import plot_simulation

            paths["plot"] = plot_simulation(self, out / "simulation.png")
        return paths


def _monitor(td: TrunkDiagram):
    """Stop a diverging run with a message naming time, coordinates and muscles."""
    plant, names = td.plant, td.model.coordinates
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
        fibers = ", ".join(f"{td.model.muscles[i]} (v/vmax={vn[i]:.3g}, a={a[i]:.3g})" for i in worst)
    except Exception as err:  # the state may be too broken to evaluate fibers
        fibers = f"(fiber states not computable: {err})"
    return (
        f"simulation diverged at t={t:.4f} s: coordinates {coords}; most extreme muscles {fibers}. "
        "Try a smaller --accuracy, lower reflex gains, or check the feed-forward excitation."
    )


def simulate(model, duration: float | None = None, perturbation="multisine", bandwidth: float = 1.0, seed: int = 0,
             lowpass_hz: float | None = None,
             options: TrunkOptions | None = None, integrator: str = DEFAULT_INTEGRATOR, accuracy: float = DEFAULT_ACCURACY,
             log_rate: float = DEFAULT_LOG_RATE, max_step: float | None = None, progress: bool = False,
             **option_overrides) -> SimulationResult:
    """Simulate the sagittal trunk model (pelvis perturbation, muscles, reflexes, bushings).

    `perturbation`: "multisine" (default: 20 s period, 0.2 Hz to `bandwidth` Hz, 2 s fades,
    seeded, optionally low-passed at `lowpass_hz` as the thesis' 2 Hz filter), None (no perturbation: settling under gravity), or any object with
    ``evaluate(t) -> (x, v, a)`` and a ``duration``. `duration` defaults to the signal's
    duration (or 5 s without perturbation). Every integrator step is logged and the
    histories are resampled (shape-preserving cubic, as the thesis did) onto a uniform grid
    of `log_rate` Hz. `max_step` defaults to min(12.5 ms, 1 / (10 * bandwidth)). Other
    keyword arguments override fields of `TrunkOptions` (e.g. ``kp=0.2, tendon="compliant"``).
    """
    opts = dataclasses.replace(options or TrunkOptions(), **option_overrides)
    signal = _perturbation(perturbation, bandwidth, seed, lowpass_hz)
    if duration is None:
        duration = signal.duration if signal is not None else 5.0
    if not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive number of seconds, got {duration!r}")
    if log_rate <= 0:
        raise ValueError(f"log_rate must be positive (Hz), got {log_rate!r}")
    if max_step is None:
        max_step = min(MAX_STEP, 0.1 / bandwidth)
    td = build_trunk_diagram(model, opts, signal)
    simulator = Simulator(td.diagram)
    ResetIntegratorFromFlags(simulator, integrator, max_step)
    integ = simulator.get_mutable_integrator()
    if integrator not in FIXED_STEP_INTEGRATORS:
        integ.set_target_accuracy(accuracy)
    _set_initial_muscle_state(td, simulator.get_mutable_context())
    simulator.set_monitor(_monitor(td))

    wall = _time.perf_counter()
    try:
        simulator.Initialize()
        _advance(simulator, duration, progress)
    except RuntimeError as err:
        raise SimulationError(str(err)) from None
    wall = _time.perf_counter() - wall
    return _collect(td, simulator, wall, integrator, accuracy, signal, seed, bandwidth, duration, log_rate)


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


def _collect(td: TrunkDiagram, simulator, wall, integrator, accuracy, signal, seed, bandwidth, duration, log_rate) -> SimulationResult:
    from trunk_drake.signals.resample import resample_pchip

    ctx = simulator.get_context()
    t = np.arange(int(np.floor(duration * log_rate + 1e-9)) + 1) / log_rate
    logs = {}
    for name, sink in td.loggers.items():
        log = sink.FindLog(ctx)
        logs[name] = resample_pchip(log.sample_times(), log.data().T, t, drop_duplicates=True)
    x = logs["state"]
    nq = td.plant.num_positions()
    q, v = x[:, :nq], x[:, nq:]
    coords = list(td.model.coordinates)
    # the platform signal is known analytically: sample it exactly (not from the step-wise log)
    platform = np.column_stack(signal.evaluate(t)) if signal is not None else np.zeros((len(t), 3))
    if td.model.dofs == "sagittal" and not td.model.pelvis_free:  # prescribed: the pelvis follows the platform
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
        time=t, coordinates=coords, q=q, v=v, lumbar_rotation=x[:, td.fe_indices].sum(axis=1), muscles=list(td.model.muscles),
        activation=logs["activation"], excitation=logs["excitation"], muscle_force=logs["tendon_force"],
        normalized_fiber_length=logs["normalized_fiber_length"], normalized_fiber_velocity=logs["normalized_fiber_velocity"],
        fiber_length=logs["fiber_length"],
        platform=platform, stats=stats, wall_time_s=wall, options=opts,
        metadata=run_metadata(td.model, seed=seed, bandwidth=bandwidth, perturbation=getattr(signal, "to_dict", lambda: None)()),
    )


def load_reflex_gains(path) -> dict[str, dict[str, float]]:
    """Per-group reflex gains from a TOML or JSON file with tables/objects ``kp`` and ``kv``.

    A file may hold several named sets (like models/reflex_gains_thesis.toml); then use
    ``FILE#name`` to pick one, e.g. ``models/reflex_gains_thesis.toml#car_passenger``.
    """
    import json
    import tomllib

    path, _, name = str(path).partition("#")
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"reflex gains file {p} does not exist")
    data = tomllib.loads(p.read_text()) if p.suffix == ".toml" else json.loads(p.read_text())
    if name:
        if name not in data:
            raise ValueError(f"{p} has no gain set {name!r}; sets: {sorted(k for k in data if isinstance(data[k], dict))}")
        data = data[name]
    missing = [k for k in ("kp", "kv") if k not in data]
    if missing:
        sets = sorted(k for k, v in data.items() if isinstance(v, dict) and {"kp", "kv"} <= set(v))
        hint = f"; it holds the sets {sets}: pick one with {p}#NAME" if sets and not name else ""
        raise ValueError(f"{p}{'#' + name if name else ''} lacks the {missing} table(s); expected [kp] and [kv] per muscle group{hint}")
    return {"kp": dict(data["kp"]), "kv": dict(data["kv"])}


DEFAULT_GAINS = "reflex_gains_thesis.toml#car_passenger"
