"""Command line: `trunk-drake <command> ...` (see `trunk-drake --help`).

The commands are the modules of `trunk_drake.commands` (one module per command).
"""

from __future__ import annotations

import argparse
import sys

from trunk_drake.commands import command_modules


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="trunk-drake", description="Neuromusculoskeletal lumbar-spine simulation on Drake.")
    sub = parser.add_subparsers(dest="command", required=True)
    for module in command_modules():
        module.add_command(sub)
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
