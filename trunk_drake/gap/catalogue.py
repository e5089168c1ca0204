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


@dataclass(frozen=True)
class Effect:
    """One candidate effect: `apply(options, values)` switches it on with the physical
    parameter values (a dict by parameter name)."""

    name: str
    description: str
    parameters: tuple[Parameter, ...]
    apply: Callable[[TrunkOptions, dict], TrunkOptions]
    note: str = ""
    # nonlinear in amplitude: the screening sees only its statistically linearised stiffness, not the
    # shift of the operating point it causes, so the search always refines it with nonlinear simulations
    amplitude_dependent: bool = False

    def values(self, x) -> dict[str, float]:
        return {p.name: p.value(v) for p, v in zip(self.parameters, x)}


def _replace(**fields) -> Callable[[TrunkOptions, dict], TrunkOptions]:
    """An `apply` that sets option fields to parameter values: field=parameter name."""
    return lambda options, values: dataclasses.replace(options, **{f: values[p] for f, p in fields.items()})


def _seat(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, pelvis="seat", seat_stiffness=values["stiffness"], seat_damping=values["damping"])


def _extra_damping(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, damping=np.asarray(options.damping, float) + values["damping"])


CATALOGUE: tuple[Effect, ...] = (
    Effect("reflex_delay", "transport delay of the spinal stretch (and Golgi) reflex loop",
           (Parameter("delay", 0.0, 0.12, 0.02, unit="s"),), _replace(reflex_delay="delay"),
           "0-120 ms spans short- and long-latency trunk reflexes (modelling choice; see models/reference_values.toml [reflex])"),
    Effect("golgi_feedback", "Golgi tendon organ (autogenic force) feedback",
           (Parameter("gain", 0.0, 1.0, 0.05, unit="excitation per F_max"),), _replace(gto_gain="gain"),
           "inhibitory force feedback on each muscle's own force change; gain bound is a modelling choice"),
    Effect("trunk_in_space", "vestibular/visual trunk-orientation feedback onto extensors and flexors",
           (Parameter("gain", 0.0, 1.0, 0.05, unit="excitation per rad"), Parameter("delay", 0.03, 0.3, 0.12, unit="s")),
           _replace(vestibular_gain="gain", vestibular_delay="delay"),
           "bounds are a modelling choice (vestibular/visual latencies are longer than spinal ones)"),
    Effect("stiffening_discs", "nonlinear, stiffening intervertebral moment-angle law M = -k (q + c q^3)",
           (Parameter("cubic", 0.0, 2000.0, 50.0, unit="1/rad^2"),), _replace(cubic="cubic"),
           "at 0.05 rad, c = 2000 triples the stiffness; amplitude-dependent, so trials of different size separate it from a stiffness error",
           amplitude_dependent=True),
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
)


def effect(name: str) -> Effect:
    for e in CATALOGUE:
        if e.name == name:
            return e
    raise ValueError(f"unknown effect {name!r}; candidates: {[e.name for e in CATALOGUE]}")
