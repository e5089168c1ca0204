"""Benchmark: the README's main job (20 s, 0.2-1 Hz pelvis perturbation, 210 muscles, stretch
reflexes) and the synthetic reference data's upright truth configuration, with their accuracy.

Prints JSON: per trial the integrator's steps and derivative evaluations, wall time, real-time
factor, its ratio to MuJoCo's on the same MyoTorso (its own muscle model, rigid tendons, no
reflexes, default 2 ms Euler step) measured in the same run (before and after, averaged), and
the RMS lumbar-rotation difference from the accurate reference (trunk_drake.accuracy, target
<= 0.01 deg); the main job with compliant tendons; the microseconds of one derivative
evaluation (minimum over repetitions); and the machine's load average. Usage:
    python benchmarks/simulate.py [--duration 20] [--compliant-duration 4]
"""

import argparse
import json
import os
import platform
import time

import mujoco
import numpy as np

from trunk_drake.accuracy import TOLERANCE_DEG, rms_deviation_deg, trial_model, trial_options
from trunk_drake.diagram import TrunkOptions, build_trunk_diagram
from trunk_drake.model.myotorso import compile_myotorso
from trunk_drake.simulation import _perturbation, simulate


def trunk_drake_run(model, duration, trial, **overrides):
    result = simulate(model, duration=duration, **{**trial_options(model, trial), **overrides})
    s = result.summary()
    out = {k: s[k] for k in ("wall_time_s", "sim_time_s", "steps", "derivative_evaluations", "real_time_factor")}
    out["rms_deviation_deg"] = rms_deviation_deg(result, trial)
    return out


def evaluation_us(model, trial, repetitions=2000):
    """Microseconds of one derivative evaluation of the whole diagram (q changed every time), minimum of 5 runs."""
    options = trial_options(model, trial)
    signal = _perturbation("multisine", options.pop("bandwidth"), options.pop("seed"))
    diagram = build_trunk_diagram(model, TrunkOptions(**options), signal).diagram
    context = diagram.CreateDefaultContext()
    context.SetTime(3.0)
    x = context.get_continuous_state_vector().CopyToVector()
    nq = model.plant.num_positions()
    x[:nq], x[2 * nq:] = 0.01, 0.03  # a displaced posture, muscles above rest
    derivatives = diagram.AllocateTimeDerivatives()
    best = np.inf
    for _ in range(5):
        t0 = time.perf_counter()
        for i in range(repetitions):
            x[0] += 1e-12 if i % 2 else -1e-12
            context.SetContinuousState(x)
            diagram.CalcTimeDerivatives(context, derivatives)
        best = min(best, (time.perf_counter() - t0) / repetitions)
    return best * 1e6


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
    model, thesis = trial_model("default"), trial_model("thesis")
    load_before = os.getloadavg()
    trunk_drake_run(model, 0.5, "default")  # warm-up: numba compilation, caches
    mujoco_before = mujoco_run(args.duration)
    runs = {
        "rigid": trunk_drake_run(model, args.duration, "default"),
        "thesis": trunk_drake_run(thesis, args.duration, "thesis"),
        "compliant": trunk_drake_run(model, args.compliant_duration, "default", tendon="compliant"),
    }
    mujoco_after = mujoco_run(args.duration)
    mujoco_rtf = 0.5 * (mujoco_before["real_time_factor"] + mujoco_after["real_time_factor"])
    for name in ("rigid", "thesis"):
        runs[name]["ratio_to_mujoco"] = runs[name]["real_time_factor"] / mujoco_rtf
    runs["compliant"].pop("rms_deviation_deg")  # the reference is the rigid-tendon model's
    out = {
        "machine": platform.machine(),
        "load_average_1_5_15_min": {"before": load_before, "after": os.getloadavg()},
        "trials": {"rigid": "README main job: the default passenger (models/presets/default.toml, rhythm), upright",
                   "thesis": "the thesis' final model (--preset thesis, independent levels), folds into flexion",
                   "compliant": "the main job with compliant tendons"},
        **runs,
        "evaluation_us": {"default": evaluation_us(model, "default"), "thesis": evaluation_us(thesis, "thesis")},
        "mujoco_myotorso": {"before": mujoco_before, "after": mujoco_after, "mean_real_time_factor": mujoco_rtf},
        "targets": {"rigid_ratio_to_mujoco": 0.5, "compliant_real_time_factor": 3.0, "rms_deviation_deg": TOLERANCE_DEG},
    }
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
