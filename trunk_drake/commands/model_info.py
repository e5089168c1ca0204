"""`trunk-drake model info [--dofs sagittal|spine3d|rhythm|all] [--json]`."""

from __future__ import annotations

from trunk_drake.commands import dofs_argument, group, print_json


def add_command(sub) -> None:
    info = group(sub, "model", "inspect the trunk model").add_parser(
        "info", help="coordinates, muscles per group, masses, upper-body centre of mass")
    dofs_argument(info, ("sagittal", "spine3d", "rhythm", "all"))
    info.add_argument("--json", action="store_true", help="print JSON instead of text")
    info.set_defaults(func=run)


def run(args) -> int:
    from trunk_drake.model.info import format_model_info, model_info
    from trunk_drake.model.trunk_model import load_model

    info = model_info(load_model(dofs=args.dofs))
    print_json(info) if args.json else print(format_model_info(info))
    return 0
