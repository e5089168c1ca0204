"""The pair case reflex_delay_delay0.04+slow_activation_scale2.5 with the delay held: slow activation and every gain
direction refitted in rounds (`polish_fit` on every coordinate but the delay, at most 6 rounds) from the all_gains
run's final model (slow activation 2.81 alone), to tell the free refit's stop at 27.5 ms from the optimum.

    python analyses/gap_pair_profile.py DELAY_S [RUN_FOLDER] [--quick]   # e.g. 0.04 docs/gap_benchmark/all_gains

`--quick`: 2 s trials, one round (a check that it runs, not a result).

Prints the result. 2026-12-04, 0.04: slow activation 2.53, training chi2 17,856 (the free refit: 18,682 at
27.5 ms), held-out 18,096 (truth 18,056); 369 simulations, 228 s (README, the partner test)."""

import argparse
import time

import numpy as np

from trunk_drake.gap.benchmark import THRESHOLD, published_case
from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.refit import TimeDomainFitter
from trunk_drake.gap.search import polish_fit
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool

CASE = "reflex_delay_delay0.04+slow_activation_scale2.5"


def main(delay: float, folder: str, quick: bool = False) -> None:
    start = time.perf_counter()
    case = published_case(CASE, folder, quick)  # its final model: slow activation alone
    effects = case["effects"] + (effect("reflex_delay"),)
    x = np.append(case["x"], delay)
    with WorkerPool(case["model"], 2) as pool:
        fitter = TimeDomainFitter(pool, case["space"], case["data"], case["noise"], OUTPUT_NAMES)
        fit = polish_fit(fitter, effects, x, case["space"], THRESHOLD, free=np.arange(x.size - 1),
                         rounds=1 if quick else 6)
    print(f"delay held at {delay} s: {fit.values}, train {fit.train_chi2:.1f}, held-out {fit.heldout_chi2:.1f}, "
          f"{fitter.simulations} simulations, {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("delay", type=float, help="the reflex delay held, s")
    parser.add_argument("folder", nargs="?", default="docs/gap_benchmark/all_gains")
    parser.add_argument("--quick", action="store_true", help="2 s trials, one round")
    args = parser.parse_args()
    main(args.delay, args.folder, args.quick)
