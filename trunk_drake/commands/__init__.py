"""The commands of `trunk-drake`: one module per command, found by `trunk_drake.cli`.

Each module (names starting with "_" are skipped) defines ``add_command(subparsers)``, whose
parser sets ``func(args) -> exit code``; domain modules expose functions only.
"""

from __future__ import annotations

import argparse
import importlib
import json
import pkgutil
import sys
import warnings

from trunk_drake.metadata import json_default


def command_modules() -> list:
    """The command modules of this package, by name."""
    return [importlib.import_module(f"{__name__}.{m.name}") for m in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name)
            if not m.name.startswith("_")]


def group(sub, name: str, help: str):
    """The sub-parsers of a command group (`trunk-drake NAME ...`), created on first use, so
    several modules can add sub-commands to one group (e.g. `model info`)."""
    if name not in sub.choices:
        parser = sub.add_parser(name, help=help)
        parser.set_defaults(group_commands=parser.add_subparsers(dest=f"{name}_command", required=True))
    return sub.choices[name].get_default("group_commands")


def positive(text: str) -> float:
    """argparse type: a finite number > 0 (argparse names the option in its error)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"must be a number > 0, got {text}")
    return value


def count(text: str) -> int:
    """argparse type: a whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value


def plain_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """warnings.showwarning for users: one line, no Python source."""
    print(f"warning: {message}", file=file or sys.stderr)


def print_json(data) -> None:
    """Print `data` as indented JSON (numpy arrays and scalars allowed)."""
    print(json.dumps(data, indent=2, default=json_default))


def add_passenger_arguments(p) -> None:
    """Options that configure the passenger (reflexes, co-activation, bushings, short-range stiffness),
    shared by the commands that build a trunk diagram; read them back with `passenger_options`."""
    from trunk_drake.simulation import DEFAULT_GAINS

    p.add_argument("--reflex-gains", default=None,
                   help=f"TOML/JSON with [kp] and [kv] per group (FILE#set picks a set); default: models/{DEFAULT_GAINS}")
    p.add_argument("--no-reflex", action="store_true", help="switch the stretch reflexes off")
    p.add_argument("--coactivation", type=float, default=0.02,
                   help="minimum activation of the feed-forward co-activation (default 0.02, as the thesis)")
    p.add_argument("--stiffness", type=float, default=125.0, help="bushing stiffness, Nm/rad (thesis final: 125)")
    p.add_argument("--damping", type=float, default=7.5, help="bushing damping, Nms/rad")
    p.add_argument("--srs", action="store_true",
                   help="short-range stiffness of active muscle (constants: models/reference_values.toml [muscle.srs])")


def passenger_options(args, model) -> dict:
    """TrunkOptions fields (and simulate() keywords) from the arguments of `add_passenger_arguments`."""
    from trunk_drake.data import models_dir
    from trunk_drake.muscle.short_range import ShortRangeStiffness
    from trunk_drake.optim.static import coactivation
    from trunk_drake.simulation import DEFAULT_GAINS, load_reflex_gains

    gains = {"kp": 0.0, "kv": 0.0} if args.no_reflex else load_reflex_gains(args.reflex_gains or models_dir() / DEFAULT_GAINS)
    with warnings.catch_warnings(record=True) as caught:  # one plain line each, no source line
        warnings.simplefilter("always")
        feedforward = coactivation(model, args.coactivation)
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    return {"feedforward": feedforward, "stiffness": args.stiffness, "damping": args.damping,
            "srs": ShortRangeStiffness.from_reference() if args.srs else None, **gains}


_CONFIGURATIONS = {"sagittal": "five independent lumbar flexion levels", "spine3d": "independent levels in 3-D, pelvis welded",
                   "rhythm": "one lumbar flexion coordinate moving the levels with Lumbar_C_210's rhythm"}


def dofs_argument(parser, choices=("sagittal", "rhythm"), default: str = "sagittal") -> None:
    """`--dofs`: the model configuration a command runs on (trunk_drake.model.plant)."""
    parser.add_argument("--dofs", choices=choices, default=default,
                        help="; ".join(f"{c}: {_CONFIGURATIONS[c]}" for c in choices) + f" (default {default})")
