"""The one-coordinate tables (trunk_drake.model.tables) against the exact computation they replace."""

import dataclasses

import numpy as np
import pytest

import trunk_drake as td
from trunk_drake.diagram import TrunkOptions
from trunk_drake.model.tables import TOLERANCE, coordinate_table
from trunk_drake.simulation import simulate


@pytest.fixture(scope="module")
def rhythm():
    return td.load_model("rhythm", pelvis_free=False)


def test_the_table_matches_the_exact_paths_and_dynamics_everywhere_it_is_used(rhythm):
    table = coordinate_table(rhythm)
    lo, hi = rhythm.coordinate_info[0].range
    plant, context = rhythm.plant, rhythm.plant.CreateDefaultContext()
    direction = np.array([0.9, 0.1, 0.3])
    used = 0
    for q in np.linspace(lo, hi, 1501):
        if not table.covers(q):
            continue
        used += 1
        exact, tabulated = rhythm.path_state_from_q(np.array([q]), np.array([0.7])), table.paths(q, 0.7)
        assert np.abs(tabulated.lengths - exact.lengths).max() < TOLERANCE["length"]
        assert np.abs(tabulated.moment_arms - exact.moment_arms).max() < TOLERANCE["moment_arm"]
        assert np.abs(tabulated.velocities - exact.velocities).max() < 0.7 * TOLERANCE["moment_arm"]
        plant.SetPositionsAndVelocities(context, [q, 1.0])
        mass, gravity, bias = table.dynamics(q)
        assert mass == pytest.approx(plant.CalcMassMatrix(context)[0, 0], rel=1e-9)
        assert gravity == pytest.approx(plant.CalcGravityGeneralizedForces(context)[0], rel=1e-9, abs=1e-9)
        assert bias == pytest.approx(plant.CalcBiasTerm(context)[0], rel=1e-9, abs=1e-12)
        assert table.com_load(q, direction)[0] == pytest.approx(rhythm.mass_weighted_com_jacobian(np.array([q]), direction)[0],
                                                                 rel=1e-9, abs=1e-9)
    assert used > 0.99 * 1501, "the table must cover nearly all of the range (it leaves out moment-arm jumps only)"
    assert not table.covers(hi + 0.01) and not table.covers(lo - 0.01)


def test_a_model_with_more_than_one_coordinate_has_no_table():
    assert coordinate_table(td.load_model("sagittal", pelvis_free=False)) is None


def test_a_simulation_with_tables_follows_the_exact_one_on_its_steps(rhythm):
    options = TrunkOptions(kp=0.5, kv=0.3, reflex_delay=0.03, stiffness=150.0, feedforward=np.full(rhythm.n_muscles, 0.03))
    exact = simulate(rhythm, duration=3.0, bandwidth=2.0, options=dataclasses.replace(options, tables=False), log=())
    tabulated = simulate(rhythm, duration=3.0, bandwidth=2.0, options=options, log=(), steps=exact.step_times)
    assert np.degrees(np.ptp(exact.lumbar_rotation)) > 0.5, "the trial must move the trunk"
    assert np.abs(np.degrees(tabulated.lumbar_rotation - exact.lumbar_rotation)).max() < 1e-6
