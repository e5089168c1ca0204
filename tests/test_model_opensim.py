"""MyoTorso as converted into Drake against its OpenSim source, Lumbar_C_210 (OpenSim 4.6)."""

import json

import numpy as np

import trunk_drake as td
from lumbar_c210_oracle import compare_hill_parameters

# Muscles whose MyoTorso path differs from the OpenSim original (measured at the neutral pose):
#   LTpT_T1..T5: OpenSim wraps them over chest ellipsoids, MyoTorso over spheres (0.4-0.9 %);
#   MF_*_l: the .osim's left multifidus sites are not mirror images of the right (0.1-0.4 %);
#   EO1-4, IO1-3: MyoTorso moved their abdominal attachment points (8-17 %).
KNOWN_PATH_DEPARTURES = {
    *(f"LTpT_T{i}_{s}" for i in range(1, 6) for s in "rl"),
    "MF_m2t.3_l", "MF_m3s_l", "MF_m3t.1_l", "MF_m4s_l", "MF_m4t.1_l", "MF_m5t.3_l",
    *(f"EO{i}_{s}" for i in range(1, 5) for s in "rl"),
    *(f"IO{i}_{s}" for i in range(1, 4) for s in "rl"),
}


def test_neutral_lengths_and_derived_hill_parameters(lumbar_c210_path):
    model = td.load_model(dofs="spine3d")
    cmp = compare_hill_parameters(model, lumbar_c210_path)
    print("\nlargest relative difference per group, ours vs Lumbar_C_210.osim:")
    print(json.dumps(cmp.by_group(), indent=1))

    # geometry: MyoTorso reproduces OpenSim's musculotendon lengths except documented departures
    departed = {m for m, e in zip(cmp.muscles, cmp.neutral_length) if e > 1e-3}
    assert departed <= KNOWN_PATH_DEPARTURES, f"new path departures: {sorted(departed - KNOWN_PATH_DEPARTURES)}"
    assert np.median(cmp.neutral_length) < 1e-5

    # Hill lengths: wherever the .osim itself follows Christophy et al.'s published method and
    # MyoTorso keeps the OpenSim path, our derivation reproduces the .osim within 1 %
    same_path = cmp.neutral_length < 1e-3
    checked = same_path & cmp.osim_follows_method
    assert checked.sum() >= 50, "guard against a vacuous check (85 muscles qualify with myo-sim 0.2.4)"
    worst_lopt = cmp.optimal_fiber_length[checked].max()
    worst_lslack = cmp.tendon_slack_length[checked].max()
    assert worst_lopt < 0.01 and worst_lslack < 0.01, (worst_lopt, worst_lslack)
