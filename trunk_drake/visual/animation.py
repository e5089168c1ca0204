"""Pages of the passenger: `animate` (a simulation as a standalone HTML recording), `view_html`
(the model at rest) and `serve` (a live Meshcat with a slider per coordinate)."""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

import numpy as np
from pydrake.geometry import MeshcatAnimation

from trunk_drake.visual.geometry import Drawing
from trunk_drake.visual.measured import MeasuredMotion, measured_motion
from trunk_drake.visual.page import (
    activation_legend,
    activation_scale,
    ghost_legend,
    group_legend,
    player_data,
    standalone_html,
    write_page,
)
from trunk_drake.visual.scene import (
    BONE_RGBA,
    DATA_GHOST_RGBA,
    GROUP_RGB,
    MODEL_GHOST_RGBA,
    OTHER_GROUP_RGB,
    PassengerScene,
    Platform,
)

CAMERA_DISTANCE = 1.1  # m from the mid-trunk, looking from front-left


def animate(result, path, model=None, title: str | None = None, measured: MeasuredMotion | None = None) -> Path:
    """Write `result` (a SimulationResult) as a self-contained HTML page that plays it in real
    time: bones, muscle lines coloured by activation, platform; play/pause and a time slider
    under "Open Controls" > Animations. One animation frame per result sample. With `measured`
    (see `measured_motion`) a second, blue trunk moves as the data do, over the model's."""
    model = model or _default_model()
    fps = _frame_rate(result.time)
    q = model_positions(model, result.coordinates, result.q)
    drawing = Drawing(model)
    motion = drawing.motion(q)
    meshcat = _meshcat()
    scene = PassengerScene(meshcat, drawing, rgba=BONE_RGBA if measured is None else MODEL_GHOST_RGBA)
    scene.pose(q[0])  # the player colours the muscles by activation
    platform = Platform(meshcat, drawing)
    _look_at_trunk(meshcat, drawing)
    animation = MeshcatAnimation(frames_per_second=fps)
    animation.set_autoplay(True)
    scene.record(animation, motion)
    platform.record(animation, result.platform[:, 0])
    legend = activation_legend(activation_scale(result.activation))
    if measured is not None:
        data_q = model_positions(model, measured.coordinates, measured.at(result.time))
        ghost = PassengerScene(meshcat, drawing, figure="data", muscles=False, rgba=DATA_GHOST_RGBA)
        ghost.pose(data_q[0])
        ghost.record(animation, drawing.motion(data_q))
        legend = ghost_legend(measured.label, measured.note, MODEL_GHOST_RGBA, DATA_GHOST_RGBA) + legend
    meshcat.SetAnimation(animation)
    title = title or f"trunk-drake simulation, {result.time[-1] - result.time[0]:g} s"
    player = player_data(fps, scene.segment_paths, scene.muscle_paths, drawing.vertices(), motion.wrap_points, result.activation)
    return write_page(standalone_html(meshcat, title, legend, player), path)


def animate_trial(trial, path, model=None, options=None, title: str | None = None, label: str | None = None):
    """Simulate a trial's platform (or pelvis) motion with `options` (TrunkOptions) and write its
    page: the model with its muscles, and the trial's measured trunk over it."""
    from trunk_drake.signals.sampled import SampledSignal
    from trunk_drake.simulation import simulate

    x = trial.platform_displacement if trial.platform_displacement is not None else trial.pelvis_displacement
    if x is None:
        raise ValueError(f"trial {trial.source or ''} has no platform or pelvis displacement to simulate; "
                         "an animation of data against the model needs the perturbation")
    model = model or _default_model()
    t = np.asarray(trial.time, dtype=float) - trial.time[0]
    result = simulate(model, perturbation=SampledSignal(t, x - x[0]), duration=float(t[-1]), options=options)
    measured = measured_motion(trial, label)
    pelvis = measured.coordinates.index("pelvis_tx")
    measured.q[:, pelvis] -= measured.q[0, pelvis]  # as the simulated platform: from 0
    return animate(result, path, model, title, measured=dataclasses.replace(measured, time=t))


def view_html(path, model=None, q=None, title: str | None = None) -> Path:
    """The model at rest (or at q) as a standalone HTML page, muscles coloured by group."""
    model = model or _default_model()
    drawing = Drawing(model)
    meshcat = _meshcat()
    scene = PassengerScene(meshcat, drawing)
    if q is not None:
        scene.pose(q)
    Platform(meshcat, drawing)
    _look_at_trunk(meshcat, drawing)
    title = title or f"trunk-drake: MyoTorso, {model.dofs} configuration, {model.n_muscles} muscles"
    return write_page(standalone_html(meshcat, title, group_legend(_groups(model))), path)


class LiveView:
    """A live Meshcat of the model with one slider per coordinate; `update()` re-poses it."""

    def __init__(self, model=None, port: int | None = None):
        self.model = model or _default_model()
        self.meshcat = _meshcat(port)
        self.drawing = Drawing(self.model)
        self.scene = PassengerScene(self.meshcat, self.drawing)
        Platform(self.meshcat, self.drawing)
        _look_at_trunk(self.meshcat, self.drawing)
        for c in self.model.coordinate_info:
            low, high = (-0.2, 0.2) if c.source_joint is None else c.range
            self.meshcat.AddSlider(c.name, low, high, (high - low) / 200, 0.0)
        self.q = np.zeros(len(self.model.coordinates))

    @property
    def url(self) -> str:
        return self.meshcat.web_url()

    def update(self) -> bool:
        """Pose the model at the sliders' values if they changed; True if it did."""
        q = np.array([self.meshcat.GetSliderValue(c) for c in self.model.coordinates])
        if np.array_equal(q, self.q):
            return False
        self.q = q
        self.scene.pose(q)
        return True


def serve(model=None, port: int | None = None, duration: float | None = None, poll_s: float = 0.05) -> None:
    """Run a live Meshcat of the model until Ctrl-C (or for `duration` seconds)."""
    live = LiveView(model, port)
    print(f"Meshcat: open {live.url} (sliders under Open Controls); Ctrl-C to stop", flush=True)
    end = None if duration is None else time.monotonic() + duration
    try:
        while end is None or time.monotonic() < end:
            live.update()
            time.sleep(poll_s)
    except KeyboardInterrupt:
        pass


def model_positions(model, coordinates, q) -> np.ndarray:
    """Rows of q (named `coordinates`) as the model's positions; missing coordinates stay 0. Level
    angles of a model whose coordinates move the levels together (the rhythm) become the coordinates
    that fit them best (least squares through `model.level_matrix`)."""
    q = np.asarray(q, dtype=float)
    levels = [c for c in coordinates if c not in model.coordinates and c in model.levels]
    unknown = [c for c in coordinates if c not in model.coordinates and c not in levels]
    if unknown:
        raise ValueError(f"the result has coordinates {unknown} that the {model.dofs!r} model lacks "
                         f"(its coordinates: {model.coordinates}); pass the model it was simulated with")
    out = np.zeros((len(q), len(model.coordinates)))
    for k, c in enumerate(coordinates):
        if c in model.coordinates:
            out[:, model.coordinates.index(c)] = q[:, k]
    if levels:
        L = model.level_matrix[[model.levels.index(c) for c in levels]]
        moved = np.flatnonzero(np.abs(L).sum(axis=0) > 0)
        angles = q[:, [coordinates.index(c) for c in levels]]
        out[:, moved] = np.linalg.lstsq(L[:, moved], angles.T, rcond=None)[0].T
    return out


def _frame_rate(t) -> float:
    dt = np.diff(np.asarray(t, dtype=float))
    if len(dt) == 0 or dt.min() <= 0 or np.ptp(dt) > 1e-6 * dt.mean():
        raise ValueError("an animation needs a result sampled on a uniform time grid of at least two samples "
                         f"(got {len(t)} samples, steps {dt.min() if len(dt) else 0:.3g}-{dt.max() if len(dt) else 0:.3g} s)")
    return float(1.0 / dt.mean())


def _default_model():
    from trunk_drake.model.trunk_model import load_model

    return load_model("sagittal")


def _meshcat(port: int | None = None):
    """A Meshcat server on localhost (its own "listening" log line silenced: pages are files,
    and `serve` prints the address itself)."""
    from pydrake.geometry import Meshcat, MeshcatParams

    drake_log = logging.getLogger("drake")
    level = drake_log.level
    drake_log.setLevel(logging.WARNING)
    try:
        meshcat = Meshcat(MeshcatParams(host="localhost", port=port))
    finally:
        drake_log.setLevel(level)
    meshcat.SetProperty("/Axes", "visible", False)
    meshcat.SetProperty("/Grid", "visible", False)
    return meshcat


def _look_at_trunk(meshcat, drawing: Drawing) -> None:
    """Camera from the passenger's front-left, aimed at the middle of the trunk."""
    names = drawing.model.body_names
    R, p = drawing.poses(np.zeros(drawing.model.plant.num_positions()))
    sacrum, head = names.index("sacrum"), names.index("head")
    target = (p[sacrum] + p[head]) / 2
    anterior, left = R[sacrum][:, 0], -R[sacrum][:, 2]  # sacrum frame: x anterior, z right
    direction = 0.55 * anterior + 0.8 * left + np.array([0.0, 0.0, 0.15])
    meshcat.SetCameraPose(target + CAMERA_DISTANCE * direction / np.linalg.norm(direction), target)


def _groups(model) -> dict[str, tuple]:
    return {g: GROUP_RGB.get(g, OTHER_GROUP_RGB) for g in model.groups}
