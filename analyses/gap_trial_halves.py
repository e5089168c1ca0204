"""Where in a gap-benchmark case's trials a withheld effect shows: the noise-free truth simulated with the effect at
two values (the case's gains), their difference in chi-square units of the 0.1 deg noise (offsets removed) in each
half of the steady period and in 2 s windows. The diagnosis fits on the first halves and scores on the second.

    python analyses/gap_trial_halves.py [CASE] [EFFECT PARAMETER A B] [--quick]

Default: stiffening_discs_cubic400, the stiffening's cubic coefficient at 400 against 50 (1/rad^2). `--quick`: 2 s
trials (a check that it runs, not a result).

2026-12-06 (on 51336de, the default passenger's truth): the difference is about twice as large in the second halves
(5.3 / 10.4, 6.3 / 13.0 and 49.0 / 100.8 on the trials 1hz_a, 1hz_b and 3hz), and it sits in one 2 s window of each
half, 10 s apart: 44.1 at 10-12 s and 96.5 at 20-22 s on the 3 Hz trial. An odd-line multisine of period T is
antisymmetric, x(t + T/2) = -x(t), so the second half drives the trunk as the first does with the sign flipped, and
the largest swing of each half is the same swing in the other direction. The passenger's response is not symmetric in
sign (one-sided reflexes; the spine deflected at rest under gravity), and an amplitude-dependent law shows in one
direction of that swing twice as much as in the other: here the training halves see its weaker side. The signature
alone differs by a factor 2; with the gains refitted on the training halves (which can take up part of the smaller
side), a profile over c moved the training chi2 by 9 and the held-out by 75 (analyses/gap_lm_scaling_check.py --held).
A split that keeps each swing with its mirror (training on the first half of each half period, say) would show a fit
both directions of the swings it trains on (alternate 2 s windows would not: 5 windows per half period put every
window's mirror in the other set), at about 40 % more simulation per refit step; where the largest swing falls stays
a matter of the design.
"""

import argparse

import numpy as np

from trunk_drake.gap.benchmark import Case, case_trials, cases, trial_timing, truth_configuration

NOISE_RAD = np.radians(0.1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("case", nargs="?", default="stiffening_discs_cubic400")
    parser.add_argument("change", nargs="*", default=["stiffening_discs", "cubic", "400", "50"],
                        help="EFFECT PARAMETER A B: the effect's parameter at A against B")
    parser.add_argument("--quick", action="store_true", help="2 s trials")
    args = parser.parse_args()
    timing = trial_timing(args.quick)
    t0, t1 = timing["fade"], timing["fade"] + timing["period"]  # s: the steady period after the fade-in
    name, parameter, a, b = args.change[0], args.change[1], float(args.change[2]), float(args.change[3])
    model, nominal = truth_configuration()
    case = next(c for c in cases(False) if c.name == args.case)
    runs = [case_trials(model, Case(case.name, case.kind, ((name, {parameter: v}),), case.seed), nominal, NOISE_RAD,
                        **timing)[2] for v in (a, b)]
    print(f"{case.name}: {name} {parameter} {a:g} against {b:g}, chi2 at 0.1 deg noise")
    for ta, tb in zip(*runs):
        t = ta.time
        d = np.column_stack([ta.lumbar_rotation - tb.lumbar_rotation] + [ta.levels[k] - tb.levels[k] for k in ta.levels])
        steady = (t >= t0) & (t < t1)
        mid = 0.5 * (t0 + t1)
        halves = [_chi2(d, steady & (t < mid)), _chi2(d, steady & (t >= mid))]
        windows = [_chi2(d, (t >= w) & (t < w + 2.0), d[steady].mean(axis=0)) for w in np.arange(t0, t1, 2.0)]
        means = [np.degrees(ta.lumbar_rotation[(t >= w) & (t < w + 2.0)].mean()) for w in np.arange(t0, t1, 2.0)]
        print(f"  {ta.source}: halves {halves[0]:.1f} / {halves[1]:.1f}; 2 s windows from {t0:g} s: "
              + " ".join(f"{w:.1f}" for w in windows) + "; mean lumbar rotation (deg): " + " ".join(f"{m:+.2f}" for m in means))


def _chi2(d: np.ndarray, mask: np.ndarray, offset: np.ndarray | None = None) -> float:
    part = d[mask] - (d[mask].mean(axis=0) if offset is None else offset)
    return float(np.sum(part**2) / NOISE_RAD**2)


if __name__ == "__main__":
    main()
