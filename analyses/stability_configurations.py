"""Stability of the upright posture for the configurations the README and the thesis use.

Runs `td.stability` (static Hessian, closed-loop roots, critical values) for: the README's main
job, which is also the thesis' final model (k = 125 Nm/rad, c = 7.5 Nms/rad, co-activation 0.020,
Table 4.3 gains, l_d = 1); the same with reflexes off (Fig. 4.13's "intrinsic only"), with the
set point at the neutral fiber length, with short-range stiffness, with the Table 4.2 (settling)
gains; and the synthetic reference data's truth configuration, with and without a 30 ms reflex
delay. Writes docs/stability/summary.json and summary.md and the main job's plots.

    python analyses/stability_configurations.py [--out docs/stability]
"""

import argparse
import dataclasses
import json
import warnings
from pathlib import Path

import trunk_drake as td
from trunk_drake import thesis
from trunk_drake.diagram import TrunkOptions
from trunk_drake.metadata import json_default
from trunk_drake.muscle.short_range import ShortRangeStiffness
from trunk_drake.optim.stability import DELAY_RANGE, stability
from trunk_drake.plots import plot_stability


def configurations(model) -> dict[str, TrunkOptions]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        final, _ = thesis.thesis_final_options(model)
        truth = thesis.reference_truth_options()
    main = TrunkOptions(**final, **thesis.thesis_gains())
    truth_options = TrunkOptions(**{k: v for k, v in truth.items() if k in {f.name for f in dataclasses.fields(TrunkOptions)}},
                                 **thesis.truth_gains())
    return {
        "README main job = thesis final model (k 125, co-activation 0.020, Table 4.3 gains, l_d 1)": main,
        "... reflexes off (intrinsic only, Fig. 4.13)": dataclasses.replace(main, kp=0.0, kv=0.0),
        "... set point at the neutral fiber length (l_d = neutral)": dataclasses.replace(main, l_desired="neutral"),
        "... with short-range stiffness": dataclasses.replace(main, srs=ShortRangeStiffness.from_reference()),
        "... Table 4.2 (settling) gains": dataclasses.replace(main, **thesis.thesis_gains("trunk_settling")),
        "synthetic-data truth (k 300, c 6, co-activation 0.03, truth gains)": truth_options,
        "... with a 30 ms reflex delay": dataclasses.replace(truth_options, reflex_delay=0.03),
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
    out = Path(parser.parse_args().out)
    out.mkdir(parents=True, exist_ok=True)
    model = td.load_model("sagittal")
    results, lines = {}, []
    for k, (name, options) in enumerate(configurations(model).items()):
        result = stability(model, options)
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
