"""Does a published case's final model lie in another basin than its truth? The training and held-out chi2 along the
straight line (gain coordinates and effect coordinates) from the final to the truth, and the final's effects
refitted from the nominal gains (`search.nominal_start`, `search.polish_fit`) as `_Search.restart` does.

    python analyses/gap_restart_check.py CASE RUN_FOLDER [--quick]   # e.g. docs/gap_benchmark/search_640a2ea

`--quick`: 2 s trials, a restart of one round (a check that it runs, not a result).

Prints one JSON line per point, then the restart. 2026-12-05, reflex_delay_delay0.04+slow_activation_scale2.5 in
search_640a2ea (final: delay 35.5 ms, slow activation 2.45): training chi2 18,092 at the final, 20,973 / 23,795 /
21,525 at 1/4, 1/2, 3/4 of the way, 17,824 at the truth; restarted: 17,827 (delay 41.3 ms, slow activation 2.47),
held-out 18,066 against the final's 18,882 and the truth's 18,054, and its remainder is noise (chi2 per sample 1.01
on the lumbar rotation; the final's 1.24); 204 simulations (189 of the restart), 147 s."""

import json
import time

import numpy as np

from trunk_drake.commands import published_case_arguments
from trunk_drake.gap.benchmark import THRESHOLD, published_case, select_cases
from trunk_drake.gap.measures import remainder
from trunk_drake.gap.refit import TimeDomainFitter
from trunk_drake.gap.search import POLISH_ROUNDS, nominal_start, polish_fit
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool


def main(name: str, folder: str, quick: bool = False) -> None:
    start = time.perf_counter()
    case = published_case(name, folder, quick)
    space, effects, x = case["space"], case["effects"], case["x"]
    withheld = dict(select_cases([name])[0].effects)
    if set(withheld) != {e.name for e in effects}:
        raise SystemExit(f"{name}: the final's effects {[e.name for e in effects]} are not the withheld ones {sorted(withheld)}")
    gains = space.layout.vector({"kp": case["truth"].kp, "kv": case["truth"].kv}) - space.layout.vector(space.layout.fixed)
    truth = np.concatenate([gains] + [e.coordinates(withheld[e.name]) for e in effects])
    with WorkerPool(case["model"], 2) as pool:
        fitter = TimeDomainFitter(pool, space, case["data"], case["noise"], OUTPUT_NAMES)
        for t in (0.0, 0.25, 0.5, 0.75, 1.0):
            fit = fitter.fit(effects, x + t * (truth - x), [], space=space)
            print(json.dumps({"towards_truth": t, "train": fit.train_chi2, "heldout": fit.heldout_chi2}), flush=True)
        fit = polish_fit(fitter, effects, nominal_start(x, space), space, THRESHOLD, rounds=1 if quick else POLISH_ROUNDS)
        left = remainder(case["data"], fit.outputs, case["noise"], OUTPUT_NAMES)
        print(json.dumps({"restarted": fit.values, "train": fit.train_chi2, "heldout": fit.heldout_chi2,
                          "remainder_is_noise": left["is_noise"], "chi2_per_sample": left["chi2_per_sample"],
                          "simulations": fitter.simulations, "wall_s": time.perf_counter() - start}, default=float))


if __name__ == "__main__":
    args = published_case_arguments(__doc__, "2 s trials, a restart of one round")
    main(args.case, args.folder, args.quick)
