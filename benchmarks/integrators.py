"""Integrator settings on the default passenger's 20 s main job: evaluations and RMS deviation of the
lumbar rotation from the accurate reference (trunk_drake.accuracy), for radau3 and runge_kutta3 at
several accuracies and maximum steps. Prints JSON (one object per setting).

Usage: python benchmarks/integrators.py [--duration S] [--quick]   (`--quick`: the first two settings)
"""

import argparse
import json
import os
import time

from trunk_drake.accuracy import DURATION, rms_deviation_deg, trial_model, trial_options
from trunk_drake.simulation import simulate

SETTINGS = [("radau3", 1e-2, 0.0125), ("runge_kutta3", 1e-2, 0.0125), ("runge_kutta3", 1e-2, 0.025),
            ("runge_kutta3", 1e-3, 0.025), ("runge_kutta3", 1e-3, 0.05), ("runge_kutta3", 1e-4, 0.05)]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=DURATION, help="simulated seconds (default: the check's 20 s)")
    parser.add_argument("--quick", action="store_true", help="the first two settings only")
    args = parser.parse_args()
    model = trial_model("default")
    options = trial_options(model, "default")
    simulate(model, duration=0.3, **options)  # warm-up: numba caches
    rows = []
    for integrator, accuracy, max_step in SETTINGS[:2] if args.quick else SETTINGS:
        start = time.perf_counter()
        result = simulate(model, duration=args.duration, integrator=integrator, accuracy=accuracy, max_step=max_step,
                          **options)
        summary = result.summary()
        rows.append({"integrator": integrator, "accuracy": accuracy, "max_step_s": max_step, "steps": summary["steps"],
                     "derivative_evaluations": summary["derivative_evaluations"], "wall_time_s": time.perf_counter() - start,
                     "rms_deviation_deg": rms_deviation_deg(result, "default")})
    print(json.dumps({"trial": f"default passenger, {args.duration:g} s, 0.2-1 Hz, seed 0", "settings": rows,
                      "load_average": os.getloadavg()},
                     indent=2))


if __name__ == "__main__":
    main()
