"""Hill parameters of MyoTorso muscles by Christophy et al.'s published method.

Inputs (literature fascicle/musculotendon length ratios, sarcomere lengths, pennation
angles, with citations) are in `models/muscle_architecture.toml`; the neutral-posture
musculotendon lengths are computed from our own path geometry.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from trunk_drake.data import load_toml
from trunk_drake.model.spec import ModelSpec

SIDE_SUFFIXES = ("_r", "_l")


def base_name(muscle: str) -> str:
    """Muscle name without its side suffix (``IL_L1_r`` -> ``IL_L1``)."""
    for s in SIDE_SUFFIXES:
        if muscle.endswith(s):
            return muscle[: -len(s)]
    return muscle


@dataclasses.dataclass(frozen=True)
class HillLengths:
    """Derived Hill parameters, arrays over muscles."""

    fascicle_length: np.ndarray  # m, at the neutral posture
    optimal_fiber_length: np.ndarray  # m
    tendon_slack_length: np.ndarray  # m
    pennation_angle: np.ndarray  # rad


def derive_hill_lengths(muscles: list[str], neutral_lengths: np.ndarray, table: dict | None = None) -> HillLengths:
    """l_F = l_MT0 * ratio;  l_opt = l_F * l_So / l_S;  l_slack = l_MT0 - l_F cos(alpha)."""
    table = table or load_toml("muscle_architecture.toml")
    entries = table["muscles"]
    missing = [m for m in muscles if base_name(m) not in entries]
    if missing:
        raise ValueError(f"no architecture inputs in models/muscle_architecture.toml for {missing}")
    ratio = np.array([entries[base_name(m)]["ratio"] for m in muscles])
    sarcomere = np.array([entries[base_name(m)]["sarcomere_um"] for m in muscles])
    alpha = np.radians([entries[base_name(m)]["pennation_deg"] for m in muscles])
    l_mt = np.asarray(neutral_lengths, dtype=float)
    fascicle = l_mt * ratio
    return HillLengths(
        fascicle_length=fascicle,
        optimal_fiber_length=fascicle * table["optimal_sarcomere_length_um"] / sarcomere,
        tendon_slack_length=l_mt - fascicle * np.cos(alpha),
        pennation_angle=alpha,
    )


def muscle_group_of(muscle: str, groups_table: dict | None = None) -> str:
    """The thesis muscle group of a MyoTorso muscle (models/muscle_groups.toml)."""
    groups = (groups_table or load_toml("muscle_groups.toml"))["groups"]
    for group, prefixes in groups.items():
        if any(muscle.startswith(p) for p in prefixes):
            return group
    raise ValueError(f"muscle {muscle!r} matches no group prefix in models/muscle_groups.toml")


def with_hill_parameters(spec: ModelSpec, neutral_lengths: np.ndarray) -> ModelSpec:
    """A copy of `spec` whose muscles carry derived Hill lengths and their thesis group."""
    hill = derive_hill_lengths(spec.muscle_names, neutral_lengths)
    muscles = tuple(
        dataclasses.replace(
            m,
            optimal_fiber_length=float(hill.optimal_fiber_length[i]),
            tendon_slack_length=float(hill.tendon_slack_length[i]),
            pennation_angle=float(hill.pennation_angle[i]),
            group=muscle_group_of(m.name),
        )
        for i, m in enumerate(spec.muscles)
    )
    return dataclasses.replace(spec, muscles=muscles)
