"""Unit tests of trunk_drake.muscle.thelen that need no OpenSim."""

import dataclasses
import math

import numpy as np
import pytest

from trunk_drake.muscle import thelen as th

THESIS = th.ThelenConstants()
OPENSIM = th.ThelenConstants.opensim_defaults()
BOTH = pytest.mark.parametrize("c", [THESIS, OPENSIM], ids=["thesis", "opensim_defaults"])


def mixed_params(n=210, seed=0):
    """n muscles with mixed parameters; a third of them unpennated."""
    rng = np.random.default_rng(seed)
    pennation = rng.uniform(0.0, 0.4, n)
    pennation[::3] = 0.0
    return th.MuscleParameters(max_isometric_force=rng.uniform(20.0, 3000.0, n),
                               optimal_fiber_length=rng.uniform(0.02, 0.2, n),
                               tendon_slack_length=rng.uniform(0.005, 0.3, n),
                               pennation_angle_at_optimal=pennation)


def one_muscle(i, p):
    return th.MuscleParameters(p.max_isometric_force[i:i + 1], p.optimal_fiber_length[i:i + 1],
                               p.tendon_slack_length[i:i + 1],
                               p.pennation_angle_at_optimal[i:i + 1])


def assert_close(actual, desired, rtol, atol):
    """Elementwise |actual - desired| <= atol + rtol |desired| (atol may be an array)."""
    actual, desired = np.broadcast_arrays(np.asarray(actual, float), np.asarray(desired, float))
    bad = ~(np.abs(actual - desired) <= atol + rtol * np.abs(desired))
    assert not bad.any(), (f"{np.count_nonzero(bad)} mismatches, e.g. "
                           f"{actual[bad][:3]} vs {desired[bad][:3]}")


def fd(f, x, h=1e-7):
    return (f(x + h) - f(x - h)) / (2 * h)


# ------------------------------------------------------------------------- constants

def test_constants_defaults_are_thesis_and_opensim():
    t = THESIS
    assert (t.tendon_strain_at_fmax, t.passive_strain_at_fmax, t.k_passive, t.gamma, t.af,
            t.flen) == (0.033, 0.6, 4.0, 0.5, 0.3, 1.8)
    o = OPENSIM
    assert (o.tendon_strain_at_fmax, o.passive_strain_at_fmax, o.k_passive, o.gamma, o.af,
            o.flen) == (0.04, 0.6, 5.0, 0.45, 0.25, 1.4)
    assert (o.fv_extrapolation_threshold, o.max_contraction_velocity,
            o.activation_time_constant, o.deactivation_time_constant,
            o.minimum_activation) == (0.95, 10.0, 0.015, 0.05, 0.01)
    assert o.maximum_pennation_angle == pytest.approx(math.radians(84.26), abs=1e-4)
    # thesis: k_lin = 1.71/e0, e_toe = 0.61 e0 (both rounded in the thesis/paper)
    assert t.tendon_linear_stiffness * t.tendon_strain_at_fmax == pytest.approx(1.71, abs=0.005)
    assert t.tendon_toe_strain / t.tendon_strain_at_fmax == pytest.approx(0.609, abs=0.001)


@pytest.mark.parametrize("field, value", [
    ("flen", 1.0), ("gamma", 0.0), ("af", -0.3), ("tendon_strain_at_fmax", float("nan")),
    ("fv_extrapolation_threshold", 0.5), ("minimum_activation", 0.0),
    ("maximum_pennation_angle", 2.0), ("activation_time_constant", 0.0),
])
def test_bad_constants_raise_naming_field(field, value):
    with pytest.raises(ValueError, match=field):
        th.ThelenConstants(**{field: value})


@pytest.mark.parametrize("field, value, match", [
    ("optimal_fiber_length", [0.1, -0.1, 0.1], "optimal_fiber_length.*> 0"),
    ("tendon_slack_length", [0.1, 0.0, 0.1], "tendon_slack_length.*> 0"),
    ("max_isometric_force", [100.0, np.nan, 1.0], "max_isometric_force.*NaN"),
    ("pennation_angle_at_optimal", [0.0, 0.1, 1.6], "pennation_angle_at_optimal"),
    ("tendon_slack_length", [0.1, 0.1], "tendon_slack_length has 2 entries"),
    ("optimal_fiber_length", [[0.1, 0.1, 0.1]], "optimal_fiber_length must be 1-D"),
    ("max_isometric_force", ["a", 1.0, 2.0], "max_isometric_force must be numeric"),
])
def test_bad_parameters_raise_naming_field(field, value, match):
    kwargs = dict(max_isometric_force=[100.0, 200.0, 300.0],
                  optimal_fiber_length=[0.1, 0.1, 0.1],
                  tendon_slack_length=[0.1, 0.2, 0.3],
                  pennation_angle_at_optimal=[0.0, 0.1, 0.2])
    kwargs[field] = value
    with pytest.raises(ValueError, match=match):
        th.MuscleParameters(**kwargs)


def test_parameters_are_read_only_arrays():
    p = mixed_params(5)
    assert p.n_muscles == 5 and p.optimal_fiber_length.dtype == float
    with pytest.raises(ValueError):
        p.optimal_fiber_length[0] = 1.0


# ---------------------------------------------------------------------------- curves

@BOTH
def test_active_force_length_peaks_at_one(c):
    l = np.linspace(0.3, 1.8, 1501)
    f = th.active_force_length(l, c)
    assert th.active_force_length(1.0, c) == 1.0
    assert l[np.argmax(f)] == pytest.approx(1.0) and f.max() == pytest.approx(1.0)
    assert np.all(f <= 1.0)
    # Gaussian width: f(1 +- sqrt(gamma)) = exp(-1)
    assert th.active_force_length(1 + math.sqrt(c.gamma), c) == pytest.approx(math.exp(-1))
    np.testing.assert_allclose(th.active_force_length_derivative(l, c),
                               fd(lambda x: th.active_force_length(x, c), l), atol=1e-7)


@BOTH
def test_passive_force_length(c):
    assert np.all(th.passive_force_length([0.2, 0.9, 1.0], c) == 0.0)
    assert th.passive_force_length(1.0 + c.passive_strain_at_fmax, c) == pytest.approx(1.0)
    l = np.linspace(1.001, 1.8, 200)
    assert np.all(np.diff(th.passive_force_length(l, c)) > 0)
    np.testing.assert_allclose(th.passive_force_length_derivative(l, c),
                               fd(lambda x: th.passive_force_length(x, c), l), rtol=1e-6)


@BOTH
def test_tendon_curve_continuous_at_toe_and_unit_force_at_e0(c):
    e_toe, e0 = c.tendon_toe_strain, c.tendon_strain_at_fmax
    assert th.tendon_force_length(e0, c) == pytest.approx(1.0, rel=1e-12)
    assert th.tendon_force_length(e_toe, c) == pytest.approx(0.33, rel=1e-12)
    d = 1e-9
    below, above = th.tendon_force_length([e_toe - d, e_toe + d], c)
    assert abs(above - below) < 1e-6
    s_below, s_above = th.tendon_force_length_derivative([e_toe - d, e_toe + d], c)
    assert s_below == pytest.approx(s_above, rel=1e-6)          # slope-continuous junction
    assert s_above == c.tendon_linear_stiffness
    assert np.all(th.tendon_force_length([-0.01, 0.0], c) == 0.0)
    x = np.linspace(1e-4, 2 * e0, 300)
    np.testing.assert_allclose(th.tendon_force_length_derivative(x, c),
                               fd(lambda s: th.tendon_force_length(s, c), x, 1e-9),
                               rtol=1e-5, atol=1e-6)


@BOTH
@pytest.mark.parametrize("a", [0.01, 0.3, 1.0])
def test_force_velocity_shape(c, a):
    assert th.force_velocity(0.0, a, c) == 1.0
    cc = 0.25 + 0.75 * a
    assert np.all(th.force_velocity([-cc, -1.0, -5.0], a, c) == 0.0)   # fv >= 0, clamped
    v = np.linspace(-cc, 3.0, 2000)
    fv = th.force_velocity(v, a, c)
    assert np.all(np.diff(fv) > 0)
    # Thelen 2003 eqs. 6-7 (normalised, F = a f_AL f_V), written out independently
    vc = np.linspace(-0.9 * cc, 0, 20)
    fv_c = th.force_velocity(vc, a, c)
    np.testing.assert_allclose(cc * (fv_c - 1) / (1 + fv_c / c.af), vc, rtol=1e-12, atol=1e-15)
    k = (2 + 2 / c.af) / (c.flen - 1)
    x0 = c.fv_extrapolation_threshold * c.flen
    ve = np.linspace(1e-4, 0.99, 20) * cc * (x0 - 1) / (k * (c.flen - x0))  # up to v0
    fv_e = th.force_velocity(ve, a, c)
    b = (2 + 2 / c.af) * (c.flen - fv_e) / (c.flen - 1)
    np.testing.assert_allclose(cc * (fv_e - 1) / b, ve, rtol=1e-12)
    # eccentric: rises towards flen; linear beyond threshold*flen with continuous value
    v_ecc = v[(fv > 1) & (fv < x0)]
    assert np.all(th.force_velocity(v_ecc, a, c) < c.flen)
    v0 = v[np.argmin(np.abs(fv - x0))]
    left, right = th.force_velocity([v0 - 1e-9, v0 + 1e-9], a, c)
    assert abs(right - left) < 1e-6


def test_force_velocity_approaches_flen_without_extrapolation():
    c = dataclasses.replace(THESIS, fv_extrapolation_threshold=1 - 1e-9)
    fv = th.force_velocity([1.0, 10.0, 1e3], 1.0, c)
    assert np.all(fv < c.flen) and np.all(np.diff(fv) > 0)
    assert fv[-1] == pytest.approx(c.flen, rel=1e-4)


@BOTH
@pytest.mark.parametrize("a", [0.02, 0.5, 1.0])
def test_force_velocity_inverse_roundtrip_and_derivatives(c, a):
    cc = 0.25 + 0.75 * a
    v = np.concatenate([np.linspace(-0.999 * cc, -1e-3, 40), np.linspace(1e-3, 4.0, 60)])
    fal = 0.7
    fv = th.force_velocity(v, a, c)
    np.testing.assert_allclose(th.fiber_velocity_from_force(a, fal, a * fal * fv, c), v,
                               rtol=1e-12, atol=1e-14)
    dv, da = th.force_velocity_derivatives(v, a, c)
    np.testing.assert_allclose(dv, fd(lambda x: th.force_velocity(x, a, c), v, 1e-8),
                               rtol=1e-6)
    np.testing.assert_allclose(da, fd(lambda x: th.force_velocity(v, x, c), a, 1e-8),
                               rtol=1e-5, atol=1e-8)


@BOTH
def test_pennation_constant_thickness_and_clamp(c):
    p = mixed_params(30)
    h = th.parallelogram_height(p)
    l_min = th.minimum_fiber_length(p, c)
    np.testing.assert_allclose(th.pennation_angle(p.optimal_fiber_length, p, c),
                               p.pennation_angle_at_optimal, rtol=1e-12, atol=1e-15)
    l = 1.3 * p.optimal_fiber_length
    np.testing.assert_allclose(l * np.sin(th.pennation_angle(l, p, c)), h, rtol=1e-12)
    pennated = p.pennation_angle_at_optimal > 0
    np.testing.assert_allclose(th.pennation_angle(0.5 * l_min, p, c)[pennated],
                               c.maximum_pennation_angle)
    assert np.all(l_min[~pennated] == 0.0) and np.all(l_min[pennated] > h[pennated])


# -------------------------------------------------------------------- muscle models

@BOTH
def test_rigid_tendon_isometric_force_by_hand(c):
    p = th.MuscleParameters([800.0], [0.1], [0.2], [0.3])
    h = 0.1 * math.sin(0.3)
    l_f = 0.11
    l_mt = 0.2 + math.sqrt(l_f ** 2 - h ** 2)
    s = th.rigid_tendon(0.6, l_mt, 0.0, p, c)
    cos_phi = math.sqrt(1 - (h / l_f) ** 2)
    fal = math.exp(-(0.1 ** 2) / c.gamma)
    fpe = (math.exp(c.k_passive * 0.1 / c.passive_strain_at_fmax) - 1) / (math.exp(c.k_passive) - 1)
    assert s.fiber_length[0] == pytest.approx(l_f, rel=1e-12)
    assert s.tendon_force[0] == pytest.approx((0.6 * fal + fpe) * 800 * cos_phi, rel=1e-12)
    # shortening lowers force, lengthening raises it
    assert th.rigid_tendon(0.6, l_mt, -0.1, p, c).tendon_force < s.tendon_force
    assert th.rigid_tendon(0.6, l_mt, 0.1, p, c).tendon_force > s.tendon_force


@BOTH
def test_rigid_split_is_linear_in_activation_when_isometric(c):
    p = mixed_params()
    l_mt = p.tendon_slack_length + 1.1 * p.optimal_fiber_length
    split = th.rigid_tendon_force_split(l_mt, 0.0, p, c)
    for a in [c.minimum_activation, 0.3, 1.0]:
        np.testing.assert_allclose(th.rigid_tendon(a, l_mt, 0.0, p, c).tendon_force,
                                   a * split.active + split.passive, rtol=1e-13)
    assert np.all(split.passive > 0) and np.all(split.active > 0)


@BOTH
@pytest.mark.parametrize("v_norm", [-0.4, -0.05, 0.0, 0.05, 0.5])
def test_rigid_tendon_derivatives_match_finite_differences(c, v_norm):
    p = mixed_params(60, seed=1)
    l_mt = p.tendon_slack_length + 1.05 * p.optimal_fiber_length
    v_mt = v_norm * c.max_contraction_velocity * p.optimal_fiber_length
    a = 0.4
    d = th.rigid_tendon_derivatives(a, l_mt, v_mt, p, c)

    def force(a=a, l=l_mt, v=v_mt):
        return th.rigid_tendon(a, l, v, p, c).tendon_force

    scale = p.max_isometric_force
    assert_close(d.d_activation, (force(a=a + 1e-6) - force(a=a - 1e-6)) / 2e-6,
                 rtol=1e-5, atol=1e-6 * scale)
    assert_close(d.d_length, (force(l=l_mt + 1e-8) - force(l=l_mt - 1e-8)) / 2e-8,
                 rtol=1e-5, atol=1e-4 * scale)
    # f_V has a kink at v = 0 (Thelen's concentric/eccentric slopes differ by 2x); the
    # derivative returned there is the concentric one, so compare one-sided.
    dv = 1e-8
    assert_close(d.d_velocity, (force(v=v_mt + dv * (v_norm != 0)) - force(v=v_mt - dv))
                 / (dv * (1 + (v_norm != 0))), rtol=1e-5, atol=1e-6 * scale)


@BOTH
def test_vectorised_over_210_mixed_muscles(c):
    p = mixed_params()
    rng = np.random.default_rng(3)
    a = rng.uniform(0.0, 1.0, p.n_muscles)
    l_mt = p.tendon_slack_length * (1 + 0.5 * c.tendon_strain_at_fmax) + \
        rng.uniform(0.6, 1.5, p.n_muscles) * p.optimal_fiber_length
    v_mt = rng.uniform(-0.5, 0.5, p.n_muscles) * p.optimal_fiber_length
    l_f = rng.uniform(0.6, 1.4, p.n_muscles) * p.optimal_fiber_length
    rigid = th.rigid_tendon(a, l_mt, v_mt, p, c)
    comp = th.compliant_tendon(a, l_f, l_mt, p, c)
    eq = th.equilibrium_fiber_length(a, l_mt, p, c)
    for name in ("tendon_force", "fiber_length", "fiber_velocity"):
        assert getattr(rigid, name).shape == (210,)
    for i in range(0, 210, 7):
        pi = one_muscle(i, p)
        assert th.rigid_tendon(a[i], l_mt[i], v_mt[i], pi, c).tendon_force[0] == \
            rigid.tendon_force[i]
        ci = th.compliant_tendon(a[i], l_f[i], l_mt[i], pi, c)
        assert ci.fiber_velocity[0] == comp.fiber_velocity[i]
        assert ci.tendon_force[0] == comp.tendon_force[i]
        ei = th.equilibrium_fiber_length(a[i], l_mt[i], pi, c)
        assert ei.fiber_length[0] == pytest.approx(eq.fiber_length[i], rel=1e-12)


@BOTH
@pytest.mark.parametrize("a", [0.01, 0.2, 1.0])
def test_equilibrium_balances_forces(c, a):
    p = mixed_params()
    rng = np.random.default_rng(4)
    l_mt = p.tendon_slack_length * (1 + rng.uniform(0, 1.5, 210) * c.tendon_strain_at_fmax) + \
        rng.uniform(0.5, 1.6, 210) * p.optimal_fiber_length
    s = th.equilibrium_fiber_length(a, l_mt, p, c)
    assert not s.fiber_clamped.any()
    along = (s.active_fiber_force + s.passive_fiber_force) * np.cos(s.pennation_angle)
    assert_close(along, s.tendon_force, rtol=1e-11, atol=1e-11 * p.max_isometric_force)
    np.testing.assert_allclose(s.force_velocity, 1.0, rtol=1e-10)
    # at equilibrium the compliant state derivative vanishes
    assert np.max(np.abs(s.normalized_fiber_velocity)) < 1e-9
    np.testing.assert_allclose(s.tendon_length + s.fiber_length * np.cos(s.pennation_angle),
                               l_mt, rtol=1e-14)


def test_equilibrium_with_path_velocity_sets_force_velocity():
    p = mixed_params(20)
    l_mt = p.tendon_slack_length * 1.02 + p.optimal_fiber_length
    v = 0.2 * THESIS.max_contraction_velocity * p.optimal_fiber_length
    shortening = th.equilibrium_fiber_length(0.5, l_mt, p, v_mt=-v)
    lengthening = th.equilibrium_fiber_length(0.5, l_mt, p, v_mt=v)
    assert np.all(shortening.force_velocity < 1) and np.all(lengthening.force_velocity > 1)
    assert np.all(shortening.fiber_velocity < 0) and np.all(lengthening.fiber_velocity > 0)
    # the fiber takes at most the path velocity (along the tendon)
    assert np.all(np.abs(lengthening.fiber_velocity) <= v + 1e-12)


def test_compliant_fiber_at_minimum_length_is_held():
    p = th.MuscleParameters([500.0], [0.05], [0.1], [0.4])
    l_min = th.minimum_fiber_length(p)
    s = th.compliant_tendon(0.5, 0.5 * l_min, 0.1 + 0.5 * l_min[0] * 0.1, p)
    assert s.fiber_clamped[0] and s.fiber_velocity[0] == 0.0 and s.fiber_length[0] == l_min[0]


@BOTH
def test_activation_derivative(c):
    ta, td = c.activation_time_constant, c.deactivation_time_constant
    assert th.activation_derivative(1.0, 0.5, c) == pytest.approx(0.5 / (ta * 1.25))
    assert th.activation_derivative(0.0, 0.5, c) == pytest.approx(-0.5 * 1.25 / td)
    a = np.linspace(c.minimum_activation, 1, 7)
    np.testing.assert_array_equal(th.activation_derivative(a, a, c), 0.0)
    # activation below the minimum is clamped: it acts as if at the minimum
    assert th.activation_derivative(0.5, 0.0, c) == th.activation_derivative(
        0.5, c.minimum_activation, c)
