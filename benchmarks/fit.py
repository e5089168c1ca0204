"""Benchmark: the car-passenger reflex-gain fit (14 gains) on the synthetic reference data.

Fits kp and kv of all 7 muscle groups to the two 0.2-1 Hz trials of models/reference
(total and per-level angles) on the data's model (`experiment.model()`: the preset named in
conditions.toml, the default passenger), from the preset's gains (`--starts N`: plus N-1
further starts, each reported), 2 worker processes. Prints JSON: wall time, number of
simulations, cost vs the noise floor and vs the cost at the truth (the minimum lies at or below
it: a fit above it has not converged), and the recovered gains against the truth (in units of
their reported standard deviation), for the best fit and for every start. "Identifiable" gains
are those the fit itself determines to better than 50 % (reported SD < half the fitted value).
Usage: python benchmarks/fit.py [--starts N] [--max-iterations N] [--progress] [--t-max S]
"""

import argparse
import contextlib
import json
import os
import sys
import tomllib
import warnings

import numpy as np

from trunk_drake.data import models_dir
from trunk_drake.diagram import TrunkOptions
from trunk_drake.io.experiment import load_experiment
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.optim.fit import MAX_ITERATIONS, Objective, fit_reflex_gains, targets_from_trials
from trunk_drake.optim.gains import GainLayout


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--starts", type=int, default=1, help="number of starts (first: the preset's gains)")
    parser.add_argument("--max-iterations", type=int, default=MAX_ITERATIONS, help="per start (the fit's default)")
    parser.add_argument("--progress", action="store_true", help="the fit's progress on stderr")
    parser.add_argument("--t-max", type=float, help="fit only the trials' first T_MAX seconds (a check that it runs)")
    args = parser.parse_args()
    reference = models_dir() / "reference"
    experiment = load_experiment([reference / "trial_1hz_a.csv", reference / "trial_1hz_b.csv"], reference / "conditions.toml")
    targets = targets_from_trials(experiment.trials, OUTPUT_NAMES, experiment.noise_rad, period=experiment.period,
                                  t_max=args.t_max)
    truth = tomllib.loads((reference / "truth.toml").read_text())
    model = experiment.model()
    load_before = os.getloadavg()
    options = TrunkOptions(**experiment.options)
    with warnings.catch_warnings(), contextlib.redirect_stdout(sys.stderr):
        warnings.simplefilter("ignore")
        result = fit_reflex_gains(model, targets, options=options, start=experiment.preset_gains(), n_starts=args.starts,
                                  max_iterations=args.max_iterations, workers=2, progress=args.progress)
    floor = 0.5 * sum(t.time.size * len(t.outputs) for t in targets)
    layout = GainLayout.for_groups(model.groups)
    r_truth, _, _ = Objective(model, targets, layout, options)(layout.vector(truth))  # the minimum lies at or below
    z = error_in_sd(result.gains, result.std, truth)
    identifiable = {f"{k}.{g}": (k, g) for k in ("kp", "kv") for g in result.gains[k] if result.std[k][g] < 0.5 * result.gains[k][g]}
    out = {
        "preset": experiment.preset,
        "model": {"dofs": model.dofs, "coordinates": list(model.coordinates)},
        "load_average": {"before": load_before, "after": os.getloadavg()},
        "wall_time_s": result.wall_time_s,
        "n_simulations": result.n_simulations,
        "trials": [t.name for t in targets],
        "n_gains": len(result.parameter_names),
        "cost": result.cost,
        "noise_floor_cost": floor,
        "cost_at_truth": 0.5 * float(r_truth @ r_truth),
        "iterations": [s.iterations for s in result.starts],
        "vaf_lumbar_rotation": {n: v["lumbar_rotation"] for n, v in result.vaf.items()},
        "gains": result.gains,
        "std": result.std,
        "truth": {"kp": truth["kp"], "kv": truth["kv"]},
        "error_in_sd": {k: (None if not np.isfinite(v) else v) for k, v in z.items()},
        "identifiable": list(identifiable),
        "identifiable_within_1sd": sum(abs(z[n]) <= 1 for n in identifiable),
        "identifiable_within_2sd": sum(abs(z[n]) <= 2 for n in identifiable),
        "relative_error_identifiable": {n: result.gains[k][g] / truth[k][g] - 1 for n, (k, g) in identifiable.items()},
        "starts": [start_summary(s, result, truth) for s in result.starts],
        "target_wall_time_s": 90,
    }
    print(json.dumps(out, indent=2, default=lambda o: None if isinstance(o, float) and not np.isfinite(o) else str(o)))


def error_in_sd(gains, std, truth) -> dict[str, float]:
    """(fitted - truth) / reported SD per gain; nan where the SD is infinite (gain untouched by the data)."""
    return {f"{k}.{g}": (gains[k][g] - truth[k][g]) / std[k][g] if np.isfinite(std[k][g]) else float("nan")
            for k in ("kp", "kv") for g in gains[k]}


def start_summary(start, result, truth) -> dict:
    """One start: where it began and ended, and its largest error in units of the best fit's SD."""
    z = error_in_sd(GainLayout.for_groups(result.options["groups"]).gains(start.x), result.std, truth)
    finite = [abs(v) for v in z.values() if np.isfinite(v)]
    return {"x0_gains": (10.0 ** start.x0).tolist(), "cost": start.cost, "iterations": start.iterations,
            "simulations": start.simulations, "status": start.status,
            "max_abs_error_in_sd": max(finite) if finite else None,
            "within_1sd": int(sum(v <= 1 for v in finite)), "identifiable": len(finite)}


if __name__ == "__main__":
    main()
