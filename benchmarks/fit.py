"""Benchmark: the car-passenger reflex-gain fit (14 gains) on the synthetic reference data.

Fits kp and kv of all 7 muscle groups to the two 0.2-1 Hz trials of models/reference
(total and per-level angles), one start from the thesis' initial values, 2 worker
processes. Prints JSON: wall time, number of simulations, cost vs the noise floor, and the
recovered gains against the truth (in units of their reported standard deviation).
"""

import json
import tomllib
import warnings

import numpy as np

import trunk_drake as td
from trunk_drake.data import models_dir
from trunk_drake.diagram import TrunkOptions
from trunk_drake.io.experiment import load_experiment
from trunk_drake.optim.fit import OUTPUT_NAMES, fit_reflex_gains, targets_from_trials


def main():
    reference = models_dir() / "reference"
    experiment = load_experiment([reference / "trial_1hz_a.csv", reference / "trial_1hz_b.csv"], reference / "conditions.toml")
    targets = targets_from_trials(experiment.trials, OUTPUT_NAMES, experiment.noise_rad, period=experiment.period)
    truth = tomllib.loads((reference / "truth.toml").read_text())
    model = td.load_model("sagittal")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = fit_reflex_gains(model, targets, options=TrunkOptions(**experiment.options), n_starts=1, workers=2, progress=False)
    floor = 0.5 * sum(t.time.size * len(t.outputs) for t in targets)
    z = {f"{k}.{g}": (result.gains[k][g] - truth[k][g]) / result.std[k][g] for k in ("kp", "kv") for g in result.gains[k]}
    out = {
        "wall_time_s": result.wall_time_s,
        "n_simulations": result.n_simulations,
        "trials": [t.name for t in targets],
        "n_gains": len(result.parameter_names),
        "cost": result.cost,
        "noise_floor_cost": floor,
        "iterations": [s.iterations for s in result.starts],
        "vaf_lumbar_rotation": {n: v["lumbar_rotation"] for n, v in result.vaf.items()},
        "gains": result.gains,
        "std": result.std,
        "truth": {"kp": truth["kp"], "kv": truth["kv"]},
        "error_in_sd": {k: (None if not np.isfinite(v) else v) for k, v in z.items()},
        "target_wall_time_s": 600,
    }
    print(json.dumps(out, indent=2, default=lambda o: None if isinstance(o, float) and not np.isfinite(o) else str(o)))


if __name__ == "__main__":
    main()
