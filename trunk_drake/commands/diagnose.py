"""`trunk-drake diagnose DATA... --out DIR`: where the model departs from the data, which effect, how far it shrinks."""

from __future__ import annotations

import json

from trunk_drake.commands import cluster_argument, count, dofs_argument, positive
from trunk_drake.gap.catalogue import CATALOGUE


def add_command(sub) -> None:
    p = sub.add_parser("diagnose", help="diagnose the sim-to-real gap: where, which unmodelled effect, how far it shrinks",
                       description="Trials (CSV/.sto/.mot or folders; a conditions.toml beside them sets the known conditions) "
                                   "against the model with the given reflex gains.")
    p.add_argument("data", nargs="+", help="trial files or folders (at least two trials)")
    p.add_argument("--out", required=True, help="output folder (report.md, diagnosis.json, figures; while it runs, its "
                                                 "simulations, so that the same command resumes an interrupted diagnosis)")
    p.add_argument("--conditions", help="TOML with a [conditions] table (default: conditions.toml beside the data)")
    p.add_argument("--gains", help="TOML with [kp] and [kv] per group: the model's reflex gains (e.g. a fit's gains.toml; "
                                   "default: the gains of the data's preset)")
    dofs_argument(p, default=None)
    p.add_argument("--noise-deg", type=positive, help="angle measurement noise (default: conditions, else estimated)")
    p.add_argument("--candidates", nargs="*", choices=[e.name for e in CATALOGUE], metavar="EFFECT",
                   help=f"candidate effects (default: the whole catalogue: {', '.join(e.name for e in CATALOGUE)})")
    p.add_argument("--threshold", type=float, default=10.0, help="held-out dBIC needed to claim an effect")
    p.add_argument("--refine", type=count, default=3,
                   help="candidates refined with nonlinear simulations (after the polish: the best check and every one "
                        "within the threshold of it or passing it)")
    p.add_argument("--gains-first", action="store_true",
                   help="widen the reflex gains beyond the identifiable directions (as far as each further direction "
                        "passes the threshold) before weighing any effect")
    p.add_argument("--workers", type=count, default=2, help="parallel simulation processes")
    cluster_argument(p, "the simulations")
    p.add_argument("--no-animation", action="store_true",
                   help="skip the two animations of the first trial (nominal and diagnosed model against the data)")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run, resumable=True)


def run(args) -> int:
    from pathlib import Path

    import numpy as np

    from trunk_drake.diagram import TrunkOptions
    from trunk_drake.gap.checkpoint import LOG_NAME
    from trunk_drake.gap.diagnose import diagnose_gap
    from trunk_drake.gap.report import write_diagnosis
    from trunk_drake.io.experiment import load_experiment
    from trunk_drake.io.trials import available_outputs

    experiment = load_experiment(args.data, args.conditions)
    if len(experiment.trials) < 2:
        raise ValueError(f"diagnose needs at least two trials (the effects are scored on held-out data), got "
                         f"{len(experiment.trials)}: {experiment.source}")
    options = {**experiment.options, **nominal_gains(experiment, args.gains, say=not args.json)}
    noise = np.radians(args.noise_deg) if args.noise_deg is not None else experiment.noise_rad
    model = experiment.model(args.dofs)
    if not args.no_animation and model.spec.path_semantics == "opensim":  # refused now, not after the diagnosis
        raise ValueError(f"the animations draw MyoTorso's muscle paths only, not those of {model.spec.name}: give --no-animation")
    diagnosis = diagnose_gap(model, experiment.trials, TrunkOptions(**options), noise=noise,
                             outputs=available_outputs(experiment.trials),
                             candidates=args.candidates, threshold=args.threshold, refine=args.refine,
                             period=experiment.period, fade=experiment.fade, workers=args.workers, cluster=args.cluster,
                             gains_first=args.gains_first,
                             progress=not args.json, checkpoint=Path(args.out) / LOG_NAME)
    animations = {} if args.no_animation else _animations(model, experiment.trials[0], TrunkOptions(**options), diagnosis, args.out)
    files = write_diagnosis(diagnosis, args.out, animations)
    (Path(args.out) / LOG_NAME).unlink(missing_ok=True)  # saved: an interruption before here resumed from the log
    if args.json:
        print(json.dumps({"verdict": diagnosis.verdict, "selected": diagnosis.selected, "final": diagnosis.final,
                          "shrink": {k: v for k, v in diagnosis.shrink.items() if k != "per_trial"},
                          "wall_time_s": diagnosis.wall_time_s, "files": {k: str(v) for k, v in files.items()}},
                         indent=2, default=str))
    else:
        print(f"{diagnosis.verdict}\nreport: {files['report']}")
    return 0


def nominal_gains(experiment, gains_file: str | None, say: bool = True) -> dict:
    """The reflex gains of the model diagnosed: `gains_file`'s, else the data's preset's (said on stdout); neither:
    none, with a warning (a model without stretch reflexes is rarely what is meant)."""
    import warnings

    from trunk_drake.simulation import load_reflex_gains

    if gains_file:
        return load_reflex_gains(gains_file)
    preset = experiment.preset_gains()
    if preset is not None:
        if say:
            print(f"reflex gains: those of the data's preset, {experiment.preset} (give --gains FILE for others, e.g. a fit's "
                  "gains.toml)")
        return preset
    warnings.warn("no reflex gains: neither --gains nor a preset with reflexes in the data's conditions, so the model "
                  "diagnosed has no stretch reflexes; give --gains FILE (e.g. a fit's gains.toml)")
    return {}


def _animations(model, trial, nominal, diagnosis, out) -> dict:
    """The first trial against the nominal and the diagnosed model, as pages (data over model)."""
    from pathlib import Path

    from trunk_drake.visual import animate_trial

    name = Path(trial.source or "trial").name
    runs = {"nominal": (nominal, "nominal model"),
            "diagnosed": (diagnosis.final_options, "diagnosed model (" + (", ".join(diagnosis.selected) or "gains refitted") + ")")}
    return {f"{text} against {name}": animate_trial(trial, Path(out) / f"animation_{key}.html", model, options,
                                                    title=f"trunk-drake diagnose: {text} against {name}", label=name)
            for key, (options, text) in runs.items()}
