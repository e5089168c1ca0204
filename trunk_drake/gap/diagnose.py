"""Sim-to-real gap diagnosis: where the model departs from the data, which unmodelled effect
causes it, and how far the gap shrinks once the effect is added.

Method (the stages are modules of this package):

1. *Where* (`measures`): the nominal model is simulated (nonlinear, time domain) on every
   trial's own perturbation. The gap is located per output and level (VAF, chi-square per
   sample), per frequency (FRF gain and phase errors at the excited lines against the data's
   own confidence bounds), per time window, and for linearity (power at non-excited lines).
2. *Which effect* (`search`): every candidate is refitted together with the nominal reflex
   gains (in their identifiable subspace) on the first half of every trial's steady window
   (`trials`) and scored by chi-square on the held-out second halves, penalised BIC-like:
   dBIC = chi2(gains-only refit) - chi2(candidate) - k ln N. The gains-only refit is the
   "mis-set parameter" explanation; an effect is claimed only when dBIC exceeds the
   threshold. The gains-only refit uses full nonlinear simulations (`refit`). Screening is
   linear (`screen`): the diagram is linearised once around the nominal operating point and a
   candidate's prediction is the refitted simulation plus the linear model's relative change
   at the excited lines, so all candidates are screened in seconds. The best `refine`
   candidates (and the amplitude-dependent ones, whose linearisation misses the
   operating-point shift they cause) are then refitted and scored with full nonlinear
   simulations; forward selection adds a second effect when its dBIC also exceeds a tenth of
   the first effect's.
3. *How far it shrinks* (`measures`): 1 - VAF and the FRF error on the held-out halves before
   (nominal), after a gains-only refit and after the selected effect(s), with bootstrap
   intervals over 2 s windows.
"""

from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass, field

import numpy as np

from trunk_drake.diagram import TrunkOptions
from trunk_drake.gap.catalogue import CATALOGUE, effect
from trunk_drake.gap.linear import OperatingPoint
from trunk_drake.gap.measures import frf_errors, locate_gap, measure_shrinkage, segment_chi2
from trunk_drake.gap.refit import Simulator, TimeDomainFitter
from trunk_drake.gap.screen import LinearScreen, identifiable_directions
from trunk_drake.gap.search import SearchResult, Settings, search_effects
from trunk_drake.gap.space import SearchSpace
from trunk_drake.gap.trials import estimate_noise, half, prepare_trials
from trunk_drake.io.trials import OUTPUT_NAMES


@dataclass
class GapDiagnosis:
    """Where, which, how far (see the module docstring); JSON-friendly via to_dict()."""

    where: dict
    ranking: list[dict]  # candidates sorted by dBIC (held-out), best first
    selected: list[str]  # claimed effects (empty: no effect needed)
    verdict: str
    shrink: dict  # VAF / FRF error before and after on held-out data
    final: dict  # parameters of the selected model
    noise_rad: list  # measurement noise per output (rad)
    wall_time_s: float
    options: dict = field(default_factory=dict)
    series: dict = field(default_factory=dict)  # per trial: time, data, nominal, refit, effect (lumbar rotation)

    def to_dict(self) -> dict:
        return {k: v for k, v in dataclasses.asdict(self).items() if k != "series"}


def diagnose_gap(model, trials, options: TrunkOptions | None = None, *, noise: float | None = None, outputs=OUTPUT_NAMES,
                 candidates=None, threshold: float = 10.0, max_effects: int = 2, refine: int = 3, period: float = 20.0,
                 fade: float = 2.0, workers: int = 2, progress: bool = False) -> GapDiagnosis:
    """Diagnose the gap between `model` (with `options`, e.g. fitted reflex gains) and `trials`.

    `noise` (rad, scalar or per output) is the measurement noise of the angles (estimated per
    output from the data's high frequencies when None). `candidates` defaults to the whole catalogue; the best `refine`
    of the linear screening are refitted with nonlinear simulations. An effect is claimed
    when it lowers the held-out chi-square by more than `threshold` after a k ln N penalty.
    """
    wall = _time.perf_counter()
    say = (lambda msg: print(f"[{_time.perf_counter() - wall:6.1f} s] {msg}", flush=True)) if progress else None
    options = options or TrunkOptions()
    candidates = tuple(effect(c) if isinstance(c, str) else c for c in (candidates or CATALOGUE))
    data = prepare_trials(trials, outputs, period, fade)
    noise = np.broadcast_to(np.asarray(noise, float), (len(outputs),)).copy() if noise is not None else estimate_noise(data)
    if say:
        say(f"{len(data)} trials, noise {np.round(np.degrees(noise), 3).tolist()} deg; simulating the nominal model")
    settings = Settings(threshold, max_effects, refine)
    with Simulator(model, workers) as simulator:
        results = simulator.run([(options, t, outputs) for t in data])
        for t, r in zip(data, results):
            if isinstance(r, Exception):
                raise ValueError(f"the nominal model diverges on {t.name}: {r}")
        nominal = [r[0] for r in results]
        screen = LinearScreen(model, options, data, nominal, OperatingPoint.mean([r[1] for r in results]), noise)
        space = SearchSpace.around(model, options)
        space = dataclasses.replace(space, directions=identifiable_directions(screen, space))
        fitter = TimeDomainFitter(simulator, space, data, noise, outputs)
        if say:
            say(f"linearised; {space.rank} identifiable gain directions; screening {len(candidates)} candidates")
        found = search_effects(space, screen, fitter, candidates, settings, nominal, say)
    found.scores.update(nominal_heldout_chi2=sum(segment_chi2(t.steady_outputs, n, noise, half(t, "test"))
                                                 for t, n in zip(data, nominal)),
                        simulations=fitter.simulations + len(data))
    return _report(data, noise, nominal, space, found, settings, candidates, outputs, wall)


def _report(data, noise, nominal, space: SearchSpace, found: SearchResult, settings: Settings, candidates, outputs,
            wall) -> GapDiagnosis:
    """Where, the search's outcome and the shrinkage, assembled."""
    variants = {"nominal": nominal, "refit": found.base.outputs}
    if found.selected:
        variants["effect"] = found.best.outputs
    shrink = measure_shrinkage(data, variants, float(noise[0]))
    shrink["frf_error"] = frf_errors(data, variants)
    final = {"effects": found.best.values if found.selected else {}, "gains": space.gains(found.best.x[:space.rank])}
    series = {t.name: {"time": t.time[t.steady], "data": t.steady_outputs[:, 0],
                       **{k: (None if v[i] is None else v[i][:, 0]) for k, v in variants.items()}}
              for i, t in enumerate(data)}
    return GapDiagnosis(where=locate_gap(data, nominal, noise, outputs), ranking=found.ranking, selected=found.selected,
                        verdict=_verdict(found, settings.threshold), shrink=shrink, final=final, noise_rad=noise.tolist(),
                        wall_time_s=_time.perf_counter() - wall,
                        options={"threshold": settings.threshold, "max_effects": settings.max_effects,
                                 "refine": settings.refine, "outputs": list(outputs),
                                 "candidates": [c.name for c in candidates], "scores": found.scores,
                                 "gain_directions": int(space.rank), "held_out": "second half of every trial's steady window"},
                        series=series)


def _verdict(found: SearchResult, threshold: float) -> str:
    if found.selected:
        return (f"missing effect: {', '.join(found.selected)} (held-out dBIC {found.ranking[0]['delta_bic']:.0f} > {threshold:g} "
                "over a refit of the nominal reflex gains)")
    if found.scores["nominal_heldout_chi2"] - found.scores["refit_heldout_chi2"] > threshold:
        return ("mis-set parameters: a refit of the nominal reflex gains reduces the held-out gap; "
                f"no candidate effect improves on it by more than dBIC {threshold:g}")
    return "no significant gap that a refit or a candidate effect explains beyond measurement noise"
