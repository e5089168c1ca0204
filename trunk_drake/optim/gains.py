"""Reflex gains as a fitted parameter vector: log10 of the free (kind, group) gains, the others fixed.

Per-muscle and per-group gains convert with `trunk_drake.systems.reflex` (`gains_by_group`,
`group_gains`); this is the one conversion between gain dictionaries and parameter vectors.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trunk_drake.systems.reflex import group_gains

# Lower bound: the thesis' 0.001 (seed 4.8). Upper bound (modelling choice): 30, about 5x the largest gain of
# the default passenger (thesis Table 4.3 x 9 = 0.1-6.3, with the set point at the neutral fiber length). The
# thesis' upper bound of 1 belongs to its set point at the optimal fiber length and would cut those gains off.
GAIN_BOUNDS = (0.001, 30.0)
KINDS = ("kp", "kv")


@dataclass(frozen=True)
class GainLayout:
    """x = log10 of the free gains `names` ("kp.<group>", "kv.<group>"); every other gain keeps
    its value in `fixed` ({"kp": {group: value}, "kv": {...}}; 0 where not given)."""

    names: tuple[str, ...]
    fixed: dict = field(default_factory=lambda: {"kp": {}, "kv": {}})

    @classmethod
    def for_groups(cls, groups, fixed: dict | None = None) -> GainLayout:
        """kp of every group in `groups`, then kv of every group."""
        return cls(tuple(f"{k}.{g}" for k in KINDS for g in groups), fixed or {"kp": {}, "kv": {}})

    @classmethod
    def nonzero(cls, model, kp, kv) -> GainLayout:
        """The nonzero gains of `kp`, `kv` (scalar, per group or per muscle) free, the zero ones fixed at 0."""
        gains = {"kp": group_gains(model, kp), "kv": group_gains(model, kv)}
        return cls(tuple(f"{k}.{g}" for k in KINDS for g, v in gains[k].items() if v > 0), gains)

    @property
    def groups(self) -> tuple[str, ...]:
        """The groups with a free gain, in order of first appearance."""
        return tuple(dict.fromkeys(n.split(".", 1)[1] for n in self.names))

    def gains(self, x) -> dict[str, dict[str, float]]:
        """All gains: the free ones from x, the others from `fixed`."""
        out = {k: dict(self.fixed.get(k, {})) for k in KINDS}
        for name, value in zip(self.names, (10.0 ** np.asarray(x, float)).tolist()):
            kind, group = name.split(".", 1)
            out[kind][group] = value
        return out

    def vector(self, gains: dict) -> np.ndarray:
        """x of a gains dictionary, clipped to GAIN_BOUNDS."""
        values = [gains[n.split(".", 1)[0]][n.split(".", 1)[1]] for n in self.names]
        return np.log10(np.clip(values, *GAIN_BOUNDS))

    def members(self, model) -> list[np.ndarray]:
        """Muscle indices of each of `groups`."""
        index = {m: i for i, m in enumerate(model.muscles)}
        return [np.array([index[m] for m in model.groups[g]], dtype=int) for g in self.groups]
