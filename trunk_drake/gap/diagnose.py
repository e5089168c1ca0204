"""Sim-to-real gap diagnosis: where the model departs from the data, which unmodelled effect
causes it, and how far the gap shrinks once the effect is added.

Method (the stages are modules of this package):

1. *Where* (`measures`): the nominal model is simulated (nonlinear, time domain) on every
   trial's own perturbation. The gap is located per output and level (VAF, chi-square per
   sample), per frequency (FRF gain and phase errors at the excited lines against the data's
   own confidence bounds), per time window, and for linearity (power at non-excited lines).
2. *Which effects* (`search`): every candidate is refitted together with the nominal reflex
   gains (in their identifiable subspace) on the first half of every trial's steady window
   (`trials`) and scored by chi-square on the held-out second halves, penalised BIC-like:
   dBIC = chi2(model without it) - chi2(model with it) - k ln N. The gains-only refit is the
   "mis-set parameter" explanation; an effect is claimed only when its own dBIC exceeds the
   threshold. Refits use full nonlinear simulations (`refit`). Screening is linear
   (`screen`): the diagram is linearised once around the nominal operating point and a
   candidate's prediction is the current model's simulation plus the linear model's relative
   change at the excited lines (amplitude-dependent laws linearised over each trial's own
   range), so all candidates are screened in seconds. The best `check` candidates above the
   threshold are then simulated at three starts (its linear fit; the effect's linear fit and the
   catalogue's start with the current gains; near the reflexes' kinks the linear change can be
   15-65 % off and the linear fit far from the truth), and the best `refine` of that check are
   refitted and scored with nonlinear simulations; forward selection adds the best effect while
   its own dBIC passes, it beats the gains refitted along as many further directions (the gain
   rival) and it still passes on top of the gains widened as far as they pass (the nested test);
   the selected effects and the gains are refitted jointly, and
   backward steps drop an effect that no longer earns its place. Finally the gains are refitted
   along further directions while each passes as an effect would, and the polish refits the model
   along every gain direction with its effects (an effect that no longer earns its dBIC is dropped);
   the selection then goes on from that model on every gain direction.
3. *How far it shrinks* (`measures`): 1 - VAF and the FRF error on the held-out halves before
   (nominal), after a gains-only refit and after the selected effect(s), with bootstrap
   intervals over 2 s windows; and whether what remains is measurement noise (held-out
   chi-square per sample, whiteness, FRF errors against the data's bounds). When it is not,
   the verdict says so first, with where the remainder lies.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trunk_drake.diagram import TrunkOptions
from trunk_drake.gap.catalogue import CATALOGUE, effect
from trunk_drake.gap.checkpoint import SimulationLog, diagnosis_identity
from trunk_drake.gap.measures import frf_errors, locate_gap, measure_shrinkage, remainder, segment_chi2
from trunk_drake.gap.refit import TimeDomainFitter, simulation_job
from trunk_drake.gap.screen import LinearScreen, gain_directions, identifiable_rank
from trunk_drake.gap.search import SearchResult, Settings, search_effects
from trunk_drake.gap.space import SearchSpace
from trunk_drake.gap.trials import estimate_noise, half, noise_variance_uncertainty, prepare_trials
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool
from trunk_drake.signals import DEFAULT_FADE_S, DEFAULT_PERIOD_S


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
    steps: list = field(default_factory=list)  # the selection, step by step
    remainder: dict = field(default_factory=dict)  # is what the selected model leaves measurement noise?
    series: dict = field(default_factory=dict)  # per trial: time, data, nominal, refit, effect (lumbar rotation)
    final_options: TrunkOptions | None = None  # the selected model, to simulate it

    def to_dict(self) -> dict:
        return {k: v for k, v in dataclasses.asdict(self).items() if k not in ("series", "final_options")}


def progress_lines(progress: bool | Path, stamp):
    """Where a diagnosis says what it does: nowhere (False), stdout (True) or appended to the file `progress`
    (a benchmark case's, to follow with `tail -f`); each line starts with `stamp()`."""
    if not progress:
        return None
    if progress is True:
        return lambda msg: print(f"{stamp()} {msg}", flush=True)
    path = Path(progress)
    path.parent.mkdir(parents=True, exist_ok=True)

    def say(msg: str) -> None:
        with path.open("a") as f:
            f.write(f"{stamp()} {msg}\n")
    return say


def diagnose_gap(model, trials, options: TrunkOptions | None = None, *, noise: float | None = None, outputs=OUTPUT_NAMES,
                 candidates=None, threshold: float = 10.0, max_effects: int = 3, refine: int = 3,
                 period: float = DEFAULT_PERIOD_S, fade: float = DEFAULT_FADE_S, workers: int = 2, cluster: str | None = None, gains_first: bool = False,
                 progress: bool | Path = False, checkpoint: Path | None = None) -> GapDiagnosis:
    """Diagnose the gap between `model` (with `options`, e.g. fitted reflex gains) and `trials`.

    `noise` (rad, scalar or per output) is the measurement noise of the angles (estimated per
    output from the data's high frequencies when None). `candidates` defaults to the whole
    catalogue; the best `refine` of each linear screening are refitted with nonlinear
    simulations. An effect is claimed when it lowers the held-out chi-square of the model
    without it by more than `threshold` after a k ln N penalty; at most `max_effects`. `gains_first`: the
    gains are widened beyond the identifiable directions (as far as each further direction passes) before
    any effect is weighed (`search.Settings`). The simulations run on `workers` local processes, or on the Dask
    cluster at `cluster`. `progress`: a line per step on stdout (True) or appended to a file. `checkpoint`: a file the
    refits' simulations are written to as they finish (`checkpoint.SimulationLog`); rerun after an interruption, the
    diagnosis takes them from there and goes on where it stopped (its wall time and progress lines count the
    interrupted runs' time too). Left in place: delete it once the results are saved, so that an interruption before
    that does not cost the diagnosis.
    """
    wall = _time.perf_counter()
    count = {"simulations": 0}  # shared with the fitter: every progress line says how many simulations so far
    say = progress_lines(progress, lambda: f"[{_time.perf_counter() - wall:6.1f} s, {count['simulations']:4d} sims]")
    options = options or TrunkOptions()
    candidates = tuple(effect(c) if isinstance(c, str) else c for c in (candidates or CATALOGUE))
    data = prepare_trials(trials, outputs, period, fade)
    if noise is None:
        noise, noise_rel_sd = estimate_noise(data), noise_variance_uncertainty(data)
    else:
        noise, noise_rel_sd = np.broadcast_to(np.asarray(noise, float), (len(outputs),)).copy(), 0.0
    if say:
        say(f"{len(data)} trials, noise {np.round(np.degrees(noise), 3).tolist()} deg; simulating the nominal model")
    settings = Settings(threshold=threshold, max_effects=max_effects, refine=refine, gains_first=gains_first)
    log = _log(checkpoint, diagnosis_identity(model, options, data, noise, outputs, candidates, settings), say)
    earlier = log.earlier_wall_s if log is not None else 0.0
    wall -= earlier  # the interrupted runs' time counts
    with WorkerPool(model, workers, cluster) as simulator, log or contextlib.nullcontext():  # the log closed on any exit
        results = simulator.map(simulation_job, [(options, t, outputs, None, None) for t in data])
        for t, r in zip(data, results):
            if isinstance(r, Exception):
                raise ValueError(f"the nominal model diverges on {t.name}: {r}")
        nominal = [r[0] for r in results]
        count["simulations"] = len(data)
        screen = LinearScreen(model, options, data, nominal, [r[1] for r in results], noise)
        space = SearchSpace.around(model, options)
        directions, singular_values = gain_directions(screen, space)
        rank = identifiable_rank(singular_values)
        space = dataclasses.replace(space, directions=directions[:, :rank])
        fitter = TimeDomainFitter(simulator, space, data, noise, outputs, count, log)
        if say:
            say(f"linearised; {space.rank} identifiable gain directions; screening {len(candidates)} candidates")
        found = search_effects(space, screen, fitter, candidates, settings, nominal, [r[2] for r in results],
                               directions[:, rank:], say)
    found.scores.update(nominal_heldout_chi2=sum(segment_chi2(t.steady_outputs, n, noise, half(t, "test"))
                                                 for t, n in zip(data, nominal)),
                        simulations=fitter.simulations, replayed_simulations=count["replayed"],
                        earlier_runs_wall_s=earlier)
    left = remainder(data, found.best.outputs, noise, outputs, noise_rel_sd)
    return _report(data, noise, nominal, space, found, left, settings, candidates, outputs, wall)


def _log(checkpoint, identity: str, say) -> SimulationLog | None:
    """The simulation log at `checkpoint` (None: none), with a line on what it holds."""
    if checkpoint is None:
        return None
    log = SimulationLog(checkpoint, identity)
    if say and log.fresh_because:
        say(f"not resuming from {checkpoint}: {log.fresh_because}; it is started afresh")
    elif say and log.entries:
        say(f"resuming: the simulations of {len(log.entries)} refit points logged in {checkpoint} (after "
            f"{log.earlier_wall_s:.0f} s of earlier runs) are taken, not run again")
    return log


def _report(data, noise, nominal, space: SearchSpace, found: SearchResult, left: dict, settings: Settings, candidates,
            outputs, wall) -> GapDiagnosis:
    """Where, the search's outcome, the remainder and the shrinkage, assembled."""
    space = found.space or space  # the final model's: more gain directions when the search widened them
    variants = {"nominal": nominal, "refit": found.base.outputs}
    if found.selected:
        variants["effect"] = found.best.outputs
    elif found.best.outputs is not found.base.outputs:  # no effect, but the gains moved: the gap removed is the final model's
        variants["widened"] = found.best.outputs
    shrink = measure_shrinkage(data, variants, float(noise[0]))
    shrink["frf_error"] = frf_errors(data, variants)
    on_bounds = _on_bounds(space, found)
    by_name = {c.name: c for c in candidates}
    final = {"effects": found.best.values if found.selected else {}, "gains": space.gains(found.best.x[:space.rank]),
             "on_bounds": on_bounds}
    series = {t.name: {"time": t.time[t.steady], "data": t.steady_outputs[:, 0],
                       **{k: (None if v[i] is None else v[i][:, 0]) for k, v in variants.items()}}
              for i, t in enumerate(data)}
    return GapDiagnosis(where=locate_gap(data, nominal, noise, outputs), ranking=found.ranking, selected=found.selected,
                        verdict=_verdict(found, left, shrink, on_bounds, settings), shrink=shrink, final=final,
                        noise_rad=noise.tolist(), wall_time_s=_time.perf_counter() - wall,
                        options={"threshold": settings.threshold, "max_effects": settings.max_effects,
                                 "refine": settings.refine, "gains_first": settings.gains_first, "outputs": list(outputs),
                                 "candidates": [c.name for c in candidates], "scores": found.scores,
                                 "gain_directions": int(space.rank), "held_out": "second half of every trial's steady window"},
                        steps=found.steps, remainder=left, series=series,
                        final_options=space.options_for(found.best.x, tuple(by_name[n] for n in found.best.effects)))


def _on_bounds(space: SearchSpace, found: SearchResult, tolerance: float = 0.01) -> list[str]:
    """The selected effects' parameters fitted within `tolerance` of their range from a bound."""
    lo, hi, _ = space.bounds(tuple(effect(n) for n in found.selected))
    flagged, k = [], space.rank
    for name in found.selected:
        for p in effect(name).parameters:
            x, span = found.best.x[k], hi[k] - lo[k]
            for side, bound in (("lower", lo[k]), ("upper", hi[k])):
                if abs(x - bound) <= tolerance * span:
                    flagged.append(f"{name}.{p.name} = {p.value(x):.4g} {p.unit} at its {side} bound")
            k += 1
    return flagged


def _verdict(found: SearchResult, left: dict, shrink: dict, on_bounds: list[str], settings: Settings) -> str:
    threshold = settings.threshold
    if found.selected:
        claims = ", ".join(f"{s['effect']} (dBIC {s['delta_bic']:.0f})" for s in found.steps
                           if s["action"] == "add" and s["effect"] in found.selected)
        explained = f"missing effect{'s' if len(found.selected) > 1 else ''}: {claims}"
    elif found.scores["nominal_heldout_chi2"] - found.scores["refit_heldout_chi2"] > threshold:
        against = ("on top of the gains widened as far as they pass" if settings.gains_first else
                   "and by more than the gains refitted along as many further directions")
        explained = ("mis-set parameters: a refit of the nominal reflex gains reduces the held-out gap; "
                     f"no candidate effect improves on it by more than dBIC {threshold:g} {against}")
    else:
        explained = "no significant gap that a refit or a candidate effect explains beyond measurement noise"
    if on_bounds:
        explained += f" (fitted on a bound: {'; '.join(on_bounds)})"
    if left["is_noise"]:
        return explained + "; what remains is measurement noise"
    share = 1.0 - shrink["reduction_above_noise"]
    where = [f"outputs {', '.join(left['outputs'])}"] if left["outputs"] else []
    lines = sorted({f for v in left["frequencies_hz"].values() for f in v})
    if lines:
        where.append(f"{', '.join(f'{f:.2f}' for f in lines)} Hz")
    windows = sorted({w for v in left["windows_s"].values() for w in v})
    if windows:
        where.append(f"windows starting at {', '.join(f'{w:.0f}' for w in windows)} s")
    percent = f"{100 * share:.0f}" if share >= 0.1 else f"{100 * share:.1g}"  # 0.4 %, not 0 %
    return (f"an unexplained gap remains: {percent} % of the gap above the noise floor"
            + (f", at {'; '.join(where)}" if where else "")
            + f" (held-out chi2 per sample {max(left['chi2_per_sample'].values()):.2f}, whiteness p = {left['ljung_box']['p']:.2g}); "
            + ("no catalogued effect explains it; " if not found.selected else "no catalogued effect explains the rest; ")
            + explained)
