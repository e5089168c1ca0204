"""A finished case's final model refitted with one catalogued effect added at its catalogue start, every coordinate in
rounds (`polish_fit`, as the search's steps on every gain direction do): where the effect ends, and the training and
held-out chi2 against the truth's. Run on the code to compare (PYTHONPATH) to see what the Levenberg-Marquardt damping
does to an effect in wide, small units (the stiffening's cubic coefficient, 0-2000 1/rad^2).

    python analyses/gap_lm_scaling_check.py CASE EFFECT [RUN_FOLDER [ROUNDS]]

2026-12-06, on the finals of docs/gap_benchmark/search_ca892f7 (polish rounds of 3 steps, at most 4; before: 8949ae1,
after: the per-coordinate scale of `levenberg_marquardt`):
stiffening_discs_cubic400 + stiffening_discs from c = 50: before 50.00007 (held-out chi2 17,892), after 104.7 (17,868;
the truth 17,816; the training chi2 over c with the gains refitted: 17,950.7 at 50, 17,945.9 at 150, 17,942.1 at 400,
18,002.2 at 1,000, so the training halves see c by 9 and the rounds stop); seat_compliance_stiffness30000_damping500
+extra_damping_damping8 + extra_damping from 1 Nms/rad: before 1.01 (held-out 18,120), after 5.74 (18,078; truth 8).
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


def main(name: str, added: str, folder: str = "docs/gap_benchmark/search_ca892f7", rounds: str = "4") -> None:
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
