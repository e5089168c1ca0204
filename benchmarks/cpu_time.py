"""Benchmark for a shared machine: CPU seconds (this process only) of the main job's first 2 s.

The minimum over 3 runs of `time.process_time()` around `simulate`, after a warm-up; less
sensitive to other jobs on the CPU than wall time. Run it alternately on two checkouts (one via
PYTHONPATH) to compare them under the same load. Prints JSON. Usage: python benchmarks/cpu_time.py [--duration 2]
"""

import argparse
import json
import os
import time
import warnings

import trunk_drake as td
from trunk_drake.accuracy import trial_options
from trunk_drake.simulation import simulate


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=2.0, help="simulated seconds per run (default 2)")
    duration = parser.parse_args().duration
    model = td.load_model("sagittal")
    options = trial_options(model, "thesis")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        simulate(model, duration=0.3, **options)  # warm-up: numba cache loading
        runs = []
        for _ in range(3):
            start = time.process_time()
            result = simulate(model, duration=duration, **options)
            runs.append(time.process_time() - start)
    print(json.dumps({"code": td.__file__, "cpu_s_min_of_3": min(runs), "cpu_s": runs, "steps": result.stats["steps"],
                      "derivative_evaluations": result.stats["derivative_evaluations"], "load_average": os.getloadavg()}))


if __name__ == "__main__":
    main()
