"""`trunk-drake simulate --out DIR ...`: one forward simulation under a multisine pelvis perturbation."""

from __future__ import annotations

from trunk_drake.commands import dofs_argument, print_json
from trunk_drake.simulation import DEFAULT_ACCURACY, DEFAULT_GAINS


def add_command(sub) -> None:
    p = sub.add_parser("simulate", help="forward-simulate a pelvis-perturbation trial",
                       description="Simulate the seated trunk (210 muscles, stretch reflexes, bushings) under a "
                                   "multisine pelvis perturbation; writes .sto, CSV, JSON and a PNG plot.")
    p.add_argument("--duration", type=float, default=20.0, help="simulated seconds (default 20)")
    p.add_argument("--bandwidth", type=float, default=1.0, help="highest perturbation frequency, Hz (1, 3 or 10)")
    p.add_argument("--seed", type=int, default=0, help="multisine phase seed")
    p.add_argument("--lowpass-hz", type=float, default=None, help="low-pass the perturbation (the thesis used 2 Hz)")
    p.add_argument("--reflex-gains", default=None,
                   help=f"TOML/JSON with [kp] and [kv] per group (FILE#set picks a set); default: models/{DEFAULT_GAINS}")
    p.add_argument("--no-reflex", action="store_true", help="switch the stretch reflexes off")
    p.add_argument("--tendon", choices=["rigid", "compliant"], default="rigid")
    dofs_argument(p)
    p.add_argument("--coactivation", type=float, default=0.02,
                   help="minimum activation of the feed-forward co-activation (default 0.02, as the thesis)")
    p.add_argument("--stiffness", type=float, default=125.0, help="bushing stiffness, Nm/rad (thesis final: 125)")
    p.add_argument("--damping", type=float, default=7.5, help="bushing damping, Nms/rad")
    p.add_argument("--pelvis", choices=["prescribed", "force"], default="prescribed",
                   help="exact prescribed pelvis motion, or the thesis' 10,000 kg force-driven pelvis")
    p.add_argument("--accuracy", type=float, default=DEFAULT_ACCURACY, help="integrator target accuracy")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.add_argument("--progress", action="store_true", help="show a progress bar")
    p.set_defaults(func=run)


def run(args) -> int:
    from trunk_drake.data import models_dir
    from trunk_drake.model.trunk_model import load_model
    from trunk_drake.optim.static import coactivation
    from trunk_drake.simulation import load_reflex_gains, simulate

    model = load_model(args.dofs)
    gains = {"kp": 0.0, "kv": 0.0} if args.no_reflex else load_reflex_gains(args.reflex_gains or models_dir() / DEFAULT_GAINS)
    result = simulate(
        model, duration=args.duration, bandwidth=args.bandwidth, seed=args.seed, lowpass_hz=args.lowpass_hz, tendon=args.tendon,
        feedforward=coactivation(model, args.coactivation), stiffness=args.stiffness, damping=args.damping,
        pelvis=args.pelvis, accuracy=args.accuracy, progress=args.progress, **gains,
    )
    files = result.write(args.out)
    summary = {**result.summary(), "files": {k: str(v) for k, v in files.items()}}
    if args.json:
        print_json(summary)
    else:
        print(f"simulated {summary['sim_time_s']:.1f} s in {summary['wall_time_s']:.2f} s "
              f"(real-time factor {summary['real_time_factor']:.1f}, {summary['steps']} steps); results in {args.out}")
        if summary["warning"]:
            print(f"warning: {summary['warning']}")
    return 0
