"""Check of the gap search's partner test (`_Search.partners`) on a benchmark run's case: regenerate the case's data,
take the run's final model and the effects that passed alone in its first step (refined or checked), and run the
partner test on them.

    python analyses/gap_partner_check.py CASE RUN_FOLDER [--quick]   # e.g. docs/gap_benchmark/all_gains

`--quick`: 2 s trials, one partner candidate, refits of one round (a check that it runs, not a result).
Prints the test's progress, then one JSON line: the steps it records, the model it returns, simulations and wall time.
The result of 2026-12-04 on reflex_delay_delay0.04+slow_activation_scale2.5 (docs/gap_benchmark/all_gains) is in the
README (the partner test)."""

import json
import time
from types import SimpleNamespace

import numpy as np

from trunk_drake.commands import published_case_arguments
from trunk_drake.gap.benchmark import published_case
from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.refit import TimeDomainFitter
from trunk_drake.gap.search import Settings, _Search
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool


def main(name: str, folder: str, quick: bool = False) -> dict:
    start = time.perf_counter()
    case = published_case(name, folder, quick)
    data, space, ranking = case["data"], case["space"], case["diagnosis"]["ranking"]
    settings = Settings(refine=1, rounds=1) if quick else Settings()
    with WorkerPool(case["model"], 2) as pool:
        fitter = TimeDomainFitter(pool, space, data, case["noise"], OUTPUT_NAMES)
        search = _Search(space, SimpleNamespace(trials=data), fitter, [effect(r["effect"]) for r in ranking],
                         settings, np.zeros((space.rank, 0)), lambda m: print(m, flush=True))
        search.all_gains = True
        final = fitter.fit(case["effects"], case["x"], [], space=space)
        search.models = {frozenset(final.effects): final}
        own = search.first_passed(ranking, final)
        steps = []
        model = search.partners(final, own, steps.append)
    return {"case": name, "final": {"values": final.values, "heldout_chi2": final.heldout_chi2}, "partners": {n: x.tolist() for n, x in own.items()},
            "steps": steps, "model": {"values": model.values, "heldout_chi2": model.heldout_chi2},
            "simulations": fitter.simulations, "wall_s": time.perf_counter() - start}


if __name__ == "__main__":
    args = published_case_arguments(__doc__, "2 s trials, one partner candidate, refits of one round")
    print(json.dumps(main(args.case, args.folder, args.quick), default=float))
