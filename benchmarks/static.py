"""Benchmark: one static-optimisation frame of the full model and the three strength maxima; prints JSON.

Frame: ``StaticOptimizer.solve(q, v, vdot)`` on the spine3d model (210 muscles, 15 coordinates):
path kinematics, force split, inverse dynamics, program update and solve, at postures near
neutral (a quarter of each joint range, where the muscles can hold gravity). Strength:
``isometric_strength`` (pelvis locked, upright) including building the optimizer, direct
maxima only and with the thesis' 10 N sweeps. Targets (the performance budget): 20 ms per frame,
10 s for the three maxima. `--quick`: 3 frames at p = 2 and the direct maxima (a check that it runs, not a result).
"""

import argparse
import json
import platform
import time

import numpy as np

import trunk_drake as td
from trunk_drake.metadata import package_versions
from trunk_drake.optim.static import StaticInfeasibleError, StaticOptimizer
from trunk_drake.optim.strength import isometric_strength


def frame_times(model, p, n=100, seed=0):
    optimizer = StaticOptimizer(model, p=p)
    rng = np.random.default_rng(seed)
    lo, hi = np.array([c.range for c in model.coordinate_info]).T
    times, solver, residual, infeasible = [], [], 0.0, 0
    for _ in range(n):
        q = rng.uniform(0.02 * lo, 0.02 * hi)
        v = rng.normal(scale=0.02, size=q.size)
        start = time.perf_counter()
        try:
            res = optimizer.solve(q, v)
        except StaticInfeasibleError:
            infeasible += 1
            continue
        times.append(time.perf_counter() - start)
        solver.append(res.solve_time)
        residual = max(residual, float(np.max(np.abs(res.residuals))))
    times, solver = np.array(times) * 1e3, np.array(solver) * 1e3
    return {"frames": len(times), "infeasible_frames": infeasible, "median_ms": float(np.median(times)),
            "p90_ms": float(np.percentile(times, 90)), "solver_median_ms": float(np.median(solver)),
            "max_abs_residual_Nm": residual, "solver": res.solver}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="3 frames at p = 2, direct maxima only")
    quick = parser.parse_args().quick
    out = {"machine": platform.processor() or platform.machine(), "python": platform.python_version(),
           "versions": package_versions()}
    start = time.perf_counter()
    model = td.load_model(dofs="spine3d")
    out["model_load_s"] = time.perf_counter() - start
    frames = {2.0: 3} if quick else {2.0: 100, 1.0: 100, 3.0: 10}
    out["frame"] = {f"p={p:g}": frame_times(model, p, n=n) for p, n in frames.items()}
    out["frame"]["target_ms"] = 20.0

    for label, sweep in (("direct", False), ("with_10N_sweep", True))[:1 if quick else 2]:
        start = time.perf_counter()
        results = isometric_strength(model, sweep=sweep)
        elapsed = time.perf_counter() - start
        out[f"strength_{label}"] = {
            "total_s": elapsed,
            **{d: {"max_force_N": r.max_force, "sweep_last_feasible_N": r.sweep_force, "sweep_solves": r.sweep_solves,
                   "limiting_coordinate": r.limiting_coordinate, "muscles_at_upper_bound": len(r.muscles_at_upper_bound)}
               for d, r in results.items()},
        }
    out["strength_target_s"] = 10.0
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
