"""The search for unmodelled effects: a gains-only refit, linear screening of every candidate,
nonlinear refits of the best, claims by held-out dBIC and forward selection."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.refit import TimeDomainFitter
from trunk_drake.gap.screen import LinearScreen
from trunk_drake.gap.space import Fit, SearchSpace
from trunk_drake.gap.trials import half


@dataclass
class Settings:
    """How the search decides: claim threshold (held-out dBIC), at most `max_effects` effects,
    the best `refine` candidates of the screening refined with nonlinear simulations."""

    threshold: float = 10.0
    max_effects: int = 2
    refine: int = 3


@dataclass
class SearchResult:
    base: Fit  # the gains-only refit
    ranking: list[dict]  # candidates, best held-out dBIC first
    selected: list[str]  # claimed effects
    best: Fit  # the selected model (the gains-only refit when nothing is claimed)
    scores: dict = field(default_factory=dict)  # n_heldout, penalty, refit_heldout_chi2


def search_effects(space: SearchSpace, screen: LinearScreen, fitter: TimeDomainFitter, candidates, settings: Settings,
                   nominal, progress=None) -> SearchResult:
    """The gains-only refit (nonlinear), then every candidate screened linearly around it with
    the refitted gains held, the best `refine` and every amplitude-dependent effect (whose
    screening is blind to the operating-point shift it causes) refined with nonlinear
    simulations; effects are claimed by held-out dBIC; forward selection adds one at a time."""
    n_test = sum(t.steady_outputs[half(t, "test")].size for t in screen.trials)
    penalty = np.log(n_test)
    rank = space.rank
    fitter.seed(np.zeros(rank), (), nominal)
    base = fitter.fit((), np.zeros(rank), np.arange(rank), max_iterations=3)
    if progress:
        progress(f"refitted the nominal gains: held-out chi2 {base.heldout_chi2:.0f}")
    reference = screen.reference(space.options_for(base.x, ()), base.outputs) if base.outputs is not None else screen.nominal
    fits = {(): base}
    screening = []
    base_residual = screen.residual(space.options_for(base.x, ()), "test", reference)
    failed = []
    for e in candidates:
        _, _, start = space.bounds((e,))
        start[:rank] = base.x
        try:
            lin = screen.fit(space, (e,), reference, start, free=np.arange(rank, start.size))
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as err:  # reported, not dropped
            failed.append({"effect": e.name, "description": e.description, "n_parameters": len(e.parameters),
                           "linear_delta_bic": -np.inf, "status": f"failed in screening: {err}"})
            continue
        screening.append((float(base_residual @ base_residual) - lin.heldout_chi2 - len(e.parameters) * penalty, e, lin))
        if progress:
            progress(f"screened {e.name}: linear dBIC {screening[-1][0]:.1f}")
    screening.sort(key=lambda item: -item[0])
    ranking = []
    for k, (lin_dbic, e, lin) in enumerate(screening):
        row = {"effect": e.name, "description": e.description, "n_parameters": len(e.parameters),
               "linear_delta_bic": float(lin_dbic), "linear_values": lin.values.get(e.name), "status": "screened"}
        if k < settings.refine or e.amplitude_dependent:
            fit = fitter.fit((e,), lin.x, np.arange(rank, lin.x.size))
            if fit.outputs is None:
                row["status"] = "failed: the refitted model diverged in simulation"
            else:
                fits[(e.name,)] = fit
                row.update(delta_bic=float(base.heldout_chi2 - fit.heldout_chi2 - len(e.parameters) * penalty),
                           heldout_chi2=fit.heldout_chi2, values=fit.values.get(e.name), status="refined")
            if progress:
                progress(f"{e.name}: {row['status']}" + (f", dBIC {row['delta_bic']:.1f} with {row['values']}" if "delta_bic" in row else ""))
        ranking.append(row)
    ranking += failed
    ranking.sort(key=lambda r: (-(r.get("delta_bic", -np.inf)), -r["linear_delta_bic"]))
    selected, current = [], base
    refined = [r["effect"] for r in ranking if "delta_bic" in r]
    if refined and ranking[0]["delta_bic"] > settings.threshold:
        selected = [ranking[0]["effect"]]
        current = fits[(selected[0],)]
        first_gain = ranking[0]["delta_bic"]
        while len(selected) < settings.max_effects:
            best = None
            for name in refined:
                if name in selected:
                    continue
                effects = tuple(effect(n) for n in selected) + (effect(name),)
                x0 = np.concatenate([current.x, fits[(name,)].x[rank:]])
                fit = fitter.fit(effects, x0, np.arange(current.x.size, x0.size))
                gain = current.heldout_chi2 - fit.heldout_chi2 - len(effect(name).parameters) * penalty
                if best is None or gain > best[0]:
                    best = (gain, name, fit)
            # an added effect must pass the threshold and explain at least a tenth of what the first
            # one did: the first effect's imperfect fit leaves structure that others mop up
            if best is None or best[0] <= max(settings.threshold, 0.1 * first_gain):
                break
            selected.append(best[1])
            current = best[2]
            if progress:
                progress(f"forward selection adds {best[1]} (dBIC {best[0]:.1f})")
    return SearchResult(base, ranking, selected, current,
                        {"n_heldout": n_test, "penalty": float(penalty), "refit_heldout_chi2": base.heldout_chi2})
