"""Write the accurate reference of the simulation accuracy check (trunk_drake.accuracy).

Simulates both check trials (20 s) with radau3 at accuracy 1e-6 and writes their lumbar
rotation at 100 Hz to benchmarks/reference/accurate_lumbar_rotation.csv; prints JSON.
Rerun it only when the model's physics change (never to absorb a numerical change).
Usage: python benchmarks/accuracy_reference.py
"""

import json
import subprocess

from trunk_drake.accuracy import DURATION, REFERENCE_ACCURACY, REFERENCE_FILE, TRIALS, trial_model, trial_options
from trunk_drake.io.storage import write_csv
from trunk_drake.simulation import simulate


def main():
    models = {name: trial_model(name) for name in TRIALS}
    results = {name: simulate(models[name], duration=DURATION, accuracy=REFERENCE_ACCURACY, **trial_options(models[name], name))
               for name in TRIALS}
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    time = results[TRIALS[0]].time
    REFERENCE_FILE.parent.mkdir(parents=True, exist_ok=True)
    write_csv(REFERENCE_FILE, time=time, columns={name: r.lumbar_rotation for name, r in results.items()}, in_degrees=False,
              metadata={"content": "lumbar rotation (rad) of the accuracy check trials (trunk_drake.accuracy)",
                        "integrator": f"radau3, accuracy {REFERENCE_ACCURACY}", "commit": commit})
    print(json.dumps({name: {**{k: r.summary()[k] for k in ("wall_time_s", "steps", "derivative_evaluations")},
                             "lumbar_rotation_deg": r.summary()["lumbar_rotation_deg"]} for name, r in results.items()}, indent=2))


if __name__ == "__main__":
    main()
