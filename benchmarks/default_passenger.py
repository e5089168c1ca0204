"""The default passenger on full 20 s trials: the issue's uprightness criteria for the README's main
job (1 Hz multisine, seed 0), five other seeds and the 0.2-3 Hz bandwidth; stability and rest state.

Run: python benchmarks/default_passenger.py > default_passenger.json   (prints JSON)
`--quick`: the first and last trial for 1 s, no critical values (a check that it runs, not a result).
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from trunk_drake.metadata import json_default, run_metadata
from trunk_drake.optim.stability import stability
from trunk_drake.presets import load_preset
from trunk_drake.simulation import simulate

TRIALS = [(1.0, 0), (1.0, 1), (1.0, 2), (1.0, 3), (1.0, 4), (1.0, 5), (3.0, 0)]  # (bandwidth Hz, seed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two trials of 1 s, no critical values")
    quick = parser.parse_args().quick
    duration = 1.0 if quick else 20.0
    preset = load_preset("default")
    model = preset.model()
    options = preset.options(model)
    rest = stability(model, options, critical=not quick)
    rows = []
    for bandwidth, seed in [TRIALS[0], TRIALS[-1]] if quick else TRIALS:
        start = time.perf_counter()
        result = simulate(model, duration=duration, bandwidth=bandwidth, seed=seed, options=options)
        rotation = np.degrees(result.lumbar_rotation)
        drift = rotation[result.time >= duration / 2].mean() - rotation[result.time <= duration / 20].mean()
        peak = float(np.max(np.abs(rotation)))
        rows.append({"bandwidth_hz": bandwidth, "seed": seed, "drift_deg": float(drift), "peak_abs_deg": peak,
                     "rms_deg": float(np.std(rotation)), "max_activation": float(result.activation.max()),
                     "upright": bool(abs(drift) < 2.0 and peak < 10.0), "wall_time_s": time.perf_counter() - start})
    print(json.dumps({"preset": preset.summary(), "max_coactivation_at_rest": float(options.feedforward.max()),
                      "unbalanced_at_rest_nm": dict(zip(rest.coordinates, rest.unbalanced.tolist())),
                      "stability": rest.summary(), "trials": rows, "all_upright": all(r["upright"] for r in rows),
                      "load_average": os.getloadavg(), "metadata": run_metadata(model)}, indent=2, default=json_default))


if __name__ == "__main__":
    main()
