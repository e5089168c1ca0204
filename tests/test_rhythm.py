"""The lumbar rhythm configuration (one coupled flexion coordinate) against MuJoCo's MyoTorso
with its equality constraints enabled, and its dynamics against Drake's own coupler constraints."""

from dataclasses import replace

import mujoco
import numpy as np
import pytest

import trunk_drake as td
from test_model_geometry import compile_mujoco
from trunk_drake.model.myotorso import RHYTHM_DRIVER, lumbar_c210_l5_s1_slope, myotorso_rhythm, read_myotorso

N_POSES = 240


def mujoco_with_couplings(l5_s1_slope):
    """MyoTorso with the sagittal pelvis slide and its equality constraints active.

    MyoTorso's couplers are relative to ``flex_extension``, which MuJoCo makes the L5/S1 hinge. For
    a rhythm in which L5/S1 turns `l5_s1_slope` of the driver (Lumbar_C_210: 0.125), every
    coupler on the driver is divided by that slope, so the constraints hold the same rhythm.
    """
    m = compile_mujoco(pelvis_slide=True)
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    driver = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, RHYTHM_DRIVER)
    on_driver = (m.eq_type == mujoco.mjtEq.mjEQ_JOINT) & (m.eq_obj2id == driver)
    m.eq_data[on_driver, 1] /= l5_s1_slope
    assert m.eq_active0.all() and on_driver.sum() == 5  # four levels and the Abdomen
    return m, mujoco.MjData(m)


def jnt(m, name):
    return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)


def set_rhythm_pose(m, d, q, l5_s1_slope, total):
    """pelvis_tx = q[0]; the driver from lumbar_FE = q[1]; coupled joints from MuJoCo's own constraints."""
    d.qpos[:] = 0.0
    d.qpos[m.jnt_qposadr[jnt(m, "pelvis_tx")]] = q[0]
    d.qpos[m.jnt_qposadr[jnt(m, RHYTHM_DRIVER)]] = -l5_s1_slope * q[1] / total
    for e in np.flatnonzero(m.eq_type == mujoco.mjtEq.mjEQ_JOINT):
        j1, j2 = m.eq_obj1id[e], m.eq_obj2id[e]
        x = d.qpos[m.jnt_qposadr[j2]] if j2 >= 0 else 0.0
        d.qpos[m.jnt_qposadr[j1]] = np.polyval(m.eq_data[e, 4::-1], x)
    mujoco.mj_forward(m, d)


def rhythm_direction(m, d, l5_s1_slope, total):
    """dq/d(lumbar_FE) in MuJoCo's dofs: the null-space direction of its active equality constraints
    with the driver turning -l5_s1_slope/total per radian and the other free dofs held."""
    rows = d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    J = d.efc_J[: d.nefc * m.nv].reshape(d.nefc, m.nv)[rows]
    held = {m.jnt_dofadr[jnt(m, n)]: 0.0 for n in ("pelvis_tx", "lat_bending", "axial_rotation")}
    held[m.jnt_dofadr[jnt(m, RHYTHM_DRIVER)]] = -l5_s1_slope / total
    fixed = np.array(sorted(held))
    free = np.setdiff1d(np.arange(m.nv), fixed)
    n = np.zeros(m.nv)
    n[fixed] = [held[i] for i in fixed]
    n[free] = np.linalg.lstsq(J[:, free], -J[:, fixed] @ n[fixed], rcond=None)[0]
    assert np.abs(J @ n).max() < 1e-12
    return n


def moment_dense(m, d):
    dense = np.zeros((m.nu, m.nv))
    mujoco.mju_sparse2dense(dense, d.actuator_moment, d.moment_rownnz, d.moment_rowadr, d.moment_colind)
    return dense


@pytest.fixture(scope="module", params=["lumbar_c_210", "myotorso_as_shipped"])
def rhythm_case(request):
    """(model, MuJoCo model, data, L5/S1 slope): the default rhythm, and MyoTorso's own (L5/S1 = driver)."""
    slope = lumbar_c210_l5_s1_slope() if request.param == "lumbar_c_210" else 1.0
    base = read_myotorso()
    model = td.load_model("rhythm", spec=replace(base, rhythm=myotorso_rhythm(base.couplings, slope)))
    return (model, *mujoco_with_couplings(slope), slope)


def test_rhythm_coordinates_and_level_shares(rhythm_case):
    model, _, _, slope = rhythm_case
    assert model.coordinates == ["pelvis_tx", "lumbar_FE"]
    shares = model.level_matrix[:, 1]
    assert model.levels == ["L5_S1_FE", "L4_L5_FE", "L3_L4_FE", "L2_L3_FE", "L1_L2_FE"]
    assert abs(shares.sum() - 1.0) < 1e-12, "lumbar_FE is the sum of the level angles"
    expected = np.array([slope, 0.185, 0.204, 0.231, 0.255])
    np.testing.assert_allclose(shares, expected / expected.sum(), rtol=1e-12)


def test_rhythm_lengths_and_moment_arms_match_mujoco_with_constraints(rhythm_case):
    model, m, d, slope = rhythm_case
    total = model.spec.rhythm.total
    lo, hi = model.coordinate_info[1].range
    rng = np.random.default_rng(17)
    worst_length = worst_arm = worst_violation = 0.0
    for theta in np.linspace(lo, hi, N_POSES):
        q = np.array([rng.uniform(-0.2, 0.2), theta])
        set_rhythm_pose(m, d, q, slope, total)
        rows = d.efc_type[: d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        worst_violation = max(worst_violation, np.abs(d.efc_pos[: d.nefc][rows]).max())
        state = model.path_state(q)
        n = rhythm_direction(m, d, slope, total)
        dense = moment_dense(m, d)
        expected = np.column_stack([-dense[:, m.jnt_dofadr[jnt(m, "pelvis_tx")]], -dense @ n])
        worst_length = max(worst_length, np.abs(state.lengths - d.actuator_length).max())
        worst_arm = max(worst_arm, np.abs(state.moment_arms - expected).max())
    assert worst_violation < 1e-12, f"poses must satisfy MuJoCo's equality constraints ({worst_violation:.2e})"
    assert worst_length < 1e-6, f"largest muscle-length difference {worst_length:.3e} m"
    assert worst_arm < 1e-5, f"largest moment-arm difference about lumbar_FE {worst_arm:.3e} m"


def test_rhythm_mass_matrix_and_gravity_are_projected_through_the_constraints(rhythm_case):
    model, m, d, slope = rhythm_case
    total = model.spec.rhythm.total
    plant, context = model.plant, model.plant.CreateDefaultContext()
    tx = m.jnt_dofadr[jnt(m, "pelvis_tx")]
    for theta in np.linspace(-0.4, 0.9, 7):
        q = np.array([0.03, theta])
        set_rhythm_pose(m, d, q, slope, total)
        N = np.column_stack([np.eye(m.nv)[tx], rhythm_direction(m, d, slope, total)])
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        M -= np.diag(m.dof_armature)  # MuJoCo's rotor inertia; not part of the bodies
        plant.SetPositions(context, q)
        plant.SetVelocities(context, np.zeros(2))
        np.testing.assert_allclose(plant.CalcMassMatrix(context), N.T @ M @ N, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(plant.CalcGravityGeneralizedForces(context), -N.T @ d.qfrc_bias, rtol=1e-9, atol=1e-9)


def test_rhythm_dynamics_match_drake_coupler_constraints():
    """Free motion of the coupled chain (gravity only) against a discrete Drake plant whose levels
    are tied by Drake's own coupler constraints (SAP), from 5 deg of flexion for 0.3 s."""
    from pydrake.multibody.plant import DiscreteContactApproximation, MultibodyPlant
    from pydrake.systems.analysis import Simulator

    from trunk_drake.model.plant import add_to_plant

    model = td.load_model("rhythm", pelvis_free=False)
    G = model.coupling[:, 0]
    q0 = np.radians(5.0)

    coupled = Simulator(model.plant)
    model.plant.SetPositions(coupled.get_mutable_context(), [q0])
    coupled.get_mutable_integrator().set_target_accuracy(1e-9)
    coupled.AdvanceTo(0.3)
    theta_coupled = model.plant.GetPositions(coupled.get_context())[0]

    discrete = MultibodyPlant(time_step=1e-4)
    add_to_plant(discrete, model.spec, model.joint_info)
    first = discrete.GetJointByName(model.joint_info[0].name)
    for c, g in zip(model.joint_info[1:], G[1:]):
        discrete.AddCouplerConstraint(discrete.GetJointByName(c.name), first, g / G[0], 0.0)  # q_c = (g/G0) q_first
    discrete.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
    discrete.Finalize()
    sim = Simulator(discrete)
    joints = [discrete.GetJointByName(c.name) for c in model.joint_info]
    for joint, g in zip(joints, G):
        joint.set_angle(sim.get_mutable_context(), g * q0)
    sim.AdvanceTo(0.3)
    theta_discrete = sum(j.get_angle(sim.get_context()) for j, c in zip(joints, model.joint_info) if c.name.endswith("_FE"))
    assert abs(theta_coupled - q0) > np.radians(1.0), "the chain must actually move under gravity"
    assert abs(theta_coupled - theta_discrete) < 2e-3 * abs(theta_coupled - q0) + 1e-5, (theta_coupled, theta_discrete)


def test_rhythm_conserves_energy():
    from pydrake.systems.analysis import Simulator

    model = td.load_model("rhythm", pelvis_free=True)
    sim = Simulator(model.plant)
    context = sim.get_mutable_context()
    model.plant.SetPositions(context, [0.0, np.radians(10.0)])
    model.plant.SetVelocities(context, [0.05, -0.5])
    energy = model.plant.CalcKineticEnergy(context) + model.plant.CalcPotentialEnergy(context)
    sim.get_mutable_integrator().set_target_accuracy(1e-10)
    sim.AdvanceTo(0.5)
    after = model.plant.CalcKineticEnergy(context) + model.plant.CalcPotentialEnergy(context)
    assert abs(model.plant.GetPositions(context)[1] - np.radians(10.0)) > np.radians(1.0)
    assert abs(after - energy) < 1e-6 * max(1.0, abs(energy)), (energy, after)


def test_coactivation_equilibrium_is_an_equilibrium_of_the_rhythm_diagram():
    """Static optimisation and the simulated diagram see the same coupled system: muscles (moment
    arms about lumbar_FE), bushings (through the level shares) and gravity balance at rest."""
    import warnings

    from trunk_drake.diagram import TrunkOptions, build_trunk_diagram

    model = td.load_model("rhythm")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the rhythm needs no reserve actuators
        excitation, so = td.coactivation(model, 0.02, return_result=True)
    assert so.reserves_used == {} and abs(so.residuals).max() < 1e-6
    td_ = build_trunk_diagram(model, TrunkOptions(feedforward=excitation))
    assert td_.model.coordinates == ["lumbar_FE"] and list(td_.fe_indices) == [0]
    context = td_.diagram.CreateDefaultContext()
    td_.muscles.GetMyMutableContextFromRoot(context).SetContinuousState(excitation)
    qdot, vdot = td_.plant.EvalTimeDerivatives(td_.plant.GetMyContextFromRoot(context)).CopyToVector()  # at rest: q = v = 0
    assert qdot == 0.0 and abs(vdot) < 1e-5, vdot  # lumbar_FE acceleration, rad/s^2
    unbalanced = build_trunk_diagram(model, TrunkOptions(feedforward=0.5 * excitation))
    context = unbalanced.diagram.CreateDefaultContext()
    unbalanced.muscles.GetMyMutableContextFromRoot(context).SetContinuousState(0.5 * excitation)
    assert abs(unbalanced.plant.EvalTimeDerivatives(unbalanced.plant.GetMyContextFromRoot(context)).CopyToVector()[1]) > 1e-2


def test_rhythm_simulation_reports_levels_and_lumbar_rotation():
    model = td.load_model("rhythm")
    result = td.simulate(model, duration=1.0, bandwidth=1.0, feedforward=td.coactivation(model, 0.02))
    assert result.coordinates == ["pelvis_tx", "lumbar_FE"]
    np.testing.assert_allclose(result.lumbar_rotation, result.coordinate("lumbar_FE"), atol=1e-12)
    levels = np.column_stack([result.coordinate(f"{lvl}_FE") for lvl in ("L5_S1", "L4_L5", "L3_L4", "L2_L3", "L1_L2")])
    np.testing.assert_allclose(levels.sum(axis=1), result.lumbar_rotation, atol=1e-12)
    np.testing.assert_allclose(levels[:, 0], 0.125 * result.lumbar_rotation, atol=1e-12)
    assert np.abs(result.coordinate("pelvis_tx") - result.platform[:, 0]).max() < 1e-12  # prescribed pelvis
    assert np.degrees(np.abs(result.lumbar_rotation).max()) > 0.01, "the platform must move the trunk"


def test_fit_objective_on_the_rhythm_is_the_noise_floor_at_the_truth():
    """Fitting accepts the rhythm: data made by the rhythm model with known gains, plus noise, give
    a chi-square of one per sample at those gains (lumbar rotation and the five level angles)."""
    from trunk_drake.gap.benchmark import nominal_options
    from trunk_drake.gap.synthetic import synthetic_trials
    from trunk_drake.io.trials import OUTPUT_NAMES
    from trunk_drake.optim.fit import Objective, targets_from_trials
    from trunk_drake.optim.gains import GainLayout

    model = td.load_model("rhythm")
    truth = nominal_options()
    noise = np.radians(0.05)
    trials = synthetic_trials(model, truth, [("rhythm", 1.0, 4)], noise, seed=5, period=10.0)
    targets = targets_from_trials(trials, OUTPUT_NAMES, noise, period=10.0)
    layout = GainLayout.for_groups(model.groups)
    r, _, _ = Objective(model, targets, layout, truth)(layout.vector({"kp": truth.kp, "kv": truth.kv}))
    assert abs(r @ r / r.size - 1.0) < 0.1, r @ r / r.size
    wrong = layout.vector({"kp": truth.kp, "kv": {g: 3 * v for g, v in truth.kv.items()}})
    r_wrong, _, _ = Objective(model, targets, layout, truth)(wrong)
    assert r_wrong @ r_wrong > 1.2 * (r @ r), ("the gains must matter", r_wrong @ r_wrong / r.size)  # chi2 SD: 1.5 % of r.size
