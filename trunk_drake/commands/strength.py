"""`trunk-drake strength`: maximal isometric trunk strength with the in vivo comparison."""

from __future__ import annotations

import numpy as np

from trunk_drake.commands import dofs_argument, print_json
from trunk_drake.optim.strength import DIRECTIONS, THESIS_STEP


def add_command(sub) -> None:
    p = sub.add_parser("strength", help="maximal isometric trunk strength (pelvis locked) with the in vivo comparison")
    dofs_argument(p, ("spine3d", "sagittal", "rhythm"), "spine3d")
    p.add_argument("--direction", choices=[*DIRECTIONS, "all"], default="all", help="all: every direction the configuration supports")
    p.add_argument("--tolerance-deg", type=float, default=0.0,
                   help="each independent level may deflect up to this angle on its bushing instead of balancing exactly")
    p.add_argument("--no-passive", action="store_true", help="leave passive muscle force out of the balance (OpenSim's tool does)")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.add_argument("--no-sweep", action="store_true", help="skip the thesis' 10 N sweep (direct maximum only)")
    p.add_argument("--step", type=float, default=THESIS_STEP, help="sweep step, N (default 10)")
    p.add_argument("--strength-scale", type=float, default=1.0, help="multiplies every max isometric force")
    p.add_argument("--min-activation", type=float, default=0.0, help="lower activation bound (thesis: 0.01)")
    p.add_argument("--p", type=float, default=2.0, help="activation exponent of static optimisation (>= 1)")
    p.add_argument("--shoulder", choices=["model", "acromion"], default="model", help="lateral load point")
    p.add_argument("--lock", nargs="*", default=[], metavar="COORD", help="coordinates (or globs) held by a lock")
    p.set_defaults(func=run)


def run(args) -> int:
    from trunk_drake.model.trunk_model import load_model
    from trunk_drake.optim.static import StaticInfeasibleError
    from trunk_drake.optim.strength import (
        StrengthResult, format_strength, isometric_strength, strength_report, supported_directions,
    )

    model = load_model(dofs=args.dofs)
    directions = supported_directions(model) if args.direction == "all" else (args.direction,)
    options = {"p": args.p, "min_activation": args.min_activation, "strength_scale": args.strength_scale,
               "include_passive": not args.no_passive, "deflection_tolerance": np.radians(args.tolerance_deg)}
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
