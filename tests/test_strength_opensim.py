"""Strength with the lumbar rhythm against the original model: OpenSim 4.6 on Lumbar_C_210.osim with
its coordinate couplers enforced (OpenSim's own moment arms about flex_extension, its muscle forces,
the same load points and the same feasibility definition), and with them disabled (independent levels)."""

from dataclasses import replace

import numpy as np
import pytest

from lumbar_c210_oracle import osim_statics
from test_model_opensim import KNOWN_PATH_DEPARTURES
from trunk_drake.model.trunk_model import load_model
from trunk_drake.optim.static import StaticInfeasibleError, StaticOptimizer
from trunk_drake.optim.strength import StrengthProblem, load_case, max_load

DIRECTIONS = ("extension", "flexion")


@pytest.fixture(scope="module")
def rhythm():
    return load_model("rhythm")


@pytest.fixture(scope="module")
def osim(lumbar_c210_path, rhythm):
    return osim_statics(lumbar_c210_path, [rhythm.spec.landmark(n).pos for n in ("T6", "T7")], couplers=True)


@pytest.fixture(scope="module")
def ours(rhythm):
    optimizer = StaticOptimizer(rhythm, locked=["pelvis_tx"], min_activation=0.0)
    balance = optimizer.balance(np.zeros(2))
    optimizer.set_state(np.zeros(2))
    per_newton = {d: StrengthProblem(optimizer, load_case(rhythm, d, context=optimizer.context), np.zeros(2), balance).per_newton
                  for d in DIRECTIONS}
    return balance, per_newton


def in_model_order(osim, rhythm, values):
    return values[[osim.muscles.index(n) for n in rhythm.muscles]]


def test_the_rhythm_moves_like_lumbar_c210_with_its_couplers(osim, rhythm, ours):
    """OpenSim's moment arms about flex_extension (couplers enforced) are ours about lumbar_FE, except
    for the muscles whose paths MyoTorso changed; the load's lever about the rhythm agrees too.
    MyoTorso puts each lumbar joint centre at the child body's origin, OpenSim 1-4 mm away
    (the CustomJoints' `location`): that is the remaining millimetre."""
    balance, per_newton = ours
    same_path = np.array([n not in KNOWN_PATH_DEPARTURES for n in rhythm.muscles])
    difference = np.abs(balance.moment_arms[:, 0] - in_model_order(osim, rhythm, osim.moment_arms[:, 0]))[same_path]
    assert same_path.sum() > 150
    assert difference.max() < 2e-3 and np.median(difference) < 5e-4, (difference.max(), np.median(difference))
    for d in DIRECTIONS:
        assert per_newton[d][0] == pytest.approx(osim.load_per_newton[d][0], rel=0.02)


@pytest.mark.parametrize("include_passive", [True, False])
def test_strength_differs_from_opensim_only_through_the_documented_muscle_differences(osim, rhythm, ours, include_passive):
    """Both maxima are computed; with OpenSim's muscle forces (its F_max and Hill parameters: the
    .osim's rect_abd tendon slack length, MyoTorso's F_max) and the moment arms of the abdominal
    muscles whose attachments MyoTorso moved, our LP on our rhythm reproduces OpenSim's strength
    within 3 % (what remains: MyoTorso's head and neck, the joint centres)."""
    balance, per_newton = ours
    reference = osim.balance(include_passive)
    moved = np.array([n.startswith(("EO", "IO")) for n in rhythm.muscles])
    arms = np.where(moved, in_model_order(osim, rhythm, osim.moment_arms[:, 0]), balance.moment_arms[:, 0])
    swapped = replace(balance, moment_arms=arms[:, None], active=in_model_order(osim, rhythm, reference.active),
                      passive=in_model_order(osim, rhythm, reference.passive))
    if not include_passive:
        balance = replace(balance, passive=np.zeros_like(balance.passive))
    for d in DIRECTIONS:
        theirs = max_load(reference, osim.load_per_newton[d], 0.0)[0]
        mine = max_load(balance, per_newton[d], 0.0)[0]
        explained = max_load(swapped, per_newton[d], 0.0)[0]
        print(f"\n{d} ({'with' if include_passive else 'without'} passive force): trunk-drake {mine:.1f} N, "
              f"OpenSim Lumbar_C_210 {theirs:.1f} N ({100 * (mine / theirs - 1):+.0f} %); with OpenSim's muscle forces "
              f"and abdominal moment arms {explained:.1f} N")
        assert 100.0 < theirs < 1000.0 and 100.0 < mine < 1000.0
        assert explained == pytest.approx(theirs, rel=0.03)


def test_independent_levels_are_weak_in_the_opensim_original_too(lumbar_c210_path, rhythm, osim):
    """The exact-balance weakness in flexion is the muscle set's, not MyoTorso's: Lumbar_C_210 with its
    couplers disabled, every level balanced on its own, holds under a third of what its rhythm holds
    (without passive force; with it, its rect_abd's passive pull already unbalances the unloaded levels)."""
    independent = osim_statics(lumbar_c210_path, [rhythm.spec.landmark(n).pos for n in ("T6", "T7")], couplers=False)
    assert len(independent.coordinates) == 5
    for d in DIRECTIONS:
        coupled = max_load(osim.balance(False), osim.load_per_newton[d], 0.0)[0]
        alone = max_load(independent.balance(False), independent.load_per_newton[d], 0.0)[0]
        print(f"\nOpenSim Lumbar_C_210, {d} without passive force: couplers enforced {coupled:.1f} N, disabled {alone:.1f} N")
        assert 0.0 < alone < coupled / 3
        with pytest.raises(StaticInfeasibleError):
            max_load(independent.balance(True), independent.load_per_newton[d], 0.0)
