"""The default passenger's stability margin and critical reflex gain, checked by nonlinear simulation.

For reflex gain scales around the critical value `td.stability` reports, each side's one-sided branch (flexion,
extension) against the rate at which the full diagram, started at the closed-loop rest state displaced 0.1 deg along
that side's mode, grows or decays: a straight line through log |deviation| over the second half of 4 / |rate| of
a decay (2 / rate of a growth, to about 0.7 deg), at most 12 s. A flexion decays faster than the central
linearisation's oscillating pair, which the displaced start also excites, so its simulated rate is that pair's. Writes
docs/stability/simulation_check.json and .md.

    python analyses/stability_vs_simulation.py [--out docs/stability] [--quick]

`--quick`: the default's gains only, at most 1 s per simulation (a check that it runs, not a result).
"""

import argparse
import json
import warnings
from pathlib import Path

import numpy as np

from trunk_drake.metadata import json_default, run_metadata
from trunk_drake.optim.stability import ClosedLoop
from trunk_drake.presets import load_preset

SCALES = (0.5, 0.56, 0.61, 0.67, 0.72, 0.78, 1.0)  # of the default's gains (Table 4.3 x 9)
DISPLACEMENT_DEG = 0.1
LONGEST = 12.0  # s


def deviation_rate(loop: ClosedLoop, x_eq, shape, rate: float, longest: float = LONGEST) -> float:
    """Fitted growth rate (1/s) of the lumbar rotation's deviation from x_eq after starting at x_eq + 0.1 deg x shape."""
    duration = min(longest, (2.0 if rate > 0 else 4.0) / max(abs(rate), 1e-3))  # a growth: to about 0.7 deg
    times = np.linspace(0.5 * duration, duration, 61)
    start = x_eq + np.radians(DISPLACEMENT_DEG) * shape / np.max(np.abs(shape[: loop.nq]))
    deviation = np.abs(loop.rotation_from(start, times, "runge_kutta3", 1e-6) - x_eq[loop.fe].sum())
    return float(np.polyfit(times, np.log(deviation), 1)[0])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/stability")
    parser.add_argument("--quick", action="store_true", help="the default's gains only, at most 1 s per simulation")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    preset = load_preset("default")
    longest = 1.0 if args.quick else LONGEST
    rows = []
    for scale in SCALES[-1:] if args.quick else SCALES:
        p = preset.with_changes(gain_scale=preset.gain_scale * scale)
        model = p.model()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            loop = ClosedLoop(model, p.options(model))
        x_eq, found, _ = loop.equilibrium(np.zeros(loop.nq))
        _, branches, modes = loop.one_sided_margin(x_eq)
        row = {"gain_scale_of_default": scale, "equilibrium_found": found,
               "central": [branches["central"].real, abs(branches["central"].imag)]}
        for side in ("flexion", "extension"):
            rate, shape = loop.branch(x_eq, branches[side].real, np.r_[modes[side], np.zeros(x_eq.size - loop.nq)])
            row[side] = {"predicted_per_s": rate.real,
                         "simulated_per_s": deviation_rate(loop, x_eq, shape, rate.real, longest)}
        rows.append(row)
        print(json.dumps(row), flush=True)
    (out / "simulation_check.json").write_text(json.dumps({"rows": rows, "metadata": run_metadata(model)}, indent=2,
                                                          default=json_default))
    lines = ["| gain scale (of the default) | central root (1/s) | flexion: predicted / simulated (1/s) | "
             "extension: predicted / simulated (1/s) |", "|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['gain_scale_of_default']:g} | {r['central'][0]:+.3f} +- {r['central'][1]:.3f}i | "
                     f"{r['flexion']['predicted_per_s']:+.3f} / {r['flexion']['simulated_per_s']:+.3f} | "
                     f"{r['extension']['predicted_per_s']:+.3f} / {r['extension']['simulated_per_s']:+.3f} |")
    (out / "simulation_check.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
