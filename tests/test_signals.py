"""Tests for trunk_drake.signals: multisine, filters, resampling, metrics, FRF, averaging."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from trunk_drake.signals import (
    average_hierarchical,
    average_repetitions,
    average_subjects,
    average_trials,
    butterworth_response,
    estimate_frf,
    lowpass_filtfilt,
    make_multisine,
    remove_offset,
    resample_pchip,
    resample_uniform,
    rms_error,
    split_repetitions,
    uniform_grid,
    vaf,
)

# ----------------------------------------------------------------------------- multisine


def test_default_multisine_design():
    ms = make_multisine(seed=0)
    assert ms.period == 20.0
    np.testing.assert_array_equal(ms.harmonics, np.arange(4, 21))  # 0.2..1.0 Hz on 0.05 Hz
    np.testing.assert_allclose(ms.frequencies, np.arange(4, 21) / 20.0)
    assert ms.rms == pytest.approx(0.01, rel=1e-12)
    assert ms.duration == pytest.approx(2 + 20 + 2)
    assert ms.steady_window == (2.0, 22.0)
    # flat displacement spectrum: all lines equal
    np.testing.assert_allclose(ms.amplitudes, ms.amplitudes[0])


@pytest.mark.parametrize(
    "lines, expected",
    [("all", np.arange(4, 21)), ("odd", np.arange(5, 21, 2)), ("even", np.arange(4, 21, 2)),
     (3, np.arange(4, 21, 3))],
)
def test_line_selection(lines, expected):
    ms = make_multisine(seed=0, lines=lines)
    np.testing.assert_array_equal(ms.harmonics, expected)
    ne = ms.nonexcited_harmonics()
    assert set(ne).isdisjoint(ms.harmonics)
    assert set(ne) | set(ms.harmonics) == set(range(ms.harmonics[0], ms.harmonics[-1] + 1))


def test_multisine_bad_band():
    with pytest.raises(ValueError, match="no line"):
        make_multisine(f_min=0.21, f_max=0.24)  # between 0.2 and 0.25 Hz grid lines
    with pytest.raises(ValueError, match="f_min"):
        make_multisine(f_min=2.0, f_max=1.0)


@pytest.mark.parametrize(
    "kw",
    [dict(), dict(fade_shape="quintic"), dict(lowpass_hz=2.0, f_max=3.0), dict(f_max=10.0, spectrum="velocity")],
)
def test_analytic_derivatives_match_numerical(kw):
    ms = make_multisine(seed=7, n_periods=2, **kw)
    rng = np.random.default_rng(1)
    t = rng.uniform(-1.0, ms.duration + 1.0, 400)
    # keep away from the window break points, where the raised-cosine acceleration jumps
    brk = np.array([0.0, ms.fade_in, ms.steady_window[1], ms.duration])
    t = t[np.min(np.abs(t[:, None] - brk[None]), axis=1) > 1e-3]
    h = 1e-5
    x, v, a = ms.evaluate(t)
    xp, vp, _ = ms.evaluate(t + h)
    xm, vm, _ = ms.evaluate(t - h)
    v_num = (xp - xm) / (2 * h)
    a_num = (vp - vm) / (2 * h)
    assert np.max(np.abs(v_num - v)) < 1e-6 * np.max(np.abs(v))
    assert np.max(np.abs(a_num - a)) < 1e-6 * np.max(np.abs(a))
    # scalar evaluation agrees with array evaluation
    for ti in t[:20]:
        np.testing.assert_allclose(ms.evaluate(float(ti)), (ms.position(ti), ms.velocity(ti), ms.acceleration(ti)))
        np.testing.assert_allclose(ms.evaluate(float(ti)), np.array(ms.evaluate(np.array([ti])))[:, 0], atol=1e-15)


def test_acceleration_matches_second_difference_of_position():
    ms = make_multisine(seed=3)
    t = np.linspace(3.0, 21.0, 50)
    h = 1e-4
    a_num = (ms.position(t + h) - 2 * ms.position(t) + ms.position(t - h)) / h**2
    np.testing.assert_allclose(a_num, ms.acceleration(t), atol=1e-5 * np.max(np.abs(ms.acceleration(t))))


def test_power_only_at_excited_lines():
    ms = make_multisine(seed=11, lines="odd", f_max=3.0, n_periods=2)
    fs = 40.0
    t, x, _, _ = ms.sample(fs)
    sl = ms.steady_slice(t)
    seg = x[sl]
    p = int(ms.period * fs)
    assert seg.size == 2 * p
    X = np.fft.rfft(seg[:p]) * 2 / p
    power = np.abs(X) ** 2 / 2
    excited = np.zeros(power.size, bool)
    excited[ms.harmonics] = True
    assert np.min(power[excited]) > 1e-3 * np.max(power)
    assert np.max(power[~excited]) < 1e-24 * np.sum(power[excited])
    # line amplitudes and phases equal the design
    np.testing.assert_allclose(np.abs(X[ms.harmonics]), ms.amplitudes, rtol=1e-10)
    # sin(w t + phi) has DFT phase phi - pi/2
    np.testing.assert_allclose(
        np.angle(X[ms.harmonics] * np.exp(-1j * (ms.phases - np.pi / 2))), 0, atol=1e-9
    )
    # both periods identical (periodicity of the steady part)
    np.testing.assert_allclose(seg[:p], seg[p:], atol=1e-14)


def test_seed_reproducibility():
    a = make_multisine(seed=42)
    b = make_multisine(seed=42)
    c = make_multisine(seed=43)
    np.testing.assert_array_equal(a.phases, b.phases)
    assert not np.allclose(a.phases, c.phases)
    d = make_multisine(rng=np.random.default_rng(42))
    np.testing.assert_array_equal(a.phases, d.phases)
    t = np.linspace(0, a.duration, 333)
    np.testing.assert_array_equal(a.position(t), b.position(t))


def test_fade_in_starts_at_zero_and_fade_out_ends_at_zero():
    for shape in ("raised_cosine", "quintic"):
        ms = make_multisine(seed=5, fade_shape=shape)
        x0, v0, a0 = ms.evaluate(0.0)
        assert x0 == 0.0 and v0 == 0.0
        x1, v1, _ = ms.evaluate(ms.duration)
        assert abs(x1) < 1e-15 and abs(v1) < 1e-15
        assert ms.evaluate(-0.5) == (0.0, 0.0, 0.0)
        assert ms.evaluate(ms.duration + 0.5) == (0.0, 0.0, 0.0)
        # continuous position/velocity at the end of the fade-in
        e = 1e-9
        np.testing.assert_allclose(ms.evaluate(ms.fade_in - e)[:2], ms.evaluate(ms.fade_in + e)[:2], atol=1e-7)
        # window is monotone from 0 to 1 during the fade-in
        w = ms.window(np.linspace(0, ms.fade_in, 101))[0]
        assert w[0] == 0 and abs(w[-1] - 1) < 1e-12 and np.all(np.diff(w) >= 0)
        if shape == "quintic":
            assert a0 == 0.0  # C2 window: no acceleration jump at t=0
        else:
            s0 = ms.periodic(0.0)
            assert a0 == pytest.approx(0.5 * (np.pi / ms.fade_in) ** 2 * s0, rel=1e-12)


def test_peak_amplitude_and_schroeder():
    ms = make_multisine(seed=2, amplitude=0.05, amplitude_kind="peak")
    t = np.linspace(0, ms.duration, 200001)
    peak = np.max(np.abs(ms.position(t)))
    assert peak <= 0.05 * (1 + 1e-9)
    assert peak == pytest.approx(0.05, rel=1e-4)
    assert ms.peak == pytest.approx(0.05, rel=1e-9)
    sch = make_multisine(phases="schroeder")
    rnd = [make_multisine(seed=s).crest_factor for s in range(5)]
    assert sch.crest_factor < 2.0 < min(rnd)


def test_lowpass_is_applied_per_line():
    plain = make_multisine(seed=9, f_max=3.0)
    filt = make_multisine(seed=9, f_max=3.0, lowpass_hz=2.0, lowpass_order=2)
    g = butterworth_response(plain.frequencies, 2.0, 2)
    ratio = filt.amplitudes / plain.amplitudes
    np.testing.assert_allclose(ratio / ratio[0], np.abs(g) / np.abs(g[0]), rtol=1e-12)
    dphi = np.angle(np.exp(1j * (filt.phases - plain.phases - np.angle(g))))
    np.testing.assert_allclose(dphi, 0, atol=1e-12)
    assert abs(g[np.argmin(np.abs(plain.frequencies - 2.0))]) == pytest.approx(2**-0.5, rel=1e-12)
    zp = make_multisine(seed=9, f_max=3.0, lowpass_hz=2.0, lowpass_zero_phase=True)
    np.testing.assert_allclose(zp.phases, plain.phases, atol=1e-12)


# ----------------------------------------------------------------------------- filters / offset


def test_lowpass_filtfilt_zero_phase():
    fs = 200.0
    t = np.arange(0, 20, 1 / fs)
    slow = np.sin(2 * np.pi * 0.5 * t)
    fast = 0.3 * np.sin(2 * np.pi * 20 * t)
    y = lowpass_filtfilt(slow + fast, fs, 2.0, order=2)
    core = slice(400, -400)
    assert np.max(np.abs(y[core] - slow[core])) < 5e-3
    with pytest.raises(ValueError, match="cutoff_hz"):
        lowpass_filtfilt(slow, fs, 150.0)
    bad = slow.copy()
    bad[10] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        lowpass_filtfilt(bad, fs, 2.0)


def test_remove_offset():
    x = np.array([[2.0, -1.0], [3.0, 0.0], [4.0, 2.0]])
    np.testing.assert_array_equal(remove_offset(x), [[0, 0], [1, 1], [2, 3]])
    np.testing.assert_allclose(remove_offset(x, 2), [[-0.5, -0.5], [0.5, 0.5], [1.5, 2.5]])
    np.testing.assert_allclose(remove_offset(x[:, 0], mode="mean"), [-1, 0, 1])
    with pytest.raises(ValueError):
        remove_offset(x, 5)


# ----------------------------------------------------------------------------- resampling


def test_resample_pchip_variable_step():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.001, 0.02, 500))
    y = np.column_stack([3 * t - 1, np.sin(t)])
    grid = uniform_grid(t[0], t[-1], 100.0)
    out = resample_pchip(t, y, grid)
    np.testing.assert_allclose(out[:, 0], 3 * grid - 1, rtol=1e-12, atol=1e-12)  # linear exact
    assert np.max(np.abs(out[:, 1] - np.sin(grid))) < 1e-4
    # shape preserving: a step does not overshoot
    ts = np.arange(10.0)
    ys = (ts >= 5).astype(float)
    fine = np.linspace(0, 9, 1000)
    r = resample_pchip(ts, ys, fine)
    assert r.min() >= 0 and r.max() <= 1
    tg, yg = resample_uniform(t, y, 50.0)
    assert tg[0] == t[0] and tg[-1] <= t[-1] and yg.shape == (tg.size, 2)


def test_resample_errors():
    t = np.array([0.0, 0.1, 0.2, 0.15, 0.3])
    with pytest.raises(ValueError, match="strictly increasing.*index 3"):
        resample_pchip(t, np.ones(5), [0.1])
    t2 = np.array([0.0, 0.1, 0.1, 0.2])
    with pytest.raises(ValueError, match="drop_duplicates"):
        resample_pchip(t2, np.arange(4.0), [0.05])
    np.testing.assert_allclose(resample_pchip(t2, [0, 1, 2, 3.0], [0.1], drop_duplicates=True), [2.0])
    with pytest.raises(ValueError, match="NaN.*index"):
        resample_pchip([0, 1, 2.0], [0, np.nan, 1], [0.5])
    with pytest.raises(ValueError, match="extrapolate"):
        resample_pchip([0, 1, 2.0], [0, 1, 1.0], [2.5])
    with pytest.raises(ValueError, match="equal length"):
        resample_pchip([0, 1, 2.0], [0, 1.0], [0.5])


# ----------------------------------------------------------------------------- metrics


def test_vaf_known_values():
    rng = np.random.default_rng(3)
    y = rng.normal(size=200)
    assert vaf(y, y) == 1.0
    assert vaf(y, np.zeros_like(y)) == 0.0
    assert vaf([1.0, 2.0, 3.0], [1.0, 2.0, 2.0]) == pytest.approx(1 - 1 / 14)
    assert vaf([1.0, -1.0], [-1.0, 1.0]) == pytest.approx(-3.0)
    # per column on 2-D input
    Y = np.column_stack([y, 2 * y])
    np.testing.assert_allclose(vaf(Y, np.column_stack([y, y])), [1.0, 0.75])
    # offset removal (thesis: signals start at 0 before VAF)
    assert vaf(y + 10, y + 3, offset="start") == pytest.approx(1.0)
    assert vaf(y + 10, y + 3) < 0.9
    assert rms_error([1.0, 2.0, 3.0], [1.0, 2.0, 2.0]) == pytest.approx(np.sqrt(1 / 3))
    with pytest.raises(ValueError, match="shape"):
        vaf([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="undefined"):
        vaf([0.0, 0.0], [1.0, 1.0])


# ----------------------------------------------------------------------------- FRF

WN = 2 * np.pi * 1.0  # natural frequency 1 Hz
ZETA = 0.3


def _h_true(f):
    """Relative displacement of a base-excited mass-spring-damper per base displacement."""
    s = 2j * np.pi * np.asarray(f)
    return -(s**2) / (s**2 + 2 * ZETA * WN * s + WN**2)


@pytest.fixture(scope="module")
def msd_simulation():
    """Integrate y'' + 2 zeta wn y' + wn^2 y = -a_platform(t) with the analytic multisine
    acceleration (as a Drake LeafSystem would), from rest, over fade-in + 4 periods."""
    ms = make_multisine(seed=3, f_max=3.0, n_periods=4)
    fs = 50.0
    tg = ms.time_grid(fs)

    def rhs(t, s):
        return [s[1], -2 * ZETA * WN * s[1] - WN**2 * s[0] - ms.evaluate(t)[2]]

    sol = solve_ivp(rhs, (0.0, ms.duration), [0.0, 0.0], method="DOP853", rtol=1e-10,
                    atol=1e-12, t_eval=tg, max_step=0.05)
    assert sol.success
    return ms, fs, tg, ms.position(tg), sol.y[0]


def test_frf_recovers_second_order_system(msd_simulation):
    ms, fs, t, u, y = msd_simulation
    sl = ms.steady_slice(t, skip_periods=1)  # drop the fade-in transient and first period
    r = estimate_frf(u[sl], y[sl], fs, excited=ms, n_adjacent=1)
    assert r.n_segments == 3
    np.testing.assert_allclose(r.frequencies, ms.frequencies)
    ht = _h_true(r.frequencies)
    gain_err = np.max(np.abs(r.gain / np.abs(ht) - 1))
    phase_err = np.degrees(np.max(np.abs(np.angle(r.H / ht))))
    assert gain_err < 0.01
    assert phase_err < 1.0
    assert np.all(r.coherence > 0.999999)
    # the resonance is where it should be
    assert r.frequencies[np.argmax(r.gain)] == pytest.approx(1.0 / np.sqrt(1 - 2 * ZETA**2), abs=0.1)
    # thesis-style averaging over two adjacent lines: equals the power-weighted mean of H
    r2 = estimate_frf(u[sl], y[sl], fs, excited=ms, n_adjacent=2)
    assert r2.frequencies.size == int(np.ceil(ms.harmonics.size / 2))
    for k, grp in enumerate(r2.group_harmonics):
        idx = np.searchsorted(ms.harmonics, grp)
        w = ms.amplitudes[idx] ** 2
        h_mean = np.sum(w * _h_true(np.array(grp) / ms.period)) / np.sum(w)
        assert abs(r2.H[k] / h_mean - 1) < 1e-6
    assert np.all(r2.n_averages[:-1] == 6)


def test_frf_multiple_outputs_and_detection(msd_simulation):
    ms, fs, t, u, y = msd_simulation
    sl = ms.steady_slice(t, skip_periods=1)
    Y = np.column_stack([y[sl], -0.5 * u[sl]])
    r = estimate_frf(u[sl], Y, fs, period=ms.period, n_adjacent=1, output_names=["theta", "neg_half"])
    # excitation detected from the input spectrum equals the design
    np.testing.assert_allclose(r.frequencies, ms.frequencies)
    assert r.H.shape == (ms.harmonics.size, 2)
    np.testing.assert_allclose(r.gain[:, 1], 0.5, rtol=1e-9)
    np.testing.assert_allclose(np.cos(r.phase[:, 1]), -1.0, atol=1e-9)
    np.testing.assert_allclose(r.H[:, 0], _h_true(r.frequencies), rtol=1e-6)
    assert r.output_names == ("theta", "neg_half")
    # band selection
    rb = estimate_frf(u[sl], y[sl], fs, excited=ms, band=(0.5, 1.0), n_adjacent=1)
    assert rb.frequencies.min() >= 0.5 and rb.frequencies.max() <= 1.0


def _periodic_response(ms, t, h_fun):
    """Exact steady-state response of a linear system to the periodic part of ms."""
    tau = t - ms.fade_in
    hv = h_fun(ms.frequencies)
    return np.sin(np.multiply.outer(tau, 2 * np.pi * ms.frequencies) + ms.phases + np.angle(hv)) @ (
        ms.amplitudes * np.abs(hv)
    )


def test_frf_noise_coherence_and_bounds():
    ms = make_multisine(seed=21, f_max=3.0, n_periods=6, fade_in=0, fade_out=0)
    fs = 25.0
    t = np.arange(int(6 * ms.period * fs)) / fs
    u = ms.periodic(t)
    y0 = _periodic_response(ms, t, _h_true)
    rng = np.random.default_rng(1234)
    noise = 0.5 * np.std(y0) * rng.normal(size=t.size)
    res = {}
    for method in ("coherence", "segments"):
        r = estimate_frf(u, y0 + noise, fs, excited=ms, n_adjacent=2, bounds=method)
        assert np.all(r.coherence < 1.0) and np.all(r.coherence > 0.0)
        ht = np.array([np.mean(_h_true(np.array(g) / ms.period)) for g in r.group_harmonics])
        inside_gain = (np.abs(ht) >= r.gain_lower) & (np.abs(ht) <= r.gain_upper)
        dphi = np.angle(ht / r.H)
        inside_phase = (r.phase + dphi >= r.phase_lower) & (r.phase + dphi <= r.phase_upper)
        assert inside_gain.mean() >= 0.8, (method, inside_gain.mean())
        assert inside_phase.mean() >= 0.8, (method, inside_phase.mean())
        assert np.all(r.gain_upper > r.gain) and np.all(r.gain_lower < r.gain)
        res[method] = r
    # noise estimate from the spread across periods is of the right size
    r = res["coherence"]
    assert r.noise_power_excited > 0
    # more noise -> lower coherence and wider bounds
    r_more = estimate_frf(u, y0 + 3 * noise, fs, excited=ms, n_adjacent=2)
    assert np.mean(r_more.coherence) < np.mean(r.coherence)
    assert np.mean(r_more.gain_upper - r_more.gain_lower) > np.mean(r.gain_upper - r.gain_lower)
    # noise-free, no pooling of lines: coherence 1, bounds collapse onto the estimate
    r_clean = estimate_frf(u, y0, fs, excited=ms, n_adjacent=1)
    np.testing.assert_allclose(r_clean.coherence, 1.0, atol=1e-9)
    np.testing.assert_allclose(r_clean.gain_upper, r_clean.gain, rtol=1e-6)
    # pooling two adjacent lines whose H differs (near resonance) lowers the coherence
    # even without noise (documented property of frequency averaging)
    r_pool = estimate_frf(u, y0, fs, excited=ms, n_adjacent=2)
    assert np.min(r_pool.coherence) < 0.999


def test_frf_nonexcited_lines_reveal_nonlinearity():
    ms = make_multisine(seed=4, lines="odd", f_max=2.0, n_periods=2, fade_in=0, fade_out=0)
    fs = 20.0
    t = np.arange(int(2 * ms.period * fs)) / fs
    u = ms.periodic(t)
    lin = estimate_frf(u, 2.0 * u, fs, excited=ms, n_adjacent=1)
    quad = estimate_frf(u, 2.0 * u + 30.0 * u**2, fs, excited=ms, n_adjacent=1)
    assert lin.nonexcited_frequencies.size > 0
    assert lin.nonexcited_ratio < 1e-20
    assert quad.nonexcited_ratio > 1e-3
    assert lin.input_nonexcited_ratio < 1e-20


def test_frf_errors():
    ms = make_multisine(seed=1, n_periods=2, fade_in=0, fade_out=0)
    fs = 10.0
    t = np.arange(int(2 * ms.period * fs)) / fs
    u = ms.periodic(t)
    with pytest.raises(ValueError, match="whole number"):
        estimate_frf(u[:-7], u[:-7], fs, excited=ms)
    with pytest.raises(ValueError, match="too short"):
        estimate_frf(u[:150], u[:150], fs, excited=ms)
    with pytest.raises(ValueError, match="not an integer"):
        estimate_frf(u, u, 10.03, excited=ms)
    with pytest.raises(ValueError, match="no excited line"):
        estimate_frf(u, u, fs, excited=ms, band=(2.0, 3.0))
    with pytest.raises(ValueError, match="not on the"):
        estimate_frf(u, u, fs, period=20.0, excited=[0.2, 0.2125])
    with pytest.raises(ValueError, match="Nyquist"):
        estimate_frf(u, u, fs, period=20.0, excited=[0.2, 6.0])
    with pytest.raises(ValueError, match="no power"):
        estimate_frf(u, u, fs, period=20.0, excited=[0.2, 1.5])
    with pytest.raises(ValueError, match="same length|samples"):
        estimate_frf(u, u[:-1], fs, excited=ms)
    bad = u.copy()
    bad[3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        estimate_frf(bad, u, fs, excited=ms)
    one = slice(0, int(ms.period * fs))
    with pytest.raises(ValueError, match="at least 2 periods"):
        estimate_frf(u[one], u[one], fs, excited=ms, bounds="segments")
    r = estimate_frf(u[one], u[one], fs, excited=ms, n_adjacent=1)
    assert np.all(np.isnan(r.gain_upper))  # one average: no bounds


# ----------------------------------------------------------------------------- averaging


def test_averaging_known_answers():
    p = np.sin(np.linspace(0, 2 * np.pi, 50, endpoint=False)) + 0.3
    trial = np.concatenate([p + 1.0, p - 1.0, p + 0.5, p - 0.5])
    reps = split_repetitions(trial, 50)
    assert reps.shape == (4, 50)
    np.testing.assert_allclose(average_repetitions(trial, 50), p)
    # start/n_repetitions select whole periods after a lead-in
    lead = np.concatenate([np.zeros(7), trial, np.zeros(3)])
    np.testing.assert_allclose(average_repetitions(lead, 50, start=7, n_repetitions=4), p)
    with pytest.raises(ValueError, match="n_repetitions"):
        average_repetitions(lead, 50)
    np.testing.assert_allclose(average_trials([p + 1, p - 1]), p)
    with pytest.raises(ValueError, match="shape"):
        average_trials([p, p[:-1]])
    # subjects with different neutral postures: offsets removed before averaging
    np.testing.assert_allclose(average_subjects([p + 5.0, 2 * p - 3.0]), 1.5 * (p - p[0]), atol=1e-12)
    # full hierarchy: 2 subjects x 2 trials x 3 repetitions, 2 channels
    P2 = np.column_stack([p, -p])
    subj = [
        [np.tile(P2, (3, 1)) + 4.0, np.tile(P2, (3, 1)) + 4.0],
        [np.tile(P2, (3, 1)) - 2.0, np.concatenate([P2 + 1, P2 - 1, P2]) - 2.0],
    ]
    res = average_hierarchical(subj, 50)
    np.testing.assert_allclose(res.mean, P2 - P2[0], atol=1e-12)
    np.testing.assert_allclose(res.std, 0, atol=1e-12)
    assert res.per_subject.shape == (2, 50, 2)
    assert res.n_repetitions == [[3, 3], [3, 3]]
    res_raw = average_hierarchical(subj, 50, remove_offset=False)
    np.testing.assert_allclose(res_raw.mean, P2 + 1.0, atol=1e-12)
    with pytest.raises(ValueError, match="subject 1, trial 0"):
        average_hierarchical([[np.tile(p, 3)], [np.tile(p, 3)[:-5]]], 50)


def test_sampled_signal_is_the_quintic_spline_for_floats_and_arrays():
    """A measured perturbation is evaluated by compiled code on the spline's piecewise-polynomial form (a
    simulation calls it at a float time every step): the same x, v, a as scipy's quintic interpolating spline,
    for floats and arrays alike, also at the ends; beyond them it holds the end value, at rest."""
    from scipy.interpolate import make_interp_spline

    from trunk_drake.signals.sampled import SampledSignal

    t = np.arange(0.0, 12.0 + 1e-9, 0.01)
    x = 0.01 * np.sin(2 * np.pi * t) + 0.004 * np.sin(2 * np.pi * 0.37 * t + 1.0)
    signal = SampledSignal(t, x)
    spline = make_interp_spline(t, x, k=5)
    times = np.concatenate([np.random.default_rng(3).uniform(0.0, 12.0, 500), [0.0, 0.01, 6.0, 11.99, 12.0]])
    expected = np.column_stack([spline(times), spline.derivative(1)(times), spline.derivative(2)(times)])
    arrays = np.column_stack(signal.evaluate(times))
    floats = np.array([signal.evaluate(float(s)) for s in times])
    np.testing.assert_allclose(arrays, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(floats, arrays, rtol=0, atol=1e-12)
    outside = np.array([-1.0, 13.0])
    np.testing.assert_array_equal(np.column_stack(signal.evaluate(outside)), [[x[0], 0.0, 0.0], [spline(12.0), 0.0, 0.0]])
    assert signal.evaluate(13.0) == (arrays[-1, 0], 0.0, 0.0)
    assert signal.evaluate(np.float64(6.0)) == signal.evaluate(6.0) and np.shape(signal.evaluate(np.zeros((2, 3)))[2]) == (2, 3)
