"""Diagram-level checks: analytic pendulum, energy conservation, the thesis' qualitative results."""

import numpy as np
import pytest
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import DiagramBuilder
from scipy.integrate import solve_ivp

import trunk_drake as td
from trunk_drake.diagram import TrunkOptions, build_trunk_diagram, muscle_systems_alive
from trunk_drake.model.spec import BodySpec, JointSpec, ModelSpec, MuscleSpec, PathElement, SiteSpec
from trunk_drake.muscle import thelen
from trunk_drake.signals import make_multisine
from trunk_drake.simulation import SimulationError, simulate

G = 9.81
MASS, COM = 1.5, np.array([0.0, 0.0, -0.3])  # pendulum hanging from a hinge about x
BASE_SITE, ARM_SITE = np.array([0.0, 0.1, 0.0]), np.array([0.0, 0.03, -0.2])
F_MAX, L_OPT = 200.0, 0.1
INERTIA = np.diag([0.02, 0.02, 0.005])  # about the COM


def pendulum_spec() -> ModelSpec:
    """One hinge, one muscle from the base (in front) to the arm: a minimal user model."""
    unit = np.array([1.0, 0, 0, 0])
    l_mt0 = np.linalg.norm(ARM_SITE - BASE_SITE)
    return ModelSpec(
        name="pendulum",
        bodies=(BodySpec("base", None, np.zeros(3), unit, 0.0, np.zeros(3), np.zeros((3, 3))),
                BodySpec("arm", "base", np.zeros(3), unit, MASS, COM, INERTIA)),
        joints=(JointSpec("hinge", "arm", "hinge", np.array([1.0, 0, 0]), np.zeros(3), (-1.0, 1.0)),),
        sites=(SiteSpec("origin", "base", BASE_SITE), SiteSpec("insertion", "arm", ARM_SITE)),
        wraps=(),
        muscles=(MuscleSpec("flexor", (PathElement("site", 0), PathElement("site", 1)), F_MAX, L_OPT, l_mt0 - L_OPT, 0.0, "flexors"),),
        root_pos=np.array([0.0, 0.0, 1.0]),
    )


def pendulum_reference(theta0, excitation, k, c, duration):
    """Independent integration: analytic geometry and inertia, scipy's DOP853."""
    constants = thelen.ThelenConstants()
    params = thelen.MuscleParameters([F_MAX], [L_OPT], [np.linalg.norm(ARM_SITE - BASE_SITE) - L_OPT], [0.0])
    inertia = INERTIA[0, 0] + MASS * COM @ COM

    def geometry(theta):
        cs, sn = np.cos(theta), np.sin(theta)
        p = np.array([0.0, cs * ARM_SITE[1] - sn * ARM_SITE[2], sn * ARM_SITE[1] + cs * ARM_SITE[2]])
        dp = np.array([0.0, -sn * ARM_SITE[1] - cs * ARM_SITE[2], cs * ARM_SITE[1] - sn * ARM_SITE[2]])
        d = p - BASE_SITE
        length = np.linalg.norm(d)
        return length, d @ dp / length

    def rhs(t, x):
        theta, omega, a = x
        length, dl = geometry(theta)
        force = thelen.rigid_tendon(a, [length], [dl * omega], params, constants).tendon_force[0]
        torque = -MASS * G * (-COM[2]) * np.sin(theta) - dl * force - k * theta - c * omega
        return [omega, torque / inertia, thelen.activation_derivative([excitation], [a], constants)[0]]

    sol = solve_ivp(rhs, (0, duration), [theta0, 0.0, excitation], method="DOP853", rtol=1e-11, atol=1e-12, dense_output=True)
    return sol.sol


def test_one_joint_one_muscle_pendulum_matches_independent_integration():
    model = td.load_model(dofs="all", spec=pendulum_spec())
    k, c, u = 2.0, 0.1, 0.3
    result = simulate(model, duration=2.0, perturbation=None, feedforward=np.array([u]), stiffness=k, damping=c,
                      accuracy=1e-7, max_step=0.002, log_rate=200.0)
    reference = pendulum_reference(0.0, u, k, c, 2.0)
    theta_ref = reference(result.time)[0]
    assert np.ptp(theta_ref) > 0.2, "the muscle must swing the pendulum noticeably"
    np.testing.assert_allclose(result.q[:, 0], theta_ref, atol=2e-4)
    np.testing.assert_allclose(result.activation[:, 0], reference(result.time)[2], atol=1e-5)


class FailingSignal:
    """A platform signal whose evaluation fails after 0.1 s: a simulation that ends in an error."""

    def evaluate(self, t):
        if np.max(t) > 0.1:
            raise ValueError("the platform signal failed at 0.1 s")
        zero = np.zeros_like(np.asarray(t, float))
        return zero, zero, zero


def test_simulations_free_their_diagrams_and_leave_the_model_reusable(sagittal):
    """pydrake keeps every diagram holding a Python system alive (drake #22515): `simulate` releases its own,
    also when the simulation fails."""
    model = td.load_model(dofs="all", spec=pendulum_spec())
    before = muscle_systems_alive()
    runs = [simulate(model, duration=0.2, perturbation=None, feedforward=np.array([0.3])) for _ in range(3)]
    assert muscle_systems_alive() == before
    np.testing.assert_array_equal(runs[0].q, runs[2].q)
    with pytest.raises(ValueError, match="failed at 0.1 s"):
        simulate(sagittal, duration=0.2, perturbation=FailingSignal())
    assert muscle_systems_alive() == before
    with pytest.raises(ValueError, match="feedforward excitation must have 210 entries"):  # bad input found mid-build
        simulate(sagittal, duration=0.2, perturbation=None, feedforward=np.zeros(3))
    assert muscle_systems_alive() == before


def test_bare_plant_conserves_energy():
    plant = td.load_model("sagittal", pelvis_free=False).variant().plant
    builder = DiagramBuilder()
    builder.AddSystem(plant)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    ResetIntegratorFromFlags(simulator, "runge_kutta5", 1e-3)
    simulator.get_mutable_integrator().set_target_accuracy(1e-10)
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    plant.SetPositions(context, [0.05, -0.03, 0.04, 0.02, -0.05])
    plant.SetVelocities(context, [0.5, -0.2, 0.1, 0.3, -0.4])

    def energy():
        return plant.CalcKineticEnergy(context) + plant.CalcPotentialEnergy(context)

    e0 = energy()
    simulator.AdvanceTo(0.5)
    assert abs(plant.GetPositions(context)).max() > 0.1, "the trunk must actually move"
    assert abs(energy() - e0) < 1e-7 * abs(e0)


def lumbar_flexion_deg(result, t):
    return np.degrees(np.interp(t, result.time, result.lumbar_rotation))


@pytest.fixture(scope="module")
def sagittal():
    return td.load_model("sagittal")


def test_bushings_alone_let_the_trunk_flex_and_coactivation_or_stiffness_reduce_it(sagittal):
    alone = simulate(sagittal, duration=1.5, perturbation=None)
    coactive = simulate(sagittal, duration=1.5, perturbation=None, feedforward=np.full(210, 0.05))
    stiff = simulate(sagittal, duration=1.5, perturbation=None, stiffness=800.0)
    damped = simulate(sagittal, duration=1.5, perturbation=None, damping=0.0)
    final = {r: lumbar_flexion_deg(x, 1.5) for r, x in [("alone", alone), ("coactive", coactive), ("stiff", stiff)]}
    assert final["alone"] > 10.0, "with bushings only (k=100) the trunk flexes under gravity"
    assert final["coactive"] < final["alone"] and final["stiff"] < final["alone"]
    # more damping slows the fall: less flexion after 0.5 s
    assert lumbar_flexion_deg(alone, 0.5) < lumbar_flexion_deg(damped, 0.5)


def test_reflexes_reduce_lumbar_rotation_under_1hz_perturbation(sagittal):
    signal = make_multisine(f_max=1.0, seed=3)
    common = dict(perturbation=signal, duration=8.0, stiffness=400.0, feedforward=np.full(210, 0.02))
    without = simulate(sagittal, **common)
    with_reflex = simulate(sagittal, kp=0.3, kv=0.3, **common)
    window = without.time > 2.0
    rms = [np.std(r.lumbar_rotation[window]) for r in (without, with_reflex)]
    assert rms[1] < 0.9 * rms[0], rms


def test_force_driven_heavy_pelvis_tracks_prescribed_motion(sagittal):
    signal = make_multisine(f_max=1.0, seed=4)
    common = dict(perturbation=signal, duration=6.0, stiffness=400.0, feedforward=np.full(210, 0.02))
    exact = simulate(sagittal, pelvis="prescribed", **common)
    forced = simulate(sagittal, pelvis="force", **common)
    assert np.abs(forced.coordinate("pelvis_tx") - forced.platform[:, 0]).max() < 2e-3
    np.testing.assert_allclose(forced.lumbar_rotation, exact.lumbar_rotation, atol=np.radians(0.2))


def test_diverging_run_stops_with_an_explanation(sagittal):
    with pytest.raises(SimulationError, match=r"diverged at t=.*coordinates L\d_.*muscles"):
        simulate(sagittal, duration=5.0, perturbation=None, stiffness=0.0, damping=0.0, strength_scale=1e-3)


def test_bad_options_are_rejected(sagittal):
    with pytest.raises(ValueError, match="tendon"):
        build_trunk_diagram(sagittal, TrunkOptions(tendon="elastic"))
    with pytest.raises(ValueError, match="unknown muscle groups"):
        simulate(sagittal, duration=0.1, perturbation=None, kp={"latissimus": 0.1})
    with pytest.raises(ValueError, match="210 entries"):
        simulate(sagittal, duration=0.1, perturbation=None, feedforward=np.zeros(3))


def test_a_simulation_records_only_the_muscle_histories_asked_for():
    """The fits log only what they read (every log is evaluated at every step); the motion is unchanged."""
    model = td.load_model(dofs="all", spec=pendulum_spec())
    full = simulate(model, duration=0.2, perturbation=None, feedforward=np.array([0.3]))
    lean = simulate(model, duration=0.2, perturbation=None, feedforward=np.array([0.3]), log=("normalized_fiber_length",))
    np.testing.assert_array_equal(lean.q, full.q)
    np.testing.assert_array_equal(lean.normalized_fiber_length, full.normalized_fiber_length)
    assert lean.activation is None and lean.muscle_force is None and lean.fiber_length is None
    with pytest.raises(ValueError, match="unknown muscle logs \\['force'\\]"):
        simulate(model, duration=0.2, perturbation=None, log=("force",))
