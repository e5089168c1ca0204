"""The pair case reflex_delay_delay0.04+slow_activation_scale2.5 with the delay held: slow activation and every gain
direction refitted in rounds (like `polish_fit`, at most 6) from the all_gains run's final model (slow activation 2.81
alone), to tell the free refit's stop at 27.5 ms from the optimum.

    python analyses/gap_pair_profile.py DELAY_S [RUN_FOLDER]   # e.g. 0.04 docs/gap_benchmark/all_gains

Prints each round and the result. 2026-12-04, 0.04: slow activation 2.53, training chi2 17,856 (the free refit:
18,682 at 27.5 ms), held-out 18,096 (truth 18,056); 369 simulations, 228 s (README, the partner test)."""

import json
import sys
import time
from pathlib import Path

import numpy as np

from trunk_drake.gap.benchmark import DEFAULT_NOISE_DEG, THRESHOLD, case_trials, select_cases, truth_configuration
from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.refit import TimeDomainFitter
from trunk_drake.gap.search import POLISH_ITERATIONS
from trunk_drake.gap.space import SearchSpace
from trunk_drake.gap.trials import prepare_trials
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool

CASE = "reflex_delay_delay0.04+slow_activation_scale2.5"


def main(delay: float, folder: str = "docs/gap_benchmark/all_gains") -> None:
    start = time.perf_counter()
    model, nominal = truth_configuration()
    noise_rad = np.radians(DEFAULT_NOISE_DEG)
    _, _, _, noisy = case_trials(model, select_cases([CASE])[0], nominal, noise_rad)
    data = prepare_trials(noisy, OUTPUT_NAMES)
    final = json.loads((Path(folder) / "cases" / CASE / "diagnosis.json").read_text())["final"]
    space = SearchSpace.around(model, nominal)
    gains = space.layout.vector(final["gains"]) - space.layout.vector(space.layout.fixed)
    effects = (effect("slow_activation"), effect("reflex_delay"))
    x = np.concatenate([gains, [final["effects"]["slow_activation"]["scale"], delay]])
    free = np.arange(x.size - 1)  # every coordinate but the delay
    with WorkerPool(model, 2) as pool:
        fitter = TimeDomainFitter(pool, space, data, np.full(len(OUTPUT_NAMES), noise_rad), OUTPUT_NAMES)
        fit = fitter.fit(effects, x, free, max_iterations=POLISH_ITERATIONS, space=space)
        for k in range(2, 7):
            again = fitter.fit(effects, fit.x, free, max_iterations=POLISH_ITERATIONS, space=space)
            print(f"round {k}: {again.values}, train {again.train_chi2:.1f}, held-out {again.heldout_chi2:.1f}", flush=True)
            if again.outputs is None or again.train_chi2 >= fit.train_chi2:
                break
            gained, fit = fit.train_chi2 - again.train_chi2, again
            if gained <= THRESHOLD:
                break
    print(f"delay held at {delay} s: {fit.values}, train {fit.train_chi2:.1f}, held-out {fit.heldout_chi2:.1f}, "
          f"{fitter.simulations} simulations, {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main(float(sys.argv[1]), *sys.argv[2:3])
