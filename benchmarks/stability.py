"""Benchmark: a full stability report (`td.stability`) for the README's main job (the default passenger) and for
the thesis preset; prints JSON.

The report: closed-loop equilibrium near upright, static energy Hessian, characteristic roots
with the one-sided branches (flexion, extension), and the three critical values by
bisection (co-activation, reflex gain scale, bushing stiffness). Model loading is timed
separately (the second preset's model reuses what the first load cached, so its load time is not a
load from scratch). Load-independent measures: diagram derivative evaluations and characteristic-root
solves. Target (the performance budget): 5 s for the report. `--quick`: the default passenger without critical values.
"""

import argparse
import json
import os
import platform
import time
import warnings

import trunk_drake as td
from trunk_drake.metadata import package_versions
from trunk_drake.optim import stability as stability_module


def counted(function, counter, key):
    def wrapper(*args, **kwargs):
        counter[key] += 1
        return function(*args, **kwargs)
    return wrapper


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the default passenger's report without critical values only")
    quick = parser.parse_args().quick
    out = {"machine": platform.processor() or platform.machine(), "python": platform.python_version(),
           "load_average_before": os.getloadavg(), "versions": package_versions()}
    counter = {"derivative_evaluations": 0, "characteristic_root_solves": 0}
    stability_module.time_derivatives = counted(stability_module.time_derivatives, counter, "derivative_evaluations")
    stability_module.characteristic_roots = counted(stability_module.characteristic_roots, counter, "characteristic_root_solves")
    for name in ("default",) if quick else ("default", "thesis"):
        preset = td.load_preset(name)
        start = time.perf_counter()
        model = preset.model()
        entry = out[name] = {"dofs": model.dofs, "model_load_s": time.perf_counter() - start}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the co-activation's residual-moment note
            options = preset.options(model)
        for label, critical in (("report_without_critical_values", False), ("full_report", True))[:1 if quick else 2]:
            for key in counter:
                counter[key] = 0
            start = time.perf_counter()
            result = stability_module.stability(model, options, critical=critical)
            entry[label] = {"wall_s": time.perf_counter() - start, **counter}
        if "full_report" in entry:
            entry["full_report"]["target_s"] = 5.0
        entry["verdict"] = result.verdict()
    out["load_average_after"] = os.getloadavg()
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
