"""Command line: `trunk-drake <command> ...` (see `trunk-drake --help`).

Each room of the package contributes its commands: a module listed in COMMAND_MODULES
defines ``add_commands(subparsers)``, whose sub-parsers set ``func(args) -> exit code``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import sys

from trunk_drake.metadata import json_default

COMMAND_MODULES = (
    "trunk_drake.model.info",
    "trunk_drake.simulation",
    "trunk_drake.optim.fit",
    "trunk_drake.gap.commands",
    "trunk_drake.optim.strength",
    "trunk_drake.reproduce",
)


def print_json(data) -> None:
    """Print `data` as indented JSON (numpy arrays and scalars allowed)."""
    print(json.dumps(data, indent=2, default=json_default))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="trunk-drake", description="Neuromusculoskeletal lumbar-spine simulation on Drake.")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError, KeyError) as err:
        print(f"trunk-drake: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
