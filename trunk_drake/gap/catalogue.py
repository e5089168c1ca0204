"""Catalogue of candidate unmodelled effects: parameters, bounds, and how each switches on in the
diagram's options (TrunkOptions). The linearised model takes the same options, so the mapping
serves the time-domain simulations and the linear screening alike.

Bounds are deliberately wide physiological ranges; where a number could be sourced it is
cited in models/reference_values.toml, otherwise the note says it is a modelling choice.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from trunk_drake.diagram import TrunkOptions
from trunk_drake.muscle.short_range import ShortRangeStiffness


@dataclass(frozen=True)
class Parameter:
    name: str
    lower: float  # bounds in the fitted (possibly log10) scale
    upper: float
    start: float
    log10: bool = False  # fitted as log10 of the physical value
    unit: str = ""

    def value(self, x: float) -> float:
        return 10.0 ** x if self.log10 else x

    def coordinate(self, value: float) -> float:
        """The fitted coordinate of a physical value (the inverse of `value`)."""
        return float(np.log10(value)) if self.log10 else value


@dataclass(frozen=True)
class Effect:
    """One candidate effect: `apply(options, values)` switches it on with the physical
    parameter values (a dict by parameter name)."""

    name: str
    description: str
    parameters: tuple[Parameter, ...]
    apply: Callable[[TrunkOptions, dict], TrunkOptions]
    note: str = ""

    def values(self, x) -> dict[str, float]:
        return {p.name: p.value(v) for p, v in zip(self.parameters, x)}

    def coordinates(self, values: dict) -> list[float]:
        """The fitted coordinates of physical `values` by parameter name (the inverse of `values`)."""
        return [p.coordinate(values[p.name]) for p in self.parameters]


def _replace(**fields) -> Callable[[TrunkOptions, dict], TrunkOptions]:
    """An `apply` that sets option fields to parameter values: field=parameter name."""
    return lambda options, values: dataclasses.replace(options, **{f: values[p] for f, p in fields.items()})


def _seat(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, pelvis="seat", seat_stiffness=values["stiffness"], seat_damping=values["damping"])


def _extra_damping(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, damping=np.asarray(options.damping, float) + values["damping"])


def _bushing_stiffness(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, stiffness=np.asarray(options.stiffness, float) * values["scale"])


def _strength(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, strength_scale=options.strength_scale * values["scale"])


def _short_range_stiffness(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, srs=dataclasses.replace(ShortRangeStiffness.from_reference(), gain=values["gain"]))


CATALOGUE: tuple[Effect, ...] = (
    Effect("reflex_delay", "transport delay of the spinal stretch (and Golgi) reflex loop",
           (Parameter("delay", 0.01, 0.12, 0.02, unit="s"),), _replace(reflex_delay="delay"),
           "10-120 ms spans short- and long-latency trunk reflexes (modelling choice; see models/reference_values.toml "
           "[reflex]); the lower bound also bounds the simulations' cost: simulate keeps its maximum step below the "
           "shortest delay, so a delay fitted towards 0 s would need ever shorter steps"),
    Effect("golgi_feedback", "Golgi tendon organ (autogenic force) feedback",
           (Parameter("gain", 0.0, 1.0, 0.05, unit="excitation per F_max"),), _replace(gto_gain="gain"),
           "inhibitory force feedback on each muscle's own force change; gain bound is a modelling choice"),
    Effect("trunk_in_space", "vestibular/visual trunk-orientation feedback onto extensors and flexors",
           (Parameter("gain", 0.0, 1.0, 0.05, unit="excitation per rad"), Parameter("delay", 0.03, 0.3, 0.12, unit="s")),
           _replace(vestibular_gain="gain", vestibular_delay="delay"),
           "bounds are a modelling choice (vestibular/visual latencies are longer than spinal ones)"),
    Effect("stiffening_discs", "nonlinear, stiffening intervertebral moment-angle law M = -k (q + c q^3)",
           (Parameter("cubic", 0.0, 2000.0, 50.0, unit="1/rad^2"),), _replace(cubic="cubic"),
           "at 0.05 rad, c = 2000 triples the stiffness; amplitude-dependent, so trials of different size separate it from "
           "a stiffness error (the screening linearises it over each trial's own RMS angle)"),
    Effect("seat_compliance", "pelvis-seat compliance: the pelvis does not follow the platform exactly",
           (Parameter("stiffness", 3.0, 6.0, 5.0, log10=True, unit="N/m"), Parameter("damping", 1.0, 4.0, 2.5, log10=True, unit="N s/m")),
           _seat,
           "spring-damper between platform and pelvis (pelvis mass: the model's sacrum)"),
    Effect("slow_activation", "slower excitation-activation dynamics",
           (Parameter("scale", 1.0, 5.0, 1.2, unit="x time constants"),), _replace(activation_scale="scale"),
           "multiplies both Thelen activation time constants"),
    Effect("extra_damping", "extra passive intervertebral damping",
           (Parameter("damping", 0.0, 30.0, 1.0, unit="Nms/rad per level"),), _extra_damping,
           "added to every lumbar level's bushing damping"),
    Effect("bushing_stiffness", "mis-set (linear) intervertebral bushing stiffness",
           (Parameter("scale", -0.5, 0.5, 0.05, log10=True, unit="x nominal stiffness"),), _bushing_stiffness,
           "multiplies every level's bushing stiffness; a factor 3 either way spans the spread of in vitro lumbar "
           "segment stiffness around the thesis' value (modelling choice; the thesis swept it over a wide range too: models/reference_values.toml [intervertebral.thesis_sweep])"),
    Effect("muscle_strength", "muscle strength scale (specific tension / maximum isometric forces)",
           (Parameter("scale", -0.3, 0.3, 0.05, log10=True, unit="x maximum isometric forces"),), _strength,
           "multiplies every muscle's maximum isometric force; a factor 2 either way (modelling choice: published "
           "specific tensions differ about twofold)"),
    Effect("upper_body_mass", "upper-body mass error (thorax body)",
           (Parameter("scale", 0.7, 1.4, 1.05, unit="x thorax mass and inertia"),), _replace(upper_body_mass_scale="scale"),
           "scales the thorax body's mass and inertia (bounds: modelling choice covering arms, clothing and anthropometric "
           "spread; a centre-of-mass shift was left out: 1 cm moves this model's posture by 2.5 deg per level and its "
           "response far beyond a linearisation)"),
    Effect("short_range_stiffness", "short-range stiffness of active muscle (cross-bridge stiffness)",
           (Parameter("gain", 1.0, 3.3, 2.0, log10=True, unit="F_max per l_opt at full activation"),), _short_range_stiffness,
           "De Groote et al. (2017) SRS with the constants of models/reference_values.toml [muscle.srs] except the gain, "
           "fitted over 10-2000 (reference value 280)"),
)


def effect(name: str) -> Effect:
    for e in CATALOGUE:
        if e.name == name:
            return e
    raise ValueError(f"unknown effect {name!r}; candidates: {[e.name for e in CATALOGUE]}")
