"""Measures of the gap: where it lies (per output, frequency, time window; linearity), the
chi-square of a segment, and how far it shrinks between model variants on held-out data."""

from __future__ import annotations

import numpy as np

from trunk_drake.gap.trials import half
from trunk_drake.signals import estimate_frf, vaf

WINDOW_S = 2.0  # time windows for "where" and for the bootstrap


def segment_chi2(y, model, noise, part: slice) -> float:
    """Chi-square of one segment, a constant offset per output fitted (removed)."""
    r = y[part] - model[part]
    r = r - r.mean(axis=0)
    return float(np.sum((r / noise) ** 2))


def locate_gap(trials, nominal, noise, outputs) -> dict:
    """Per output, per frequency, per time window; linearity (non-excited power, coherence)."""
    per_output = {}
    for j, out in enumerate(outputs):
        data = np.concatenate([t.steady_outputs[:, j] for t in trials])
        model = np.concatenate([n[:, j] for n in nominal])
        r = data - model
        per_output[out] = {"vaf": float(vaf(data, model)), "chi2_per_sample": float(np.mean(r**2) / noise[j] ** 2),
                           "rms_residual_deg": float(np.degrees(np.std(r)))}
    per_frequency, per_window = {}, {}
    for trial, nom in zip(trials, nominal):
        u, y = trial.platform[trial.steady], trial.steady_outputs
        fd = estimate_frf(u, y[:, 0], trial.fs, trial.period, n_adjacent=2)
        fm = estimate_frf(u, nom[:, 0], trial.fs, trial.period, n_adjacent=2)
        ratio = fm.H / fd.H
        sigma = np.maximum((fd.gain_upper - fd.gain_lower) / (2 * 1.96 * np.abs(fd.H)), 0.005)
        gain_err, phase_err = np.log(np.abs(ratio)), np.angle(ratio)
        per_frequency[trial.name] = {
            "frequencies_hz": fd.frequencies.tolist(), "gain_error_percent": (100 * (np.abs(ratio) - 1)).tolist(),
            "phase_error_deg": np.degrees(phase_err).tolist(), "sigma_percent": (100 * sigma).tolist(),
            "significant": ((np.abs(gain_err) > 2 * sigma) | (np.abs(phase_err) > 2 * sigma)).tolist(),
            "coherence": fd.coherence.tolist(), "data_gain": np.abs(fd.H).tolist(), "model_gain": np.abs(fm.H).tolist(),
            "data_phase_deg": np.degrees(np.unwrap(np.angle(fd.H))).tolist(),
            "model_phase_deg": np.degrees(np.unwrap(np.angle(fm.H))).tolist(),
            "nonexcited_ratio_data": _scalar(fd.nonexcited_ratio), "nonexcited_ratio_model": _scalar(fm.nonexcited_ratio),
        }
        n_win = int(round(WINDOW_S * trial.fs))
        r = y[:, 0] - nom[:, 0]
        chunks = [r[k:k + n_win] for k in range(0, r.size - n_win + 1, n_win)]
        per_window[trial.name] = {"start_s": (trial.time[trial.steady][0] + WINDOW_S * np.arange(len(chunks))).tolist(),
                                  "chi2_per_sample": [float(np.mean((c - c.mean()) ** 2) / noise[0] ** 2) for c in chunks]}
    return {"per_output": per_output, "per_frequency": per_frequency, "per_window": per_window}


def _scalar(x):
    x = np.asarray(x, float)
    return float(np.nanmean(x)) if x.size else None


def measure_shrinkage(trials, variants: dict, noise: float, seed: int = 0, n_boot: int = 1000) -> dict:
    """1 - VAF of the total lumbar rotation on the held-out halves for each model variant
    (e.g. nominal, refit, effect), pooled over trials, with the reduction of the gap from the
    first to the last variant and a 95 % bootstrap interval over 2 s windows. `noise`: that of
    the total lumbar rotation (rad)."""
    names = list(variants)
    rows = []
    err = {k: [] for k in names}
    tot = []
    for i, trial in enumerate(trials):
        part = half(trial, "test")
        y = trial.steady_outputs[part, 0] - trial.steady_outputs[part, 0].mean()
        n_win = int(round(WINDOW_S * trial.fs))
        wins = [slice(k, k + n_win) for k in range(0, y.size - n_win + 1, n_win)]
        tot += [np.sum(y[w] ** 2) for w in wins]
        row = {"trial": trial.name, "noise_floor_gap": float(noise**2 / np.mean(y**2))}
        for k in names:
            out = variants[k][i]
            if out is None:
                err[k] += [np.nan] * len(wins)
                row[f"gap_{k}"] = None
                continue
            m = out[part, 0] - out[part, 0].mean()
            err[k] += [np.sum((y[w] - m[w]) ** 2) for w in wins]
            row[f"gap_{k}"] = float(np.sum((y - m) ** 2) / np.sum(y**2))
        rows.append(row)
    tot = np.array(tot)
    err = {k: np.array(v) for k, v in err.items()}
    gap = {k: float(np.sum(v) / tot.sum()) for k, v in err.items()}
    floor = float(noise**2 * sum(t.steady_outputs[half(t, "test")].shape[0] for t in trials) / tot.sum())
    first, last = names[0], names[-1]
    out = {"per_trial": rows, "gap": gap, "noise_floor_gap": floor,
           "reduction": 1.0 - gap[last] / gap[first],
           "reduction_above_noise": 1.0 - max(gap[last] - floor, 0.0) / max(gap[first] - floor, 1e-12)}
    rng = np.random.default_rng(seed)
    idx = rng.integers(0, tot.size, size=(n_boot, tot.size))
    samples = 1.0 - err[last][idx].sum(axis=1) / err[first][idx].sum(axis=1)
    out["reduction_ci95"] = [float(np.nanpercentile(samples, 2.5)), float(np.nanpercentile(samples, 97.5))]
    return out


def frf_errors(trials, variants: dict) -> dict:
    """Mean |log(H_model / H_data)| at the excited line groups (total rotation, whole record)."""
    out = {}
    for key, sims in variants.items():
        errs = []
        for trial, s in zip(trials, sims):
            if s is None:
                continue
            u = trial.platform[trial.steady]
            fd = estimate_frf(u, trial.steady_outputs[:, 0], trial.fs, trial.period, n_adjacent=2)
            fm = estimate_frf(u, s[:, 0] - s[:, 0].mean(), trial.fs, trial.period, n_adjacent=2)
            errs.append(np.abs(np.log(fm.H / fd.H)))
        out[key] = float(np.mean(np.concatenate(errs))) if errs else None
    return out


def remainder(trials, model_outputs, noise, outputs, noise_rel_sd=None, p_threshold: float = 1e-3, lags: int = 20) -> dict:
    """Is what the selected model leaves on the held-out halves measurement noise? Three tests, each
    against its distribution under white Gaussian noise of the given level:

    * chi-square per sample, per output: the sum of squared residuals (offset removed) over
      noise^2 against chi2 with n - 1 degrees of freedom per trial; when the noise was estimated,
      its relative uncertainty (`noise_rel_sd`, of the variance) widens the expected spread;
    * whiteness: the Ljung-Box statistic of the residual's autocorrelation (lags 1..`lags`)
      against chi2 with `lags` degrees of freedom per trial and output;
    * FRF errors: the count of excited lines whose gain or phase error lies beyond 2 SD of the
      data's own bounds (`locate_gap`) against a binomial with the 2-SD two-test rate.

    The remainder is noise when no test rejects at `p_threshold`. Also returns where it is not:
    outputs, frequencies and time windows whose residual exceeds the noise."""
    from scipy import stats

    noise = np.broadcast_to(np.asarray(noise, float), (len(outputs),))
    rel_sd = np.zeros(len(outputs)) if noise_rel_sd is None else np.broadcast_to(np.asarray(noise_rel_sd, float), (len(outputs),))
    chi2, dof, q, q_dof = np.zeros(len(outputs)), np.zeros(len(outputs)), 0.0, 0
    for trial, out in zip(trials, model_outputs):
        part = half(trial, "test")
        r = trial.steady_outputs[part] - out[part]
        r = r - r.mean(axis=0)
        chi2 += np.sum(r**2, axis=0) / noise**2
        dof += r.shape[0] - 1
        for j in range(r.shape[1]):
            rho = np.array([r[k:, j] @ r[:-k, j] for k in range(1, lags + 1)]) / (r[:, j] @ r[:, j])
            q += r.shape[0] * (r.shape[0] + 2) * np.sum(rho**2 / (r.shape[0] - np.arange(1, lags + 1)))
            q_dof += lags
    z = (chi2 / dof - 1.0) / np.sqrt(2.0 / dof + rel_sd**2)
    p_chi2 = stats.norm.sf(z)
    p_white = float(stats.chi2.sf(q, q_dof))
    where = locate_gap(trials, model_outputs, noise, outputs)
    lines = {name: np.asarray(f["frequencies_hz"])[np.asarray(f["significant"])].tolist() for name, f in where["per_frequency"].items()}
    n_lines = sum(len(f["significant"]) for f in where["per_frequency"].values())
    n_significant = sum(len(v) for v in lines.values())
    rate = 1.0 - (1.0 - 2.0 * stats.norm.sf(2.0)) ** 2  # P(beyond 2 SD) in gain or in phase
    p_frf = float(stats.binom.sf(n_significant - 1, n_lines, rate)) if n_lines else 1.0
    windows = {}
    for name, w in where["per_window"].items():
        n_win = int(round(WINDOW_S * trials[0].fs))
        limit = 1.0 + stats.norm.isf(p_threshold) * np.sqrt(2.0 / n_win)
        windows[name] = [s for s, c in zip(w["start_s"], w["chi2_per_sample"]) if c > limit]
    noise_like = bool(min(p_chi2.min(), p_white, p_frf) >= p_threshold)
    return {"is_noise": noise_like, "p_threshold": p_threshold,
            "chi2_per_sample": dict(zip(outputs, (chi2 / dof).tolist())), "chi2_z": dict(zip(outputs, z.tolist())),
            "p_chi2": dict(zip(outputs, p_chi2.tolist())), "ljung_box": {"q": float(q), "dof": q_dof, "p": p_white},
            "frf": {"significant": n_significant, "lines": n_lines, "expected_rate": rate, "p": p_frf},
            "outputs": [o for o, p in zip(outputs, p_chi2) if p < p_threshold],
            "frequencies_hz": {k: v for k, v in lines.items() if v}, "windows_s": {k: v for k, v in windows.items() if v}}
