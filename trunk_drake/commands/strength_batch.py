"""`trunk-drake strength-batch GRID.toml --out DIR [--cluster ADDRESS] [--workers N]`."""

from __future__ import annotations

from trunk_drake.commands import cluster_argument, count, print_json


def add_command(sub) -> None:
    p = sub.add_parser("strength-batch", help="isometric strength over a grid of cases (parallel, resumable)")
    p.add_argument("grid", help="grid file (TOML), e.g. models/strength_grid_example.toml")
    p.add_argument("--out", required=True, help="output folder (results.jsonl, results.csv); rerun to resume")
    cluster_argument(p, "the cases")
    p.add_argument("--workers", type=count, default=None, help="local worker processes (default: CPU count)")
    p.add_argument("--retry-failed", action="store_true", help="rerun cases recorded as failed")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.set_defaults(func=run, resumable=True)


def run(args) -> int:
    import sys

    from trunk_drake.batch import load_grid, run_batch

    cases = load_grid(args.grid)
    try:
        counts = run_batch(cases, args.out, cluster=args.cluster, workers=args.workers,
                           progress=not args.no_progress, retry_failed=args.retry_failed)
    except RuntimeError as err:
        print(f"trunk-drake strength-batch: error: {err}", file=sys.stderr)
        return 1
    print_json(counts)
    if counts["failed_total"]:
        print(f"trunk-drake strength-batch: {counts['failed_total']} of {counts['cases']} cases failed: their errors are in "
              f"{counts['csv']} (--retry-failed reruns them)", file=sys.stderr)
        return 1
    return 0
