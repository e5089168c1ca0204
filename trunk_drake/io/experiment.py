"""A data set on disk: measured trials plus the experimental conditions known to the fit."""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trunk_drake.signals import DEFAULT_FADE_S, DEFAULT_PERIOD_S

from .trials import Trial, load_trial

TRIAL_SUFFIXES = (".csv", ".sto", ".mot")
CONDITIONS_FILE = "conditions.toml"


@dataclass
class Experiment:
    """Trials and conditions. `options` are TrunkOptions overrides (stiffness, damping, ...)."""

    trials: list[Trial]
    options: dict = field(default_factory=dict)
    noise_rad: float | None = None  # angle measurement noise from the conditions, if given
    period: float = DEFAULT_PERIOD_S
    fade: float = DEFAULT_FADE_S
    coactivation_min_activation: float | None = None
    preset: str | None = None  # the passenger preset the data were taken with (models/presets/), if stated
    source: str = ""

    def model(self, dofs: str | None = None):
        """The model these data need: the preset's passenger and configuration (`dofs` overrides it),
        or bare MyoTorso in `dofs` (default "sagittal") when the conditions name no preset."""
        if self.preset is None:
            from trunk_drake.model.trunk_model import load_model

            return load_model(dofs or "sagittal")
        from trunk_drake.presets import load_preset

        return load_preset(self.preset).model(dofs)

    def preset_gains(self) -> dict | None:
        """The reflex gains of the data's preset (the fit's natural start); None without a preset or its reflexes."""
        if self.preset is None:
            return None
        from trunk_drake.presets import load_preset

        preset = load_preset(self.preset)
        return preset.gains() if preset.reflex_gains is not None else None


def load_experiment(paths, conditions: str | None = None) -> Experiment:
    """Trials from files and/or folders (every .csv/.sto/.mot inside), and the conditions from
    `conditions` or a `conditions.toml` next to the data (defaults otherwise)."""
    files: list[Path] = []
    folders: list[Path] = []
    for p in map(Path, [paths] if isinstance(paths, (str, Path)) else paths):
        if p.is_dir():
            folders.append(p)
            files += sorted(f for f in p.iterdir() if f.suffix in TRIAL_SUFFIXES and not f.name.startswith("truth"))
        elif p.exists():
            files.append(p)
        else:
            raise FileNotFoundError(f"data path {p} does not exist")
    if not files:
        raise ValueError(f"no trial files ({', '.join(TRIAL_SUFFIXES)}) in {[str(p) for p in paths]}")
    trials = [load_trial(f) for f in files]
    rates = {f.name: round(t.fs, 6) for f, t in zip(files, trials)}
    if len(set(rates.values())) > 1:
        raise ValueError("the trials have different sampling rates (" + ", ".join(f"{n}: {r:g} Hz" for n, r in rates.items())
                         + "): resample them to one rate (trunk_drake.signals.resample_uniform) before loading them together")
    beside = [*folders, *(f.parent for f in files)]
    cond_path = Path(conditions) if conditions else next((d / CONDITIONS_FILE for d in beside if (d / CONDITIONS_FILE).exists()), None)
    experiment = Experiment(trials, source=", ".join(map(str, files)))
    if cond_path is not None:
        _apply_conditions(experiment, cond_path)
    return experiment


def _apply_conditions(experiment: Experiment, path: Path) -> None:
    table = tomllib.loads(path.read_text()).get("conditions")
    if table is None:
        raise ValueError(f"{path} has no [conditions] table")
    options = {}
    for key in ("stiffness", "damping", "l_desired", "reflex_delay", "tendon", "pelvis"):
        if key in table:
            options[key] = table[key]
    if table.get("srs"):
        from trunk_drake.muscle.short_range import ShortRangeStiffness

        options["srs"] = ShortRangeStiffness.from_reference()
    if "feedforward_file" in table:
        ff_path = path.parent / table["feedforward_file"]
        options["feedforward"] = np.loadtxt(ff_path, delimiter=",", skiprows=1, usecols=1)
    experiment.options = options
    if "noise_deg" in table:
        experiment.noise_rad = float(np.radians(table["noise_deg"]))
    experiment.period = float(table.get("period_s", experiment.period))
    experiment.fade = float(table.get("fade_s", experiment.fade))
    experiment.coactivation_min_activation = table.get("coactivation_min_activation")
    experiment.preset = table.get("preset")
    experiment.source += f" (conditions: {path})"
