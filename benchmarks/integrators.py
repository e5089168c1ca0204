"""Integrator settings on the default passenger's 20 s main job: evaluations and RMS deviation of the
lumbar rotation from the accurate reference (trunk_drake.accuracy), for radau3 and runge_kutta3 at
several accuracies and maximum steps. Prints JSON (one object per setting).

Usage: python benchmarks/integrators.py
"""

import json
import os
import time

from trunk_drake.accuracy import DURATION, rms_deviation_deg, trial_model, trial_options
from trunk_drake.simulation import simulate

SETTINGS = [("radau3", 1e-2, 0.0125), ("runge_kutta3", 1e-2, 0.0125), ("runge_kutta3", 1e-2, 0.025),
            ("runge_kutta3", 1e-3, 0.025), ("runge_kutta3", 1e-3, 0.05), ("runge_kutta3", 1e-4, 0.05)]


def main():
    model = trial_model("default")
    options = trial_options(model, "default")
    simulate(model, duration=0.3, **options)  # warm-up: numba caches
    rows = []
    for integrator, accuracy, max_step in SETTINGS:
        start = time.perf_counter()
        result = simulate(model, duration=DURATION, integrator=integrator, accuracy=accuracy, max_step=max_step, **options)
        summary = result.summary()
        rows.append({"integrator": integrator, "accuracy": accuracy, "max_step_s": max_step, "steps": summary["steps"],
                     "derivative_evaluations": summary["derivative_evaluations"], "wall_time_s": time.perf_counter() - start,
                     "rms_deviation_deg": rms_deviation_deg(result, "default")})
    print(json.dumps({"trial": "default passenger, 20 s, 0.2-1 Hz, seed 0", "settings": rows, "load_average": os.getloadavg()},
                     indent=2))


if __name__ == "__main__":
    main()
