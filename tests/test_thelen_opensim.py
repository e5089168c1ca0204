"""Oracle tests: trunk_drake.muscle.thelen against OpenSim 4.6's Thelen2003Muscle.

A small OpenSim model holds one Thelen2003Muscle per slider joint (path from the ground
origin to the slider body, so path length = q and lengthening speed = qdot); states are
set directly and OpenSim's own outputs are compared with ours on grids of activation,
fiber length, velocity and tendon stretch.
"""

import math

import numpy as np
import pytest

osim = pytest.importorskip(
    "opensim", reason="OpenSim Python bindings (pip 'opensim==4.6') not importable; "
                      "Thelen2003Muscle oracle tests skipped")

from trunk_drake.muscle import thelen as th  # noqa: E402

PARAMS = th.MuscleParameters(
    max_isometric_force=[1000.0, 250.0, 3000.0, 600.0],
    optimal_fiber_length=[0.10, 0.045, 0.20, 0.06],
    tendon_slack_length=[0.20, 0.03, 0.05, 0.012],
    pennation_angle_at_optimal=[0.0, 0.25, 0.45, 0.1],
)

CONSTANTS = {
    "thesis": th.ThelenConstants(),
    "opensim_defaults": th.ThelenConstants.opensim_defaults(),
    # every remaining field away from its default, so each one is exercised
    "custom": th.ThelenConstants(fv_extrapolation_threshold=0.9, max_contraction_velocity=8.0,
                                 activation_time_constant=0.01, deactivation_time_constant=0.04,
                                 minimum_activation=0.02, maximum_pennation_angle=1.2),
}

ACTIVATIONS = [0.01, 0.05, 0.2, 0.5, 0.8, 1.0]
NORM_FIBER_LENGTHS = np.linspace(0.5, 1.6, 7)


class OsimRig:
    """OpenSim model with one Thelen2003Muscle per slider joint."""

    def __init__(self, params: th.MuscleParameters, c: th.ThelenConstants):
        self.params, self.c = params, c
        model = osim.Model()
        model.setGravity(osim.Vec3(0))
        self.muscles, self.coords = [], []
        for i in range(params.n_muscles):
            body = osim.Body(f"b{i}", 1.0, osim.Vec3(0), osim.Inertia(1))
            model.addBody(body)
            joint = osim.SliderJoint(f"s{i}", model.getGround(), osim.Vec3(0), osim.Vec3(0),
                                     body, osim.Vec3(0), osim.Vec3(0))
            model.addJoint(joint)
            m = osim.Thelen2003Muscle(f"m{i}", float(params.max_isometric_force[i]),
                                      float(params.optimal_fiber_length[i]),
                                      float(params.tendon_slack_length[i]),
                                      float(params.pennation_angle_at_optimal[i]))
            m.addNewPathPoint("origin", model.getGround(), osim.Vec3(0))
            m.addNewPathPoint("insertion", body, osim.Vec3(0))
            m.set_FmaxTendonStrain(c.tendon_strain_at_fmax)
            m.set_FmaxMuscleStrain(c.passive_strain_at_fmax)
            m.set_KshapePassive(c.k_passive)
            m.set_KshapeActive(c.gamma)
            m.set_Af(c.af)
            m.set_Flen(c.flen)
            m.set_fv_linear_extrap_threshold(c.fv_extrapolation_threshold)
            m.set_max_contraction_velocity(c.max_contraction_velocity)
            m.set_activation_time_constant(c.activation_time_constant)
            m.set_deactivation_time_constant(c.deactivation_time_constant)
            m.set_minimum_activation(c.minimum_activation)
            m.setMinControl(c.minimum_activation)
            m.set_maximum_pennation_angle(c.maximum_pennation_angle)
            model.addForce(m)
        self.model = model
        self.state = model.initSystem()
        for i in range(params.n_muscles):
            self.muscles.append(osim.Thelen2003Muscle.safeDownCast(
                model.getMuscles().get(f"m{i}")))
            self.coords.append(model.getCoordinateSet().get(f"s{i}_coord_0"))

    def set(self, l_mt, v_mt=None, activation=None, fiber_length=None):
        s = self.state
        for i, m in enumerate(self.muscles):
            self.coords[i].setValue(s, float(l_mt[i]), False)
            if v_mt is not None:
                self.coords[i].setSpeedValue(s, float(v_mt[i]))
            if activation is not None:
                m.setActivation(s, float(activation[i]))
            if fiber_length is not None:
                m.setFiberLength(s, float(fiber_length[i]))
        return s

    def get(self, name):
        return np.array([getattr(m, name)(self.state) for m in self.muscles])


@pytest.fixture(scope="module", params=list(CONSTANTS))
def rig(request):
    return OsimRig(PARAMS, CONSTANTS[request.param])


def _rel_err(ours, ref, scale):
    """|ours - ref| relative to |ref|, with ``scale`` as the floor of the denominator."""
    return np.abs(ours - ref) / np.maximum(np.abs(ref), scale)


def test_rig_geometry(rig):
    """Sanity check of the harness: path length and speed are the slider q and qdot."""
    l_mt = PARAMS.tendon_slack_length + PARAMS.optimal_fiber_length
    rig.set(l_mt, v_mt=np.full(PARAMS.n_muscles, 0.1))
    rig.model.realizeVelocity(rig.state)
    np.testing.assert_allclose(rig.get("getLength"), l_mt, rtol=1e-14)
    np.testing.assert_allclose(rig.get("getLengtheningSpeed"), 0.1, rtol=1e-14)
    np.testing.assert_allclose(th.minimum_fiber_length(PARAMS, rig.c),
                               [m.getMinimumFiberLength() for m in rig.muscles],
                               rtol=1e-14, atol=1e-15)


def test_rigid_tendon_force(rig):
    """Rigid tendon: active part from OpenSim's calcInextensibleTendonActiveFiberForce,
    passive part from OpenSim's passive multiplier at the rigid-tendon fiber length."""
    p, c = PARAMS, rig.c
    h = th.parallelogram_height(p)
    s = rig.state
    pen = [m.getPennationModel() for m in rig.muscles]
    worst = 0.0
    for ln in NORM_FIBER_LENGTHS:
        l_f = ln * p.optimal_fiber_length
        l_mt = p.tendon_slack_length + np.sqrt(l_f ** 2 - h ** 2)
        cos_phi = np.sqrt(l_f ** 2 - h ** 2) / l_f
        # OpenSim's own rigid-tendon fiber length, set as the state for the passive part
        l_f_os = np.array([pen[i].calcFiberLength(float(l_mt[i]), float(p.tendon_slack_length[i]))
                           for i in range(p.n_muscles)])
        np.testing.assert_allclose(l_f_os, l_f, rtol=1e-12)
        for vn in np.linspace(-1.0, 1.0, 9):
            v_mt = vn * c.max_contraction_velocity * p.optimal_fiber_length / cos_phi
            rig.set(l_mt, v_mt, fiber_length=l_f_os)
            rig.model.realizePosition(s)
            passive = (rig.get("getPassiveForceMultiplier") * p.max_isometric_force
                       * np.cos(rig.get("getPennationAngle")))
            rig.model.realizeVelocity(s)
            for a in ACTIVATIONS:
                ref = np.array([m.calcInextensibleTendonActiveFiberForce(s, a)
                                for m in rig.muscles]) + passive
                ours = th.rigid_tendon(a, l_mt, v_mt, p, c)
                np.testing.assert_allclose(ours.normalized_fiber_velocity, vn, rtol=1e-12,
                                           atol=1e-15)
                err = _rel_err(ours.tendon_force, ref, 1e-9 * p.max_isometric_force)
                worst = max(worst, err.max())
                assert err.max() < 1e-6, (ln, vn, a, ours.tendon_force, ref)
                a_eff = max(a, c.minimum_activation)  # OpenSim clamps; the split does not
                split = th.rigid_tendon_force_split(l_mt, v_mt, p, c, fv_activation=a_eff)
                err = _rel_err(a_eff * split.active + split.passive, ref,
                               1e-9 * p.max_isometric_force)
                assert err.max() < 1e-6, (ln, vn, a, split, ref)
    print(f"rigid tendon force: max rel. error {worst:.2e}")


def _compliant_grid(p, c):
    """(l_f, l_mt) pairs: fiber length 0.5..1.6 l_opt times tendon strain 0..1.6 e0."""
    h = th.parallelogram_height(p)
    for ln in NORM_FIBER_LENGTHS:
        l_f = ln * p.optimal_fiber_length
        l_f_at = np.sqrt(l_f ** 2 - h ** 2)
        for k in (0.0, 0.2, 0.6, 1.0, 1.6):
            yield l_f, l_f_at + p.tendon_slack_length * (1.0 + k * c.tendon_strain_at_fmax)


def test_compliant_fiber_velocity_and_tendon_force(rig):
    """Compliant tendon: d(fiber_length)/dt (OpenSim's state derivative), tendon force,
    fiber force-velocity multiplier at given (activation, fiber length, path length)."""
    p, c = PARAMS, rig.c
    s = rig.state
    vscale = c.max_contraction_velocity * p.optimal_fiber_length
    worst_v = worst_f = 0.0
    for l_f, l_mt in _compliant_grid(p, c):
        for a in ACTIVATIONS:
            act = np.full(p.n_muscles, a)
            rig.set(l_mt, np.zeros(p.n_muscles), activation=act, fiber_length=l_f)
            rig.model.realizeAcceleration(s)
            ref_v = np.array([m.getStateVariableDerivativeValue(s, "fiber_length")
                              for m in rig.muscles])
            ref_f = rig.get("getTendonForce")
            ours = th.compliant_tendon(a, l_f, l_mt, p, c)
            np.testing.assert_allclose(ref_v, rig.get("getFiberVelocity"), rtol=0, atol=0)
            err_v = np.abs(ours.fiber_velocity - ref_v) / np.maximum(np.abs(ref_v), vscale)
            err_f = _rel_err(ours.tendon_force, ref_f, 1e-9 * p.max_isometric_force)
            worst_v, worst_f = max(worst_v, err_v.max()), max(worst_f, err_f.max())
            assert err_v.max() < 1e-12, (a, l_f, l_mt, ours.fiber_velocity, ref_v)
            assert err_f.max() < 1e-12, (a, l_f, l_mt, ours.tendon_force, ref_f)
            np.testing.assert_allclose(ours.force_velocity,
                                       rig.get("getForceVelocityMultiplier"),
                                       rtol=1e-10, atol=1e-12)
            np.testing.assert_allclose(ours.pennation_angle, rig.get("getPennationAngle"),
                                       rtol=1e-14, atol=1e-15)
    print(f"compliant: max rel. error fiber velocity {worst_v:.2e}, tendon force {worst_f:.2e}")


@pytest.mark.parametrize("v_norm", [0.0, -0.3, 0.3])
def test_equilibrium_matches_opensim(rig, v_norm):
    """Static equilibrium fiber length and tendon force (computeInitialFiberEquilibrium);
    ``v_norm`` is the path speed in v_max l_opt (OpenSim's stiffness-sharing heuristic)."""
    p, c = PARAMS, rig.c
    s = rig.state
    v_mt = v_norm * c.max_contraction_velocity * p.optimal_fiber_length
    worst_l = worst_f = 0.0
    for _, l_mt in _compliant_grid(p, c):
        for a in ACTIVATIONS[::2] + [1.0]:
            rig.set(l_mt, v_mt, activation=np.full(p.n_muscles, a),
                    fiber_length=p.optimal_fiber_length)
            for m in rig.muscles:
                m.computeInitialFiberEquilibrium(s)
            rig.model.realizeDynamics(s)
            ref_l, ref_f = rig.get("getFiberLength"), rig.get("getTendonForce")
            ours = th.equilibrium_fiber_length(a, l_mt, p, c, v_mt=v_mt)
            err_l = _rel_err(ours.fiber_length, ref_l, 0.0)
            # OpenSim stops at |force error| < 1e-8 F_max, i.e. 1e-5 relative at 1e-3 F_max:
            # smaller forces are compared relative to that floor.
            err_f = _rel_err(ours.tendon_force, ref_f, 1e-3 * p.max_isometric_force)
            worst_l, worst_f = max(worst_l, err_l.max()), max(worst_f, err_f.max())
            assert err_l.max() < 1e-5, (a, l_mt, ours.fiber_length, ref_l)
            assert err_f.max() < 1e-5, (a, l_mt, ours.tendon_force, ref_f)
    print(f"equilibrium (v={v_norm}): max rel. error fiber length {worst_l:.2e}, "
          f"tendon force {worst_f:.2e}")


def test_activation_derivative(rig):
    """da/dt from the model's state derivative (excitation as the muscle's control)."""
    c = rig.c
    s = rig.state
    n = PARAMS.n_muscles
    grid = [-0.2, 0.0, 0.005, 0.01, 0.02, 0.1, 0.3, 0.5, 0.7, 0.99, 1.0, 1.3]
    l_mt = PARAMS.tendon_slack_length * 1.01 + PARAMS.optimal_fiber_length
    worst = 0.0
    for a in grid:
        for u in grid:
            rig.set(l_mt, np.zeros(n), activation=np.full(n, a),
                    fiber_length=PARAMS.optimal_fiber_length)
            rig.model.realizeVelocity(s)
            controls = rig.model.updControls(s)
            for m in rig.muscles:
                m.setControls(osim.Vector(1, u), controls)
            rig.model.setControls(s, controls)
            rig.model.realizeAcceleration(s)
            ref = np.array([m.getStateVariableDerivativeValue(s, "activation")
                            for m in rig.muscles])
            direct = rig.muscles[0].getActivationModel().calcDerivative(a, u)
            ours = th.activation_derivative(u, a, c)
            np.testing.assert_allclose(ours, ref, rtol=1e-14, atol=1e-12)
            np.testing.assert_allclose(ours, direct, rtol=1e-14, atol=1e-12)
            worst = max(worst, float(np.max(np.abs(ours - ref))))
    print(f"activation derivative: max abs. error {worst:.2e} 1/s")


def test_minimum_fiber_length_edge_cases(rig):
    """Short paths and fibers at/below the minimum length (clamping, zero active force)."""
    p, c = PARAMS, rig.c
    s = rig.state
    n = p.n_muscles
    l_min = th.minimum_fiber_length(p, c)
    l_min_at = l_min * math.cos(c.maximum_pennation_angle)
    pennated = p.pennation_angle_at_optimal > 0
    # compliant tendon: fiber state below the minimum, tendon slack or stretched
    for strain in (0.0, 0.02):
        l_f = np.where(pennated, 0.5 * l_min, 0.3 * p.optimal_fiber_length)
        l_mt = l_min_at + p.tendon_slack_length * (1 + strain)
        for a in (0.05, 1.0):
            rig.set(l_mt, np.zeros(n), activation=np.full(n, a), fiber_length=l_f)
            rig.model.realizeAcceleration(s)
            ours = th.compliant_tendon(a, l_f, l_mt, p, c)
            np.testing.assert_allclose(ours.fiber_velocity, rig.get("getFiberVelocity"),
                                       rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(ours.tendon_force, rig.get("getTendonForce"),
                                       rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(ours.fiber_length, rig.get("getFiberLength"),
                                       rtol=1e-14)
        assert ours.fiber_clamped[pennated].all() == (strain == 0.0)
    # rigid tendon: no active force once the fiber reaches its minimum length
    for fac in (0.5, 0.999, 1.001):
        l_mt = p.tendon_slack_length + fac * l_min_at
        rig.set(l_mt, np.full(n, -0.05))
        rig.model.realizeVelocity(s)
        ref = np.array([m.calcInextensibleTendonActiveFiberForce(s, 0.5) for m in rig.muscles])
        ours = th.rigid_tendon(0.5, l_mt, -0.05, p, c)
        np.testing.assert_allclose(ours.active_fiber_force * np.cos(ours.pennation_angle), ref,
                                   rtol=1e-9, atol=1e-12)
        assert (ref[pennated] > 0).all() == (fac > 1)
    # equilibrium with a path so short that the fiber ends at its minimum length
    l_mt = p.tendon_slack_length + 0.3 * l_min_at + 1e-4
    rig.set(l_mt, np.zeros(n), activation=np.full(n, 0.5), fiber_length=p.optimal_fiber_length)
    for m in rig.muscles:
        m.computeInitialFiberEquilibrium(s)
    rig.model.realizeDynamics(s)
    ours = th.equilibrium_fiber_length(0.5, l_mt, p, c)
    np.testing.assert_allclose(ours.fiber_length, rig.get("getFiberLength"), rtol=1e-12)
    np.testing.assert_allclose(ours.tendon_force, rig.get("getTendonForce"), rtol=1e-9,
                               atol=1e-9)
    assert ours.fiber_clamped[pennated].all()
