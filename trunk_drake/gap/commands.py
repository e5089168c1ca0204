"""CLI: `trunk-drake diagnose DATA... --out DIR` and `trunk-drake gap-benchmark --out DIR`."""

from __future__ import annotations

import json

import numpy as np


def add_commands(sub) -> None:
    p = sub.add_parser("diagnose", help="diagnose the sim-to-real gap: where, which unmodelled effect, how far it shrinks",
                       description="Trials (CSV/.sto/.mot or folders; a conditions.toml beside them sets the known conditions) "
                                   "against the model with the given reflex gains.")
    p.add_argument("data", nargs="+", help="trial files or folders (at least two trials)")
    p.add_argument("--out", required=True, help="output folder (report.md, diagnosis.json, figures)")
    p.add_argument("--conditions", help="TOML with a [conditions] table (default: conditions.toml beside the data)")
    p.add_argument("--gains", help="TOML with [kp] and [kv] per group: the model's reflex gains (e.g. a fit's gains.toml)")
    p.add_argument("--noise-deg", type=float, help="angle measurement noise (default: conditions, else estimated)")
    p.add_argument("--candidates", nargs="*", help="candidate effects (default: the whole catalogue)")
    p.add_argument("--threshold", type=float, default=10.0, help="held-out dBIC needed to claim an effect")
    p.add_argument("--refine", type=int, default=3, help="candidates refined with nonlinear simulations")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=_cmd_diagnose)

    b = sub.add_parser("gap-benchmark", help="diagnose data whose effect was withheld: confusion matrix and gap reduction")
    b.add_argument("--out", required=True, help="output folder (results.jsonl, summary.md/json, one report per case)")
    b.add_argument("--quick", action="store_true", help="one magnitude per effect and 2 no-effect cases (9 cases)")
    b.add_argument("--noise-deg", type=float, default=None, help="angle noise (default 0.1 deg)")
    b.add_argument("--workers", type=int, default=2)
    b.add_argument("--json", action="store_true", help="print the summary as JSON")
    b.set_defaults(func=_cmd_benchmark)


def _cmd_diagnose(args) -> int:
    from trunk_drake.diagram import TrunkOptions
    from trunk_drake.gap.diagnose import diagnose_gap
    from trunk_drake.gap.report import write_diagnosis
    from trunk_drake.io.experiment import load_experiment
    from trunk_drake.io.trials import available_outputs
    from trunk_drake.model.trunk_model import load_model
    from trunk_drake.simulation import load_reflex_gains

    experiment = load_experiment(args.data, args.conditions)
    options = dict(experiment.options)
    if args.gains:
        options.update(load_reflex_gains(args.gains))
    noise = np.radians(args.noise_deg) if args.noise_deg is not None else experiment.noise_rad
    diagnosis = diagnose_gap(load_model("sagittal"), experiment.trials, TrunkOptions(**options), noise=noise,
                             outputs=available_outputs(experiment.trials),
                             candidates=args.candidates, threshold=args.threshold, refine=args.refine,
                             period=experiment.period, fade=experiment.fade, workers=args.workers, progress=not args.json)
    files = write_diagnosis(diagnosis, args.out)
    if args.json:
        print(json.dumps({"verdict": diagnosis.verdict, "selected": diagnosis.selected, "final": diagnosis.final,
                          "shrink": {k: v for k, v in diagnosis.shrink.items() if k != "per_trial"},
                          "wall_time_s": diagnosis.wall_time_s, "files": {k: str(v) for k, v in files.items()}},
                         indent=2, default=str))
    else:
        print(f"{diagnosis.verdict}\nreport: {files['report']}")
    return 0


def _cmd_benchmark(args) -> int:
    from trunk_drake.gap.benchmark import DEFAULT_NOISE_DEG, run_benchmark

    summary = run_benchmark(args.out, quick=args.quick, noise_deg=args.noise_deg or DEFAULT_NOISE_DEG,
                            workers=args.workers, progress=None if args.json else print)
    if args.json:
        print(json.dumps({k: v for k, v in summary.items() if k != "rows"}, indent=2, default=str))
    else:
        print(f"summary: {args.out}/summary.md")
    return 0
