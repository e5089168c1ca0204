"""Benchmark: one gap diagnosis of a 3-trial data set with every candidate effect of the catalogue.

The data: the reference truth configuration with a withheld 40 ms reflex delay, two 0.2-1 Hz
trials and one 0.2-3 Hz trial, 0.1 deg noise. Prints JSON: wall time (target <= 120 s, issue 13),
simulations used, the verdict and the gap reduction on held-out data. `python benchmarks/gap.py LOG` also
appends the diagnosis' progress lines (time, simulations so far, each step) to the file LOG. `--quick`: two 5 s-period
trials, two candidates, one refined (a check that it runs, not a result).
"""

import argparse
import json
from pathlib import Path

import numpy as np

from trunk_drake.gap.benchmark import Case, truth_configuration, truth_options
from trunk_drake.gap.diagnose import diagnose_gap
from trunk_drake.gap.synthetic import synthetic_trials


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", nargs="?", type=Path, help="append the diagnosis' progress lines to this file")
    parser.add_argument("--quick", action="store_true", help="two 5 s-period trials, two candidates, one refined")
    args = parser.parse_args()
    model, nominal = truth_configuration()
    noise = np.radians(0.1)
    truth = truth_options(nominal, Case("delay", "single", (("reflex_delay", {"delay": 0.04}),), seed=7))
    designs = [("1hz_a", 1.0, 71), ("1hz_b", 1.0, 72), ("3hz", 3.0, 73)]
    period = 5.0 if args.quick else 20.0
    short = {"candidates": ["reflex_delay", "extra_damping"], "refine": 1} if args.quick else {}
    trials = synthetic_trials(model, truth, designs[1:] if args.quick else designs, noise, seed=7, period=period)
    d = diagnose_gap(model, trials, nominal, noise=noise, workers=2, period=period, progress=args.log or False, **short)
    print(json.dumps({
        "wall_time_s": d.wall_time_s, "target_s": 120, "trials": len(trials), "candidates": len(d.ranking),
        "simulations": d.options["scores"]["simulations"], "verdict": d.verdict, "selected": d.selected,
        "fitted": d.final["effects"], "remainder_is_noise": d.remainder["is_noise"], "gap": d.shrink["gap"], "reduction": d.shrink["reduction"],
        "reduction_above_noise": d.shrink["reduction_above_noise"],
    }, indent=2, default=float))


if __name__ == "__main__":
    main()
