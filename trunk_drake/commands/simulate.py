"""`trunk-drake simulate --out DIR ...`: one forward simulation under a multisine pelvis perturbation."""

from __future__ import annotations

import argparse

from trunk_drake.commands import add_passenger_arguments, passenger, positive, print_json


BANDWIDTHS = (1.0, 3.0, 10.0)


def accuracy(text: str) -> float:
    value = positive(text)
    if value >= 1:
        raise argparse.ArgumentTypeError(f"must lie in (0, 1), got {text}")
    return value


def add_command(sub) -> None:
    p = sub.add_parser("simulate", help="forward-simulate a pelvis-perturbation trial",
                       description="Simulate the seated trunk (210 muscles, stretch reflexes, bushings) under a "
                                   "multisine pelvis perturbation; writes .sto, CSV, JSON and a PNG plot.")
    p.add_argument("--duration", type=positive, default=20.0, help="simulated seconds (default 20)")
    p.add_argument("--bandwidth", type=float, choices=BANDWIDTHS, default=1.0,
                   help="highest perturbation frequency, Hz: 1, 3 or 10 (the thesis' multisines)")
    p.add_argument("--seed", type=int, default=0, help="multisine phase seed")
    p.add_argument("--lowpass-hz", type=positive, default=None, help="low-pass the perturbation (the thesis used 2 Hz)")
    add_passenger_arguments(p)
    p.add_argument("--tendon", choices=["rigid", "compliant"], default="rigid")
    p.add_argument("--pelvis", choices=["prescribed", "force"], default="prescribed",
                   help="exact prescribed pelvis motion, or the thesis' 10,000 kg force-driven pelvis")
    p.add_argument("--accuracy", type=accuracy, default=None,
                   help="integrator target accuracy, in (0, 1) (default: the integrator's, 1e-3 on the rhythm, 1e-2 with radau3)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--html", action="store_true",
                   help="also write animation.html: the run in 3-D (bones, muscles by activation), opens offline")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--progress", action="store_true", help="show a progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    from trunk_drake.simulation import simulate

    model, options = passenger(args)
    if args.html and model.spec.path_semantics == "opensim":  # refused now, not after the simulation
        raise ValueError(f"--html draws MyoTorso's muscle paths only, not those of {model.spec.name}: leave it out")
    result = simulate(
        model, duration=args.duration, bandwidth=args.bandwidth, seed=args.seed, lowpass_hz=args.lowpass_hz, tendon=args.tendon,
        pelvis=args.pelvis, accuracy=args.accuracy, progress=args.progress, options=options,
    )
    files = result.write(args.out)
    if model.spec.path_semantics == "opensim":  # --model FILE.osim: results OpenSim loads with that file
        from trunk_drake.io.opensim_export import write_opensim_results

        files.update(write_opensim_results(result, model, args.out))
    if args.html:
        from pathlib import Path

        from trunk_drake.visual import animate

        title = f"trunk-drake simulate --duration {args.duration:g} --bandwidth {args.bandwidth:g}"
        files["animation"] = animate(result, Path(args.out) / "animation.html", model, title=title)
    summary = {**result.summary(), "files": {k: str(v) for k, v in files.items()}}
    if args.json:
        print_json(summary)
    else:
        print(f"simulated {summary['sim_time_s']:.1f} s in {summary['wall_time_s']:.2f} s "
              f"(real-time factor {summary['real_time_factor']:.1f}, {summary['steps']} steps); results in {args.out}")
        if summary["warning"]:
            print(f"warning: {summary['warning']}")
    return 0
