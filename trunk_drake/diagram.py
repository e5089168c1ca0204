"""Wire the neuromuscular trunk Diagram: plant, muscle paths, muscles, stretch reflex,
feed-forward co-activation, intervertebral bushings and the pelvis perturbation.

    perturbation ──► plant ──► paths ──► muscles ──► generalized forces ──► plant
                   reflex(fiber state) ─┘   ▲ feed-forward excitation
                   bushings(q, v) ──────────┘
"""

from __future__ import annotations

import dataclasses
import gc
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import Adder, ConstantVectorSource, VectorLogSink

from trunk_drake.model.anthropometry import with_upper_body_mass
from trunk_drake.model.coupled import CoupledPlant
from trunk_drake.model.levels import LEVELS
from trunk_drake.model.tables import coordinate_table
from trunk_drake.muscle.short_range import ShortRangeStiffness
from trunk_drake.muscle.thelen import ThelenConstants
from trunk_drake.systems.bushing import DEFAULT_DAMPING, DEFAULT_STIFFNESS, IntervertebralBushings
from trunk_drake.systems.delay import TransportDelay
from trunk_drake.systems.muscles import MuscleSystem, muscle_parameters
from trunk_drake.systems.paths import MusclePathSystem
from trunk_drake.systems.perturbation import PelvisForcePerturbation, PrescribedPelvisMotion
from trunk_drake.systems.tabulated_plant import TabulatedPlant
from trunk_drake.systems.effects import GolgiTendonFeedback, SeatCompliance, TrunkInSpaceFeedback
from trunk_drake.systems.reflex import ExcitationMixer, StretchReflex, gains_by_group

PELVIS_MODES = ("prescribed", "force", "seat", "none")  # seat: pelvis on a spring-damper to the platform
SLIDING_PELVIS = ("sagittal", "rhythm")  # configurations with the pelvis_tx slide
EXTENSOR_GROUPS = ("sacrospinalis", "transversospinalis", "quadratus_lumborum")
FLEXOR_GROUPS = ("rectus_abdominis", "external_oblique", "internal_oblique", "psoas_major")
THESIS_PELVIS_MASS = 10_000.0  # kg, seed section 3.4.2
MUSCLE_LOGS = ("activation", "excitation", "tendon_force", "normalized_fiber_length", "normalized_fiber_velocity", "fiber_length")


@dataclass
class TrunkOptions:
    """Everything that defines one trunk diagram (SI units). Defaults follow the thesis."""

    tendon: str = "rigid"
    kp: float | dict | np.ndarray = 0.0  # stretch-reflex position gain (scalar, per group, or per muscle)
    kv: float | dict | np.ndarray = 0.0  # velocity gain
    l_desired: float | str | np.ndarray = 1.0  # seed eq. 3.2 (1 = optimal fiber length); "neutral": l_n at q = 0
    reflex_delay: float = 0.0  # s
    feedforward: np.ndarray | None = None  # constant excitation; None -> minimum activation
    stiffness: float | np.ndarray = DEFAULT_STIFFNESS  # Nm/rad per lumbar level
    damping: float | np.ndarray = DEFAULT_DAMPING  # Nms/rad
    cubic: float = 0.0  # nonlinear bushing: M = -k (dq + cubic dq^3)
    pelvis: str = "prescribed"
    pelvis_mass: float = THESIS_PELVIS_MASS  # only for pelvis="force"
    seat_stiffness: float = 0.0  # N/m, pelvis="seat": pelvis-seat spring
    seat_damping: float = 0.0  # N s/m
    gto_gain: float = 0.0  # Golgi tendon organ force feedback (shares reflex_delay)
    vestibular_gain: float = 0.0  # trunk-in-space feedback, excitation per rad of trunk inclination
    vestibular_delay: float = 0.0  # s
    activation_scale: float = 1.0  # multiplies both activation time constants (slower excitation-activation)
    strength_scale: float = 1.0
    muscle_mask: np.ndarray | None = None  # 0/1 per muscle: which muscles act (Table 4.1 study)
    srs: ShortRangeStiffness | None = None  # short-range stiffness of active muscle; None: off
    upper_body_mass_scale: float = 1.0  # scales the thorax body's mass and inertia (an upper-body mass error)
    constants: ThelenConstants = field(default_factory=ThelenConstants)
    tables: bool = True  # one-coordinate models (the rhythm): paths and dynamics from tables (model.tables)

    def per_muscle(self, model, value) -> np.ndarray:
        if isinstance(value, dict):
            return gains_by_group(model, value)
        return np.broadcast_to(np.asarray(value, dtype=float), (model.n_muscles,)).copy()


@dataclass
class TrunkDiagram:
    """A built diagram and handles to its parts."""

    diagram: Diagram
    model: object  # the TrunkModel whose plant is inside the diagram
    options: TrunkOptions
    plant: object
    paths: MusclePathSystem
    muscles: MuscleSystem
    reflex: StretchReflex
    bushings: IntervertebralBushings
    perturbation: object | None
    loggers: dict[str, VectorLogSink]
    fe_indices: np.ndarray  # indices of the lumbar flexion-extension coordinates in q
    feedforward: np.ndarray  # the constant feed-forward excitation
    copies: int = 1  # copies of the model (`variants`): q holds copy b's coordinates at b * nq ... (b + 1) * nq - 1

    def names(self, kind: str) -> list[str]:
        """The diagram's "coordinates" or "muscles" in order, each copy's marked (``name[b]``) where there are copies."""
        names = list(getattr(self.model, kind))
        return names if self.copies == 1 else [f"{name}[{b}]" for b in range(self.copies) for name in names]


def _desired_length(model, opts: TrunkOptions, params) -> np.ndarray:
    """The reflex set point per muscle; "neutral" = normalised fiber length at the neutral posture."""
    if isinstance(opts.l_desired, str):
        if opts.l_desired != "neutral":
            raise ValueError(f"l_desired={opts.l_desired!r}; expected a number, an array or 'neutral'")
        from trunk_drake.muscle import thelen

        path = model.path_state(np.zeros(len(model.coordinates)), np.zeros(len(model.coordinates)))
        return thelen.rigid_kinematics(path.lengths, path.velocities, params, opts.constants).normalized_fiber_length
    return opts.per_muscle(model, opts.l_desired)


def rotation_coordinates(model) -> np.ndarray:
    """Indices of the lumbar flexion-extension coordinates (any model: its hinge coordinates).

    Their sum is the lumbar rotation (S1-L1 link to the vertical): the five level angles, or the
    rhythm's lumbar_FE. The bushings act on the level angles, ``model.level_matrix @ q``."""
    names = model.coordinates
    fe = [names.index(f"{lvl}_FE") for lvl in LEVELS if f"{lvl}_FE" in names]
    return np.array(fe or [i for i, c in enumerate(model.coordinate_info) if c.kind == "hinge"], dtype=int)


def plant_model_for(model, pelvis: str):
    """The model variant a pelvis mode needs (prescribed motion: pelvis welded), with a plant of its own: a diagram
    owns its plant, so the caller's model stays usable (and may be simulated again)."""
    if pelvis not in PELVIS_MODES:
        raise ValueError(f"pelvis={pelvis!r}; expected one of {PELVIS_MODES}")
    if model.dofs == "spine3d":
        raise ValueError("dynamic simulation needs the 'sagittal' or 'rhythm' model (or a user model, dofs='all'), got dofs='spine3d'")
    if model.dofs == "all":
        return model.variant()
    return model.variant(pelvis_free=(pelvis == "force"))


# What copies of the model in one diagram may differ in (`build_trunk_diagram`'s `variants`): TrunkOptions fields.
VARIANT_FIELDS = ("kp", "kv", "stiffness", "damping", "cubic", "strength_scale", "activation_scale", "reflex_delay",
                  "seat_stiffness", "seat_damping")


def build_trunk_diagram(model, options: TrunkOptions | None = None, perturbation=None, log_period: float = 0.0,
                        log: tuple[str, ...] = MUSCLE_LOGS, variants: list[dict] | None = None) -> TrunkDiagram:
    """Build the diagram for `model` (sagittal or rhythm). `perturbation` is a platform signal with
    `evaluate(t) -> (x, v, a)` (e.g. `trunk_drake.signals.make_multisine(...)`), or None.
    Loggers record the plant state and the muscle histories `log` (of MUSCLE_LOGS) at every integrator
    step (``log_period=0``) or at a fixed period; fits log only what they use (each log is evaluated every step).
    `variants` (a list of dicts of `VARIANT_FIELDS`, e.g. {"kp": ..., "kv": ...} as `TrunkOptions.kp`, the
    others as in `options`): one copy of the model per variant, all in one diagram on one integrator (a
    TabulatedPlant: the rhythm on the prescribed pelvis or the seat, rigid tendons, the stretch reflex as the only
    feedback), so that a finite-difference Jacobian's points share each evaluation's fixed cost; the copies differ
    only in those fields (reflex gains, bushing stiffness, damping and stiffening, muscle strength, activation time
    scale, reflex delay: all delays positive or none; seat stiffness and damping)."""
    unknown = set(log) - set(MUSCLE_LOGS)
    if unknown:
        raise ValueError(f"unknown muscle logs {sorted(unknown)}; choose from {MUSCLE_LOGS}")
    opts = options or TrunkOptions()
    if opts.pelvis not in PELVIS_MODES:
        raise ValueError(f"pelvis={opts.pelvis!r}; expected one of {PELVIS_MODES}")
    if opts.upper_body_mass_scale != 1.0:
        model = model.variant(spec=with_upper_body_mass(model.spec, opts.upper_body_mass_scale))
    pelvis_mode = opts.pelvis if perturbation is not None or opts.pelvis == "seat" else "none"
    if opts.pelvis == "force" and model.dofs in SLIDING_PELVIS:
        base = model.variant(pelvis_free=True, pelvis_mass=opts.pelvis_mass)
    elif opts.pelvis == "seat" and model.dofs in SLIDING_PELVIS:
        base = model.variant(pelvis_free=True)
    else:
        base = plant_model_for(model, "prescribed")
    builder = DiagramBuilder()
    try:
        return _assemble(builder, base, opts, perturbation, pelvis_mode, log_period, log, variants)
    except BaseException:  # bad input found mid-build: free what was added (nested diagrams too)
        release(builder)
        raise


def _assemble(builder, base, opts: TrunkOptions, perturbation, pelvis_mode: str, log_period: float,
              log: tuple[str, ...], variants: list[dict] | None) -> TrunkDiagram:
    """The systems of `build_trunk_diagram`, added to `builder` and connected; the built diagram."""
    table = coordinate_table(base) if opts.tables else None
    copies = _copies(base, opts, pelvis_mode, table, variants)
    each = [replace(opts, **v) for v in variants] if variants else [opts]  # each copy's options
    plant = base.plant if copies == 1 else TabulatedPlant(table, copies)
    nq, nv, n = plant.num_positions(), plant.num_velocities(), base.n_muscles * copies
    fe = (rotation_coordinates(base)[None, :] + base.plant.num_positions() * np.arange(copies)[:, None]).reshape(-1)
    builder.AddSystem(plant)
    if table is not None and isinstance(plant, CoupledPlant):  # a MultibodyPlant computes its dynamics in C++
        plant.use_table(table)
    paths = builder.AddNamedSystem("muscle_paths", MusclePathSystem(base, table, copies))
    params_each = _parameters_each(base, each)
    params = params_each[0] if copies == 1 else _joined(params_each)
    constants, time_scale = _activation_constants(base, opts.constants, [o.activation_scale for o in each])
    muscles = builder.AddNamedSystem("muscles", MuscleSystem(base, constants, opts.tendon, params, mask=opts.muscle_mask,
                                                                srs=opts.srs, copies=copies, time_scale=time_scale))
    reflex = builder.AddNamedSystem("stretch_reflex", StretchReflex(
        n, np.concatenate([o.per_muscle(base, o.kp) for o in each]), np.concatenate([o.per_muscle(base, o.kv) for o in each]),
        np.tile(_desired_length(base, opts, params_each[0]), copies)))  # fiber lengths: not changed by the strength
    feedforward = opts.feedforward if opts.feedforward is not None else np.full(base.n_muscles, opts.constants.minimum_activation)
    feedforward = np.asarray(feedforward, dtype=float)
    if feedforward.shape != (base.n_muscles,):
        raise ValueError(f"feedforward excitation must have {base.n_muscles} entries (one per muscle), got shape {feedforward.shape}")
    feedforward = np.tile(feedforward, copies)
    ff = builder.AddNamedSystem("feedforward", ConstantVectorSource(feedforward))
    feedback = [reflex.GetOutputPort("feedback")]
    if opts.gto_gain:
        gto = builder.AddNamedSystem("golgi_tendon_feedback", GolgiTendonFeedback(
            opts.gto_gain, params.max_isometric_force, _operating_force(base, feedforward, params, constants)))
        _connect_delayed(builder, muscles.GetOutputPort("tendon_force"), gto.get_input_port(0), opts.reflex_delay, "gto", n)
        feedback.append(gto.get_output_port(0))
    if opts.vestibular_gain:
        vest = builder.AddNamedSystem("trunk_in_space_feedback", TrunkInSpaceFeedback(
            opts.vestibular_gain, _group_mask(base, EXTENSOR_GROUPS), _group_mask(base, FLEXOR_GROUPS), fe, nq + nv))
        builder.Connect(plant.get_state_output_port(), vest.get_input_port(0))
        port = vest.get_output_port(0)
        if opts.vestibular_delay > 0:
            delay = builder.AddNamedSystem("delay_vestibular", TransportDelay(n, opts.vestibular_delay))
            builder.Connect(port, delay.get_input_port(0))
            port = delay.get_output_port(0)
        feedback.append(port)
    mixer = builder.AddNamedSystem("excitation", ExcitationMixer(n, len(feedback), opts.constants.minimum_activation))
    levels = len(base.level_matrix)
    per_level = {f: np.concatenate([np.broadcast_to(np.asarray(getattr(o, f), float), (levels,)) for o in each])
                 for f in ("stiffness", "damping", "cubic")}
    bushings = builder.AddNamedSystem("bushings", IntervertebralBushings(
        nq, nv, np.kron(np.eye(copies), base.level_matrix), per_level["stiffness"], per_level["damping"], cubic=per_level["cubic"]))

    builder.Connect(plant.get_state_output_port(), paths.get_input_port())
    builder.Connect(plant.get_state_output_port(), bushings.get_input_port(0))
    builder.Connect(paths.GetOutputPort("path_state"), muscles.GetInputPort("path_state"))
    delays = np.repeat([o.reflex_delay for o in each], base.n_muscles)
    for name in ("normalized_fiber_length", "normalized_fiber_velocity"):
        _connect_delayed(builder, muscles.GetOutputPort(name), reflex.GetInputPort(name), delays, name, n)
    builder.Connect(ff.get_output_port(), mixer.GetInputPort("feedforward"))
    for k, port in enumerate(feedback):
        builder.Connect(port, mixer.GetInputPort(f"feedback_{k}"))
    builder.Connect(mixer.GetOutputPort("excitation"), muscles.GetInputPort("excitation"))

    forces = [muscles.GetOutputPort("generalized_force"), bushings.GetOutputPort("generalized_force")]
    pert = None
    if pelvis_mode == "prescribed":
        direction = _anterior_direction(base)
        pert = builder.AddNamedSystem("perturbation", PrescribedPelvisMotion(base, perturbation, direction, table, copies))
        builder.Connect(plant.get_state_output_port(), pert.GetInputPort("plant_state"))
        forces.append(pert.GetOutputPort("generalized_force"))
    elif pelvis_mode == "force":
        if perturbation is None:
            raise ValueError("pelvis='force' needs a perturbation signal")
        pert = builder.AddNamedSystem(
            "perturbation", PelvisForcePerturbation(nv, base.coordinates.index("pelvis_tx"), perturbation, opts.pelvis_mass)
        )
        forces.append(pert.GetOutputPort("generalized_force"))
    elif pelvis_mode == "seat":
        pelvis = base.coordinates.index("pelvis_tx") + base.plant.num_positions() * np.arange(copies)
        pert = builder.AddNamedSystem("perturbation", SeatCompliance(
            perturbation, [o.seat_stiffness for o in each], [o.seat_damping for o in each], pelvis, nq, nv))
        builder.Connect(plant.get_state_output_port(), pert.GetInputPort("plant_state"))
        forces.append(pert.GetOutputPort("generalized_force"))
    adder = builder.AddNamedSystem("generalized_force_sum", Adder(len(forces), nv))
    for i, port in enumerate(forces):
        builder.Connect(port, adder.get_input_port(i))
    builder.Connect(adder.get_output_port(), plant.get_applied_generalized_force_input_port())

    loggers = {}

    def log_port(name, port):
        sink = builder.AddNamedSystem(f"log_{name}", VectorLogSink(port.size(), log_period))
        builder.Connect(port, sink.get_input_port())
        loggers[name] = sink

    log_port("state", plant.get_state_output_port())
    for name in log:
        log_port(name, mixer.GetOutputPort(name) if name == "excitation" else muscles.GetOutputPort(name))
    diagram = builder.Build()
    diagram.set_name("trunk")
    return TrunkDiagram(diagram, base, opts, plant, paths, muscles, reflex, bushings, pert, loggers, fe, feedforward, copies)


class CopiesUnsupported(ValueError):
    """This diagram cannot hold copies of its model (`build_trunk_diagram`'s `variants`): simulate one by one."""


def _copies(base, opts: TrunkOptions, pelvis_mode: str, table, variants) -> int:
    """The number of model copies `variants` asks for, checked against what copies support."""
    if variants is None:
        return 1
    if not variants:
        raise ValueError("variants is empty: give at least one dict of option fields (e.g. {'kp': ..., 'kv': ...})")
    for k, variant in enumerate(variants):
        other = set(variant) - set(VARIANT_FIELDS)
        if other:
            raise ValueError(f"variants[{k}] sets {sorted(other)}: copies of the model may differ in {list(VARIANT_FIELDS)} only")
    unsupported = _unsupported(opts, pelvis_mode, table)
    delays = [v.get("reflex_delay", opts.reflex_delay) for v in variants]
    if any(d > 0 for d in delays) and not all(d > 0 for d in delays):
        unsupported.append("reflex delays all positive or all zero")
    if unsupported:
        raise CopiesUnsupported(f"copies of the model (variants) need {'; '.join(unsupported)}; simulate them one by one")
    return len(variants)


def _parameters_each(base, each: list[TrunkOptions]) -> list:
    """Each copy's muscle parameters (computed once per strength scale)."""
    by_scale = {}
    for o in each:
        if o.strength_scale not in by_scale:
            by_scale[o.strength_scale] = muscle_parameters(base, o.strength_scale)
    return [by_scale[o.strength_scale] for o in each]


def _joined(params_each: list):
    """The muscle parameters of copies one after another."""
    fields = dataclasses.asdict(params_each[0])
    return type(params_each[0])(**{k: np.concatenate([getattr(p, k) for p in params_each]) for k in fields})


def _activation_constants(base, constants, scales: list[float]):
    """(constants, time scale per muscle or None): one scale for all copies is folded into the activation time
    constants; copies with scales of their own keep the constants and scale per muscle."""
    for scale in scales:
        if not scale > 0:
            raise ValueError(f"activation_scale must be > 0, got {scale}")
    if len(set(scales)) > 1:
        return constants, np.repeat(scales, base.n_muscles)
    if scales[0] == 1.0:
        return constants, None
    return replace(constants, activation_time_constant=constants.activation_time_constant * scales[0],
                   deactivation_time_constant=constants.deactivation_time_constant * scales[0]), None


def copies_unsupported(model, options: TrunkOptions) -> list[str]:
    """What keeps a perturbed simulation of `model` with `options` from copies of the model in one diagram
    (`variants`): empty if nothing does. Callers group their runs by it instead of learning it from a failure."""
    table = coordinate_table(plant_model_for(model, "prescribed")) if options.tables and model.dofs != "spine3d" else None
    return _unsupported(options, options.pelvis, table)


def _unsupported(opts: TrunkOptions, pelvis_mode: str, table) -> list[str]:
    return [what for what, bad in [
        ("a model with one coordinate (the rhythm, on the prescribed pelvis or the seat) and its table (TrunkOptions.tables)", table is None),
        ("the prescribed pelvis, the seat or none", pelvis_mode not in ("prescribed", "seat", "none")), ("rigid tendons", opts.tendon != "rigid"),
        ("no Golgi tendon or trunk-in-space feedback", bool(opts.gto_gain or opts.vestibular_gain)),
        ("no muscle mask and no short-range stiffness", opts.muscle_mask is not None or opts.srs is not None)] if bad]


def release(diagram: Diagram | DiagramBuilder) -> None:
    """Let Python free a finished diagram, or the builder of one whose build failed: nothing of it (systems,
    ports, contexts) may be used afterwards.

    pydrake (measured on 1.51.1) never frees a diagram holding a Python LeafSystem: the reference cycles between
    builder, diagram, systems, ports and cache entries pass through C++ where the garbage collector cannot see
    them (drake issues #22515, #23161, #24162). Each simulation left ~11 MB behind, a gap diagnosis of 450
    simulations 5 GB. This drops the Python attributes of the diagram and its systems, where pydrake keeps its
    side of those cycles; our systems' callbacks hold their system weakly (`systems.weak`), so nothing else
    keeps it. tests/test_diagram.py checks that a simulation's systems are freed."""
    for system in diagram.GetSystems():
        if isinstance(system, Diagram):
            release(system)
        system.__dict__.clear()
    diagram.__dict__.clear()


def muscle_systems_alive() -> int:
    """How many MuscleSystems Python still holds after a garbage collection: unchanged by a simulation
    once its diagram is released (`release`); tests/test_diagram.py and benchmarks/memory.py count them."""
    gc.collect()
    return sum(type(item) is MuscleSystem for item in gc.get_objects())


def _connect_delayed(builder, source, destination, delay, name: str, size: int) -> None:
    """Connect `source` to `destination`, through a TransportDelay when `delay` (s; one, or one per element) > 0."""
    if np.all(np.asarray(delay) > 0):
        block = builder.AddNamedSystem(f"delay_{name}", TransportDelay(size, delay))
        builder.Connect(source, block.get_input_port(0))
        source = block.get_output_port(0)
    builder.Connect(source, destination)


def _group_mask(model, groups) -> np.ndarray:
    members = {m for g in groups if g in model.groups for m in model.groups[g]}
    return np.array([m in members for m in model.muscles], dtype=float)


def _operating_force(model, feedforward, params, constants) -> np.ndarray:
    """Rigid-tendon forces at the neutral posture with the feed-forward activation."""
    from trunk_drake.muscle import thelen

    zeros = np.zeros(len(model.coordinates))
    path = model.path_state(zeros, zeros)
    return thelen.rigid_tendon(feedforward, path.lengths, path.velocities, params, constants).tendon_force


def _anterior_direction(model) -> np.ndarray:
    """World direction of the pelvis' anterior (x) axis at the default posture."""
    plant = model.plant
    context = plant.CreateDefaultContext()
    return plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(model.spec.pelvis)).rotation().matrix()[:, 0]
