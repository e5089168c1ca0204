"""`trunk-drake stability`: is the upright posture stable, by what margin, in which mode, and what would make it so?"""

from __future__ import annotations

from trunk_drake.commands import add_passenger_arguments, passenger, print_json


def add_command(sub) -> None:
    p = sub.add_parser("stability", help="static and dynamic stability of the upright posture, and what would stabilise it",
                       description="Energy Hessian (static) and closed-loop characteristic roots (dynamic) of the trunk "
                                   "about its upright posture, the reflexes engaged there, and the smallest co-activation, "
                                   "reflex gain scale and bushing stiffness that make it stable. Same options as simulate.")
    add_passenger_arguments(p, ("rhythm", "sagittal", "spine3d"))  # spine3d: static analysis only
    p.add_argument("--no-critical", action="store_true", help="skip the critical co-activation, gain and stiffness")
    p.add_argument("--out", default=None, help="folder for stability.json and the PNG plots")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=run)


def run(args) -> int:
    import json
    from pathlib import Path

    from trunk_drake.metadata import json_default
    from trunk_drake.optim.stability import stability

    model, options = passenger(args)
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

