"""Write the accurate reference of the simulation accuracy check (trunk_drake.accuracy).

Simulates both check trials (20 s) with radau3 at accuracy 1e-6 and writes their lumbar
rotation at 100 Hz to benchmarks/reference/accurate_lumbar_rotation.csv; prints JSON.
Rerun it only when the model's physics change (never to absorb a numerical change).
Usage: python benchmarks/accuracy_reference.py [--duration S] [--out FILE]
(defaults: the check's 20 s and its reference file)
"""

import argparse
import json
import subprocess
from pathlib import Path

from trunk_drake.accuracy import DURATION, REFERENCE_ACCURACY, REFERENCE_FILE, TRIALS, trial_model, trial_options
from trunk_drake.io.storage import write_csv
from trunk_drake.simulation import simulate


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=DURATION, help="simulated seconds (default: the check's)")
    parser.add_argument("--out", type=Path, default=REFERENCE_FILE, help="CSV to write (default: the check's reference)")
    args = parser.parse_args()
    models = {name: trial_model(name) for name in TRIALS}
    results = {name: simulate(models[name], duration=args.duration, accuracy=REFERENCE_ACCURACY,
                              **trial_options(models[name], name)) for name in TRIALS}
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    time = results[TRIALS[0]].time
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_csv(args.out, time=time, columns={name: r.lumbar_rotation for name, r in results.items()}, in_degrees=False,
              metadata={"content": "lumbar rotation (rad) of the accuracy check trials (trunk_drake.accuracy)",
                        "integrator": f"radau3, accuracy {REFERENCE_ACCURACY}", "commit": commit})
    print(json.dumps({name: {**{k: r.summary()[k] for k in ("wall_time_s", "steps", "derivative_evaluations")},
                             "lumbar_rotation_deg": r.summary()["lumbar_rotation_deg"]} for name, r in results.items()}, indent=2))


if __name__ == "__main__":
    main()
