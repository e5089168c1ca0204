"""Gap benchmark bookkeeping: noise, effect signatures and the summary's rates."""

import numpy as np

from trunk_drake.gap.benchmark import summarize, summary_markdown
from trunk_drake.gap.synthetic import add_noise, signature_chi2
from trunk_drake.io.trials import LUMBAR_LEVELS, Trial


def _trial(scale: float) -> Trial:
    t = np.arange(0.0, 10.0, 0.01)
    y = scale * np.sin(2 * np.pi * t)
    return Trial(time=t, fs=100.0, platform_displacement=0.01 * np.sin(t), lumbar_rotation=y,
                 levels={lvl: y / 5 for lvl in LUMBAR_LEVELS})


def test_signature_is_the_noise_normalised_difference_and_noise_is_added():
    a, b = [_trial(1e-3)], [_trial(2e-3)]
    noise = 1e-3
    keep = a[0].time >= 2.0
    d = 1e-3 * np.sin(2 * np.pi * a[0].time[keep])
    expected = (np.sum((d - d.mean()) ** 2) + 5 * np.sum((d / 5 - d.mean() / 5) ** 2)) / noise**2
    assert abs(signature_chi2(a, b, noise, skip=2.0) / expected - 1) < 1e-12
    assert signature_chi2(a, a, noise) == 0.0
    noisy = add_noise(a, noise, seed=1)
    assert abs(np.std(noisy[0].lumbar_rotation - a[0].lumbar_rotation) / noise - 1) < 0.1
    assert np.array_equal(noisy[0].platform_displacement, a[0].platform_displacement)


def test_summary_leaves_unobservable_cases_out_of_the_rates():
    def row(case, truth, first, selected, observable=True):
        return {"case": case, "truth": truth, "ranked_first": first, "selected": selected, "observable": observable,
                "reduction": 0.5, "reduction_above_noise": 0.9, "wall_time_s": 1.0, "signature_chi2": 100.0}
    rows = [row("d1", "reflex_delay", "reflex_delay", ["reflex_delay"]),
            row("d2", "extra_damping", "reflex_delay", ["reflex_delay"]),
            row("s1", "stiffening_discs", "reflex_delay", [], observable=False),
            row("n1", None, "reflex_delay", []), row("n2", None, "golgi_feedback", ["golgi_feedback"])]
    s = summarize(rows, 0.1)
    assert s["ranked_first_rate"] == 0.5 and s["no_effect_correct_rate"] == 0.5
    assert abs(s["ranked_first_rate_all"] - 1 / 3) < 1e-12
    assert s["unobservable"] == ["s1"]
    assert s["confusion"]["stiffening_discs"]["none"] == 1 and s["confusion"]["none"]["golgi_feedback"] == 1
    assert "unobservable" in summary_markdown(s)
