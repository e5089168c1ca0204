"""The default passenger (models/presets/default.toml) stays upright, unsaturated and balanced.

Issue criteria on short runs; `benchmarks/default_passenger.py` runs the same checks on full 20 s trials.
"""

import numpy as np
import pytest

from trunk_drake.optim.stability import stability
from trunk_drake.presets import load_preset
from trunk_drake.simulation import simulate


@pytest.fixture(scope="module")
def passenger():
    preset = load_preset("default")
    model = preset.model()
    return model, preset.options(model)


def test_at_rest_every_muscle_is_below_0_3_and_every_coordinate_balances(passenger):
    model, options = passenger
    assert options.feedforward.max() <= 0.3
    result = stability(model, options, critical=False)  # the whole diagram's generalized force at rest, upright
    assert np.max(np.abs(result.unbalanced)) <= 0.01, dict(zip(result.coordinates, result.unbalanced))
    # the slowest side, extension, decays e-fold within 2 s (-0.92 1/s, as the simulation of
    # tests/test_stability.py::test_default_passengers_one_sided_rates_match_simulation)
    assert result.dynamic.stable and result.dynamic.margin < -0.5


@pytest.mark.parametrize("bandwidth, seed", [(1.0, 1), (1.0, 2), (1.0, 3), (1.0, 4), (1.0, 5), (3.0, 0)])
def test_stays_upright_under_platform_motion(passenger, bandwidth, seed):
    model, options = passenger
    result = simulate(model, duration=8.0, bandwidth=bandwidth, seed=seed, options=options)
    rotation = np.degrees(result.lumbar_rotation)
    first = rotation[result.time <= 1.0].mean()
    assert abs(rotation[result.time >= 4.0].mean() - first) < 2.0
    assert np.max(np.abs(rotation)) < 10.0
    assert np.std(rotation) > 0.05  # it does sway: the perturbation reaches the trunk
