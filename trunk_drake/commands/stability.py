"""`trunk-drake stability`: is the upright posture stable, by what margin, in which mode, and what would make it so?"""

from __future__ import annotations

from trunk_drake.commands import add_passenger_arguments, passenger_options, print_json


def add_command(sub) -> None:
    from trunk_drake.model.plant import DOFS

    p = sub.add_parser("stability", help="static and dynamic stability of the upright posture, and what would stabilise it",
                       description="Energy Hessian (static) and closed-loop characteristic roots (dynamic) of the trunk "
                                   "about its upright posture, the reflexes engaged there, and the smallest co-activation, "
                                   "reflex gain scale and bushing stiffness that make it stable. Same options as simulate.")
    p.add_argument("--dofs", choices=DOFS, default="sagittal", help="model configuration (spine3d: static analysis only)")
    add_passenger_arguments(p)
    p.add_argument("--reflex-delay", type=float, default=0.0, help="stretch-reflex transport delay, s")
    p.add_argument("--l-desired", default="1", help="reflex set point: a normalised fiber length (default 1) or 'neutral'")
    p.add_argument("--no-critical", action="store_true", help="skip the critical co-activation, gain and stiffness")
    p.add_argument("--out", default=None, help="folder for stability.json and the PNG plots")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=run)


def run(args) -> int:
    import json
    from pathlib import Path

    from trunk_drake.diagram import TrunkOptions
    from trunk_drake.metadata import json_default
    from trunk_drake.model.trunk_model import load_model
    from trunk_drake.optim.stability import stability

    l_desired = args.l_desired if args.l_desired == "neutral" else _number(args.l_desired, "--l-desired")
    model = load_model(args.dofs)
    options = TrunkOptions(reflex_delay=args.reflex_delay, l_desired=l_desired, **passenger_options(args, model))
    result = stability(model, options, critical=not args.no_critical)
    summary = result.summary()
    if args.out:
        from trunk_drake.plots import plot_stability

        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        files = {"json": out / "stability.json", **plot_stability(result, out)}
        files["json"].write_text(json.dumps(summary, indent=2, default=json_default))
        summary["files"] = {k: str(v) for k, v in files.items()}
    if args.json:
        print_json(summary)
    else:
        print("\n".join(result.verdict()))
        if args.out:
            print(f"results in {args.out}")
    return 0


def _number(text: str, option: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{option} {text!r} is neither a number nor 'neutral'") from None
