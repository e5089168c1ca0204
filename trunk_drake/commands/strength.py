"""`trunk-drake strength`: maximal isometric trunk strength with the in vivo comparison."""

from __future__ import annotations

from trunk_drake.commands import print_json
from trunk_drake.optim.strength import DIRECTIONS, THESIS_STEP


def add_command(sub) -> None:
    p = sub.add_parser("strength", help="maximal isometric trunk strength (pelvis locked) with the in vivo comparison")
    p.add_argument("--direction", choices=[*DIRECTIONS, "all"], default="all")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.add_argument("--no-sweep", action="store_true", help="skip the thesis' 10 N sweep (direct maximum only)")
    p.add_argument("--step", type=float, default=THESIS_STEP, help="sweep step, N (default 10)")
    p.add_argument("--strength-scale", type=float, default=1.0, help="multiplies every max isometric force")
    p.add_argument("--min-activation", type=float, default=0.01)
    p.add_argument("--p", type=float, default=2.0, help="activation exponent of static optimisation (>= 1)")
    p.add_argument("--shoulder", choices=["model", "acromion"], default="model", help="lateral load point")
    p.add_argument("--lock", nargs="*", default=[], metavar="COORD", help="coordinates (or globs) held by a lock")
    p.set_defaults(func=run)


def run(args) -> int:
    from trunk_drake.model.trunk_model import load_model
    from trunk_drake.optim.static import StaticInfeasibleError
    from trunk_drake.optim.strength import StrengthResult, format_strength, isometric_strength, strength_report

    model = load_model(dofs="spine3d")
    directions = DIRECTIONS if args.direction == "all" else (args.direction,)
    options = {"p": args.p, "min_activation": args.min_activation, "strength_scale": args.strength_scale}
    results = {}
    for direction in directions:
        try:
            results.update(isometric_strength(model, (direction,), shoulder=args.shoulder, sweep=not args.no_sweep,
                                              step=args.step, locked=args.lock, **options))
        except StaticInfeasibleError as err:
            results[direction] = err
    report = strength_report(results, model, {**options, "shoulder": args.shoulder, "locked": args.lock, "step_N": args.step})
    print_json(report) if args.json else print(format_strength(report))
    return 0 if all(isinstance(r, StrengthResult) for r in results.values()) else 1
