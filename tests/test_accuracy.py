"""Forward simulation gives the same answer as the accurate reference (trunk_drake.accuracy):
the default settings' lumbar rotation within 0.01 deg RMS of radau3 at accuracy 1e-6, on the
default passenger (upright) and the thesis' model (which folds into flexion). Also: a diagram's state lives in
its Context (a cloned Context continues identically)."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator

import trunk_drake as td
from trunk_drake.accuracy import REFERENCE_FILE, TOLERANCE_DEG, TRIALS, load_reference, rms_deviation_deg, trial_model, trial_options
from trunk_drake.diagram import TrunkOptions, build_trunk_diagram
from trunk_drake.signals import make_multisine
from trunk_drake.simulation import simulate

SHORT = 4.0  # s: past the fade-in, where the perturbation is at full amplitude


@pytest.fixture(scope="module")
def sagittal():
    return td.load_model("sagittal")


@pytest.mark.parametrize("trial", TRIALS)
def test_default_settings_match_the_accurate_reference(trial):
    model = trial_model(trial)
    result = simulate(model, duration=SHORT, **trial_options(model, trial))
    time, reference = load_reference()
    moved = np.degrees(np.ptp(reference[trial][time <= SHORT]))
    assert moved > 1.0, f"the {trial} trial must move the trunk for the check to mean something ({moved:.2f} deg)"
    deviation = rms_deviation_deg(result, trial)
    assert deviation <= TOLERANCE_DEG, (f"{trial}: lumbar rotation {deviation:.4f} deg RMS from the reference "
                                        f"{REFERENCE_FILE.name} (rerun benchmarks/accuracy_reference.py only if the physics changed)")


def test_two_simulations_of_one_diagram_interleaved_do_not_interfere(sagittal):
    """Delay history and cached path kinematics are Context state: two simulators of one diagram
    (one from a clone of the other's initial Context), advanced in turns, stay identical to each other
    (with the history on the system object they would write into each other's)."""
    options = TrunkOptions(kp=0.3, kv=0.2, reflex_delay=0.03, stiffness=300.0, feedforward=np.full(210, 0.03))
    diagram = build_trunk_diagram(sagittal, options, make_multisine(f_max=1.0, seed=5)).diagram
    first = Simulator(diagram)
    second = Simulator(diagram, first.get_context().Clone())
    for simulator in (first, second):
        simulator.get_mutable_integrator().set_maximum_step_size(0.01)
        simulator.Initialize()
    for t in np.arange(0.1, 2.6, 0.1):
        first.AdvanceTo(t)
        second.AdvanceTo(t)
    states = [s.get_context().get_continuous_state_vector().CopyToVector() for s in (first, second)]
    assert np.abs(states[0][:5]).max() > 1e-3, "the trunk must move"
    np.testing.assert_array_equal(states[1], states[0])


def test_a_replayed_step_sequence_gives_smooth_finite_differences():
    """The fits' finite differences (`differentiable_settings`): a run replayed on its own step sequence
    is the run, and a reflex-gain column on the replayed sequence is within 3 % of the column on a
    1e-6 sequence (on 24 s trials, runs each on its own 1e-3 sequence were 15-1400 % off)."""
    from trunk_drake.simulation import differentiable_settings

    model = trial_model("default")
    kw = trial_options(model, "default")
    options = TrunkOptions(**{k: v for k, v in kw.items() if k not in ("bandwidth", "seed")})
    more = {g: 1.02 * k for g, k in options.kp.items()}

    def run(kp, **settings):
        return simulate(model, duration=SHORT, bandwidth=1.0, seed=0, options=options, kp=kp, **settings).lumbar_rotation

    base = simulate(model, duration=SHORT, bandwidth=1.0, seed=0, options=options, **differentiable_settings(model, options))
    replay = lambda kp: run(kp, **differentiable_settings(model, options, base.step_times))  # noqa: E731
    # the fits take a run for its own replay (measured: 5e-12 deg apart)
    np.testing.assert_allclose(replay(options.kp), base.lumbar_rotation, rtol=0, atol=np.radians(1e-9))
    fine = simulate(model, duration=SHORT, bandwidth=1.0, seed=0, options=options, integrator="runge_kutta3", accuracy=1e-6)
    exact = run(more, integrator="runge_kutta3", steps=fine.step_times) - fine.lumbar_rotation
    assert np.linalg.norm(exact) > np.radians(0.01), "the gain must move the trunk"
    on_sequence = replay(more) - base.lumbar_rotation
    assert np.linalg.norm(on_sequence - exact) < 0.03 * np.linalg.norm(exact)
    with pytest.raises(ValueError, match="steps must be increasing times from 0"):
        run(options.kp, integrator="runge_kutta3", steps=base.step_times[::-1])
