"""The parameters of a candidate model: x = [coordinates along the identifiable directions of
the nominal reflex gains (log10 units), the effects' parameters (fitted scale)]."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from trunk_drake.diagram import TrunkOptions
from trunk_drake.optim.gains import GAIN_BOUNDS, GainLayout

GAIN_RANGE = 1.0  # log10 units the gain coordinates may move (a factor 10 either way)


@dataclass(frozen=True)
class SearchSpace:
    """The nominal options, their nonzero reflex gains (`layout`) and the directions (columns,
    log10 units per gain of `layout`) along which the gains are refitted."""

    options: TrunkOptions
    layout: GainLayout
    directions: np.ndarray

    @classmethod
    def around(cls, model, options: TrunkOptions, directions=None) -> SearchSpace:
        """Every nonzero gain of `options` free (one direction per gain unless `directions` are given)."""
        layout = GainLayout.nonzero(model, options.kp, options.kv)
        return cls(options, layout, np.eye(len(layout.names)) if directions is None else np.asarray(directions, float))

    @property
    def rank(self) -> int:
        return self.directions.shape[1]

    def log_gains(self, coordinates) -> np.ndarray:
        """log10 of the gains of `layout` after moving the nominal ones by directions @ coordinates (clipped to the gain bounds)."""
        nominal = np.log10([self.layout.fixed[n.split(".", 1)[0]][n.split(".", 1)[1]] for n in self.layout.names])
        return np.clip(nominal + self.directions @ np.asarray(coordinates, float), *np.log10(GAIN_BOUNDS))

    def gains(self, coordinates) -> dict:
        """Group gains after moving the nominal log10 gains by directions @ coordinates (clipped to the gain bounds)."""
        return self.layout.gains(self.log_gains(coordinates))

    def options_for(self, x, effects) -> TrunkOptions:
        """The diagram's options for x = [gain coordinates, effect parameters]."""
        gains = self.gains(x[:self.rank])
        options = dataclasses.replace(self.options, kp=gains["kp"], kv=gains["kv"])
        for e, v in zip(effects, self.values(x, effects)):
            options = e.apply(options, v)
        return options

    def values(self, x, effects) -> list[dict]:
        """Physical parameter values of each effect."""
        out, k = [], self.rank
        for e in effects:
            out.append(e.values(x[k:k + len(e.parameters)]))
            k += len(e.parameters)
        return out

    def bounds(self, effects) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lower, upper, start) of x."""
        params = [p for e in effects for p in e.parameters]
        lo = np.concatenate([np.full(self.rank, -GAIN_RANGE), [p.lower for p in params]])
        hi = np.concatenate([np.full(self.rank, GAIN_RANGE), [p.upper for p in params]])
        x0 = np.concatenate([np.zeros(self.rank), [p.start for p in params]])
        return lo, hi, x0


@dataclass
class Fit:
    """A fitted model variant (gains-only refit, or with effects)."""

    effects: tuple[str, ...]
    x: np.ndarray  # [gain coordinates, effect parameters (fitted scale)]
    train_chi2: float
    heldout_chi2: float
    values: dict  # physical effect parameter values per effect
    outputs: list | None = None  # nonlinear simulations of every trial (time-domain fits)
