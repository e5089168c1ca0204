"""Check of the gap search's final polish on a published benchmark run: regenerate a case's data, then the
remainder test at the truth, at the run's final model, and at that model polished (`search.polish_fit`: every
gain direction with its effects, in rounds while a round lowers the training chi2 by more than 10).

    python analyses/gap_polish_check.py CASE RUN_FOLDER [--quick]   # e.g. docs/gap_benchmark/default_passenger

`--quick`: 2 s trials, one round (a check that it runs, not a result).

Prints one JSON line. The results of 2026-12-04 in docs/gap_benchmark/polish_check/results.jsonl came from one
round per case (slow_activation_scale4: rounds, as here)."""

import json
import time

from trunk_drake.commands import published_case_arguments
from trunk_drake.gap.benchmark import THRESHOLD, published_case
from trunk_drake.gap.measures import remainder, segment_chi2
from trunk_drake.gap.refit import TimeDomainFitter, simulate_outputs
from trunk_drake.gap.search import POLISH_ROUNDS, polish_fit
from trunk_drake.gap.trials import half
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool


def main(name: str, folder: str, quick: bool = False) -> dict:
    start = time.perf_counter()
    case = published_case(name, folder, quick)
    model, data, noise, space, effects, x0 = (case[k] for k in ("model", "data", "noise", "space", "effects", "x"))

    def tested(outputs) -> dict:
        r = remainder(data, outputs, noise, OUTPUT_NAMES)
        return {"is_noise": r["is_noise"], "chi2": {k: round(v, 4) for k, v in r["chi2_per_sample"].items()},
                "lb_p": r["ljung_box"]["p"], "lb_q": r["ljung_box"]["q"], "frf_p": r["frf"]["p"],
                "heldout": sum(segment_chi2(t.steady_outputs, o, noise, half(t, "test")) for t, o in zip(data, outputs))}

    out = {"case": name, "truth": tested([simulate_outputs(model, case["truth"], t, OUTPUT_NAMES)[0] for t in data])}
    with WorkerPool(model, 2) as pool:
        fitter = TimeDomainFitter(pool, space, data, noise, OUTPUT_NAMES)
        published = fitter.fit(effects, x0, [], space=space)
        polished = polish_fit(fitter, effects, x0, space, THRESHOLD, rounds=1 if quick else POLISH_ROUNDS)
    out.update(final=tested(published.outputs), polished=tested(polished.outputs), polished_values=polished.values,
               train=[published.train_chi2, polished.train_chi2], sims=fitter.simulations, wall_s=time.perf_counter() - start)
    return out


if __name__ == "__main__":
    args = published_case_arguments(__doc__, "2 s trials, one round")
    print(json.dumps(main(args.case, args.folder, args.quick), default=float))
