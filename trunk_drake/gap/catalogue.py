"""Catalogue of candidate unmodelled effects: parameters, bounds, and how each enters the
time-domain diagram (TrunkOptions) and the linearised model (LinearParams).

Bounds are deliberately wide physiological ranges; where a number could be sourced it is
cited in models/reference_values.toml, otherwise the note says it is a modelling choice.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from trunk_drake.diagram import TrunkOptions
from trunk_drake.gap.linear import LinearParams


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
    """One candidate effect; `apply_*` take the physical parameter values as a dict."""

    name: str
    description: str
    parameters: tuple[Parameter, ...]
    note: str = ""
    # nonlinear in amplitude: the screening sees only its statistically linearised stiffness, not the
    # shift of the operating point it causes, so the search always refines it with nonlinear simulations
    amplitude_dependent: bool = False

    def values(self, x) -> dict[str, float]:
        return {p.name: p.value(v) for p, v in zip(self.parameters, x)}

    def apply_options(self, options: TrunkOptions, values: dict) -> TrunkOptions:
        return _OPTIONS[self.name](options, values)

    def apply_linear(self, params: LinearParams, values: dict, amplitude: np.ndarray, stiffness: np.ndarray) -> LinearParams:
        """`amplitude` (rad, per level) and `stiffness` (Nm/rad, per level) describe the trial's
        operating range for the amplitude-dependent (statistically linearised) effects."""
        return _LINEAR[self.name](params, values, amplitude, stiffness)

    @property
    def needs_seat(self) -> bool:
        return self.name == "seat_compliance"


_OPTIONS = {
    "reflex_delay": lambda o, v: dataclasses.replace(o, reflex_delay=v["delay"]),
    "golgi_feedback": lambda o, v: dataclasses.replace(o, gto_gain=v["gain"]),
    "trunk_in_space": lambda o, v: dataclasses.replace(o, vestibular_gain=v["gain"], vestibular_delay=v["delay"]),
    "stiffening_discs": lambda o, v: dataclasses.replace(o, cubic=v["cubic"]),
    "seat_compliance": lambda o, v: dataclasses.replace(o, pelvis="seat", seat_stiffness=v["stiffness"], seat_damping=v["damping"]),
    "slow_activation": lambda o, v: dataclasses.replace(o, activation_scale=v["scale"]),
    "extra_damping": lambda o, v: dataclasses.replace(o, damping=np.asarray(o.damping, float) + v["damping"]),
}

_LINEAR = {
    "reflex_delay": lambda p, v, amp, k: dataclasses.replace(p, reflex_delay=v["delay"]),
    "golgi_feedback": lambda p, v, amp, k: dataclasses.replace(p, gto_gain=v["gain"]),
    "trunk_in_space": lambda p, v, amp, k: dataclasses.replace(p, vestibular_gain=v["gain"], vestibular_delay=v["delay"]),
    # M = -k (dq + c dq^3): statistical linearisation of dq^3 for a Gaussian-like signal about 0: 3 E[dq^2] dq
    "stiffening_discs": lambda p, v, amp, k: dataclasses.replace(p, extra_stiffness=k * 3.0 * v["cubic"] * amp**2),
    "seat_compliance": lambda p, v, amp, k: dataclasses.replace(p, seat_stiffness=v["stiffness"], seat_damping=v["damping"]),
    "slow_activation": lambda p, v, amp, k: dataclasses.replace(p, activation_scale=v["scale"]),
    "extra_damping": lambda p, v, amp, k: dataclasses.replace(p, extra_damping=p.extra_damping + v["damping"]),
}

CATALOGUE: tuple[Effect, ...] = (
    Effect("reflex_delay", "transport delay of the spinal stretch (and Golgi) reflex loop",
           (Parameter("delay", 0.0, 0.12, 0.02, unit="s"),),
           "0-120 ms spans short- and long-latency trunk reflexes (modelling choice; see models/reference_values.toml [reflex])"),
    Effect("golgi_feedback", "Golgi tendon organ (autogenic force) feedback",
           (Parameter("gain", 0.0, 1.0, 0.05, unit="excitation per F_max"),),
           "inhibitory force feedback on each muscle's own force change; gain bound is a modelling choice"),
    Effect("trunk_in_space", "vestibular/visual trunk-orientation feedback onto extensors and flexors",
           (Parameter("gain", 0.0, 1.0, 0.05, unit="excitation per rad"), Parameter("delay", 0.03, 0.3, 0.12, unit="s")),
           "bounds are a modelling choice (vestibular/visual latencies are longer than spinal ones)"),
    Effect("stiffening_discs", "nonlinear, stiffening intervertebral moment-angle law M = -k (q + c q^3)",
           (Parameter("cubic", 0.0, 2000.0, 50.0, unit="1/rad^2"),),
           "at 0.05 rad, c = 2000 triples the stiffness; amplitude-dependent, so trials of different size separate it from a stiffness error",
           amplitude_dependent=True),
    Effect("seat_compliance", "pelvis-seat compliance: the pelvis does not follow the platform exactly",
           (Parameter("stiffness", 3.0, 6.0, 5.0, log10=True, unit="N/m"), Parameter("damping", 1.0, 4.0, 2.5, log10=True, unit="N s/m")),
           "spring-damper between platform and pelvis (pelvis mass: the model's sacrum)"),
    Effect("slow_activation", "slower excitation-activation dynamics",
           (Parameter("scale", 1.0, 5.0, 1.2, unit="x time constants"),),
           "multiplies both Thelen activation time constants"),
    Effect("extra_damping", "extra passive intervertebral damping",
           (Parameter("damping", 0.0, 30.0, 1.0, unit="Nms/rad per level"),),
           "added to every lumbar level's bushing damping"),
)


def effect(name: str) -> Effect:
    for e in CATALOGUE:
        if e.name == name:
            return e
    raise ValueError(f"unknown effect {name!r}; candidates: {[e.name for e in CATALOGUE]}")
