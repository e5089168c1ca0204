"""Benchmark: lengths + moment arms of all 210 MyoTorso muscles at one pose; prints JSON.

Ours: `TrunkModel.path_state(q)` (MyoTorso: compiled body kinematics and vectorised paths, one
numba call each). MuJoCo (same model, same pose): mj_kinematics + mj_comPos + mj_tendon + mj_transmission.
With `../shared/reference/lumbar_c_210/Lumbar_C_210.osim` present, also the original OpenSim
model read by trunk-drake (OpenSim path semantics and wrapping, poses from the plant), same configurations.
Usage: python benchmarks/paths.py [--quick]   (`--quick`: a check that it runs, not a result)
"""

import argparse
import json
import os
import platform
import time
from pathlib import Path

import mujoco
import numpy as np

import trunk_drake as td
from trunk_drake.model.myotorso import compile_myotorso


def best_of(fn, repeat=7, number=200):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - t0) / number)
    return min(times), float(np.median(times))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the sagittal model, 3 calls each (a check that it runs)")
    quick = parser.parse_args().quick
    timing = {"repeat": 1, "number": 3} if quick else {}
    out = {"machine": platform.processor() or platform.machine(), "python": platform.python_version()}
    m = compile_myotorso()
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    osim = Path(__file__).resolve().parents[2] / "shared" / "reference" / "lumbar_c_210" / "Lumbar_C_210.osim"
    sources = {"trunk_drake": None, "lumbar_c_210_osim": osim if osim.exists() else None}
    for label, source in sources.items():
        if label != "trunk_drake" and source is None:
            continue
        for dofs in ("sagittal",) if quick else ("sagittal", "spine3d"):
            model = td.load_model(source, dofs=dofs)
            q = np.array([rng.uniform(*c.range) * 0.5 if c.source_joint else 0.0 for c in model.coordinate_info])
            best, median = best_of(lambda: model.path_state(q), **timing)
            out[f"{label}_{dofs}_ms"] = {"best": best * 1e3, "median": median * 1e3}
    out["load_average"] = os.getloadavg()[0]

    def mj():
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_tendon(m, d)
        mujoco.mj_transmission(m, d)

    best, median = best_of(mj, **timing)
    out["mujoco_ms"] = {"best": best * 1e3, "median": median * 1e3}
    out["n_muscles"] = int(m.nu)
    out["target_ms"] = 0.5
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
