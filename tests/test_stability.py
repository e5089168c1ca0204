"""Stability analysis: analytic cases (inverted pendulum with a spring, two-link chain, delayed PD
loop), second derivatives of muscle lengths, the fast Jacobian, and the dynamic roots against
nonlinear simulations of the full MyoTorso diagram."""

import warnings

import numpy as np
import pytest

import trunk_drake as td
from trunk_drake.diagram import TrunkOptions
from trunk_drake.gap.linear import state_jacobian
from trunk_drake.model.spec import BodySpec, JointSpec, ModelSpec, MuscleSpec, PathElement, SiteSpec
from trunk_drake.muscle import thelen
from trunk_drake.muscle.short_range import ShortRangeStiffness
from trunk_drake.optim.stability import ClosedLoop, length_hessian, stability
from trunk_drake.optim.stability_math import characteristic_roots, critical_value, static_stability
from trunk_drake.presets import load_preset

G = 9.81
UNIT = np.array([1.0, 0, 0, 0])
BASE_SITE, ARM_SITE = np.array([0.0, 0.1, 0.0]), np.array([0.0, 0.03, 0.2])
F_MAX, L_OPT = 200.0, 0.1


def chain_spec(masses, coms, lengths) -> ModelSpec:
    """An upright chain of links on hinges about x (link k's hinge at the top of link k-1), COMs
    above their hinges, and one muscle from the base to the first link (for the path code)."""
    bodies = [BodySpec("base", None, np.zeros(3), UNIT, 0.0, np.zeros(3), np.zeros((3, 3)))]
    joints = []
    parent, offset = "base", np.zeros(3)
    for k, (m, c) in enumerate(zip(masses, coms)):
        name = f"link{k}"
        bodies.append(BodySpec(name, parent, offset, UNIT, m, np.array([0.0, 0.0, c]), np.diag([0.01, 0.01, 0.002])))
        joints.append(JointSpec(f"hinge{k}", name, "hinge", np.array([1.0, 0, 0]), np.zeros(3), (-1.0, 1.0)))
        parent, offset = name, np.array([0.0, 0.0, lengths[k]])
    l_mt0 = np.linalg.norm(ARM_SITE - BASE_SITE)
    return ModelSpec(
        name="chain", bodies=tuple(bodies), joints=tuple(joints),
        sites=(SiteSpec("origin", "base", BASE_SITE), SiteSpec("insertion", "link0", ARM_SITE)), wraps=(),
        muscles=(MuscleSpec("flexor", (PathElement("site", 0), PathElement("site", 1)), F_MAX, L_OPT, l_mt0 - L_OPT, 0.0, "flexors"),),
        root_pos=np.array([0.0, 0.0, 1.0]),
    )


def pendulum_length(theta):
    """Analytic musculotendon length of the chain's muscle (hinge about x at the origin)."""
    cs, sn = np.cos(theta), np.sin(theta)
    p = np.array([0.0, cs * ARM_SITE[1] - sn * ARM_SITE[2], sn * ARM_SITE[1] + cs * ARM_SITE[2]])
    return np.linalg.norm(p - BASE_SITE)


# ------------------------------------------------------------------------------ analytic cases

@pytest.mark.parametrize("factor", [0.9, 1.1])
def test_inverted_pendulum_with_spring_is_stable_exactly_when_k_exceeds_mgl(factor):
    mass, com = 2.0, 0.4
    model = td.load_model(dofs="all", spec=chain_spec([mass], [com], [0.5]))
    k, c = factor * mass * G * com, 0.3
    result = stability(model, TrunkOptions(stiffness=k, damping=c, muscle_mask=np.zeros(1)), critical=False)
    assert result.static.hessian[0, 0] == pytest.approx(k - mass * G * com, rel=1e-6)
    assert result.static.stable == (factor > 1) and result.dynamic.stable == (factor > 1)
    inertia = 0.01 + mass * com**2  # about the hinge
    expected = np.roots([inertia, c, k - mass * G * com]).real.max()
    assert result.dynamic.margin == pytest.approx(expected, rel=1e-6)


def test_muscle_terms_of_the_hessian_match_the_analytic_pendulum_geometry():
    mass, com = 2.0, 0.4
    model = td.load_model(dofs="all", spec=chain_spec([mass], [com], [0.5]))
    loop = ClosedLoop(model, TrunkOptions(stiffness=50.0, feedforward=np.array([0.5])))
    x = loop.rest_state(np.array([0.05]))
    static = loop.static(x)
    h = 1e-4
    dl = (pendulum_length(0.05 + h) - pendulum_length(0.05 - h)) / (2 * h)
    d2l = (pendulum_length(0.05 + h) - 2 * pendulum_length(0.05) + pendulum_length(0.05 - h)) / h**2
    params = thelen.MuscleParameters([F_MAX], [L_OPT], [np.linalg.norm(ARM_SITE - BASE_SITE) - L_OPT], [0.0])
    l_mt = pendulum_length(0.05)
    force = thelen.rigid_tendon(0.5, [l_mt], [0.0], params).tendon_force[0]
    slope = thelen.rigid_tendon_derivatives(0.5, [l_mt], [0.0], params).d_length[0]
    assert abs(force * d2l) > 1.0 and abs(slope * dl * dl) > 1.0, "both muscle terms must matter in this case"
    assert static.terms["muscle_geometry"][0, 0] == pytest.approx(force * d2l, rel=1e-5)
    assert static.terms["muscle_stiffness"][0, 0] == pytest.approx(slope * dl * dl, rel=1e-6)


def test_two_link_chain_gravity_hessian_matches_closed_form():
    m1, c1, l1, m2, c2 = 3.0, 0.2, 0.45, 1.5, 0.3
    model = td.load_model(dofs="all", spec=chain_spec([m1, m2], [c1, c2], [l1, 0.4]))
    k = np.array([40.0, 25.0])
    loop = ClosedLoop(model, TrunkOptions(stiffness=k, muscle_mask=np.zeros(1)))
    for q in (np.zeros(2), np.array([0.2, -0.3])):
        s1, s12 = np.cos(q[0]), np.cos(q.sum())
        # V = m1 g c1 cos q1 + m2 g (l1 cos q1 + c2 cos(q1 + q2)) (+ springs): its Hessian
        gravity = -G * np.array([[m1 * c1 * s1 + m2 * (l1 * s1 + c2 * s12), m2 * c2 * s12],
                                 [m2 * c2 * s12, m2 * c2 * s12]])
        static = loop.static(loop.rest_state(q))
        np.testing.assert_allclose(static.hessian, gravity + np.diag(k), rtol=1e-7, atol=1e-7)


def test_delayed_pd_loop_critical_delay_matches_closed_form():
    """m x'' = -kp x(t - tau) - kd x'(t - tau): roots cross at s = i w, m w^2 = |kp + i kd w|,
    tau_c = atan2(kd w, kp) / w."""
    m, kp, kd = 1.3, 4.0, 1.5
    a0 = np.array([[0.0, 1.0], [0.0, 0.0]])
    a1 = np.array([[0.0, 0.0], [-kp / m, -kd / m]])
    w = np.sqrt((kd**2 + np.sqrt(kd**4 + 4 * m**2 * kp**2)) / (2 * m**2))
    tau_c = np.arctan2(kd * w, kp) / w
    roots, _ = characteristic_roots(a0, a1, tau_c)
    assert roots[0].real == pytest.approx(0.0, abs=1e-9) and abs(roots[0].imag) == pytest.approx(w, rel=1e-9)
    assert characteristic_roots(a0, a1, 0.98 * tau_c)[0][0].real < 0 < characteristic_roots(a0, a1, 1.02 * tau_c)[0][0].real
    assert np.allclose(characteristic_roots(a0, a1, 0.0)[0], np.linalg.eigvals(a0 + a1)[np.argsort(-np.linalg.eigvals(a0 + a1).real)])
    found = critical_value("delay", lambda tau: -characteristic_roots(a0, a1, tau)[0][0].real, 0.01, 2.0, "s", rtol=1e-4)
    assert found.value == pytest.approx(tau_c, rel=1e-3)  # the unstable side is the upper interval of -margin


def test_static_stability_of_plain_arrays():
    """One joint, two antagonists on constant moment arms: H = k - mgl + sum k_i r_i^2 (no geometry term)."""
    result = static_stability(["q"], [[-10.0]], [4.0], [100.0, 100.0], np.zeros((2, 1, 1)), [[0.05], [-0.05]], [2000.0, 2000.0])
    assert result.stability_index == pytest.approx(4.0 - 10.0 + 2 * 2000.0 * 0.05**2)
    assert result.stable


def test_critical_value_reports_none_when_the_range_holds_no_stable_value():
    found = critical_value("x", lambda x: 1.0 - x, 0.1, 0.5)
    assert found.value is None and "none within" in found.summary()["text"]


# ------------------------------------------------------------------------------ MyoTorso

@pytest.fixture(scope="module")
def myotorso():
    return td.load_model("sagittal")


@pytest.fixture(scope="module")
def main_job_options(myotorso):
    from trunk_drake.data import models_dir
    from trunk_drake.simulation import DEFAULT_GAINS, load_reflex_gains

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        feedforward = td.coactivation(myotorso, 0.02)
    return TrunkOptions(feedforward=feedforward, stiffness=125.0, damping=7.5, **load_reflex_gains(models_dir() / DEFAULT_GAINS))


def test_length_hessian_matches_second_difference_of_lengths(myotorso):
    base = myotorso.variant(pelvis_free=False)
    q = np.radians([3.0, -2.0, 4.0, 1.0, -3.0])
    hess = length_hessian(base, q)
    h = 1e-4
    eye = np.eye(5)
    second = np.empty_like(hess)
    for j in range(5):
        for k in range(5):
            L = [base.muscle_lengths(q + sj * h * eye[j] + sk * h * eye[k]) for sj, sk in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
            second[:, j, k] = (L[0] - L[1] - L[2] + L[3]) / (4 * h * h)
    assert np.max(np.abs(hess)) > 0.01
    np.testing.assert_allclose(hess, second, atol=2e-5 * np.max(np.abs(hess)))


@pytest.mark.parametrize("srs", [None, ShortRangeStiffness()])
def test_fast_jacobian_equals_the_full_finite_difference_jacobian(myotorso, main_job_options, srs):
    import dataclasses

    loop = ClosedLoop(myotorso, dataclasses.replace(main_job_options, srs=srs))
    x, found, _ = loop.equilibrium(np.zeros(5))
    assert found
    x = x + 1e-3 * np.random.default_rng(1).standard_normal(x.size) * np.r_[np.ones(10), 1e-2 * np.ones(x.size - 10)]
    fast, full = loop.jacobian(x), state_jacobian(loop.td, x, 1e-7, loop.context)
    np.testing.assert_allclose(fast, full, atol=1e-7 * np.max(np.abs(full)))


def test_static_hessian_equals_the_diagram_stiffness_without_reflexes(myotorso, main_job_options):
    """Two independent routes to the same stiffness: the energy Hessian (plant gravity, moment-arm
    derivatives, Thelen slope, SRS) and -M d(vdot)/dq of the simulated diagram at fixed activations."""
    import dataclasses

    for srs in (None, ShortRangeStiffness()):
        loop = ClosedLoop(myotorso, dataclasses.replace(main_job_options, kp=0.0, kv=0.0, srs=srs))
        x, _, _ = loop.equilibrium(np.zeros(5))
        A = loop.jacobian(x)
        loop.context.SetContinuousState(x)
        stiffness = -loop.td.plant.CalcMassMatrix(loop.plant_context) @ A[5:10, :5]
        np.testing.assert_allclose(loop.static(x).hessian, stiffness, rtol=1e-5, atol=1e-4)


@pytest.mark.parametrize("stiffness", [125.0, 300.0])
def test_rightmost_root_predicts_growth_or_decay_of_a_small_perturbation(myotorso, main_job_options, stiffness):
    """The README's main-job configuration is unstable (a 0.1 deg perturbation grows); with stiffer
    bushings it is stable (it decays). Either way the rate in the nonlinear simulation matches the
    root of that direction's one-sided linearisation within 10 %."""
    import dataclasses

    options = dataclasses.replace(main_job_options, stiffness=stiffness)
    loop = ClosedLoop(myotorso, options)
    x_eq, found, _ = loop.equilibrium(np.zeros(5))
    dynamic = loop.dynamic(x_eq)
    assert found and dynamic.stable == (stiffness > 200)
    roots, vectors = loop.rightmost(x_eq)
    mode = np.real(vectors[:, 0]) * np.sign(np.real(vectors[:5, 0]).sum())
    times = np.linspace(0.0, 1.5, 151)
    for direction in (1.0, -1.0):
        rate, shape = loop.branch(x_eq, roots[0], direction * mode)
        rotation = loop.rotation_from(x_eq + np.radians(0.1) * shape / np.abs(shape[:5]).max(), times)
        deviation = np.abs(rotation - x_eq[:5].sum())
        fitted = np.polyfit(times[times > 0.2], np.log(deviation[times > 0.2]), 1)[0]
        assert fitted == pytest.approx(rate.real, rel=0.10), f"direction {direction}: simulated {fitted}, predicted {rate.real}"


def test_report_names_the_reflexes_engaged_at_rest_and_critical_values(myotorso, main_job_options):
    result = stability(myotorso, main_job_options)
    summary = result.summary()
    reflexes = summary["dynamic"]["reflexes"]
    # with l_d = 1 the back extensors' fibers are shorter than optimal at rest: no position reflex there
    assert reflexes["sacrospinalis"]["engaged_at_rest"] == 0 and reflexes["sacrospinalis"]["mean_stretch_beyond_set_point"] < 0
    assert reflexes["psoas_major"]["engaged_at_rest"] > 0
    names = {c.name for c in result.critical}
    assert names == {"co-activation (minimum activation)", "reflex gain scale", "bushing stiffness"}
    stiff = next(c for c in result.critical if c.name == "bushing stiffness")
    assert stiff.value is not None and 125.0 < stiff.value < 300.0  # consistent with the two cases above


def test_short_range_stiffness_is_a_force_on_quick_stretch_that_fades():
    """SRS in the muscle system: force gain * a * f_AL * F_max * stretch (capped), about a reference
    length that follows the fiber with the time constant; an equilibrium is not changed by it."""
    srs = ShortRangeStiffness()
    model = td.load_model(dofs="all", spec=chain_spec([2.0], [0.4], [0.5]))
    loop = ClosedLoop(model, TrunkOptions(stiffness=50.0, feedforward=np.array([0.4]), srs=srs))
    x = loop.rest_state(np.array([0.05]))
    port = loop.td.muscles.GetOutputPort("tendon_force")

    def force_and_rate(stretch):
        y = x.copy()
        y[-1] -= stretch  # reference shorter than the fiber: the fiber is stretched by `stretch`
        loop.context.SetContinuousState(y)
        rate = loop.td.diagram.EvalTimeDerivatives(loop.context).CopyToVector()[-1]
        return port.Eval(loop.muscle_context)[0], rate

    rest, rest_rate = force_and_rate(0.0)
    ln = loop.td.muscles.GetOutputPort("normalized_fiber_length").Eval(loop.muscle_context)[0]
    per_stretch = srs.gain * 0.4 * thelen.active_force_length(ln) * F_MAX
    small, rate = force_and_rate(0.5 * srs.max_stretch)
    large, _ = force_and_rate(3.0 * srs.max_stretch)
    assert rest_rate == 0.0
    assert small - rest == pytest.approx(per_stretch * 0.5 * srs.max_stretch, rel=1e-9)
    assert large - rest == pytest.approx(per_stretch * srs.max_stretch, rel=1e-9)  # detached beyond max_stretch
    assert rate == pytest.approx(0.5 * srs.max_stretch / srs.time_constant, rel=1e-9)  # the reference follows
    assert ShortRangeStiffness.from_reference() == srs  # the defaults are the cited constants


def test_critical_value_gives_the_stable_interval_around_the_current_value():
    """Stable only for 2 < x < 5: from a stable current value both bounds; from an unstable one the
    first stable interval above the range's lower end."""
    window = lambda x: (x - 2.0) * (x - 5.0)  # noqa: E731  (negative = stable inside the window)
    around = critical_value("x", window, 0.5, 20.0, current=3.0, rtol=1e-4)
    assert around.value == pytest.approx(2.0, rel=1e-3) and around.upper == pytest.approx(5.0, rel=1e-3)
    assert around.summary()["text"].startswith("x in [2")
    scanned = critical_value("x", window, 0.5, 20.0, current=10.0, rtol=1e-4)
    assert scanned.value == pytest.approx(2.0, rel=1e-3) and scanned.upper == pytest.approx(5.0, rel=1e-3)
    open_ended = critical_value("x", lambda x: 1.0 - x, 0.1, 5.0, rtol=1e-4)
    assert open_ended.value == pytest.approx(1.0, rel=1e-3) and open_ended.upper is None


@pytest.mark.parametrize("gain_scale, l_desired", [(9.0, "neutral"), (4.5, "neutral"), (27.0, "neutral"), (9.0, 1.1)])
def test_default_passengers_one_sided_rates_match_simulation(gain_scale, l_desired):
    """The default passenger (Table 4.3 gains x 9, set point at the neutral length): the central linearisation's
    rightmost pair oscillates and decays fast (-5.7 1/s), but a trunk displaced into extension returns at about
    -0.9 1/s; with half the gains it runs away. With three times the gains the central root is real, and with the set
    point beyond the rest length (position reflexes off, velocity reflexes on) both sides run away, flexion faster.
    Each side's simulated rate, from the rest state displaced 0.1 deg along that side's mode, matches its branch
    within 15 % (a flexion beside an oscillating central pair decays faster than the pair, which it also excites, so
    there only that), and the margin is the largest. (Branches computed only where the central root is real gave the
    central pair's -5.7 as the margin and called half the gains stable; a branch that stopped after its first step
    returned the central root's +0.67 for the set point at 1.1, where flexion runs away at +1.1.)"""
    preset = load_preset("default").with_changes(gain_scale=gain_scale, l_desired=l_desired)
    model = preset.model()
    options = preset.options(model)
    loop = ClosedLoop(model, options)
    x_eq, found, _ = loop.equilibrium(np.zeros(loop.nq))
    roots, branches, modes = loop.one_sided_margin(x_eq)
    oscillating = abs(roots[0].imag) > 0
    assert found and oscillating == (gain_scale <= 9.0 and l_desired == "neutral")
    fitted = {}
    for side in ("flexion", "extension"):
        rate, shape = loop.branch(x_eq, branches[side].real, np.r_[modes[side], np.zeros(x_eq.size - loop.nq)])
        assert np.sign(shape[loop.fe].sum()) == (1 if side == "flexion" else -1)
        duration = min(3.0, (2.0 if rate.real > 0 else 4.0) / abs(rate.real))
        times = np.linspace(0.0, duration, 121)
        start = x_eq + np.radians(0.1) * shape / np.max(np.abs(shape[: loop.nq]))
        rotation = loop.rotation_from(start, times)
        late = times > 0.25 * duration
        fitted[side] = np.polyfit(times[late], np.log(np.abs(rotation[late] - x_eq[loop.fe].sum())), 1)[0]
    assert fitted["extension"] == pytest.approx(branches["extension"].real, rel=0.15), (fitted, branches)
    if oscillating:
        assert fitted["flexion"] < min(fitted["extension"], 0.0), fitted
    else:
        assert fitted["flexion"] == pytest.approx(branches["flexion"].real, rel=0.15), (fitted, branches)
    dynamic = loop.dynamic(x_eq, delay_search=False)
    assert dynamic.margin == pytest.approx(max(b.real for b in branches.values()))
    assert dynamic.stable == (max(fitted.values()) < 0)
    if dynamic.mode_branch != "central":  # the reported mode is turned to its side (the verdict prints it)
        assert np.sign(dynamic.mode[loop.fe].sum()) == (1 if dynamic.mode_branch == "flexion" else -1)
