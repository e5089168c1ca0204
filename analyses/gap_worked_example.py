"""README worked example: a model without reflex delay and with a rigid seat against data with both.

Simulates three SYNTHETIC trials from the gap benchmark's truth (the default passenger, perturbed gains) plus a
40 ms stretch-reflex transport delay AND a compliant pelvis-seat contact (3e4 N/m, 500 Ns/m),
0.1 deg noise, diagnoses them with the nominal model and writes the report and figures to
docs/gap_example/. Run: python analyses/gap_worked_example.py [--out DIR] [--workers N]
"""

import argparse
from pathlib import Path

import numpy as np

from trunk_drake.gap.benchmark import Case, truth_configuration, truth_options
from trunk_drake.gap.diagnose import diagnose_gap
from trunk_drake.gap.report import write_diagnosis
from trunk_drake.gap.synthetic import synthetic_trials

DOCS = Path(__file__).resolve().parents[1] / "docs" / "gap_example"
WITHHELD = (("reflex_delay", {"delay": 0.04}), ("seat_compliance", {"stiffness": 3e4, "damping": 500.0}))


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", default=str(DOCS))
    parser.add_argument("--workers", type=int, default=2, help="local processes for the diagnosis' simulations")
    args = parser.parse_args()
    model, nominal = truth_configuration()
    noise = np.radians(0.1)
    truth = truth_options(nominal, Case("delay_and_seat", "pair", WITHHELD, seed=40))
    trials = synthetic_trials(model, truth, [("1hz_a", 1.0, 41), ("1hz_b", 1.0, 42), ("3hz", 3.0, 43)], noise, seed=40)
    diagnosis = diagnose_gap(model, trials, nominal, noise=noise, workers=args.workers, progress=True)
    files = write_diagnosis(diagnosis, args.out)
    print(diagnosis.verdict)
    print(f"report: {files['report']}")


if __name__ == "__main__":
    main()
