"""The one-coordinate tables (trunk_drake.model.tables) against the exact computation they replace, and copies of the
model in one diagram (simulation.simulate_copies) against their own simulations."""

import dataclasses

import numpy as np
import pytest

import trunk_drake as td
from trunk_drake.diagram import CopiesUnsupported, TrunkOptions
from trunk_drake.model.tables import TOLERANCE, coordinate_table
from trunk_drake.signals import make_multisine
from trunk_drake.simulation import simulate, simulate_copies


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
        assert table.com_load(q, direction) == pytest.approx(rhythm.mass_weighted_com_jacobian(np.array([q]), direction)[0],
                                                                 rel=1e-9, abs=1e-9)
    assert used > 0.99 * 1501, "the table must cover nearly all of the range (it leaves out moment-arm jumps only)"
    assert not table.covers(hi + 0.01) and not table.covers(lo - 0.01)


def test_the_rhythm_on_the_pelvis_slide_takes_its_dynamics_from_the_welded_table():
    """The slide's coupling, velocity-product and gravity terms (`Slide`): accelerations from the table equal the exact
    plant's solve of M vdot = g - C + tau at postures, rates and forces across the range."""
    sliding = td.load_model("rhythm", pelvis_free=True)
    table = coordinate_table(sliding)
    assert table.slide is not None and table.width == 2
    plant, context = sliding.plant, sliding.plant.CreateDefaultContext()
    rng = np.random.default_rng(1)
    lo, hi = sliding.coordinate_info[1].range
    for angle in np.linspace(lo + 0.01, hi - 0.01, 37):
        if not table.covers(angle):
            continue
        q, v, tau = np.array([rng.normal(0, 0.05), angle]), rng.normal(0, 1.5, 2), rng.normal(0, 30, 2)
        plant.SetPositionsAndVelocities(context, np.concatenate([q, v]))
        exact = np.linalg.solve(plant.CalcMassMatrix(context),
                                plant.CalcGravityGeneralizedForces(context) - plant.CalcBiasTerm(context) + tau)
        assert np.abs(table.accelerations(q, v, tau) - exact).max() < 1e-6 * (1 + np.abs(exact).max()), angle
        arms = table.paths(angle).moment_arms
        assert arms.shape == (sliding.n_muscles, 2) and not arms[:, 0].any()


def test_a_seat_simulation_with_tables_follows_the_exact_one_on_its_steps(rhythm):
    options = TrunkOptions(kp=0.5, kv=0.3, reflex_delay=0.03, stiffness=150.0, feedforward=np.full(rhythm.n_muscles, 0.03),
                           pelvis="seat", seat_stiffness=4e4, seat_damping=600.0)
    exact = simulate(rhythm, duration=3.0, bandwidth=2.0, options=dataclasses.replace(options, tables=False), log=())
    tabulated = simulate(rhythm, duration=3.0, bandwidth=2.0, options=options, log=(), steps=exact.step_times)
    pelvis = exact.q[:, 0] - exact.platform[:, 0]
    assert np.ptp(pelvis) > 1e-4, "the seat must let the pelvis lag the platform"
    assert np.abs(tabulated.q[:, 0] - exact.q[:, 0]).max() < 1e-8
    assert np.abs(np.degrees(tabulated.lumbar_rotation - exact.lumbar_rotation)).max() < 1e-6


def test_a_model_with_more_than_one_coordinate_has_no_table():
    assert coordinate_table(td.load_model("sagittal", pelvis_free=False)) is None


def test_a_simulation_with_tables_follows_the_exact_one_on_its_steps(rhythm):
    options = TrunkOptions(kp=0.5, kv=0.3, reflex_delay=0.03, stiffness=150.0, feedforward=np.full(rhythm.n_muscles, 0.03))
    exact = simulate(rhythm, duration=3.0, bandwidth=2.0, options=dataclasses.replace(options, tables=False), log=())
    tabulated = simulate(rhythm, duration=3.0, bandwidth=2.0, options=options, log=(), steps=exact.step_times)
    assert np.degrees(np.ptp(exact.lumbar_rotation)) > 0.5, "the trial must move the trunk"
    assert np.abs(np.degrees(tabulated.lumbar_rotation - exact.lumbar_rotation)).max() < 1e-6


def test_copies_of_the_model_in_one_diagram_give_each_copys_own_simulation(rhythm):
    """simulate_copies: every copy equals its own simulate on the same step sequence (to round-off)."""
    options = TrunkOptions(reflex_delay=0.02, stiffness=150.0, feedforward=np.full(rhythm.n_muscles, 0.03))
    sets = [{"kp": 0.5, "kv": 0.3}, {"kp": {"sacrospinalis": 2.0}, "kv": 0.1}, {"kp": 0.0, "kv": 1.0}]
    own = simulate(rhythm, duration=2.0, bandwidth=2.0, options=options, log=(), **sets[0])
    copies = simulate_copies(rhythm, sets, own.step_times, duration=2.0, perturbation=make_multisine(f_max=2.0, seed=0, fade_shape="quintic"),
                                options=options, log=("normalized_fiber_length",))
    for gains, copy in zip(sets, copies):
        alone = simulate(rhythm, duration=2.0, bandwidth=2.0, options=options, steps=own.step_times,
                         log=("normalized_fiber_length",), **gains)
        assert np.abs(copy.lumbar_rotation - alone.lumbar_rotation).max() < 1e-12
        assert np.abs(copy.normalized_fiber_length - alone.normalized_fiber_length).max() < 1e-10
    assert np.degrees(np.abs(copies[0].lumbar_rotation - copies[2].lumbar_rotation).max()) > 0.01, "the gains must matter"


def _copies_and_alone(model, options, variants, signal):
    """A 2 s run of `options` on its own steps, `variants` simulated as copies on those steps, and each alone on them."""
    own = simulate(model, duration=2.0, perturbation=signal, options=options, log=())
    copies = simulate_copies(model, variants, own.step_times, duration=2.0, perturbation=signal, options=options, log=())
    alone = [simulate(model, duration=2.0, perturbation=signal, options=dataclasses.replace(options, **variant),
                      steps=own.step_times, log=()) for variant in variants]
    return own, copies, alone


def test_copies_may_differ_in_every_variant_field(rhythm):
    """Copies whose bushings, strength, activation time scale and reflex delay differ (the gap search's effect
    columns): each equals its own simulation on the same steps, and each field changes the response."""
    options = TrunkOptions(reflex_delay=0.02, stiffness=150.0, feedforward=np.full(rhythm.n_muscles, 0.03), kp=0.5, kv=0.3)
    variants = [{}, {"stiffness": 300.0}, {"damping": 12.0}, {"cubic": 800.0}, {"strength_scale": 1.4},
                {"activation_scale": 2.5}, {"reflex_delay": 0.05}, {"kp": 1.0, "reflex_delay": 0.03, "activation_scale": 1.5}]
    signal = make_multisine(f_max=2.0, seed=0, fade_shape="quintic")
    own, copies, alone = _copies_and_alone(rhythm, options, variants, signal)
    for variant, copy, single in zip(variants, copies, alone):
        assert np.abs(copy.lumbar_rotation - single.lumbar_rotation).max() < 1e-12, variant
        if variant:
            assert np.degrees(np.abs(copy.lumbar_rotation - copies[0].lumbar_rotation).max()) > 1e-4, f"{variant} must matter"
    with pytest.raises(ValueError, match="may differ in"):
        simulate_copies(rhythm, [{"tendon": "compliant"}] * 2, own.step_times, duration=2.0, perturbation=signal, options=options)
    with pytest.raises(CopiesUnsupported, match="all positive or all zero"):
        simulate_copies(rhythm, [{}, {"reflex_delay": 0.0}], own.step_times, duration=2.0, perturbation=signal, options=options)


def test_copies_on_the_seat_may_differ_in_its_stiffness_and_damping(rhythm):
    options = TrunkOptions(reflex_delay=0.02, stiffness=150.0, feedforward=np.full(rhythm.n_muscles, 0.03), kp=0.5, kv=0.3,
                           pelvis="seat", seat_stiffness=4e4, seat_damping=600.0)
    variants = [{}, {"seat_stiffness": 1.5e4}, {"seat_damping": 200.0}, {"kp": 1.0, "seat_stiffness": 1e5}]
    _, copies, alone = _copies_and_alone(rhythm, options, variants, make_multisine(f_max=2.0, seed=0, fade_shape="quintic"))
    for variant, copy, single in zip(variants, copies, alone):
        assert copy.coordinates == ["pelvis_tx", "lumbar_FE"]
        assert np.abs(copy.q - single.q).max() < 1e-12, variant
        if variant:
            assert np.abs(copy.q[:, 0] - copies[0].q[:, 0]).max() > 1e-6, f"{variant} must matter"


def test_copies_need_a_model_and_options_they_support(rhythm):
    steps = np.linspace(0.0, 1.0, 11)
    with pytest.raises(CopiesUnsupported, match="rigid tendons"):
        simulate_copies(rhythm, [{"kp": 0.1, "kv": 0.1}] * 2, steps, duration=1.0, options=TrunkOptions(tendon="compliant"))
    with pytest.raises(CopiesUnsupported, match="the prescribed pelvis, the seat or none"):
        simulate_copies(rhythm, [{"kp": 0.1, "kv": 0.1}] * 2, steps, duration=1.0, options=TrunkOptions(pelvis="force"))
    with pytest.raises(CopiesUnsupported, match="one coordinate"):
        simulate_copies(td.load_model("sagittal"), [{"kp": 0.1, "kv": 0.1}] * 2, steps, duration=1.0)
