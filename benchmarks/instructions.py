"""Benchmark, independent of the machine's load: CPU instructions of forward simulation.

Counts (valgrind's callgrind) the instructions executed inside Drake's Simulator::AdvanceTo for
the README main job's first `--duration` seconds (default 1 s), after a warm-up evaluation
(numba cache loading) run without instrumentation, and divides by the integrator's steps and
derivative evaluations. Prints JSON. Needs valgrind; takes a few minutes. Usage:
    python benchmarks/instructions.py [--duration 1]
(with PYTHONPATH pointing at another checkout, the same measurement of that code).
"""

import argparse
import json
import os
import pickle
import re
import subprocess
import sys
import tempfile


def measured_run(duration: float, spec_file: str) -> dict:
    """Inside valgrind: warm up outside AdvanceTo, then simulate (AdvanceTo is what is counted)."""
    import trunk_drake as td
    from trunk_drake.accuracy import trial_options
    from trunk_drake.diagram import TrunkOptions, build_trunk_diagram
    from trunk_drake.simulation import _perturbation, simulate

    with open(spec_file, "rb") as f:
        model = td.load_model("sagittal", spec=pickle.load(f))
    options = trial_options(model, "thesis")
    warm = dict(options)
    signal = _perturbation("multisine", warm.pop("bandwidth"), warm.pop("seed"))
    diagram = build_trunk_diagram(model, TrunkOptions(**warm), signal).diagram
    context = diagram.CreateDefaultContext()
    diagram.CalcTimeDerivatives(context, diagram.AllocateTimeDerivatives())
    print("READY", flush=True)  # the parent switches the instrumentation on, then answers
    sys.stdin.readline()
    result = simulate(model, duration=duration, **options)
    return {k: result.stats[k] for k in ("steps", "derivative_evaluations")}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=1.0)
    parser.add_argument("--inside", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.inside:
        print("STATS " + json.dumps(measured_run(args.duration, args.inside)))
        return
    import trunk_drake as td

    with tempfile.TemporaryDirectory() as tmp:
        spec_file, out = os.path.join(tmp, "spec.pkl"), os.path.join(tmp, "callgrind.out")
        with open(spec_file, "wb") as f:  # MyoTorso compiled outside valgrind (its XML parsing is slow there)
            pickle.dump(td.load_model("sagittal").spec, f)
        child = subprocess.Popen(["valgrind", "--tool=callgrind", "--instr-atstart=no", "--toggle-collect=*Simulator*AdvanceTo*",
                                  f"--callgrind-out-file={out}", sys.executable, __file__, "--duration", str(args.duration),
                                  "--inside", spec_file], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        for line in child.stdout:
            if line.startswith("READY"):
                subprocess.run(["callgrind_control", "-i", "on", str(child.pid)], check=True, capture_output=True)
                child.stdin.write("go\n")
                child.stdin.flush()
            elif line.startswith("STATS"):
                stats = json.loads(line[6:])
        if child.wait() != 0:
            raise SystemExit(f"the measured run failed (exit {child.returncode})")
        total = int(re.search(r"^totals: (\d+)", open(out).read(), re.M).group(1))
    print(json.dumps({"code": td.__file__, "trial": "README main job (trunk_drake.accuracy 'folding')", "sim_time_s": args.duration,
                      **stats, "instructions": total, "instructions_per_step": total / stats["steps"],
                      "instructions_per_derivative_evaluation": total / stats["derivative_evaluations"],
                      "instructions_per_simulated_second": total / args.duration}, indent=2))


if __name__ == "__main__":
    main()
