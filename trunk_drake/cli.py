"""Command line: `trunk-drake <command> ...` (see `trunk-drake --help`)."""

from __future__ import annotations

import argparse
import json
import sys


def _json_default(obj):
    import numpy as np

    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"not JSON serialisable: {type(obj)}")


def print_json(data) -> None:
    print(json.dumps(data, indent=2, default=_json_default))


def cmd_model_info(args) -> int:
    from trunk_drake.model.info import format_model_info, model_info
    from trunk_drake.model.trunk_model import load_model

    info = model_info(load_model(dofs=args.dofs))
    print_json(info) if args.json else print(format_model_info(info))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="trunk-drake", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    model = sub.add_parser("model", help="inspect the trunk model").add_subparsers(dest="model_command", required=True)
    info = model.add_parser("info", help="coordinates, muscles per group, masses, upper-body centre of mass")
    info.add_argument("--dofs", choices=["sagittal", "spine3d"], default="sagittal")
    info.add_argument("--json", action="store_true", help="print JSON instead of text")
    info.set_defaults(func=cmd_model_info)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (ValueError, FileNotFoundError) as err:
        print(f"trunk-drake: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
