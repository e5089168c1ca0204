"""Benchmark: a 20 s, 0.2-1 Hz pelvis-perturbation trial with all 210 muscles and stretch reflexes.

Prints JSON: trunk-drake with rigid tendons (the target: real-time factor >= 5) and with
compliant tendons, and MuJoCo on the same MyoTorso (its own muscle model, rigid tendons, no
reflexes, default 2 ms Euler step) measured in the same run. Usage:
    python benchmarks/simulate.py [--duration 20] [--compliant-duration 4]
"""

import argparse
import json
import platform
import time

import mujoco
import numpy as np

import trunk_drake as td
from trunk_drake.data import models_dir
from trunk_drake.model.myotorso import compile_myotorso
from trunk_drake.optim.static import coactivation
from trunk_drake.simulation import DEFAULT_GAINS, load_reflex_gains, simulate


def trunk_drake_run(model, duration, tendon, feedforward, gains):
    result = simulate(model, duration=duration, bandwidth=1.0, seed=0, tendon=tendon, feedforward=feedforward,
                      stiffness=125.0, damping=7.5, **gains)
    s = result.summary()
    return {k: s[k] for k in ("wall_time_s", "sim_time_s", "steps", "derivative_evaluations", "real_time_factor")}


def mujoco_run(duration):
    m = compile_myotorso()
    d = mujoco.MjData(m)
    d.ctrl[:] = 0.02
    n = int(round(duration / m.opt.timestep))
    t0 = time.perf_counter()
    for _ in range(n):
        mujoco.mj_step(m, d)
    wall = time.perf_counter() - t0
    return {"wall_time_s": wall, "sim_time_s": n * m.opt.timestep, "steps": n, "timestep_s": m.opt.timestep,
            "integrator": str(mujoco.mjtIntegrator(m.opt.integrator)), "real_time_factor": n * m.opt.timestep / wall}


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=20.0)
    parser.add_argument("--compliant-duration", type=float, default=4.0)
    args = parser.parse_args()
    model = td.load_model("sagittal")
    gains = load_reflex_gains(models_dir() / DEFAULT_GAINS)
    feedforward = coactivation(model, 0.02)
    trunk_drake_run(model, 0.5, "rigid", feedforward, gains)  # warm-up: numba compilation, caches
    out = {
        "machine": platform.machine(),
        "trial": {"bandwidth_hz": 1.0, "muscles": model.n_muscles, "reflex_gains": DEFAULT_GAINS,
                  "coactivation_min_activation": 0.02, "stiffness_nm_per_rad": 125.0},
        "rigid": trunk_drake_run(model, args.duration, "rigid", feedforward, gains),
        "compliant": trunk_drake_run(model, args.compliant_duration, "compliant", feedforward, gains),
        "mujoco_myotorso": mujoco_run(args.duration),
        "target_rigid_real_time_factor": 5.0,
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
