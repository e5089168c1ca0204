"""Static optimisation: analytic one-joint cases through the same solver, and the full model."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.tree import MultibodyForces

from trunk_drake.diagram import TrunkOptions, build_trunk_diagram
from trunk_drake.model.trunk_model import load_model
from trunk_drake.optim.static import (
    COACTIVATION_LEVELS, MomentBalance, PointLoad, StaticInfeasibleError, StaticOptimizer, coactivation, solve_balance,
    static_optimization,
)

# One hinge, a flexor (moment arm +5 cm) and an extensor (-4 cm); active force capacities in N.
R = np.array([[0.05], [-0.04]])
ACTIVE = np.array([800.0, 600.0])
MUSCLES = ("flexor", "extensor")


def one_joint(required, passive=(0.0, 0.0), moment_arms=R, active=ACTIVE, muscles=MUSCLES):
    return MomentBalance(moment_arms, active, passive, [required], ("hinge",), muscles)


@pytest.fixture(scope="module")
def spine3d():
    return load_model(dofs="spine3d")


@pytest.fixture(scope="module")
def sagittal():
    return load_model(dofs="sagittal")


def test_antagonists_match_the_analytic_solution():
    # minimise a1^2 + a2^2 with 40 a1 - 24 a2 = 10 Nm: the extensor stays at its lower bound
    amin = 0.01
    res = solve_balance(one_joint(10.0), p=2, min_activation=amin)
    c1, c2 = R[:, 0] * ACTIVE
    np.testing.assert_allclose(res.activations, [(10.0 - c2 * amin) / c1, amin], atol=1e-7)
    np.testing.assert_allclose(res.forces, res.activations * ACTIVE, rtol=1e-12)
    assert res.success and res.at_upper_bound == [] and abs(res.residuals[0]) < 1e-9


def test_load_the_flexor_can_barely_hold_then_infeasible():
    amin = 0.01
    c1, c2 = R[:, 0] * ACTIVE
    limit = c1 + c2 * amin  # flexor fully active, extensor at its minimum
    res = solve_balance(one_joint(limit), min_activation=amin)
    np.testing.assert_allclose(res.activations, [1.0, amin], atol=1e-6)
    assert res.at_upper_bound == ["flexor"]
    with pytest.raises(StaticInfeasibleError) as err:
        solve_balance(one_joint(limit + 0.5), min_activation=amin)
    assert "hinge" in str(err.value) and "flexor" in str(err.value)
    assert err.value.shortfall == pytest.approx({"hinge": 0.5}, abs=1e-6)
    assert err.value.saturated == ["flexor"]


@pytest.mark.parametrize("p", [1.0, 2.0, 3.0])
def test_exponent_shares_load_between_synergists(p):
    # two flexors with capacities c1 = 40, c2 = 10 Nm: KKT gives a_i ~ c_i^(1/(p-1)); p = 1 loads the strongest
    arms, active, tau, amin = np.array([[0.05], [0.05]]), np.array([800.0, 200.0]), 20.0, 0.0
    c = arms[:, 0] * active
    res = solve_balance(one_joint(tau, moment_arms=arms, active=active, muscles=("strong", "weak")), p=p, min_activation=amin)
    expected = np.array([tau / c[0], 0.0]) if p == 1 else tau * c ** (1 / (p - 1)) / np.sum(c ** (p / (p - 1)))
    np.testing.assert_allclose(res.activations, expected, atol=1e-6)
    assert abs(res.residuals[0]) < 1e-9


def test_reserve_actuator_shares_as_the_kkt_conditions_say():
    amin, s = 0.01, 2.0  # reserve of optimal force 2 Nm, cost r^2
    c1, c2 = R[:, 0] * ACTIVE
    tau = 10.0
    res = solve_balance(one_joint(tau), min_activation=amin, reserves=s)
    rest = tau - c2 * amin
    np.testing.assert_allclose(res.activations[0], c1 * rest / (c1**2 + s**2), rtol=1e-6)
    np.testing.assert_allclose(res.reserve_forces, [s**2 * rest / (c1**2 + s**2)], rtol=1e-6)
    assert set(res.reserves_used) == {"hinge"} and abs(res.residuals[0]) < 1e-9


def test_passive_force_reduces_the_active_demand():
    passive = (100.0, 0.0)  # 5 Nm of passive flexor moment
    with_passive = solve_balance(one_joint(10.0, passive=passive), min_activation=0.0)
    without = solve_balance(one_joint(10.0), min_activation=0.0)
    np.testing.assert_allclose(with_passive.activations[0], (10.0 - 5.0) / 40.0, atol=1e-7)
    np.testing.assert_allclose(without.activations[0], 10.0 / 40.0, atol=1e-7)


def test_bad_options_are_rejected():
    with pytest.raises(ValueError, match="p=0.5"):
        solve_balance(one_joint(1.0), p=0.5)
    with pytest.raises(ValueError, match="activation bounds"):
        solve_balance(one_joint(1.0), min_activation=0.5, max_activation=0.4)


def test_full_model_balances_inverse_dynamics(spine3d):
    model, plant = spine3d, spine3d.plant
    rng = np.random.default_rng(4)
    lo, hi = np.array([c.range for c in model.coordinate_info]).T
    optimizer = StaticOptimizer(model, p=2)
    load = PointLoad("torso", tuple(model.spec.landmark("T8").pos), (0.0, -5.0, 2.0))
    for _ in range(3):
        q = rng.uniform(0.05 * lo, 0.05 * hi)
        v = rng.normal(scale=0.05, size=q.size)
        vdot = rng.normal(scale=0.1, size=q.size)
        res = optimizer.solve(q, v, vdot, [load])
        assert res.success and np.max(np.abs(res.residuals)) < 1e-6
        # independent check with Drake's inverse dynamics: muscles + bushings + load + gravity = M vdot + C v
        ctx = plant.CreateDefaultContext()
        plant.SetPositions(ctx, q)
        plant.SetVelocities(ctx, v)
        forces = MultibodyForces(plant)
        plant.CalcForceElementsContribution(ctx, forces)  # gravity
        tau_id = plant.CalcInverseDynamics(ctx, vdot, forces)
        tau_muscles = model.path_state(q, v).moment_arms.T @ res.forces
        fe = [model.coordinates.index(c) for c in model.coordinates if c.endswith("_FE")]
        tau_bushing = np.zeros_like(q)
        tau_bushing[fe] = -100.0 * q[fe] - 7.5 * v[fe]
        tau_load = optimizer.generalized_load([load])
        np.testing.assert_allclose(tau_muscles + tau_bushing + tau_load, tau_id, atol=1e-6)


def test_passive_off_and_locked_coordinates(spine3d):
    q = np.zeros(len(spine3d.coordinates))
    full = static_optimization(spine3d, q)
    opensim_like = StaticOptimizer(spine3d, include_passive=False)
    assert not opensim_like.balance(q).passive.any() and StaticOptimizer(spine3d).balance(q).passive.any()
    no_passive = opensim_like.solve(q)
    assert no_passive.success and np.max(np.abs(no_passive.residuals)) < 1e-6 and no_passive.cost != pytest.approx(full.cost)
    locked = static_optimization(spine3d, q, locked=["*_AR", "*_LB"])
    assert locked.coordinates == tuple(c for c in spine3d.coordinates if c.endswith("_FE"))
    with pytest.raises(ValueError, match="matches none"):
        static_optimization(spine3d, q, locked=["L9_*"])


def test_unbalanceable_coordinate_is_named(sagittal):
    vdot = np.zeros(len(sagittal.coordinates))
    vdot[sagittal.coordinates.index("pelvis_tx")] = 1.0  # muscles cannot accelerate the pelvis
    with pytest.raises(StaticInfeasibleError, match="pelvis_tx"):
        static_optimization(sagittal, np.zeros(len(sagittal.coordinates)), vdot=vdot)


def test_coactivation_feeds_the_diagram(sagittal):
    levels = {}
    for amin in COACTIVATION_LEVELS[:2]:
        levels[amin] = coactivation(sagittal, amin)
        assert levels[amin].shape == (sagittal.n_muscles,) and levels[amin].min() >= amin - 1e-9
    assert levels[0.011].sum() > levels[0.010].sum()
    # the excitation balances gravity at the lumbar levels
    fixed = sagittal.variant(pelvis_free=False)
    balance = StaticOptimizer(fixed).balance(np.zeros(len(fixed.coordinates)))
    moment = balance.moment_arms.T @ (levels[0.010] * balance.active + balance.passive)
    np.testing.assert_allclose(moment, balance.required, atol=1e-6)
    diagram = build_trunk_diagram(sagittal, TrunkOptions(feedforward=levels[0.010]))
    assert diagram.muscles.n == sagittal.n_muscles
    with pytest.warns(UserWarning, match="unbalanced"):
        excitation, result = coactivation(sagittal, 0.070, return_result=True)
    assert excitation.min() >= 0.070 - 1e-9 and result.reserves_used
