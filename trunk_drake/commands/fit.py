"""`trunk-drake fit DATA... --out DIR`: reflex gains fitted to measured trials (or trunk settling)."""

from __future__ import annotations

from trunk_drake.commands import cluster_argument, count, dofs_argument, positive, print_json
from trunk_drake.optim.fit import MAX_ITERATIONS, THESIS_START


def add_command(sub) -> None:
    p = sub.add_parser("fit", help="fit stretch-reflex gains (kp, kv per muscle group) to measured trials",
                       description="Levenberg-Marquardt fit of the reflex gains to trials (CSV/.sto/.mot or folders). "
                                   "A conditions.toml beside the data sets the known conditions (bushings, co-activation, noise).")
    p.add_argument("data", nargs="*", help="trial files or folders (e.g. models/reference); none for --scenario settling")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--scenario", choices=sorted(THESIS_START), default="car")
    dofs_argument(p, default=None)
    p.add_argument("--conditions", help="TOML with a [conditions] table (default: conditions.toml beside the data)")
    p.add_argument("--outputs", choices=["total", "levels", "all"], default="all",
                   help="fit the total lumbar rotation, the five level angles, or all (default; those present in the data)")
    p.add_argument("--t-max", type=positive, default=None, metavar="SECONDS",
                   help="fit only the first SECONDS of each trial (a quick look; the FRF needs whole periods)")
    p.add_argument("--starts", type=count, default=1,
                   help="number of starting points (multi-start; the first: the data's preset's gains, else the thesis' initial values)")
    p.add_argument("--workers", type=count, default=2, help="parallel simulation processes")
    cluster_argument(p, "the simulations")
    p.add_argument("--max-iterations", type=count, default=MAX_ITERATIONS, help="per start")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run)


def run(args) -> int:
    import numpy as np

    from trunk_drake.diagram import TrunkOptions
    from trunk_drake.io.experiment import load_experiment
    from trunk_drake.io.trials import OUTPUT_NAMES, available_outputs
    from trunk_drake.optim.fit import fit_reflex_gains, settling_target, targets_from_trials, write_fit
    from trunk_drake.optim.static import coactivation

    names = {"total": ("lumbar_rotation",), "levels": OUTPUT_NAMES[1:], "all": OUTPUT_NAMES}[args.outputs]
    if args.scenario == "settling":
        from trunk_drake.model.trunk_model import load_model

        model = load_model(args.dofs or "sagittal")
        targets = [settling_target()]
        options = TrunkOptions(feedforward=coactivation(model, 0.02))
        start = None
    else:
        if not args.data:
            raise ValueError("the car scenario needs measured trials: trunk-drake fit DATA... --out DIR")
        experiment = load_experiment(args.data, args.conditions)
        model = experiment.model(args.dofs)
        present = available_outputs(experiment.trials)
        names = tuple(n for n in names if n in present) or names
        noise = experiment.noise_rad if experiment.noise_rad is not None else np.radians(0.1)
        targets = targets_from_trials(experiment.trials, names, noise, period=experiment.period,
                                      steady_start=experiment.fade, t_max=args.t_max)
        opts = dict(experiment.options)
        if "feedforward" not in opts:
            opts["feedforward"] = coactivation(model, experiment.coactivation_min_activation or 0.02)
        options = TrunkOptions(**opts)
        start = experiment.preset_gains()
    result = fit_reflex_gains(model, targets, scenario=args.scenario, options=options, start=start, n_starts=args.starts,
                              workers=args.workers, cluster=args.cluster, max_iterations=args.max_iterations, progress=not args.json)
    files = write_fit(result, args.out)
    summary = {"gains": result.gains, "std": result.std, "vaf": result.vaf, "cost": result.cost,
               "n_simulations": result.n_simulations, "wall_time_s": result.wall_time_s,
               "files": {k: str(v) for k, v in files.items()}}
    if args.json:
        print_json(summary)
    else:
        print(f"fitted {len(result.parameter_names)} gains in {result.wall_time_s:.0f} s ({result.n_simulations} simulations); "
              f"results in {args.out}")
    return 0
