"""README worked example: a model without reflex delay against data with a 40 ms delay.

Simulates three SYNTHETIC trials from the reference truth configuration plus a 40 ms stretch-
reflex transport delay (0.1 deg noise), diagnoses them with the delay-free model and writes the
report and figures to docs/gap_example/. Run: python analyses/gap_worked_example.py [--out DIR]
"""

import argparse
from pathlib import Path

import numpy as np

import trunk_drake as td
from trunk_drake.gap.benchmark import Case, nominal_options, truth_options
from trunk_drake.gap.diagnose import diagnose_gap
from trunk_drake.gap.report import write_diagnosis
from trunk_drake.gap.synthetic import synthetic_trials

DOCS = Path(__file__).resolve().parents[1] / "docs" / "gap_example"


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default=str(DOCS))
    args = parser.parse_args()
    model = td.load_model("sagittal")
    nominal = nominal_options()
    noise = np.radians(0.1)
    truth = truth_options(nominal, Case("delay_40ms", "reflex_delay", {"delay": 0.04}, seed=40))
    trials = synthetic_trials(model, truth, [("1hz_a", 1.0, 41), ("1hz_b", 1.0, 42), ("3hz", 3.0, 43)], noise, seed=40)
    diagnosis = diagnose_gap(model, trials, nominal, noise=noise, workers=2, progress=True)
    files = write_diagnosis(diagnosis, args.out)
    print(diagnosis.verdict)
    print(f"report: {files['report']}")


if __name__ == "__main__":
    main()
