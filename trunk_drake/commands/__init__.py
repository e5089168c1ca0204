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
from pathlib import Path

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


def cluster_argument(parser, runs: str) -> None:
    """--cluster ADDRESS: a Dask scheduler whose workers run `runs` (instead of local processes)."""
    parser.add_argument("--cluster", default=None, metavar="ADDRESS",
                        help=f"Dask scheduler address, e.g. tcp://host:8786: {runs} run on its workers (--workers is then unused)")


def published_case_arguments(doc: str, quick: str) -> argparse.Namespace:
    """The command line `CASE RUN_FOLDER [--quick]` of a check on a published gap-benchmark case
    (analyses/gap_*_check.py): `doc`, the script's docstring; `quick`, what `--quick` shortens."""
    parser = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    parser.add_argument("case", help="the case's name (trunk-drake gap-benchmark --help lists the cases)")
    parser.add_argument("folder", help="the run's folder, e.g. docs/gap_benchmark/all_gains")
    parser.add_argument("--quick", action="store_true", help=f"{quick} (a check that it runs, not a result)")
    return parser.parse_args()


def plain_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """warnings.showwarning for users: one line, no Python source."""
    print(f"warning: {message}", file=file or sys.stderr)


def print_json(data) -> None:
    """Print `data` as indented JSON (numpy arrays and scalars allowed)."""
    print(json.dumps(data, indent=2, default=json_default))


def add_passenger_arguments(p, dofs_choices=("sagittal", "rhythm")) -> None:
    """`--preset` (the passenger configuration, models/presets/) and options overriding single settings
    of it, shared by the commands that build a trunk diagram; read them back with `passenger` (or
    `passenger_preset`)."""
    from trunk_drake.presets import DEFAULT_PRESET, preset_names

    p.add_argument("--preset", default=DEFAULT_PRESET,
                   help=f"passenger configuration: a name in models/presets ({', '.join(preset_names())}) or a TOML file; "
                        f"the options below override single settings of it (default: {DEFAULT_PRESET})")
    dofs_argument(p, dofs_choices, default=None)
    p.add_argument("--reflex-gains", default=None, help="TOML/JSON with [kp] and [kv] per group (FILE#set picks a set)")
    p.add_argument("--gain-scale", type=float, default=None, help="multiplies every reflex gain")
    p.add_argument("--no-reflex", action="store_true", help="switch the stretch reflexes off")
    p.add_argument("--coactivation", type=float, default=None,
                   help="minimum activation of the feed-forward co-activation (static optimisation at rest)")
    p.add_argument("--stiffness", type=float, default=None, help="bushing stiffness per lumbar level, Nm/rad")
    p.add_argument("--damping", type=float, default=None, help="bushing damping per lumbar level, Nms/rad")
    p.add_argument("--l-desired", default=None, help="reflex set point: a normalised fiber length (e.g. 1) or 'neutral'")
    p.add_argument("--reflex-delay", type=float, default=None, help="stretch-reflex transport delay, s")
    p.add_argument("--srs", action=argparse.BooleanOptionalAction, default=None,
                   help="short-range stiffness of active muscle (constants: models/reference_values.toml [muscle.srs])")


def passenger_preset(args):
    """The Preset of `--preset` with the single settings given on the command line."""
    from trunk_drake.presets import load_preset

    changes = {"dofs": args.dofs, "stiffness": args.stiffness, "damping": args.damping, "coactivation": args.coactivation,
               "gain_scale": args.gain_scale, "reflex_delay": args.reflex_delay, "srs": args.srs,
               "l_desired": None if args.l_desired is None else _set_point(args.l_desired),
               "reflex_gains": None if args.reflex_gains is None else _absolute(args.reflex_gains)}
    changes = {k: v for k, v in changes.items() if v is not None}
    if args.no_reflex:
        changes["reflex_gains"] = None
    preset = load_preset(args.preset)
    return preset.with_changes(**changes) if changes else preset


def passenger(args):
    """(model, TrunkOptions) of the command line's passenger (`--preset`, `--dofs` and single settings), the
    preset read once; the optimiser's warnings (residual moments of the co-activation) as one plain line each."""
    preset = passenger_preset(args)
    model = preset.model()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        options = preset.options(model)
    for warning in caught:
        print(f"warning: {warning.message}", file=sys.stderr)
    return model, options


def _absolute(gains: str) -> str:
    """A gains file given on the command line (FILE or FILE#set), relative to the working directory."""
    file, sep, name = gains.partition("#")
    return str(Path(file).resolve()) + sep + name


def _set_point(text: str):
    if text == "neutral":
        return text
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"--l-desired {text!r} is neither a number nor 'neutral'") from None


_CONFIGURATIONS = {"sagittal": "five independent lumbar flexion levels", "spine3d": "independent levels in 3-D, pelvis welded",
                   "rhythm": "one lumbar flexion coordinate moving the levels with Lumbar_C_210's rhythm",
                   "all": "every joint of the model as its file defines it (an .osim model without named lumbar levels)"}


def dofs_argument(parser, choices=("sagittal", "rhythm"), default: str | None = "sagittal") -> None:
    """`--dofs`: the model configuration a command runs on (trunk_drake.model.plant); default None: the preset's."""
    parser.add_argument("--dofs", choices=choices, default=default,
                        help="; ".join(f"{c}: {_CONFIGURATIONS[c]}" for c in choices)
                             + (f" (default {default})" if default else " (default: the preset's)"))
