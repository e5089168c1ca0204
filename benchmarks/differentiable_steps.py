"""Finite differences of the fits' simulations (`simulation.differentiable_settings`): reflex-gain columns on a
replayed runge_kutta3 step sequence at several accuracies, and on fixed runge_kutta2 steps of 5 ms, against the
columns on a 1e-6 sequence; steps and wall time per 24 s trial of the gap benchmark's truth at 1 and 3 Hz.
Prints JSON.

Usage: python benchmarks/differentiable_steps.py [--quick]
(`--quick`: 2 s, 1 Hz, one group, one accuracy; a check that it runs, not a result)
"""

import argparse
import dataclasses
import json
import os
import time

import numpy as np

from trunk_drake.gap.benchmark import truth_configuration
from trunk_drake.simulation import simulate

DURATION, SEED, STEP = 24.0, 3, 1e-2  # one gap-benchmark trial; a 1 % gain change
GROUPS = ("sacrospinalis", "transversospinalis", "quadratus_lumborum", "psoas_major")
ACCURACIES = (1e-4, 3e-4, 1e-3)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="2 s, 1 Hz, one group, one accuracy")
    quick = parser.parse_args().quick
    duration, groups, accuracies, bandwidths = ((2.0, GROUPS[:1], ACCURACIES[-1:], (1.0,)) if quick
                                                else (DURATION, GROUPS, ACCURACIES, (1.0, 3.0)))
    model, options = truth_configuration()

    def run(bandwidth, group=None, **settings):
        kp = dict(options.kp)
        if group:
            kp[group] *= 1 + STEP
        start = time.perf_counter()
        result = simulate(model, duration=duration, bandwidth=bandwidth, seed=SEED,
                          options=dataclasses.replace(options, kp=kp), **settings)
        angles = np.degrees(np.column_stack([result.lumbar_rotation, *result.levels.values()]))
        return result, angles, time.perf_counter() - start

    def columns(bandwidth, base, settings):
        return {g: (run(bandwidth, g, **settings)[1] - base) / STEP for g in groups}

    def errors(cols, exact):
        return {g: float(np.linalg.norm(cols[g] - exact[g]) / np.linalg.norm(exact[g])) for g in groups}

    rows = []
    for bandwidth in bandwidths:
        fine, fine_angles, _ = run(bandwidth, integrator="runge_kutta3", accuracy=1e-6, max_step=0.005)
        exact = columns(bandwidth, fine_angles, {"integrator": "runge_kutta3", "steps": fine.step_times})
        for accuracy in accuracies:
            base, angles, wall = run(bandwidth, integrator="runge_kutta3", accuracy=accuracy)
            replay = {"integrator": "runge_kutta3", "steps": base.step_times}
            start = time.perf_counter()
            cols = columns(bandwidth, angles, replay)
            rows.append({"bandwidth_hz": bandwidth, "setting": f"runge_kutta3 sequence at {accuracy:g}, replayed",
                         "steps": int(base.step_times.size - 1), "wall_own_s": wall,
                         "wall_replay_s": (time.perf_counter() - start) / len(groups),
                         "column_error": errors(cols, exact)})
        fixed = {"integrator": "runge_kutta2", "max_step": 0.005}
        base, angles, wall = run(bandwidth, **fixed)
        rows.append({"bandwidth_hz": bandwidth, "setting": "runge_kutta2 fixed 5 ms", "steps": int(base.stats["steps"]),
                     "wall_own_s": wall, "column_error": errors(columns(bandwidth, angles, fixed), exact)})
    print(json.dumps({"trial": f"gap benchmark truth, {duration} s, seed {SEED}, kp +{STEP:.0%} per group",
                      "settings": rows, "load_average": os.getloadavg()}, indent=2))


if __name__ == "__main__":
    main()
