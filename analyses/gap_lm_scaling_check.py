"""A finished case's final model refitted with one catalogued effect added at its catalogue start, every coordinate in
rounds (`polish_fit`, as the search's steps on every gain direction do): where the effect ends, and the training and
held-out chi2 against the truth's. Run on the code to compare (PYTHONPATH) to see what the Levenberg-Marquardt damping
does to an effect in wide, small units (the stiffening's cubic coefficient, 0-2000 1/rad^2). With `--held V ...` the
effect (of one parameter) is instead held at each value while the gains are refitted: a profile over it.

    python analyses/gap_lm_scaling_check.py CASE EFFECT [--folder RUN_FOLDER] [--rounds N] [--held V ...] [--quick]

`--quick`: 2 s trials (a check that it runs, not a result; with `--rounds 1`, seconds).

2026-12-06, on the finals of docs/gap_benchmark/search_ca892f7 (polish rounds of 3 steps, at most 4; before: 8949ae1,
after: the per-coordinate scale of `levenberg_marquardt`):
stiffening_discs_cubic400 + stiffening_discs from c = 50: before 50.00007 (held-out chi2 17,892), after 104.7 (17,868;
the truth 17,816); `--held 50 150 400 1000` (the gains refitted, the stiffening alone): training / held-out chi2
17,950.7 / 17,892.2, 17,945.9 / 17,852.5, 17,942.1 / 17,816.7, 18,002.2 / 18,048.5, so the training halves see c by 9
and the rounds stop; seat_compliance_stiffness30000_damping500+extra_damping_damping8 + extra_damping from 1 Nms/rad:
before 1.01 (held-out 18,120), after 5.74 (18,078; truth 8).
"""

import argparse
import json
import time
from pathlib import Path

import numpy as np

from trunk_drake.gap.benchmark import THRESHOLD, published_case
from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.refit import TimeDomainFitter
from trunk_drake.gap.search import polish_fit
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case")
    parser.add_argument("effect")
    parser.add_argument("--folder", default="docs/gap_benchmark/search_ca892f7")
    parser.add_argument("--rounds", type=int, default=4)
    parser.add_argument("--held", type=float, nargs="+", help="hold the added effect's parameter at each value (a profile): "
                        "the final's gains alone refitted, its other effects dropped")
    parser.add_argument("--quick", action="store_true", help="2 s trials")
    args = parser.parse_args()
    start = time.perf_counter()
    case = published_case(args.case, args.folder, args.quick)
    rows = (json.loads(line) for line in (Path(args.folder) / "results.jsonl").read_text().splitlines())
    truth = next(r for r in rows if r["case"] == args.case).get("truth_heldout_chi2")
    e = effect(args.effect)
    rank = case["space"].rank
    with WorkerPool(case["model"], 2) as pool:
        fitter = TimeDomainFitter(pool, case["space"], case["data"], case["noise"], OUTPUT_NAMES)
        if args.held:
            for value in args.held:
                fit = polish_fit(fitter, (e,), np.append(case["x"][:rank], e.coordinates({e.parameters[0].name: value})),
                                 case["space"], THRESHOLD, free=np.arange(rank), rounds=args.rounds)
                report(args, fit, truth, fitter, start, held=value)
            return
        effects = tuple(x for x in case["effects"] if x.name != args.effect)
        final = case["diagnosis"]["final"]["effects"]
        x = np.concatenate([case["x"][:rank]] + [other.coordinates(final[other.name]) for other in effects]
                           + [[p.start for p in e.parameters]])
        report(args, polish_fit(fitter, effects + (e,), x, case["space"], THRESHOLD, rounds=args.rounds), truth, fitter, start)


def report(args, fit, truth, fitter, start, **extra) -> None:
    print(json.dumps({"case": args.case, "added": args.effect, **extra,
                      "values": {k: {p: float(v) for p, v in d.items()} for k, d in fit.values.items()},
                      "train_chi2": fit.train_chi2, "heldout_chi2": fit.heldout_chi2, "truth_heldout_chi2": truth,
                      "simulations": fitter.simulations, "wall_s": round(time.perf_counter() - start)}), flush=True)


if __name__ == "__main__":
    main()
