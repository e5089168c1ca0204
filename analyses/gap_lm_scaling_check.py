"""A finished case's final model refitted with one catalogued effect added at its catalogue start, every coordinate in
rounds (`polish_fit`, as the search's steps on every gain direction do): where the effect ends, and the training and
held-out chi2 against the truth's. Run on the code to compare (PYTHONPATH) to see what the Levenberg-Marquardt damping
does to an effect in wide, small units (the stiffening's cubic coefficient, 0-2000 1/rad^2).

    python analyses/gap_lm_scaling_check.py CASE EFFECT [RUN_FOLDER]
"""

import json
import sys
import time
from pathlib import Path

import numpy as np

from trunk_drake.gap.benchmark import THRESHOLD, published_case
from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.refit import TimeDomainFitter
from trunk_drake.gap.search import polish_fit
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool


def main(name: str, added: str, folder: str = "/work/main/docs/gap_benchmark/search_ca892f7", rounds: str = "4") -> None:
    start = time.perf_counter()
    case = published_case(name, folder)
    row = next(json.loads(line) for line in (Path(folder) / "results.jsonl").read_text().splitlines()
               if json.loads(line)["case"] == name)
    e = effect(added)
    effects = tuple(x for x in case["effects"] if x.name != added)
    x = case["x"][:case["space"].rank]
    for other in effects:
        x = np.concatenate([x, other.coordinates(case["diagnosis"]["final"]["effects"][other.name])])
    x = np.concatenate([x, [p.start for p in e.parameters]])
    with WorkerPool(case["model"], 2) as pool:
        fitter = TimeDomainFitter(pool, case["space"], case["data"], case["noise"], OUTPUT_NAMES)
        fit = polish_fit(fitter, effects + (e,), x, case["space"], THRESHOLD, rounds=int(rounds))
    print(json.dumps({"case": name, "added": added, "values": {k: {p: float(v) for p, v in d.items()} for k, d in fit.values.items()},
                      "train_chi2": fit.train_chi2, "heldout_chi2": fit.heldout_chi2,
                      "truth_heldout_chi2": row.get("truth_heldout_chi2"), "simulations": fitter.simulations,
                      "wall_s": round(time.perf_counter() - start)}))


if __name__ == "__main__":
    main(*sys.argv[1:])
