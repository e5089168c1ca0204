"""`trunk-drake gap-benchmark --out DIR`: diagnose synthetic data whose effect was withheld."""

from __future__ import annotations

import json

from trunk_drake.commands import cluster_argument, count, positive
from trunk_drake.gap.benchmark import CLASSES, cases
from trunk_drake.gap.catalogue import CATALOGUE


def add_command(sub) -> None:
    b = sub.add_parser("gap-benchmark", help="diagnose data whose effect was withheld: confusion matrix and gap reduction")
    b.add_argument("--out", required=True, help="output folder (results.jsonl, summary.md/json, one report per case)")
    b.add_argument("--quick", action="store_true",
                   help="one magnitude per effect, 4 of the 8 pairs, 3 of the 4 outside mechanisms, 2 no-effect cases (20 cases)")
    b.add_argument("--noise-deg", type=positive, default=None, help="angle noise (default 0.1 deg)")
    b.add_argument("--case", nargs="+", metavar="NAME", choices=[*CLASSES, *(c.name for c in cases())], default=None,
                   help=f"run only these cases, or every case of these classes ({', '.join(CLASSES)}); "
                        f"cases: {', '.join(c.name for c in cases())}")
    b.add_argument("--candidates", nargs="+", choices=[e.name for e in CATALOGUE], metavar="EFFECT", default=None,
                   help="the effects each diagnosis chooses among (default: the whole catalogue); a restricted "
                        "catalogue is a different benchmark: a folder resumes only with the candidates it began with")
    b.add_argument("--workers", type=count, default=2,
                   help="local processes: the cases run on them in parallel (one case: its diagnosis does)")
    cluster_argument(b, "the cases (in parallel, one per worker)")
    b.add_argument("--gains-first", action="store_true",
                   help="the search variant that widens the gains before weighing any effect (a different benchmark: "
                        "a folder resumes only with the variant it began with)")
    b.add_argument("--json", action="store_true", help="print the summary as JSON")
    b.set_defaults(func=run, resumable=True)


def _line(text: str) -> None:
    print(text, flush=True)  # one line per finished case, visible at once also when redirected to a file


def run(args) -> int:
    from trunk_drake.gap.benchmark import DEFAULT_NOISE_DEG, run_benchmark

    summary = run_benchmark(args.out, quick=args.quick, noise_deg=args.noise_deg or DEFAULT_NOISE_DEG,
                            workers=args.workers, progress=None if args.json else _line, cluster=args.cluster,
                            only=args.case, candidates=args.candidates, gains_first=args.gains_first)
    if args.json:
        print(json.dumps({k: v for k, v in summary.items() if k != "rows"}, indent=2, default=str))
    else:
        print(f"summary: {args.out}/summary.md")
    return 0
