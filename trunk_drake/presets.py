"""Named passenger presets: a whole configuration (model and diagram options) with a source per number.

A preset is a TOML file in `models/presets/` (or any path): one table per setting, each with a
``value`` and one of ``reference`` (a key of `models/reference_values.toml` whose value it must
equal), ``source`` (a cited file of `models/`) or ``choice`` (a modelling choice and its reason). `Preset.model()` builds the model and
`Preset.options(model)` the `TrunkOptions` (co-activation by static optimisation on that model).
The commands use the ``default`` preset unless told otherwise; ``thesis`` is the thesis' final
configuration on MyoTorso.
"""

from __future__ import annotations

import dataclasses
import tomllib
from dataclasses import dataclass
from pathlib import Path

from trunk_drake.data import load_toml, models_dir

DEFAULT_PRESET = "default"
SETTINGS = ("dofs", "passenger", "stiffness", "damping", "coactivation", "reflex_gains", "gain_scale", "l_desired",
            "srs", "reflex_delay")


@dataclass(frozen=True)
class Preset:
    """One passenger configuration; `provenance` says where each setting comes from."""

    name: str
    description: str
    dofs: str
    passenger: dict | None  # Passenger fields, or None: MyoTorso's own upper body
    stiffness: float  # bushing stiffness per lumbar level, Nm/rad
    damping: float  # Nms/rad
    coactivation: float  # minimum activation of the static-optimisation co-activation at rest
    reflex_gains: str | None  # "FILE#set" under models/, or None: no stretch reflex
    gain_scale: float  # multiplies every reflex gain of that set
    l_desired: float | str  # reflex set point: a normalised fiber length or "neutral"
    srs: bool  # short-range stiffness of active muscle
    reflex_delay: float  # s
    provenance: dict

    def model(self, dofs: str | None = None, **load_options):
        """The preset's model (another configuration with `dofs`)."""
        from trunk_drake.model.anthropometry import Passenger
        from trunk_drake.model.trunk_model import load_model

        passenger = Passenger(**self.passenger) if self.passenger else None
        return load_model(dofs or self.dofs, passenger=passenger, **load_options)

    def gains(self) -> dict:
        """{"kp": {group: gain}, "kv": {...}} scaled by `gain_scale` (zeros without reflexes)."""
        if self.reflex_gains is None:
            return {"kp": 0.0, "kv": 0.0}
        from trunk_drake.simulation import load_reflex_gains

        gains = load_reflex_gains(models_dir() / self.reflex_gains)
        return {kind: {g: self.gain_scale * v for g, v in values.items()} for kind, values in gains.items()}

    def options(self, model, **overrides):
        """`TrunkOptions` for `model`: feed-forward co-activation, reflexes, bushings; `overrides` win."""
        from trunk_drake.diagram import TrunkOptions
        from trunk_drake.muscle.short_range import ShortRangeStiffness
        from trunk_drake.optim.static import coactivation

        fields = {"stiffness": self.stiffness, "damping": self.damping, "l_desired": self.l_desired,
                  "reflex_delay": self.reflex_delay, "srs": ShortRangeStiffness.from_reference() if self.srs else None,
                  **self.gains()}
        fields.update(overrides)
        if "feedforward" not in fields:
            fields["feedforward"] = coactivation(model, self.coactivation)
        return TrunkOptions(**fields)

    def with_changes(self, **changes) -> "Preset":
        """A copy with some settings replaced (their provenance becomes "set by the user")."""
        unknown = set(changes) - set(SETTINGS)
        if unknown:
            raise ValueError(f"unknown preset settings {sorted(unknown)}; settings: {list(SETTINGS)}")
        provenance = {**self.provenance, **{k: "set by the user" for k in changes}}
        return dataclasses.replace(self, name=f"{self.name} (modified)", provenance=provenance, **changes)

    def summary(self) -> dict:
        return {"name": self.name, "description": self.description,
                "settings": {k: {"value": getattr(self, k), "from": self.provenance[k]} for k in SETTINGS}}


def preset_names() -> list[str]:
    """The names of the presets in `models/presets/`."""
    return sorted(p.stem for p in (models_dir() / "presets").glob("*.toml"))


def preset_path(name_or_path: str) -> Path:
    """`models/presets/NAME.toml` for a name, else the path itself."""
    path = Path(name_or_path)
    if path.suffix != ".toml":
        path = models_dir() / "presets" / f"{name_or_path}.toml"
    if not path.is_file():
        raise FileNotFoundError(f"preset {name_or_path!r} not found (looked for {path}); presets: {preset_names()}, "
                                "or a .toml path")
    return path


def load_preset(name_or_path: str = DEFAULT_PRESET) -> Preset:
    """A preset by name (`models/presets/`) or from a TOML file; every setting is checked."""
    path = preset_path(name_or_path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise ValueError(f"preset {path}: not valid TOML ({err})") from None
    values, provenance = {}, {}
    for key in SETTINGS:
        entry = data.get(key)
        if not isinstance(entry, dict) or "value" not in entry:
            raise ValueError(f"preset {path}: [{key}] with a 'value' is missing")
        values[key], provenance[key] = entry["value"], _provenance(path, key, entry)
    for key in ("passenger", "reflex_gains"):
        if values[key] in ("none", ""):
            values[key] = None
    return Preset(name=data.get("name", path.stem), description=data.get("description", ""), provenance=provenance, **values)


def _provenance(path: Path, key: str, entry: dict) -> str:
    """Where a setting comes from: a reference value it equals, or a stated modelling choice."""
    if "reference" in entry:
        reference = _reference_value(entry["reference"])
        if reference != entry["value"]:
            raise ValueError(f"preset {path}: [{key}] value {entry['value']!r} differs from its reference "
                             f"{entry['reference']} = {reference!r}")
        return f"models/reference_values.toml {entry['reference']}"
    if entry.get("source", "").strip():
        return entry["source"].strip()
    if entry.get("choice", "").strip():
        return f"modelling choice: {entry['choice'].strip()}"
    raise ValueError(f"preset {path}: [{key}] needs 'reference' (a key of models/reference_values.toml), "
                     "'source' (a cited file in models/) or 'choice' (the reason for a modelling choice)")


def _reference_value(key: str):
    node = load_toml("reference_values.toml")
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            raise ValueError(f"reference {key!r} is not a key of models/reference_values.toml")
        node = node[part]
    return node["value"] if isinstance(node, dict) and "value" in node else node
