"""The commands of `trunk-drake`: one module per command, found by `trunk_drake.cli`.

Each module (names starting with "_" are skipped) defines ``add_command(subparsers)``, whose
parser sets ``func(args) -> exit code``; domain modules expose functions only.
"""

from __future__ import annotations

import importlib
import json
import pkgutil

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


def print_json(data) -> None:
    """Print `data` as indented JSON (numpy arrays and scalars allowed)."""
    print(json.dumps(data, indent=2, default=json_default))


_CONFIGURATIONS = {"sagittal": "five independent lumbar flexion levels", "spine3d": "independent levels in 3-D, pelvis welded",
                   "rhythm": "one lumbar flexion coordinate moving the levels with Lumbar_C_210's rhythm"}


def dofs_argument(parser, choices=("sagittal", "rhythm"), default: str = "sagittal") -> None:
    """`--dofs`: the model configuration a command runs on (trunk_drake.model.plant)."""
    parser.add_argument("--dofs", choices=choices, default=default,
                        help="; ".join(f"{c}: {_CONFIGURATIONS[c]}" for c in choices) + f" (default {default})")
