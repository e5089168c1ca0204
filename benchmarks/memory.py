"""Benchmark: memory kept per forward simulation and per stability analysis of the default passenger; prints JSON.

A fit or gap diagnosis is a loop of hundreds of simulations in one process, so what each one leaves behind
decides whether a long run fits in memory. Measured as the growth of the resident set size (RSS) over
`--repeats` repetitions after one warm-up, divided by the repetitions, with the number of MuscleSystem
objects still alive (0 when every diagram was freed). Before `diagram.release` and the weak callbacks
(`systems.weak`) each simulation kept about 11 MB (pydrake never freed a diagram with Python systems).

    python benchmarks/memory.py [--repeats 20] [--duration 0.5]
"""

import argparse
import gc
import json
import os
import platform
import time

import trunk_drake as td
from trunk_drake.diagram import muscle_systems_alive
from trunk_drake.metadata import package_versions
from trunk_drake.optim.stability import stability
from trunk_drake.simulation import simulate


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def growth(work, repeats: int) -> dict:
    work()
    gc.collect()
    before, alive_before, start = rss_mb(), muscle_systems_alive(), time.perf_counter()
    for _ in range(repeats):
        work()
    gc.collect()
    return {"repeats": repeats, "rss_before_mb": round(before, 1), "rss_after_mb": round(rss_mb(), 1),
            "kept_mb_per_repeat": round((rss_mb() - before) / repeats, 3),
            "muscle_systems_kept": muscle_systems_alive() - alive_before,
            "wall_s_per_repeat": round((time.perf_counter() - start) / repeats, 3)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--duration", type=float, default=0.5, help="simulated seconds per simulation")
    args = parser.parse_args()
    preset = td.load_preset("default")
    model = preset.model()
    options = preset.options(model)
    out = {"machine": platform.processor() or platform.machine(), "python": platform.python_version(),
           "versions": package_versions(), "model": "default passenger",
           "simulate": growth(lambda: simulate(model, duration=args.duration, options=options), args.repeats),
           "stability": growth(lambda: stability(model, options, critical=False), max(2, args.repeats // 4))}
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
