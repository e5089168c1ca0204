"""Check of the gap search's partner test (`_Search.partners`) on a benchmark run's case: regenerate the case's data,
take the run's final model and the effects that passed alone in its first step, and run the partner test on them.

    python analyses/gap_partner_check.py CASE RUN_FOLDER   # e.g. docs/gap_benchmark/all_gains

Prints the test's progress, then one JSON line: the steps it records, the model it returns, simulations and wall time.
The result of 2026-12-04 on reflex_delay_delay0.04+slow_activation_scale2.5 (docs/gap_benchmark/all_gains) is in the
README (the partner test)."""

import json
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from trunk_drake.gap.benchmark import DEFAULT_NOISE_DEG, case_trials, select_cases, truth_configuration
from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.refit import TimeDomainFitter
from trunk_drake.gap.search import Settings, _Search
from trunk_drake.gap.space import SearchSpace
from trunk_drake.gap.trials import prepare_trials
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool


def coordinates(name: str, values: dict) -> list[float]:
    """An effect's parameter values as search coordinates (log10 where the catalogue says so)."""
    return [np.log10(values[p.name]) if p.log10 else values[p.name] for p in effect(name).parameters]


def main(name: str, folder: str) -> dict:
    start = time.perf_counter()
    model, nominal = truth_configuration()
    noise_rad = np.radians(DEFAULT_NOISE_DEG)
    _, _, _, noisy = case_trials(model, select_cases([name])[0], nominal, noise_rad)
    data = prepare_trials(noisy, OUTPUT_NAMES)
    run = json.loads((Path(folder) / "cases" / name / "diagnosis.json").read_text())
    final_effects = run["final"]["effects"]
    space = SearchSpace.around(model, nominal)
    gains = space.layout.vector(run["final"]["gains"]) - space.layout.vector(space.layout.fixed)
    x = np.concatenate([gains] + [coordinates(n, v) for n, v in final_effects.items()])
    settings = Settings()
    with WorkerPool(model, 2) as pool:
        fitter = TimeDomainFitter(pool, space, data, np.full(len(OUTPUT_NAMES), noise_rad), OUTPUT_NAMES)
        search = _Search(space, SimpleNamespace(trials=data), fitter, [effect(r["effect"]) for r in run["ranking"]],
                         settings, np.zeros((space.rank, 0)), lambda m: print(m, flush=True))
        search.all_gains = True
        final = fitter.fit(tuple(effect(n) for n in final_effects), x, [], space=space)
        search.models = {frozenset(final.effects): final}
        singles = {r["effect"]: SimpleNamespace(x=np.array(coordinates(r["effect"], r["values"]))) for r in run["ranking"]
                   if r["status"] == "refined" and r["delta_bic"] > settings.threshold and r["effect"] not in final_effects}
        steps = []
        model_out = search.partners(final, singles, steps.append)
    return {"case": name, "final": {"values": final.values, "heldout_chi2": final.heldout_chi2}, "partners": list(singles),
            "steps": steps, "model": {"values": model_out.values, "heldout_chi2": model_out.heldout_chi2},
            "simulations": fitter.simulations, "wall_s": time.perf_counter() - start}


if __name__ == "__main__":
    print(json.dumps(main(*sys.argv[1:3]), default=float))
