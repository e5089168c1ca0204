"""Stability of the upright posture for the configurations the README and the thesis use.

Runs `td.stability` (static Hessian, closed-loop roots, critical values) for: the default passenger
(models/presets/default.toml, the README's main job), with a 50 ms reflex delay, with its gains at
the thesis' scale (x1), and with reflexes off; the thesis' final model (`--preset thesis`: independent
levels, k = 125 Nm/rad, c = 7.5 Nms/rad, co-activation 0.020, Table 4.3 gains, l_d = 1), the same with
reflexes off (Fig. 4.13's "intrinsic only"), with the neutral set point, with short-range stiffness and
with the Table 4.2 (settling) gains; and the synthetic reference data's truth configuration. Writes
docs/stability/summary.json and summary.md and the default passenger's plots.

    python analyses/stability_configurations.py [--out docs/stability] [--quick]

`--quick`: the first configuration without critical values (a check that it runs, not a result).
"""

import argparse
import dataclasses
import json
import warnings
from pathlib import Path

from trunk_drake import thesis
from trunk_drake.data import models_dir
from trunk_drake.io.experiment import load_experiment
from trunk_drake.metadata import json_default
from trunk_drake.muscle.short_range import ShortRangeStiffness
from trunk_drake.optim.stability import DELAY_RANGE, stability
from trunk_drake.plots import plot_stability
from trunk_drake.presets import load_preset


def configurations() -> dict[str, tuple]:
    """{name: (model, TrunkOptions)}."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the thesis' co-activation leaves residual moments (its row says so)
        default, final = load_preset("default"), load_preset("thesis")
        passenger, sagittal = default.model(), final.model()
        ours, main = default.options(passenger), final.options(sagittal)
        reference = models_dir() / "reference"
        experiment = load_experiment([reference / "trial_1hz_a.csv"], reference / "conditions.toml")
        truth_model = experiment.model()
        truth = final.options(truth_model, **experiment.options, **thesis.truth_gains())
    return {
        "default passenger (README main job; rhythm, arms, Table 4.3 gains x9, l_d neutral)": (passenger, ours),
        "... with a 50 ms reflex delay": (passenger, dataclasses.replace(ours, reflex_delay=0.05)),
        "... gains at the thesis' scale (x1)": (passenger, default.with_changes(gain_scale=1.0).options(passenger)),
        "... reflexes off": (passenger, dataclasses.replace(ours, kp=0.0, kv=0.0)),
        "thesis final model (--preset thesis: independent levels, k 125, co-activation 0.020, Table 4.3 gains, l_d 1)": (sagittal, main),
        "... reflexes off (intrinsic only, Fig. 4.13)": (sagittal, dataclasses.replace(main, kp=0.0, kv=0.0)),
        "... set point at the neutral fiber length (l_d = neutral)": (sagittal, dataclasses.replace(main, l_desired="neutral")),
        "... with short-range stiffness": (sagittal, dataclasses.replace(main, srs=ShortRangeStiffness.from_reference())),
        "... Table 4.2 (settling) gains": (sagittal, dataclasses.replace(main, **thesis.thesis_gains("trunk_settling"))),
        "synthetic-data truth (models/reference)": (truth_model, truth),
    }


def row(name, summary) -> str:
    d, c = summary["dynamic"], summary["critical"]
    root = d["rightmost_root"]
    kind = f"{root['frequency_hz']:.2f} Hz" if root["frequency_hz"] > 1e-6 else f"real, {root['branch']}"
    crit = "; ".join(v["text"] for v in c.values())
    delay = (f"{1e3 * d['critical_delay_s']:.0f} ms" if d["critical_delay_s"]
             else f"none up to {1e3 * DELAY_RANGE[1]:.0f} ms" if d["stable"] else "-")
    return (f"| {name} | {summary['static']['stability_index_nm_per_rad']:+.0f} | {'stable' if d['stable'] else 'unstable'} "
            f"| {d['margin_per_s']:+.3f} ({kind}) | {delay} | {sum(g['at_threshold'] for g in d['reflexes'].values())} | {crit} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/stability")
    parser.add_argument("--quick", action="store_true", help="the first configuration without critical values")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results, lines = {}, []
    for k, (name, (model, options)) in enumerate(list(configurations().items())[:1 if args.quick else None]):
        result = stability(model, options, critical=not args.quick)
        results[name] = result.summary()
        lines.append(row(name, results[name]))
        if k == 0:
            plot_stability(result, out)
        print(name, "\n  " + "\n  ".join(result.verdict()), flush=True)
    (out / "summary.json").write_text(json.dumps(results, indent=2, default=json_default))
    header = ("| configuration | static index (Nm/rad) | dynamic | margin (1/s) | critical delay | reflexes at threshold "
              "| what makes it stable |\n|---|---|---|---|---|---|---|")
    (out / "summary.md").write_text(header + "\n" + "\n".join(lines) + "\n")
    print(header + "\n" + "\n".join(lines))


if __name__ == "__main__":
    main()
