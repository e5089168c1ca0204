"""`trunk-drake gap-benchmark --out DIR`: diagnose synthetic data whose effect was withheld."""

from __future__ import annotations

import json


def add_command(sub) -> None:
    b = sub.add_parser("gap-benchmark", help="diagnose data whose effect was withheld: confusion matrix and gap reduction")
    b.add_argument("--out", required=True, help="output folder (results.jsonl, summary.md/json, one report per case)")
    b.add_argument("--quick", action="store_true",
                   help="one magnitude per effect, 4 of the 8 pairs, 3 of the 4 outside mechanisms, 2 no-effect cases (20 cases)")
    b.add_argument("--only", help="only the cases whose name contains this text (e.g. a class: 'outside', '+' for pairs)")
    b.add_argument("--noise-deg", type=float, default=None, help="angle noise (default 0.1 deg)")
    b.add_argument("--workers", type=int, default=2)
    b.add_argument("--json", action="store_true", help="print the summary as JSON")
    b.set_defaults(func=run)


def run(args) -> int:
    from trunk_drake.gap.benchmark import DEFAULT_NOISE_DEG, run_benchmark

    summary = run_benchmark(args.out, quick=args.quick, noise_deg=args.noise_deg or DEFAULT_NOISE_DEG,
                            workers=args.workers, only=args.only, progress=None if args.json else print)
    if args.json:
        print(json.dumps({k: v for k, v in summary.items() if k != "rows"}, indent=2, default=str))
    else:
        print(f"summary: {args.out}/summary.md")
    return 0
