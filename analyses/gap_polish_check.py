"""Check of the gap search's final polish on a published benchmark run: regenerate a case's data, then the
remainder test at the truth, at the run's final model, and at that model polished (`search.polish_fit`: every
gain direction with its effects, in rounds while a round lowers the training chi2 by more than 10).

    python analyses/gap_polish_check.py CASE RUN_FOLDER   # e.g. docs/gap_benchmark/default_passenger

Prints one JSON line. The results of 2026-12-04 in docs/gap_benchmark/polish_check/results.jsonl came from one
round per case (slow_activation_scale4: rounds, as here)."""

import json
import sys
import time
from pathlib import Path

import numpy as np

from trunk_drake.gap.benchmark import DEFAULT_NOISE_DEG, THRESHOLD, case_trials, select_cases, truth_configuration
from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.measures import remainder, segment_chi2
from trunk_drake.gap.refit import TimeDomainFitter, simulate_outputs
from trunk_drake.gap.search import polish_fit
from trunk_drake.gap.space import SearchSpace
from trunk_drake.gap.trials import half, prepare_trials
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool


def main(name: str, folder: str) -> dict:
    start = time.perf_counter()
    model, nominal = truth_configuration()
    noise_rad = np.radians(DEFAULT_NOISE_DEG)
    _, truth, _, noisy = case_trials(model, select_cases([name])[0], nominal, noise_rad)
    data = prepare_trials(noisy, OUTPUT_NAMES)
    noise = np.full(len(OUTPUT_NAMES), noise_rad)

    def tested(outputs) -> dict:
        r = remainder(data, outputs, noise, OUTPUT_NAMES)
        return {"is_noise": r["is_noise"], "chi2": {k: round(v, 4) for k, v in r["chi2_per_sample"].items()},
                "lb_p": r["ljung_box"]["p"], "lb_q": r["ljung_box"]["q"], "frf_p": r["frf"]["p"],
                "heldout": sum(segment_chi2(t.steady_outputs, o, noise, half(t, "test")) for t, o in zip(data, outputs))}

    final = json.loads((Path(folder) / "cases" / name / "diagnosis.json").read_text())["final"]
    space = SearchSpace.around(model, nominal)
    effects = tuple(effect(n) for n in final["effects"])
    fitted = [np.log10(v) if p.log10 else v for e in effects for p, v in zip(e.parameters, final["effects"][e.name].values())]
    x0 = np.concatenate([space.layout.vector(final["gains"]) - space.layout.vector(space.layout.fixed), fitted])
    out = {"case": name, "truth": tested([simulate_outputs(model, truth, t, OUTPUT_NAMES)[0] for t in data])}
    with WorkerPool(model, 2) as pool:
        fitter = TimeDomainFitter(pool, space, data, noise, OUTPUT_NAMES)
        published = fitter.fit(effects, x0, [], space=space)
        polished = polish_fit(fitter, effects, x0, space, THRESHOLD)
    out.update(final=tested(published.outputs), polished=tested(polished.outputs), polished_values=polished.values,
               train=[published.train_chi2, polished.train_chi2], sims=fitter.simulations, wall_s=time.perf_counter() - start)
    return out


if __name__ == "__main__":
    print(json.dumps(main(*sys.argv[1:3]), default=float))
