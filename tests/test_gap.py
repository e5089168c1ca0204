"""Sim-to-real gap diagnosis: inputs, noise estimate, catalogue, and an end-to-end case."""

import dataclasses
import time

import numpy as np
import pytest

import trunk_drake as td
from trunk_drake.diagram import TrunkOptions
from trunk_drake.gap.benchmark import nominal_options, truth_options, Case
from trunk_drake.gap.catalogue import CATALOGUE
from trunk_drake.gap.diagnose import diagnose_gap
from trunk_drake.gap.linear import OperatingPoint, linearize
from trunk_drake.gap.trials import estimate_noise, prepare_trials
from trunk_drake.gap.report import write_diagnosis
from trunk_drake.gap.synthetic import synthetic_trials
from trunk_drake.io.trials import LUMBAR_LEVELS, Trial
from trunk_drake.signals import make_multisine
from trunk_drake.thesis import coactivation_quiet, thesis_gains

PERIOD = 10.0  # short trials keep the test fast (one whole period after the 2 s fade-in)


def changed_fields(a, b) -> set:
    return {f.name for f in dataclasses.fields(a)
            if not np.array_equal(np.asarray(getattr(a, f.name), dtype=object), np.asarray(getattr(b, f.name), dtype=object))}


@pytest.fixture(scope="module")
def linearised(model):
    """The reference truth configuration linearised at rest (the feed-forward excitation as activation)."""
    nominal = nominal_options()
    u = np.asarray(nominal.feedforward, float)
    op = OperatingPoint(angles=np.zeros(5), a=u, u=u, amplitude=np.full(5, 0.01))
    return nominal, linearize(model, nominal, op), linearize(model, nominal, op, seat=True)


def off_kink_options(model) -> TrunkOptions:
    """Reflexes where the screening's linearisation holds: the set point at the optimal fiber length
    (l_d = 1: in small motions no fiber crosses it), the thesis' Table 4.3 gains, bushings 300 Nm/rad and
    6 Nms/rad, co-activation at minimum activation 0.03 (the synthetic truth's values before the reference
    data moved to the default passenger, whose set point at the neutral length sits on the reflex's kink)."""
    feedforward, _ = coactivation_quiet(model, 0.03)
    return TrunkOptions(stiffness=300.0, damping=6.0, feedforward=feedforward, l_desired=1.0, **thesis_gains())


class FakeFitter:
    """Base of the search tests' stand-ins for TimeDomainFitter: independent fits one after another."""

    def concurrently(self, calls):
        return [call() for call in calls]

    def outputs_near(self, x, effects, points, each):
        return self.outputs_of(points, each), [None] * len(points)


@pytest.mark.parametrize("dofs", ["sagittal", "rhythm"])
def test_linearisation_matches_a_small_amplitude_simulation(dofs):
    """The screening's linear model against the nonlinear diagram on a 0.5 mm RMS multisine (0.2-3 Hz, odd
    lines) with a flat acceleration spectrum, so every line is driven alike and none is swamped by the
    distortion of the others (with a flat displacement spectrum the lowest lines get 100 times less drive
    than the 3 Hz ones). FRF of the total lumbar rotation at every excited line within 2 % and 2 deg, in
    the sagittal configuration (five level coordinates) and the rhythm (one coupled lumbar_FE, levels
    through the level matrix). The rhythm runs without the velocity reflex: its one-sided (v)+, counted
    half in the linear model, alone leaves 2-3 % there (0.4 % without it)."""
    model = td.load_model(dofs)
    nominal = off_kink_options(model)
    if dofs == "rhythm":
        nominal = dataclasses.replace(nominal, kv=0.0)
    period, fs = 10.0, 100.0
    signal = make_multisine(period=period, f_max=3.0, seed=5, lines="odd", amplitude=5e-4, spectrum="acceleration",
                               n_periods=2, fade_shape="quintic")
    result = td.simulate(model, perturbation=signal, options=nominal, log_rate=fs, accuracy=1e-4)
    last = slice(int((2.0 + period) * fs), int((2.0 + 2 * period) * fs))  # the second whole period
    lin = linearize(model, nominal, OperatingPoint.of(result, last))
    bins = np.round(np.asarray(signal.frequencies) * period).astype(int)
    simulated = np.fft.rfft(result.lumbar_rotation[last])[bins] / np.fft.rfft(result.platform[last, 0])[bins]
    ratio = lin.frf(bins / period, nominal)[:, 0] / simulated
    assert np.max(np.abs(np.abs(ratio) - 1)) < 0.02 and np.degrees(np.max(np.abs(np.angle(ratio)))) < 2.0, ratio


def test_one_sided_reflexes_count_with_the_share_of_time_they_engage():
    """Bussgang: the best linear gain of (x - c)+ for a Gaussian x is P(x > c); statistics averaged over trials."""
    u = np.full(3, 0.02)
    op = OperatingPoint(angles=np.zeros(5), a=u, u=u, amplitude=np.full(5, 0.01),
                        fiber_length=np.array([[1.0, 1.0, 1.0], [0.01, 0.01, 0.0]]),
                        fiber_velocity=np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]))
    share = op.share_above(np.array([1.0, 1.01, 0.99]), fallback=np.zeros(3))
    assert share == pytest.approx([0.5, 0.158655, 1.0], abs=1e-6)  # at the set point half, 1 SD below 16 %, no spread: a step
    assert op.share_lengthening() == pytest.approx([0.5, 0.0, 0.0])
    bare = OperatingPoint(angles=np.zeros(5), a=u, u=u, amplitude=np.full(5, 0.01))
    assert np.array_equal(bare.share_above(np.ones(3), fallback=np.ones(3)), np.ones(3)) and bare.share_lengthening() == 0.5
    assert OperatingPoint.mean([op, bare]).fiber_length is None
    assert OperatingPoint.mean([op, op]).fiber_length == pytest.approx(op.fiber_length)


def test_every_candidate_switches_on_in_the_diagram_and_the_linear_model(linearised):
    nominal, lin, lin_seat = linearised
    freqs = np.array([0.3, 1.1, 2.9])
    for e in CATALOGUE:
        assert len(e.parameters) <= 2 and all(p.lower < p.upper and p.lower <= p.start <= p.upper for p in e.parameters)
        options = e.apply(nominal, e.values([p.start for p in e.parameters]))
        assert changed_fields(options, nominal), e.name
        after = (lin_seat if options.pelvis == "seat" else lin).frf(freqs, options)
        assert np.all(np.abs(after / lin.frf(freqs, nominal) - 1) > 1e-4), e.name
    with pytest.raises(ValueError, match="cannot follow a change of tendon"):
        lin.frf(freqs, dataclasses.replace(nominal, tendon="compliant"))
    with pytest.raises(ValueError, match="seat=True"):
        lin.frf(freqs, CATALOGUE[[e.name for e in CATALOGUE].index("seat_compliance")].apply(nominal, {"stiffness": 1e4, "damping": 300}))


def test_trial_checks_and_noise_estimate():
    fs, n = 100.0, 2400
    t = np.arange(n) / fs
    x = 0.01 * np.sin(2 * np.pi * 0.5 * t) * np.minimum(t / 2, 1)
    rng = np.random.default_rng(1)
    levels = {lvl: 0.01 * np.sin(2 * np.pi * 0.5 * t - 0.3) + rng.normal(0, 0.002, n)
              for lvl in LUMBAR_LEVELS}
    trial = Trial(time=t, fs=fs, platform_displacement=x, lumbar_rotation=sum(levels.values()), levels=levels, source="sine")
    data = prepare_trials([trial], period=20.0)
    assert data[0].excited_lines[0].size >= 1 and data[0].steady_outputs.shape[0] == 2000
    noise = estimate_noise(data)
    assert noise[1:] == pytest.approx(np.full(5, 0.002), rel=0.25)
    assert noise[0] == pytest.approx(0.002 * np.sqrt(5), rel=0.25)  # the total sums five noisy levels
    short = dataclasses.replace(trial, time=t[:1500], platform_displacement=x[:1500], lumbar_rotation=trial.lumbar_rotation[:1500],
                                levels={k: v[:1500] for k, v in levels.items()})
    with pytest.raises(ValueError, match="too short"):
        prepare_trials([short], period=20.0)
    with pytest.raises(ValueError, match="no excitation"):
        prepare_trials([dataclasses.replace(trial, platform_displacement=np.zeros(n))], period=20.0)
    with pytest.raises(ValueError, match="output 'T1'"):
        prepare_trials([trial], outputs=("T1",))
    with pytest.raises(ValueError, match="no platform or pelvis displacement"):
        prepare_trials([dataclasses.replace(trial, platform_displacement=None)])


@pytest.fixture(scope="module")
def model():
    return td.load_model("sagittal")


def diagnose_withheld_damping(model, checkpoint=None):
    """Two short trials of the reference truth with 20 Nms/rad extra damping withheld, diagnosed
    against three candidates; asserts that the damping is named and the gap closes."""
    nominal = nominal_options()
    truth = truth_options(nominal, Case("damping", "single", (("extra_damping", {"damping": 20.0}),), seed=3))
    noise = np.radians(0.1)
    trials = synthetic_trials(model, truth, [("a", 1.0, 1), ("b", 3.0, 2)], noise, seed=3, period=PERIOD)
    d = diagnose_gap(model, trials, nominal, noise=noise, period=PERIOD, refine=2, max_effects=1,
                     candidates=["extra_damping", "reflex_delay", "seat_compliance"], workers=2, checkpoint=checkpoint)
    assert d.selected == ["extra_damping"], d.ranking
    assert d.final["effects"]["extra_damping"]["damping"] == pytest.approx(20.0, rel=0.5)
    assert d.shrink["gap"]["effect"] < d.shrink["gap"]["nominal"]
    assert d.shrink["reduction_above_noise"] > 0.5
    return nominal, trials, d


def test_diagnosis_on_the_rhythm_names_withheld_damping_resumes_where_it_was_interrupted_and_writes_its_report(tmp_path, monkeypatch):
    """The diagnosis in the coupled rhythm configuration (one lumbar_FE; levels through the level matrix), stopped
    in the middle of its refits and rerun with the same simulation log: it takes the logged simulations and goes on,
    its wall time counting the stopped run's; the log stays until the caller has saved the results. Its report and
    the key run as pages: the diagnosed model follows the data closer than the nominal one. (The same diagnosis on
    the five independent levels of `sagittal` took 1,004 s of CI's 2,127 s, five times the rhythm's per simulation
    with as many simulations; its linearisation is checked above.)"""
    from trunk_drake.gap.refit import TimeDomainFitter

    class Stop(Exception):
        pass

    model, log = td.load_model("rhythm"), tmp_path / "simulations.pickle"
    outputs_of, calls = TimeDomainFitter.outputs_of, []

    def stopping(self, *args, **kwargs):
        calls.append(1)
        if len(calls) > 12:
            raise Stop
        return outputs_of(self, *args, **kwargs)

    monkeypatch.setattr(TimeDomainFitter, "outputs_of", stopping)
    start = time.perf_counter()
    with pytest.raises(Stop):
        diagnose_withheld_damping(model, log)
    stopped_after = time.perf_counter() - start
    assert log.stat().st_size > 0
    monkeypatch.setattr(TimeDomainFitter, "outputs_of", outputs_of)
    start = time.perf_counter()
    nominal, trials, d = diagnose_withheld_damping(model, log)
    scores = d.options["scores"]
    assert 0 < scores["replayed_simulations"] < scores["simulations"]
    assert 0 < scores["earlier_runs_wall_s"] <= stopped_after  # up to the stopped run's last logged simulation
    assert d.wall_time_s > time.perf_counter() - start  # this run's time and the stopped run's
    assert log.exists()  # kept until the results are saved (the caller removes it)
    check_report_and_pages(model, nominal, trials, d, tmp_path)


def check_report_and_pages(model, nominal, trials, d, folder):
    """`d`'s report with the key run as pages, data over model: the diagnosed model follows the data closer than the
    nominal one."""
    from trunk_drake.visual import animate_trial
    from trunk_drake.visual.page import recorded_positions

    assert d.final_options.damping != nominal.damping
    pages = {f"{k} model against trial a": animate_trial(trials[0], folder / f"{k}.html", model, options)
             for k, options in (("nominal", nominal), ("diagnosed", d.final_options))}
    files = write_diagnosis(d, folder, pages)
    text = files["report"].read_text()
    assert "Where the gap lies" in text and "extra_damping" in text and files["frf_plot"].exists()
    assert "[diagnosed model against trial a](diagnosed.html)" in text
    miss = {}
    for label, page in pages.items():
        tracks = recorded_positions(page.read_text())
        miss[label] = np.sqrt(np.mean(np.sum((tracks["/passenger/bones/lumbar1"] - tracks["/data/bones/lumbar1"]) ** 2, axis=1)))
    assert miss["diagnosed model against trial a"] < miss["nominal model against trial a"], miss


def test_an_effect_no_better_than_more_gain_directions_is_not_claimed():
    """The search's gain rival and nested test: an effect of k parameters is claimed only when it beats the
    current model with its gains refitted along k more directions by the threshold (held-out chi2, same k),
    and when it still passes as dBIC on top of the gains widened as far as they pass."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # the gains along one more direction reach `rival`; an effect on top of them `nested` (held-out)
        def __init__(self, rival, nested):
            self.rival, self.nested, self.spaces = rival, nested, []

        def fit(self, effects, x0, free, space=None):
            self.spaces.append(space)
            chi2 = self.nested if effects else self.rival
            return Fit(tuple(e.name for e in effects), np.asarray(x0, float), 0.0, chi2, {}, outputs=[])

    layout = GainLayout(("kp.sacrospinalis", "kv.sacrospinalis", "kp.psoas_major"))
    space = SearchSpace(TrunkOptions(), layout, np.eye(3)[:, :2])
    trial = SimpleNamespace(steady_outputs=np.zeros((1000, 1)))
    current = Fit((), np.zeros(2), 0.0, 1500.0, {})
    delay, mass = effect("reflex_delay"), effect("upper_body_mass")
    fits = {"reflex_delay": Fit(("reflex_delay",), np.zeros(3), 0.0, 1300.0, {}),
            "upper_body_mass": Fit(("upper_body_mass",), np.zeros(3), 0.0, 1400.0, {})}
    for rival, nested, claimed in ((1350.0, 1300.0, "reflex_delay"), (1295.0, 1290.0, None), (1350.0, 1345.0, None)):
        fitter = Fitter(rival, nested)
        search = _Search(space, SimpleNamespace(trials=[trial]), fitter, (delay, mass), Settings(), np.eye(3)[:, 2:], None)
        chosen, tried = search.claim(current, fits)
        assert (chosen and chosen["effect"]) == claimed
        assert tried[0]["effect"] == "reflex_delay" and tried[0]["beats_gain_rival_by"] == pytest.approx(rival - 1300.0)
        assert fitter.spaces[0].rank == 3  # one rival per k, along the third direction
        if rival - 1300.0 > search.settings.threshold:  # past the rival: the delay refitted on the widened gains
            assert fitter.spaces[-1].rank == 3 and tried[0]["on_widened_gains"] == {
                "delta_bic": pytest.approx(rival - nested - search.penalty), "directions": 1}
        else:
            assert len(fitter.spaces) == 1 and "on_widened_gains" not in tried[0]
        assert [t["effect"] for t in tried] == (["reflex_delay"] if claimed else ["reflex_delay", "upper_body_mass"])
    fit, wider, dbic = search.widen(current)  # no claim: the gains along the third direction pass as an effect would
    assert wider.rank == 3 and fit.heldout_chi2 == 1350.0 and dbic == pytest.approx(1500.0 - 1350.0 - search.penalty)
    for gains_first, claimed in ((False, None), (True, "reflex_delay")):  # loses to its rival, adds 45 on top of it
        search = _Search(space, SimpleNamespace(trials=[trial]), Fitter(1295.0, 1250.0), (delay, mass),
                         Settings(gains_first=gains_first), np.eye(3)[:, 2:], None)
        chosen, tried = search.claim(current, fits)
        assert (chosen and chosen["effect"]) == claimed and tried[0]["beats_gain_rival_by"] == pytest.approx(-5.0)


def test_gains_first_adopts_the_widened_gains_before_any_effect_is_weighed():
    """`Settings.gains_first`: the search widens the gains while each further direction passes as an effect would,
    then searches on in that space: its rivals and further widening start from the directions left."""
    from types import SimpleNamespace

    from trunk_drake.gap.search import Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # the gains along a third direction gain 150 held-out; a fourth 5 (below the threshold)
        space = None

        def fit(self, effects, x0, free, space=None):
            return Fit((), np.asarray(x0, float), 0.0, {3: 1350.0, 4: 1345.0}[space.rank], {}, outputs=[])

    layout = GainLayout(("kp.sacrospinalis", "kv.sacrospinalis", "kp.psoas_major", "kv.psoas_major"))
    space = SearchSpace(TrunkOptions(), layout, np.eye(4)[:, :2])
    trial = SimpleNamespace(steady_outputs=np.zeros((1000, 1)))
    fitter = Fitter()
    search = _Search(space, SimpleNamespace(trials=[trial]), fitter, (), Settings(gains_first=True), np.eye(4)[:, 2:], None)
    base, wider, dbic = search.widen(Fit((), np.zeros(2), 0.0, 1500.0, {}))
    assert wider.rank == 3 and base.x.size == 3 and dbic == pytest.approx(150.0 - search.penalty)
    search.adopt(wider)
    assert search.space is wider and fitter.space is wider and search.rivals == {}
    np.testing.assert_array_equal(search.spare, np.eye(4)[:, 3:])  # the directions beyond the adopted ones
    assert search.rival(base, 1).heldout_chi2 == 1345.0 and search.rival(base, 2) is None
    assert search.widen(base) is None  # the fourth direction does not pass


def test_the_check_also_simulates_a_linear_fit_with_the_current_gains():
    """The linear fit can be far off at the reflexes' kinks: the check simulates each screened row at its linear
    fit, at the effect's linear fit with the current gains and at the catalogue's start with the current gains,
    and keeps the best start on the training halves."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # a simulation fits the training halves well only with the current gains (0.1, 0.2)
        def outputs_of(self, points, effects, space=None):
            return [np.asarray(p, float) for p in points]

        def chi2(self, x, which):  # best near the truth (0.15, 0.15)
            return 1000.0 + 1e4 * float(np.sum((x - [0.1, 0.2, 0.15, 0.15]) ** 2)) + (0.0 if which == "train" else 50.0)

    layout = GainLayout(("kp.sacrospinalis", "kv.sacrospinalis"))
    space = SearchSpace(TrunkOptions(), layout, np.eye(2))
    trial = SimpleNamespace(steady_outputs=np.zeros((1000, 1)))
    tis = effect("trunk_in_space")
    search = _Search(space, SimpleNamespace(trials=[trial]), Fitter(), (tis,), Settings(), np.zeros((2, 0)), None)
    current = Fit((), np.array([0.1, 0.2]), 1100.0, 1200.0, {})
    linear = Fit(("trunk_in_space",), np.array([0.9, -0.7, 0.3, 0.08]), 0.0, 0.0, {})
    row, = search.check(current, [{"effect": "trunk_in_space", "linear_delta_bic": 500.0, "linear_fit": linear}])
    start = [p.start for p in tis.parameters]
    assert np.allclose(row["linear_fit"].x, [0.1, 0.2, *start])  # the catalogue's start with the current gains
    assert row["checked_values"] == tis.values(np.array(start))  # reported with the dBIC simulated there
    chi2 = 1000.0 + 1e4 * float(np.sum((np.array(start) - 0.15) ** 2)) + 50.0
    assert row["checked_delta_bic"] == pytest.approx(1200.0 - chi2 - 2 * search.penalty)
    linear = Fit(("trunk_in_space",), np.array([0.9, -0.7, 0.14, 0.16]), 0.0, 0.0, {})
    row, = search.check(current, [{"effect": "trunk_in_space", "linear_delta_bic": 500.0, "linear_fit": linear}])
    assert np.allclose(row["linear_fit"].x, [0.1, 0.2, 0.14, 0.16])  # the effect's linear fit, the current gains
    search.settings = Settings(check=1)  # only the best `check` rows by linear dBIC are simulated
    rows = search.check(current, [{"effect": "trunk_in_space", "linear_delta_bic": v, "linear_fit": linear} for v in (500.0, 400.0)])
    assert "checked_delta_bic" in rows[0] and "checked_delta_bic" not in rows[1]
    for gains_first in (False, True):  # below the threshold linearly: simulated only when the gains were widened first
        search.settings = Settings(gains_first=gains_first)
        row, = search.check(current, [{"effect": "trunk_in_space", "linear_delta_bic": -10.0, "linear_fit": linear}])
        assert ("checked_delta_bic" in row) == gains_first
    search.settings, search.all_gains = Settings(check=1), True  # on all gain directions: every row, at five points
    simulated = []
    search.fitter.outputs_of = lambda points, effects, space=None: simulated.append(len(points)) or [np.asarray(p, float) for p in points]
    rows = search.check(current, [{"effect": "trunk_in_space", "linear_delta_bic": -10.0, "linear_fit": linear} for _ in range(2)])
    assert all("checked_delta_bic" in r for r in rows) and simulated == [10]


def test_with_gains_first_an_added_effect_is_refitted_from_several_magnitudes():
    """Gains widened first take up part of an effect, and a refit from a small start stays there
    (extra_damping_damping16: 1.1 Nms/rad from a start of 1, 16 from 16): with gains first the refit also starts at
    fractions of the effect's range with the current gains, and the best on the training halves is kept."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import START_FRACTIONS, Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    def chi2(x):  # two basins: the gains absorbing a little damping (1400), and the truth, 16 (1000)
        return min(1400.0 + 1e3 * (x[1] - 1.0) ** 2, 1000.0 + 1e3 * (x[1] - 16.0) ** 2)

    class Fitter(FakeFitter):
        def __init__(self):
            self.starts = []

        def outputs_of(self, points, effects, space=None):
            return [np.asarray(p, float) for p in points]

        def chi2(self, x, which):
            return chi2(x) + (0.0 if which == "train" else 50.0)

        def fit(self, effects, x0, free, max_iterations=2, space=None, on=None):  # to the bottom of the start's basin
            self.starts.append(np.asarray(x0, float))
            x = np.array([x0[0], 16.0 if x0[1] > 8.5 else 1.0])
            return Fit(("extra_damping",), x, chi2(x), chi2(x) + 50.0, {"extra_damping": {"damping": x[1]}}, [x])

    layout = GainLayout(("kv.sacrospinalis",), {"kp": {}, "kv": {"sacrospinalis": 0.1}})
    e = effect("extra_damping")
    screen = SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))])
    current = Fit((), np.array([0.5]), 1500.0, 1550.0, {})
    lo, hi = e.parameters[0].lower, e.parameters[0].upper
    for gains_first in (False, True):
        fitter = Fitter()
        search = _Search(SearchSpace(TrunkOptions(), layout, np.eye(1)), screen, fitter, (e,), Settings(gains_first=gains_first),
                         np.zeros((1, 0)), None)
        linear = Fit(("extra_damping",), np.array([0.5, 2.0]), 0.0, 0.0, {})  # the check keeps the catalogue's start, 1
        fits = search.refine(current, [{"effect": "extra_damping", "linear_delta_bic": 500.0, "linear_fit": linear}])
        expected = [[0.5, 1.0]] + ([[0.5, lo + f * (hi - lo)] for f in START_FRACTIONS] if gains_first else [])
        assert np.allclose(fitter.starts, expected)
        assert fits["extra_damping"].x[1] == (16.0 if gains_first else 1.0)


def test_a_run_replayed_on_its_own_step_sequences_is_not_simulated_again():
    from trunk_drake.gap.refit import TimeDomainFitter
    from trunk_drake.gap.space import SearchSpace

    space = SearchSpace.around(td.load_model("rhythm"), nominal_options())
    space = SearchSpace(space.options, space.layout, np.eye(len(space.layout.names))[:, :1])
    fitter = TimeDomainFitter(None, space, [], None, ())
    own = fitter.key([0.1], ())
    assert fitter.key([0.1], (), on=own) == own  # its own replay: the run itself
    assert fitter.key([0.2], (), on=own) == fitter.key([0.2], ())[:3] + (own,)


def test_a_point_of_a_wider_gain_space_at_zero_along_the_new_directions_is_the_same_run():
    """The refits key their simulations by the model simulated (gains and effects), not by the space's coordinates:
    the gain rivals and nested fits start in a wider space at a model already simulated."""
    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.refit import TimeDomainFitter
    from trunk_drake.gap.space import SearchSpace

    narrow = SearchSpace.around(td.load_model("rhythm"), nominal_options())
    n = len(narrow.layout.names)
    narrow = SearchSpace(narrow.options, narrow.layout, np.eye(n)[:, :2])
    wide = SearchSpace(narrow.options, narrow.layout, np.eye(n)[:, :3])
    fitter = TimeDomainFitter(None, narrow, [], None, ())
    delay = effect("reflex_delay")
    assert fitter.key([0.1, -0.2, 0.05], (delay,)) == fitter.key([0.1, -0.2, 0.0, 0.05], (delay,), space=wide)
    assert fitter.key([0.1, -0.2, 0.05], (delay,)) != fitter.key([0.1, -0.2, 0.01, 0.05], (delay,), space=wide)
    assert fitter.key([0.1, -0.2], ()) != fitter.key([0.1, -0.2, 0.05], (delay,))  # the effect is part of the model


def test_a_refits_points_that_differ_in_variant_fields_run_as_copies():
    """On replayed steps the points whose options differ only in `VARIANT_FIELDS` (the gains, and effects that set
    only those: a delay, damping, strength) run as one group per trial; an effect that changes the diagram (seat
    compliance: a sliding pelvis), a delay of zero beside positive ones, and points on their own steps run one by one."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.refit import TimeDomainFitter
    from trunk_drake.gap.space import SearchSpace

    model = td.load_model("rhythm")
    space = SearchSpace.around(model, dataclasses.replace(nominal_options(), reflex_delay=0.02))
    space = SearchSpace(space.options, space.layout, np.eye(len(space.layout.names))[:, :2])
    fitter = TimeDomainFitter(SimpleNamespace(capacity=2, model=model), space, [None] * 3, None, ())
    delay, damping, seat = effect("reflex_delay"), effect("extra_damping"), effect("seat_compliance")
    steps = [np.linspace(0.0, 1.0, 5)] * 3
    points = [(np.array([0.0, 0.0, 0.03]), (delay,)), (np.array([0.1, 0.0, 0.03]), (delay,)),
              (np.array([0.0, 0.1, 0.03]), (delay,)), (np.array([0.0, 0.0, 0.05]), (delay,)),  # a Jacobian's columns
              (np.array([0.0, 0.0, 4.0]), (damping,)), (np.array([0.0, 0.0, 5.0, 2.5]), (seat,))]
    options = [space.options_for(*p) for p in points]
    plan = fitter._plan(options, steps)
    assert sorted(k for group, k in plan if group == [0, 1, 2, 3, 4]) == [0, 1, 2]  # the delay's and damping's points
    assert sorted((group, k) for group, k in plan if group != [0, 1, 2, 3, 4]) == [([5], 0), ([5], 1), ([5], 2)]
    no_delay = SearchSpace(dataclasses.replace(space.options, reflex_delay=0.0), space.layout, space.directions)
    plan = fitter._plan([no_delay.options_for(*p) for p in [(np.zeros(2), ()), (np.array([0.0, 0.0, 0.03]), (delay,))]], steps)
    assert sorted(group for group, _ in plan) == [[0]] * 3 + [[1]] * 3
    assert len(fitter._plan(options[:4], [None] * 3)) == 12  # each on its own steps


def test_the_checks_replay_the_current_models_steps_as_copies_where_the_diagram_allows():
    """`TimeDomainFitter.outputs_near`: the current model runs on its own steps; points whose diagram is its own up to
    `VARIANT_FIELDS` and whose delay is no shorter replay those steps as one group per trial; a shorter delay (the
    steps follow the shortest delay) and another diagram (a sliding pelvis) run on their own steps."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.refit import TimeDomainFitter
    from trunk_drake.gap.space import SearchSpace

    model = td.load_model("rhythm")
    own_steps = np.linspace(0.0, 1.0, 7)

    class Pool:  # records the jobs; every run gives zero outputs and its steps
        capacity = 2

        def __init__(self):
            self.model, self.jobs = model, []

        def map(self, fn, jobs):
            self.jobs += jobs
            runs = []
            for options, _, _, steps, _ in jobs:
                one = (np.zeros((4, 1)), None, own_steps if steps is None else steps)
                runs.append([one] * len(options) if isinstance(options, list) else one)
            return runs

    space = SearchSpace.around(model, nominal_options())
    space = SearchSpace(space.options, space.layout, np.eye(len(space.layout.names))[:, :2])
    pool = Pool()
    fitter = TimeDomainFitter(pool, space, [None] * 3, None, ())
    delay, damping, seat = effect("reflex_delay"), effect("extra_damping"), effect("seat_compliance")
    x = np.array([0.0, 0.0, 0.03])
    points = [(np.array([0.0, 0.1, 0.05]), (delay,)), (np.array([0.0, 0.0, 0.01]), (delay,)),
              (np.array([0.0, 0.0, 0.03, 4.0]), (delay, damping)), (np.array([0.0, 0.0, 0.03, 5.0, 2.5]), (delay, seat))]
    outputs, runs = fitter.outputs_near(x, (delay,), [p for p, _ in points], [e for _, e in points])
    assert len(outputs) == 4 and all(o is not None for o in outputs)
    assert runs == [fitter.key(x, (delay,)), None, fitter.key(x, (delay,)), None]  # where a refit from each replays
    own, replayed, alone = pool.jobs[:3], pool.jobs[3:6], pool.jobs[6:]
    assert all(not isinstance(j[0], list) and j[3] is None for j in own)  # the current model on its own steps
    assert all(len(j[0]) == 2 and j[3] is own_steps for j in replayed)  # the longer delay and the damping: copies
    assert [j[0][0].reflex_delay for j in replayed] == [0.05] * 3 and [j[0][1].damping for j in replayed] != [space.options.damping] * 3
    assert len(alone) == 6 and all(not isinstance(j[0], list) and j[3] is None for j in alone)
    assert sorted({(j[0].reflex_delay, j[0].pelvis) for j in alone}) == [(0.01, "prescribed"), (0.03, "seat")]


def test_a_refit_step_simulates_the_training_half_only_and_gets_its_outputs_exactly():
    """The refits' own steps are scored on the training halves: their simulations stop at the end of the half,
    on the same replayed steps, and give the same outputs there as the whole run (the fitted point runs whole)."""
    from trunk_drake.gap.refit import simulate_outputs, train_end
    from trunk_drake.gap.trials import half
    from trunk_drake.io.trials import OUTPUT_NAMES

    model = td.load_model("rhythm")
    options = nominal_options()
    trial = prepare_trials(synthetic_trials(model, options, [("a", 1.0, 1)], np.radians(0.1), seed=3, period=PERIOD),
                           period=PERIOD)[0]
    _, _, steps = simulate_outputs(model, options, trial, OUTPUT_NAMES)
    whole, point, _ = simulate_outputs(model, options, trial, OUTPUT_NAMES, steps)
    part, no_point, part_steps = simulate_outputs(model, options, trial, OUTPUT_NAMES, steps, until=train_end(trial))
    train = half(trial, "train")
    assert part_steps[-2] >= train_end(trial) > part_steps[-3] and part_steps[-1] < steps[-1]
    np.testing.assert_array_equal(part_steps, steps[: len(part_steps)])
    assert point is not None and no_point is None  # no operating point from a part of the window
    centred = [y[train] - y[train].mean(axis=0) for y in (whole, part)]
    np.testing.assert_allclose(centred[1], centred[0], rtol=0, atol=1e-12)


def test_the_polish_refits_every_gain_direction_and_drops_an_effect_the_gains_then_explain():
    """`_Search.polish`: the final model refitted along every gain direction with its effects (the coordinates
    of the narrower space kept, zeros along the new directions), then each effect refitted away on those gains:
    one whose own dBIC no longer passes is dropped, one that passes is kept."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import POLISH_ITERATIONS, Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # held-out chi2 by the effects fitted: both 1000, the delay alone 1005, the mass alone 1400
        def __init__(self):
            self.calls = []

        def fit(self, effects, x0, free, max_iterations=2, space=None, on=None):
            names = tuple(e.name for e in effects)
            self.calls.append((names, np.asarray(x0, float), space.rank, max_iterations))
            chi2 = {("reflex_delay", "upper_body_mass"): 1000.0, ("reflex_delay",): 1400.0, ("upper_body_mass",): 1005.0,
                    (): 2000.0}[names]
            return Fit(names, np.asarray(x0, float), chi2 - 100.0, chi2, {}, outputs=[])

    layout = GainLayout(("kp.sacrospinalis", "kv.sacrospinalis", "kp.psoas_major"))
    space = SearchSpace(TrunkOptions(), layout, np.eye(3)[:, :2])
    fitter, steps = Fitter(), []
    search = _Search(space, SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))]), fitter,
                     (effect("reflex_delay"), effect("upper_body_mass")), Settings(), np.eye(3)[:, 2:], None)
    final = Fit(("reflex_delay", "upper_body_mass"), np.array([0.1, 0.2, 0.05, 1.1]), 950.0, 1010.0, {})
    fit, dropped = search.polish(final, space, steps.append)
    assert search.space.rank == 3 and search.all_gains and fitter.calls[0][2] == 3 and fitter.calls[0][3] == POLISH_ITERATIONS
    np.testing.assert_array_equal(fitter.calls[0][1], [0.1, 0.2, 0.0, 0.05, 1.1])
    assert [s["action"] for s in steps] == ["polish", "drop", "keep"]
    assert steps[1]["effect"] == "reflex_delay" and steps[1]["own_delta_bic"]["reflex_delay"] == pytest.approx(5.0 - search.penalty)
    assert fit.effects == ("upper_body_mass",) and fit.x.tolist() == [0.1, 0.2, 0.0, 1.1] and dropped == {"reflex_delay"}
    assert steps[2]["own_delta_bic"] == {"upper_body_mass": pytest.approx(995.0 - search.penalty)}
    # the polish fits the training halves worse: the same model (zero along the new direction), nothing dropped
    search = _Search(space, search.screen, fitter, search.candidates.values(), Settings(), np.eye(3)[:, 2:], None)
    worse = Fit(final.effects, final.x, 800.0, 1010.0, {})
    fit, dropped = search.polish(worse, space, steps.append)
    assert fit.x.tolist() == [0.1, 0.2, 0.0, 0.05, 1.1] and fit.train_chi2 == 800.0 and not dropped and len(steps) == 3
    assert search.space.rank == 3 and search.models == {frozenset(worse.effects): fit}


def test_after_the_polish_the_selection_goes_on_on_every_gain_direction():
    """`select` with `_Search.all_gains` (the search after the polish): no gain direction is left to rival an
    effect, so a further effect is claimed on its own dBIC, also against the model without it refitted from its
    gains; the joint refit and the backward test run in rounds
    like the polish (every coordinate free), and the polished model's gains are not refitted again first."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import POLISH_ITERATIONS, Settings, _Search, select
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # held-out chi2 by the effects fitted: both 1000, the delay alone 1400, the mass alone 1300
        def __init__(self):
            self.calls = []

        def fit(self, effects, x0, free, max_iterations=2, space=None, on=None):
            names = tuple(e.name for e in effects)
            self.calls.append((names, list(free), max_iterations))
            chi2 = {("reflex_delay", "upper_body_mass"): 1000.0, ("reflex_delay",): 1400.0, ("upper_body_mass",): 1300.0}[names]
            return Fit(names, np.asarray(x0, float), chi2 - 100.0, chi2, {}, outputs=[])

    layout = GainLayout(("kp.sacrospinalis", "kv.sacrospinalis"))
    fitter, steps = Fitter(), []
    search = _Search(SearchSpace(TrunkOptions(), layout, np.eye(2)), SimpleNamespace(trials=[SimpleNamespace(
        steady_outputs=np.zeros((1000, 1)))]), fitter, (effect("reflex_delay"), effect("upper_body_mass")), Settings(),
        np.zeros((2, 0)), None)
    search.all_gains = True
    polished = Fit(("reflex_delay",), np.array([0.1, 0.2, 0.05]), 1300.0, 1400.0, {}, outputs=[])
    added = Fit(("reflex_delay", "upper_body_mass"), np.array([0.1, 0.2, 0.05, 1.1]), 950.0, 1050.0, {}, outputs=[])
    screened = []
    search.screen_additions = lambda current, names: screened.append(names) or [{"effect": n} for n in names]
    search.refine = lambda current, rows: {"upper_body_mass": added}
    final = select(search, polished, steps.append)
    assert screened == [["upper_body_mass"]] and final.effects == ("reflex_delay", "upper_body_mass")
    assert [s["action"] for s in steps] == ["add", "keep"] and all(s["directions"] == 2 for s in steps)
    assert steps[0]["ranking"] == [{"effect": "upper_body_mass"}]  # the step's ranking, recorded with it
    assert steps[0]["delta_bic"] == pytest.approx(350.0 - search.penalty) and steps[0]["beats_gain_rival_by"] is None
    assert all(free == list(range(len(free))) and n == POLISH_ITERATIONS for _, free, n in fitter.calls)
    # no gain rival is left: the model without the mass refitted in rounds from the mass's fit must not do as well
    # (it does not: 1400 held-out, so the current model stands; its second round gains nothing), then the joint refit
    assert [c[0] for c in fitter.calls[:4]] == [("reflex_delay",)] * 2 + [("reflex_delay", "upper_body_mass")] * 2
    assert steps[0]["delta_bic_against_refit"] == pytest.approx(350.0 - search.penalty)


def test_on_every_gain_direction_an_effect_credited_with_further_gain_rounds_is_not_claimed():
    """After the polish an added effect's refit runs further gain rounds: the model without it, refitted in rounds from
    the effect's fit, takes that credit back (here it reaches the effect's held-out chi2, so the effect is not claimed),
    and where it fits the training halves better than the polished model by more than the threshold the selection goes
    on from it (`regain`)."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import Settings, _Search, select
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # the model without the mass, refitted from the mass's gains, fits as well as with it
        def fit(self, effects, x0, free, max_iterations=2, space=None, on=None):
            assert tuple(e.name for e in effects) == ("reflex_delay",)
            return Fit(("reflex_delay",), np.asarray(x0, float), 1200.0, 1048.0, {}, outputs=[])

    search = _Search(SearchSpace(TrunkOptions(), GainLayout(("kp.sacrospinalis", "kv.sacrospinalis")), np.eye(2)),
                     SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))]), Fitter(),
                     (effect("reflex_delay"), effect("upper_body_mass")), Settings(), np.zeros((2, 0)), None)
    search.all_gains = True
    polished = Fit(("reflex_delay",), np.array([0.1, 0.2, 0.05]), 1300.0, 1400.0, {}, outputs=[])
    added = Fit(("reflex_delay", "upper_body_mass"), np.array([0.3, 0.1, 0.05, 1.1]), 1190.0, 1050.0, {}, outputs=[])
    search.screen_additions = lambda current, names: [{"effect": n} for n in names]
    search.refine = lambda current, rows: {"upper_body_mass": added}
    steps = []
    final = select(search, polished, steps.append)
    # the refit without the mass fits the training halves better than the polished model (1200 against 1300): the
    # selection goes on from it, where the mass passes neither against it nor against its refit
    assert [s["action"] for s in steps] == ["regain", "stop"] and final.effects == ("reflex_delay",)
    assert final.train_chi2 == 1200.0 and steps[0]["train_chi2"] == [1300.0, 1200.0]
    tried = steps[-1]["matched_by_gains"]
    assert tried == [] and steps[-1]["delta_bic"] == pytest.approx(-2.0 - search.penalty)


def test_on_every_gain_direction_checks_tied_at_their_absence_are_each_refitted():
    """`_Search.refine` after the polish: the best checked row, and every row within the threshold of it, however
    many (checks at an effect's absence tie at minus its penalty: golgi_feedback_gain0.15 on 9b5788c refitted only
    the stiffening law, -9.4 against the Golgi feedback's -9.5; their order is no ranking, so no cut at `refine`),
    and every row whose check passes the threshold; a clear lead is refitted alone."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    names = ("stiffening_discs", "golgi_feedback", "seat_compliance", "extra_damping")
    search = _Search(SearchSpace(TrunkOptions(), GainLayout(("kp.sacrospinalis", "kv.sacrospinalis")), np.eye(2)),
                     SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))]), FakeFitter(),
                     tuple(effect(n) for n in names), Settings(), np.zeros((2, 0)), None)
    search.all_gains = True
    current = Fit((), np.array([0.1, 0.2]), 1300.0, 1400.0, {}, outputs=[])
    refitted = []
    search.fit_added = lambda current, held, x0, on=None: refitted.append(held[-1].name) or Fit(
        tuple(e.name for e in held), x0, 1200.0, 1300.0, {held[-1].name: {}}, outputs=[])

    def refine_after(checked: dict) -> list[str]:
        refitted.clear()
        search.check = lambda current, rows: [dict(r, checked_delta_bic=checked[r["effect"]]) for r in rows]
        rows = [{"effect": n, "linear_fit": Fit((), np.array([0.1, 0.2, 0.0]), 0.0, 0.0, {})} for n in checked]
        search.refine(current, rows)
        return refitted

    tied = {"stiffening_discs": -9.4, "golgi_feedback": -9.5, "seat_compliance": -32.0, "extra_damping": -40.0}
    assert refine_after(tied) == ["stiffening_discs", "golgi_feedback"]
    assert refine_after({"golgi_feedback": 30.0, "stiffening_discs": 8.0, "seat_compliance": -5.0}) == ["golgi_feedback"]
    passing = {"seat_compliance": 2443.0, "golgi_feedback": 578.0, "extra_damping": 40.1, "stiffening_discs": 9.0}
    assert refine_after(passing) == ["seat_compliance", "golgi_feedback", "extra_damping"]  # every check passing too
    assert len(names) > Settings().refine and refine_after({n: -9.4 for n in names}) == list(names)  # every tied row


def test_on_every_gain_direction_a_candidate_is_judged_against_the_best_refit_without_a_candidate():
    """After the polish, the first candidate's refit without it fits better than the polished model; a second candidate
    that beats its own refit-without but not that better model is not claimed, and the selection goes on from the
    better model (`regain`) instead of claiming it against the polished one."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import Settings, _Search, select
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    search = _Search(SearchSpace(TrunkOptions(), GainLayout(("kp.sacrospinalis", "kv.sacrospinalis")), np.eye(2)),
                     SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))]), FakeFitter(),
                     (effect("reflex_delay"), effect("upper_body_mass"), effect("muscle_strength")), Settings(),
                     np.zeros((2, 0)), None)
    search.all_gains = True
    polished = Fit(("reflex_delay",), np.array([0.1, 0.2, 0.05]), 1300.0, 1400.0, {}, outputs=[])
    mass = Fit(("reflex_delay", "upper_body_mass"), np.array([0.3, 0.1, 0.05, 1.1]), 1150.0, 1040.0, {}, outputs=[])
    strength = Fit(("reflex_delay", "muscle_strength"), np.array([0.3, 0.1, 0.05, 1.1]), 1190.0, 1090.0, {}, outputs=[])
    without = {"upper_body_mass": Fit(("reflex_delay",), polished.x, 1100.0, 1045.0, {}, outputs=[]),  # the better
               "muscle_strength": Fit(("reflex_delay",), polished.x, 1250.0, 1300.0, {}, outputs=[])}
    search.refit_without = lambda current, fit, name: without[name]
    chosen, tried = search.claim(polished, {"upper_body_mass": mass, "muscle_strength": strength})
    assert chosen is None and search.better is without["upper_body_mass"]
    # strength would beat its own refit-without (held-out chi2 1300) but not the mass's (1045, the better in training)
    assert [t["effect"] for t in tried] == ["upper_body_mass", "muscle_strength"]
    assert tried[1]["delta_bic_against_refit"] == pytest.approx(1045.0 - 1090.0 - search.penalty)
    search.screen_additions = lambda current, names: [{"effect": n} for n in names]
    search.refine = lambda current, rows: ({"upper_body_mass": mass, "muscle_strength": strength}
                                           if current is polished else {})
    steps = []
    final = select(search, polished, steps.append)
    assert [s["action"] for s in steps] == ["regain", "stop"] and final is without["upper_body_mass"]


def test_a_gain_rival_starts_from_the_rival_with_one_direction_fewer():
    """`_Search.rival` with k directions starts from the rival with k - 1 (the new direction at zero), so it fits the
    training halves at least as well (from the current model the 2-direction rival of the delay + slow activation
    pair ended far worse than the 1-direction one)."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    starts = []

    class Fitter(FakeFitter):  # each fit moves its last free coordinate to 1
        def fit(self, effects, x0, free, max_iterations=2, space=None, on=None):
            starts.append(np.array(x0))
            x = np.array(x0, float)
            x[free[-1]] = 1.0
            return Fit(tuple(e.name for e in effects), x, 100.0 - len(free), 100.0, {}, outputs=[])

    search = _Search(SearchSpace(TrunkOptions(), GainLayout(("kp.sacrospinalis", "kv.sacrospinalis")), np.eye(2)[:, :1]),
                     SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))]), Fitter(),
                     (effect("reflex_delay"),), Settings(), np.array([[0.0, 1.0], [1.0, 1.0]]), None)
    current = Fit(("reflex_delay",), np.array([0.5, 0.05]), 120.0, 120.0, {}, outputs=[])
    two = search.rival(current, 2)
    assert len(starts) == 2  # the 1-direction rival first, then the 2-direction one from it
    np.testing.assert_array_equal(starts[0], [0.5, 0.0, 0.05])
    np.testing.assert_array_equal(starts[1], [0.5, 1.0, 0.0, 0.05])  # the first rival's new direction kept
    assert two.x.size == 4 and search.rival(current, 1).x[1] == 1.0 and len(starts) == 2  # cached


def test_a_partner_masked_by_the_chosen_effect_is_refitted_with_it_from_its_own_first_step_fit():
    """`_Search.partners`: each effect that passed the first step is added to the final model at its own values and refitted
    with it on every gain direction; the best is claimed on its dBIC against the final model's effects refitted from
    the pair's gains without it (here better on the training halves than the final model), then the backward test."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # held-out chi2 by the effects fitted
        def __init__(self, chi2):
            self.chi2, self.calls = chi2, []

        def fit(self, effects, x0, free, max_iterations=2, space=None, on=None):
            names = tuple(e.name for e in effects)
            self.calls.append((names, np.asarray(x0, float).tolist()))
            return Fit(names, np.asarray(x0, float), self.chi2[names] - 100.0, self.chi2[names], {}, outputs=[])

    layout = GainLayout(("kp.sacrospinalis", "kv.sacrospinalis"))
    candidates = (effect("slow_activation"), effect("reflex_delay"), effect("upper_body_mass"))
    screen = SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))])
    final = Fit(("slow_activation",), np.array([0.1, 0.2, 2.8]), 1300.0, 1400.0, {}, outputs=[])
    own = {"reflex_delay": np.array([0.029]), "upper_body_mass": np.array([1.2])}
    chi2 = {("slow_activation", "reflex_delay"): 1000.0, ("slow_activation", "upper_body_mass"): 1395.0,
            ("slow_activation",): 1380.0, ("reflex_delay",): 1500.0}
    fitter, steps = Fitter(chi2), []
    search = _Search(SearchSpace(TrunkOptions(), layout, np.eye(2)), screen, fitter, candidates, Settings(), np.zeros((2, 0)), None)
    search.all_gains = True
    model = search.partners(final, own, steps.append)
    assert model.effects == ("slow_activation", "reflex_delay")
    assert fitter.calls[0] == (("slow_activation", "reflex_delay"), [0.1, 0.2, 2.8, 0.029])  # at the single's own fit
    assert (("slow_activation", "upper_body_mass"), [0.1, 0.2, 2.8, 1.2]) in fitter.calls
    assert [s["action"] for s in steps] == ["add", "keep"] and steps[0]["partner_of"] == ["slow_activation"]
    assert steps[0]["delta_bic"] == pytest.approx(380.0 - search.penalty)  # against the refit without it (1380), not 1400
    assert steps[0]["tried"]["upper_body_mass"] == pytest.approx(5.0 - search.penalty)
    assert steps[1]["own_delta_bic"]["slow_activation"] == pytest.approx(500.0 - search.penalty)
    # no partner passes against the refit without it: that refit is the model (better on the training halves)
    fitter, steps = Fitter({**chi2, ("slow_activation", "reflex_delay"): 1375.0}), []
    search = _Search(search.space, screen, fitter, candidates, Settings(), np.zeros((2, 0)), None)
    search.all_gains = True
    model = search.partners(final, own, steps.append)
    assert model.effects == ("slow_activation",) and model.heldout_chi2 == 1380.0
    assert [s["action"] for s in steps] == ["partners"] and steps[0]["best"] == "reflex_delay"


def test_every_effect_that_passed_the_first_step_is_a_partner_candidate_refined_or_only_checked():
    """`_Search.first_passed`: a partner candidate is an effect outside the final model that passed alone in the
    first step, at its refit where it was refined and at its checked point where it was only checked (the check
    simulates more candidates than are refined), at most `refine` of them, the strongest first; effects that failed,
    or were never checked, are not."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    names = ("reflex_delay", "slow_activation", "muscle_strength", "trunk_in_space", "upper_body_mass", "golgi_feedback",
             "seat_compliance", "stiffening_discs", "extra_damping")
    screen = SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))])
    search = _Search(SearchSpace(TrunkOptions(), GainLayout(("kp.sacrospinalis",)), np.eye(1)), screen, FakeFitter(),
                     [effect(n) for n in names], Settings(), np.zeros((1, 0)), None)
    ranking = [
        {"effect": "reflex_delay", "status": "refined", "delta_bic": 132103.0, "checked_delta_bic": 130993.0,
         "values": {"delay": 0.028}, "checked_values": {"delay": 0.0278}},  # in the final model
        {"effect": "slow_activation", "status": "refined", "delta_bic": 106814.0, "checked_delta_bic": 84359.0,
         "values": {"scale": 1.68}, "checked_values": {"scale": 1.38}},
        {"effect": "muscle_strength", "status": "refined", "delta_bic": 5.0, "checked_delta_bic": 44642.0,
         "values": {"scale": 0.79}, "checked_values": {"scale": 0.83}},  # failed once refined
        {"effect": "trunk_in_space", "status": "screened", "checked_delta_bic": 28495.0,
         "checked_values": {"gain": 0.05, "delay": 0.12}},  # passed its check, not refined
        {"effect": "upper_body_mass", "status": "screened", "checked_delta_bic": 27608.0, "checked_values": {"scale": 1.18}},
        {"effect": "stiffening_discs", "status": "screened", "checked_delta_bic": -3.0, "checked_values": {"cubic": 50.0}},
        {"effect": "extra_damping", "status": "screened", "checked_delta_bic": 2000.0, "checked_values": {"damping": 4.0}},
        {"effect": "golgi_feedback", "status": "failed: the refitted model diverged in simulation", "checked_delta_bic": 2750.0,
         "checked_values": {"gain": 0.05}},
        {"effect": "seat_compliance", "status": "screened", "linear_delta_bic": 50252.0},  # never checked
    ]
    final = Fit(("reflex_delay",), np.array([0.1, 0.028]), 1300.0, 1400.0, {}, outputs=[])
    own = search.first_passed(ranking, final)
    assert list(own) == ["slow_activation", "trunk_in_space", "upper_body_mass"]  # extra damping passed, fourth
    assert own["slow_activation"] == pytest.approx([1.68]) and own["trunk_in_space"] == pytest.approx([0.05, 0.12])
    assert list(search.first_passed(ranking[:4], final)) == ["slow_activation", "trunk_in_space"]


def test_the_effects_chosen_are_refitted_from_the_nominal_gains_and_kept_where_that_fits_better():
    """`_Search.restart`: gains and effects trade off, and a refit can stop in another basin than the truth's; the final
    effects are refitted from the nominal gains (x = 0 along every gain direction, the effects where the final had
    them), kept where that fits the training halves better by more than the threshold, and each must then keep its
    place; otherwise the final stays."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.report import _step
    from trunk_drake.gap.search import Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # fits stay where they start; the pair fits best from the nominal gains
        def __init__(self, basin):
            self.basin, self.calls = basin, []

        def fit(self, effects, x0, free, max_iterations=2, space=None, on=None):
            names, x = tuple(e.name for e in effects), np.asarray(x0, float)
            self.calls.append((names, x.tolist()))
            chi2 = {("slow_activation", "reflex_delay"): self.basin + 1e3 * float(np.sum(x[:2] ** 2)),
                    ("slow_activation",): 1400.0, ("reflex_delay",): 1500.0}[names]
            return Fit(names, x, chi2 - 100.0, chi2, {n: {"value": v} for n, v in zip(names, x[2:])}, outputs=[])

    layout = GainLayout(("kp.sacrospinalis", "kv.sacrospinalis"))
    candidates = (effect("slow_activation"), effect("reflex_delay"))
    screen = SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))])
    final = Fit(("slow_activation", "reflex_delay"), np.array([0.3, -0.4, 2.45, 0.0355]), 1150.0, 1250.0, {}, outputs=[])

    def restarted(basin):
        fitter, steps = Fitter(basin), []
        search = _Search(SearchSpace(TrunkOptions(), layout, np.eye(2)), screen, fitter, candidates, Settings(),
                         np.zeros((2, 0)), None)
        search.all_gains = True
        return search.restart(final, steps.append), steps, fitter

    model, steps, fitter = restarted(1000.0)
    assert fitter.calls[0] == (("slow_activation", "reflex_delay"), [0.0, 0.0, 2.45, 0.0355])
    assert model.x.tolist() == [0.0, 0.0, 2.45, 0.0355] and model.heldout_chi2 == 1000.0
    assert [s["action"] for s in steps] == ["restart", "keep"] and steps[0]["train_chi2"] == [1150.0, 900.0]
    assert "from the nominal gains fit the training halves better (1150 -> 900)" in _step(steps[0])  # the report's line
    model, steps, _ = restarted(1245.0)  # from the nominal gains 1145 on the training halves: not better by 10
    assert model is final and steps == []


def test_a_partner_refit_that_stops_short_is_overtaken_by_the_profile_over_its_parameter():
    """`_Search.profile`: besides the free refit from the partner's own first-step fit, the partner is held at 1/4 and
    3/4 of its range while the rest is refitted; the pair is freed from the held point that fits best."""
    from types import SimpleNamespace

    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.search import START_FRACTIONS, Settings, _Search
    from trunk_drake.gap.space import Fit, SearchSpace
    from trunk_drake.optim.gains import GainLayout

    class Fitter(FakeFitter):  # fits stay where they start; the pair's chi2 has its minimum at a 40 ms delay
        calls = []

        def fit(self, effects, x0, free, max_iterations=2, space=None, on=None):
            names, x = tuple(e.name for e in effects), np.asarray(x0, float)
            self.calls.append((names, x.tolist(), list(free)))
            chi2 = 1000.0 + 1e6 * (x[-1] - 0.04) ** 2 if names == ("slow_activation", "reflex_delay") else 1400.0
            return Fit(names, x, chi2 - 100.0, chi2, {n: {"value": v} for n, v in zip(names, x[2:])}, outputs=[])

    layout = GainLayout(("kp.sacrospinalis", "kv.sacrospinalis"))
    candidates = (effect("slow_activation"), effect("reflex_delay"))
    screen = SimpleNamespace(trials=[SimpleNamespace(steady_outputs=np.zeros((1000, 1)))])
    search = _Search(SearchSpace(TrunkOptions(), layout, np.eye(2)), screen, Fitter(), candidates, Settings(),
                     np.zeros((2, 0)), None)
    search.all_gains = True
    final = Fit(("slow_activation",), np.array([0.1, 0.2, 2.8]), 1300.0, 1400.0, {}, outputs=[])
    fits = search.profile(final, {"reflex_delay": np.array([0.0288])})
    delay = effect("reflex_delay").parameters[0]
    held = [delay.lower + f * (delay.upper - delay.lower) for f in START_FRACTIONS]  # 37.5 and 92.5 ms
    calls = search.fitter.calls
    assert (("slow_activation", "reflex_delay"), [0.1, 0.2, 2.8, 0.0288], [0, 1, 2, 3]) in calls  # free, own fit
    for value in held:  # held: every coordinate but the delay free
        assert (("slow_activation", "reflex_delay"), [0.1, 0.2, 2.8, value], [0, 1, 2]) in calls
    assert calls[-1] == (("slow_activation", "reflex_delay"), [0.1, 0.2, 2.8, held[0]], [0, 1, 2, 3])  # freed from 37.5
    assert fits["reflex_delay"].x[-1] == pytest.approx(held[0])
    assert fits["reflex_delay"].heldout_chi2 == pytest.approx(1000.0 + 1e6 * 0.0025 ** 2)


def test_a_simulation_log_gives_back_what_was_simulated_and_survives_a_record_cut_short(tmp_path):
    """`TimeDomainFitter` with a `SimulationLog`: what it simulates is written to the log; a new fitter on the same log
    (the rerun of an interrupted diagnosis) takes those results, exactly, instead of simulating them, and counts them
    as simulations (replayed). A record cut short by the interruption is dropped and overwritten; a log of another
    diagnosis is started afresh."""
    from trunk_drake.gap.catalogue import effect
    from trunk_drake.gap.checkpoint import SimulationLog
    from trunk_drake.gap.refit import TimeDomainFitter
    from trunk_drake.gap.space import SearchSpace

    model = td.load_model("rhythm")

    class Pool:  # every run gives outputs no other run gives, and its steps
        capacity = 1

        def __init__(self):
            self.model, self.jobs = model, []

        def map(self, fn, jobs):
            self.jobs += jobs
            return [(np.full((4, 1), np.random.default_rng().normal()), None, np.linspace(0.0, 1.0, 5)) for _ in jobs]

    space = SearchSpace.around(model, nominal_options())
    space = SearchSpace(space.options, space.layout, np.eye(len(space.layout.names))[:, :2])
    delay = effect("reflex_delay")
    points = [(np.array([0.0, 0.1, 0.05]), (delay,)), (np.array([0.1, 0.0]), ()), (np.array([0.0, 0.2]), ())]
    path = tmp_path / "simulations.pickle"

    def run(log, chosen):
        pool, counter = Pool(), {"simulations": 0}
        fitter = TimeDomainFitter(pool, space, [None] * 3, None, (), counter, log)
        out = fitter.outputs_of([points[i][0] for i in chosen], [points[i][1] for i in chosen])
        return out, pool, counter

    start = time.perf_counter()
    with SimulationLog(path, "a") as log:
        assert log.earlier_wall_s == 0.0
        first, pool, _ = run(log, [0, 1])
    first_run = time.perf_counter() - start
    assert len(pool.jobs) == 6
    with path.open("ab") as f:
        f.write(b"\x80\x05\x95 cut short")
    time.sleep(first_run + 0.5)  # between the runs: not counted
    start = time.perf_counter()
    with SimulationLog(path, "a") as log:
        assert len(log.entries) == 2 and log.fresh_because is None
        assert 0.0 < log.earlier_wall_s <= first_run  # the first run's time, up to its last record
        again, pool, counter = run(log, [0, 1, 2])
    assert len(pool.jobs) == 3  # only the new point, on each trial
    for a, b in zip(first, again[:2]):
        for x, y in zip(a, b):
            np.testing.assert_array_equal(x, y)
    assert counter == {"simulations": 9, "replayed": 6}
    second_run = time.perf_counter() - start
    resumed = SimulationLog(path, "a")
    assert len(resumed.entries) == 3  # the cut record is gone, the new one readable
    assert log.earlier_wall_s < resumed.earlier_wall_s <= log.earlier_wall_s + second_run  # the runs' times summed
    other = SimulationLog(path, "b")
    assert not other.entries and "another diagnosis" in other.fresh_because
    other.add({"k": (None, None)})
    other.close()
    assert not SimulationLog(path, "a").entries  # the other diagnosis' log replaced it


def test_a_diagnosis_says_its_steps_on_stdout_or_in_a_file(tmp_path, capsys):
    """`diagnose_gap(progress=...)`: nothing, stdout, or a file a benchmark case appends to (to follow with tail -f)."""
    from trunk_drake.gap.diagnose import progress_lines

    assert progress_lines(False, lambda: "[0 s]") is None
    progress_lines(True, lambda: "[1 s]")("screened")
    assert capsys.readouterr().out == "[1 s] screened\n"
    log = tmp_path / "cases" / "no_effect_0" / "progress.log"
    say = progress_lines(log, lambda: "[2 s]")
    say("refitted")
    say("added")
    assert log.read_text() == "[2 s] refitted\n[2 s] added\n"


def test_an_effects_coordinates_invert_its_values():
    """`Effect.coordinates` (physical values -> fitted coordinates, log10 where the catalogue says so) inverts
    `Effect.values` for every candidate, at its start and at its bounds."""
    for e in CATALOGUE:
        for x in ([p.start for p in e.parameters], [p.lower for p in e.parameters], [p.upper for p in e.parameters]):
            np.testing.assert_allclose(e.coordinates(e.values(x)), x, rtol=1e-12, atol=1e-12, err_msg=e.name)


def test_the_report_shows_the_ranking_that_decided_the_selection_beside_the_first_steps(tmp_path, monkeypatch):
    """Where the first step's leaders stood in for mis-set gains and the truth was claimed later (on every gain
    direction), the report shows that step's ranking too, and its plot draws it: the claimed effect leads it."""
    from types import SimpleNamespace

    from trunk_drake.gap.report import _plot_ranking, markdown

    first = [{"effect": "short_range_stiffness", "delta_bic": 7783.1, "linear_delta_bic": 6980.4, "status": "refined"},
             {"effect": "golgi_feedback", "linear_delta_bic": 6708.6, "status": "screened"}]
    later = [{"effect": "golgi_feedback", "delta_bic": 44.9, "checked_delta_bic": 30.2, "linear_delta_bic": 2.1,
              "values": {"gain": 0.105}, "status": "refined"},
             {"effect": "short_range_stiffness", "checked_delta_bic": -120.0, "linear_delta_bic": 1.0, "status": "screened"}]
    steps = [{"action": "stop", "model": [], "best_candidate": "short_range_stiffness", "delta_bic": 7783.1, "matched_by_gains": []},
             {"action": "polish", "directions": 14, "model": [], "values": {}},
             {"action": "add", "effect": "golgi_feedback", "delta_bic": 44.9, "beats_gain_rival_by": None, "model": ["golgi_feedback"],
              "values": {"golgi_feedback": {"gain": 0.105}}, "directions": 14, "ranking": later}]
    d = SimpleNamespace(verdict="missing effect: golgi_feedback", noise_rad=[0.0017], where={"per_output": {}, "per_frequency": {}},
                        options={"held_out": "halves", "scores": {"simulations": 10}, "threshold": 10.0}, wall_time_s=1.0,
                        ranking=first, steps=steps, selected=["golgi_feedback"], shrink={}, remainder={}, final={})
    text = markdown(d, {"frf_plot": "f.png", "ranking_plot": "r.png"})
    assert "step 3 (claimed golgi_feedback): each candidate added to the gains on all 14 gain directions" in text
    decided = text.split("The ranking that decided the selection")[1]
    assert decided.index("| 1 | golgi_feedback | 44.9 | 30.2 | 2.1 | gain = 0.105 |") < decided.index("| 2 | short_range_stiffness | - | -120.0 |")
    assert "| 2 | golgi_feedback | - | - | 6708.6 |" in text  # the first step's ranking stays
    import matplotlib.pyplot as plt

    drawn, barh = [], plt.Axes.barh
    monkeypatch.setattr(plt.Axes, "barh", lambda ax, names, *args, **kwargs: drawn.append(list(names)) or barh(ax, names, *args, **kwargs))
    _plot_ranking(d, tmp_path / "r.png")
    assert drawn == [["short_range_stiffness", "golgi_feedback"]]  # bottom to top: the claimed effect on top
