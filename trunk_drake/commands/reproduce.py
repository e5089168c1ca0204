"""`trunk-drake reproduce --out DIR [--only NAME ...] [--force] [--workers N]`: every thesis experiment."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

from trunk_drake.commands import count, plain_warning
from trunk_drake.reproduce import EXPERIMENTS, REPORT_MD


def add_run_arguments(parser) -> None:
    """Options shared by `trunk-drake reproduce` and the analyses/ scripts."""
    parser.add_argument("--out", required=True, help="output folder (report.md, report.json, one folder per experiment)")
    parser.add_argument("--workers", type=count, default=2, help="parallel processes for sweeps and fits (default 2)")
    parser.add_argument("--force", action="store_true", help="recompute experiments already in report.json")
    parser.add_argument("--quick", action="store_true",
                        help="every experiment shortened to seconds (a check that each runs, not a result)")


def add_command(sub) -> None:
    p = sub.add_parser("reproduce", help="run every thesis experiment (analyses/) and write a Markdown + PNG report",
                       description="Runs the thesis' experiments on the default model (MyoTorso) and writes report.md "
                                   "(thesis vs trunk-drake, side by side), report.json and the figures into --out.")
    add_run_arguments(p)
    p.add_argument("--only", nargs="+", metavar="NAME", choices=[e.name for e in EXPERIMENTS],
                   help="run only these experiments (and what they require)")
    p.set_defaults(func=run, resumable=True)


def run(args) -> int:
    from trunk_drake.reproduce import run_experiments

    report = run_experiments(args.out, args.only, force=args.force, workers=args.workers, quick=args.quick)
    failed = [n for n in report["run"]["selected"] if report["experiments"][n].get("status") != "ok"]
    if failed:
        print(f"trunk-drake: failed experiments: {', '.join(failed)} (see {Path(args.out) / REPORT_MD})", file=sys.stderr)
    return 1 if failed else 0


def script_main(script: str) -> int:
    """Entry point of an analyses/<name>.py script: run it (and what it requires) into --out."""
    import argparse

    from trunk_drake.reproduce import experiment, run_experiments

    name = Path(script).stem
    parser = argparse.ArgumentParser(description=f"{experiment(name).title}: run it and write report.md/.json into --out")
    add_run_arguments(parser)
    args = parser.parse_args()
    with warnings.catch_warnings():
        warnings.showwarning = plain_warning
        report = run_experiments(args.out, [name], force=args.force, workers=args.workers, quick=args.quick)
    return 0 if report["experiments"][name]["status"] == "ok" else 1
