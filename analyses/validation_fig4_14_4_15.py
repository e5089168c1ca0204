"""Thesis Figs. 4.14-4.15: validation of the car-passenger fit in the time domain (VAF) and the
frequency domain (FRF of lumbar rotation to platform displacement).

Uses the car fit of fitted_gains_tables4_2_4_3 (passed by the runner: no second fit) on the
two 0.2-1 Hz SYNTHETIC trials, and predicts the held-out 0.2-3 Hz trial with the fitted gains on
the data's own model (the preset of models/reference/conditions.toml; the runner's model is unused).
"""

from pathlib import Path

import numpy as np

from trunk_drake import thesis
from trunk_drake.data import models_dir
from trunk_drake.diagram import TrunkOptions
from trunk_drake.io.experiment import load_experiment
from trunk_drake.optim.fit import Objective, goodness_of_fit, targets_from_trials
from trunk_drake.optim.gains import GainLayout
from trunk_drake.visual import animate_trial

FIT = "fitted_gains_tables4_2_4_3"
HELD_OUT = ("trial_3hz.csv",)
THESIS = ("Fig. 4.14: a reasonable time-domain fit, VAF 86.00 %, the model more damped than the data. Fig. 4.15: gain rises "
          "with frequency, phase lag grows; the model has more phase lag (damping); below the ~1 Hz natural frequency the "
          "gain slope lies between +1 and +2 (stiffness, damping and reflexes dominate).")


def _slope(frequencies, gain, f_max=1.0) -> float:
    """Log-log slope of |H| over the lines at or below f_max."""
    keep = (frequencies <= f_max + 1e-9) & (gain > 0)
    return float(np.polyfit(np.log10(frequencies[keep]), np.log10(gain[keep]), 1)[0]) if keep.sum() >= 2 else float("nan")


def _held_out(gains, files):
    """Prediction of the held-out trials on the data's own model (the preset of their conditions)."""
    ref = models_dir() / "reference"
    experiment = load_experiment([ref / f for f in files], ref / "conditions.toml")
    targets = targets_from_trials(experiment.trials, ("lumbar_rotation",), experiment.noise_rad, period=experiment.period,
                                  steady_start=experiment.fade)
    layout = GainLayout.for_groups(tuple(gains["kp"]))
    model = experiment.model()
    objective = Objective(model, targets, layout, TrunkOptions(**experiment.options))
    vafs, frfs, series = goodness_of_fit(targets, objective(layout.vector(gains))[0])
    return {name: {**series[name], "vaf": vafs[name]["lumbar_rotation"], "frf": frfs.get(name)} for name in series}, experiment, model


def _animation(model, gains, experiment, out_dir) -> str:
    """The held-out trial as a page: the data's trunk over the model's with the fitted gains (a report note)."""
    trial = experiment.trials[0]
    name = Path(trial.source).name
    page = animate_trial(trial, Path(out_dir) / "held_out_trial.html", model, TrunkOptions(**{**experiment.options, **gains}),
                         title=f"Held-out trial {name}: model with the fitted gains (data in blue)", label=name)
    return (f"Animation of the held-out trial {name} (opens offline): [{page.name}]({Path(out_dir).name}/{page.name}), "
            "the SYNTHETIC data's trunk in blue over the model's with the fitted gains.")


def _noise_ceiling(data, noise_rad) -> float:
    """VAF of a perfect model on data with white noise of `noise_rad` (about the mean)."""
    return float(1.0 - noise_rad**2 / np.var(data))


def run(out_dir, model=None, workers=2, inputs=None, held_out=HELD_OUT):
    entry = (inputs or {}).get(FIT)
    if not entry or entry.get("status") != "ok":
        raise RuntimeError(f"the validation needs the car-passenger fit: run {FIT} first (the runner does so)")
    car = entry["numbers"]["car"]
    trained = thesis.load_fit_arrays(Path(out_dir).parent / entry["numbers"]["files"]["car_arrays"])  # relative to the report
    for name, s in trained.items():
        s["vaf"] = car["vaf"][name]["lumbar_rotation"]
    thesis.log(f"  predicting the held-out trial(s) {', '.join(held_out)} with the fitted gains ...")
    predicted, experiment, model = _held_out(car["gains"], held_out)  # the data's model, not the runner's
    noise = experiment.noise_rad
    runs = {**{f"{Path(n).stem} (fitted)": s for n, s in trained.items()},
            **{f"{Path(n).stem} (held out)": s for n, s in predicted.items()}}

    plt = thesis.pyplot()
    fig, axes = plt.subplots(len(runs), 1, figsize=(10, 2.8 * len(runs)), squeeze=False)
    for ax, (label, s) in zip(axes[:, 0], runs.items()):
        ax.plot(s["time"], np.degrees(s["data"]), color="0.6", lw=1.5, label="synthetic data")
        ax.plot(s["time"], np.degrees(s["model"]), "k", lw=0.9, label=f"model (VAF {100 * s['vaf']:.1f} %)")
        ax.set_title(label, fontsize=9)
        ax.set_ylabel("lumbar rotation (deg)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("Fig. 4.14: time-domain fit, fitted gains on the SYNTHETIC reference data")
    fig_time = thesis.save_figure(fig, f"{out_dir}/fig4_14_time_domain.png")

    fig, (ax_g, ax_p) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    slopes = {}
    for k, (label, s) in enumerate(runs.items()):
        f = s["frf"]
        if f is None:
            continue
        freq, color = np.asarray(f["frequencies"]), f"C{k}"
        data_gain, model_gain = np.degrees(np.abs(f["data"])), np.degrees(np.abs(f["model"]))
        ax_g.loglog(freq, data_gain, "o", color=color, ms=4, mfc="none", label=f"data {label}")
        ax_g.fill_between(freq, np.degrees(f["data_lower"]), np.degrees(f["data_upper"]), color=color, alpha=0.15)
        ax_g.loglog(freq, model_gain, "-", color=color, lw=1, label="model")
        ax_p.semilogx(freq, np.degrees(np.unwrap(np.angle(f["data"]))), "o", color=color, ms=4, mfc="none")
        ax_p.semilogx(freq, np.degrees(np.unwrap(np.angle(f["model"]))), "-", color=color, lw=1)
        lag = np.degrees(np.unwrap(np.angle(f["model"])) - np.unwrap(np.angle(f["data"])))
        slopes[label] = {"data": _slope(freq, data_gain), "model": _slope(freq, model_gain),
                         "peak_gain_hz": {"data": float(freq[np.argmax(data_gain)]), "model": float(freq[np.argmax(model_gain)])},
                         "band_edge_hz": float(freq[-1]),
                         "model_minus_data_phase_deg": {"mean": float(lag.mean()), "max_abs": float(np.abs(lag).max())}}
    f_ref = np.array([0.2, 0.6])
    ax_g.loglog(f_ref, 2.0 * (f_ref / 0.2) ** 1, "k:", lw=1, label="slope +1 (damping)")
    ax_g.loglog(f_ref, 2.0 * (f_ref / 0.2) ** 2, "k--", lw=1, label="slope +2 (stiffness)")
    ax_g.set_ylabel("gain (deg/m)")
    ax_g.legend(fontsize=7, ncol=2)
    ax_p.set_ylabel("phase (deg)")
    ax_p.set_xlabel("frequency (Hz)")
    for ax in (ax_g, ax_p):
        ax.grid(alpha=0.3, which="both")
    fig.suptitle("Fig. 4.15: FRF lumbar rotation / platform displacement (data: 95 % bounds shaded)")
    fig_frf = thesis.save_figure(fig, f"{out_dir}/fig4_15_frf.png")

    thesis_vaf = thesis.reference_value("reflex.thesis.vaf_final")
    ceilings = {label: _noise_ceiling(s["data"], noise) for label, s in runs.items()}
    vaf_text = "; ".join(f"{label} {100 * s['vaf']:.1f} % (noise ceiling {100 * ceilings[label]:.1f} %)" for label, s in runs.items())
    slope_text = "; ".join(f"{label}: data {v['data']:+.2f}, model {v['model']:+.2f}" for label, v in slopes.items())
    peak_text = "; ".join(f"{label}: data {v['peak_gain_hz']['data']:.2f} Hz, model {v['peak_gain_hz']['model']:.2f} Hz"
                          + (" (the band edge: the gain still rises)" if v["peak_gain_hz"]["data"] >= v["band_edge_hz"] else "")
                          for label, v in slopes.items())
    phase_text = "; ".join(f"{label}: mean {v['model_minus_data_phase_deg']['mean']:+.1f} deg (max |.| "
                           f"{v['model_minus_data_phase_deg']['max_abs']:.1f})" for label, v in slopes.items())
    ours = (f"VAF of lumbar rotation: {vaf_text}. Gain slope at 0.2-1 Hz: {slope_text}. The model is the data's own "
            "structure with fitted gains, so the VAF measures how well the fit recovers a known truth, not realism.")
    return thesis.section(
        THESIS, ours,
        comparison=[["VAF (lumbar rotation, 0.2-1 Hz)", f"{thesis_vaf:.2f} % (measured data, 6 subjects averaged)",
                     "; ".join(f"{100 * s['vaf']:.1f} % ({label})" for label, s in runs.items() if "fitted" in label) + " (synthetic)"],
                    ["prediction of another bandwidth", "not tested",
                     "; ".join(f"{100 * s['vaf']:.1f} % ({label})" for label, s in runs.items() if "held out" in label)],
                    ["gain slope below ~1 Hz", "between +1 and +2", slope_text],
                    ["largest gain at", "natural frequency ~1 Hz (van Drunen et al.)", peak_text],
                    ["model minus data phase", "negative: the model lags more (more damped)", phase_text]],
        figures=[fig_time, fig_frf],
        notes=[thesis.SYNTHETIC_NOTE,
               "VAF here is computed about the means (offsets removed, as the thesis removed offsets); the thesis' eq. 3.3 divides "
               "by the sum of squares of the data. The noise ceiling is the VAF a perfect model reaches on data with the "
               f"reference data's {np.degrees(noise):.2f} deg white noise.",
               "Fitted and held-out trials share the synthetic data's conditions (models/reference/conditions.toml).",
               _animation(model, car["gains"], experiment, out_dir)],
        numbers={"vaf": {label: s["vaf"] for label, s in runs.items()}, "noise_ceiling_vaf": ceilings, "frf_slopes": slopes,
                 "thesis_vaf_percent": thesis_vaf, "gains": car["gains"],
                 "frf": {label: {"frequencies_hz": s["frf"]["frequencies"], "data_gain_deg_per_m": np.degrees(np.abs(s["frf"]["data"])),
                                 "model_gain_deg_per_m": np.degrees(np.abs(s["frf"]["model"])),
                                 "data_phase_deg": np.degrees(np.unwrap(np.angle(s["frf"]["data"]))),
                                 "model_phase_deg": np.degrees(np.unwrap(np.angle(s["frf"]["model"])))}
                         for label, s in runs.items() if s["frf"] is not None}},
        settings={"fitted on": ", ".join(Path(n).stem for n in trained), "held out": ", ".join(held_out)},
    )


if __name__ == "__main__":
    from trunk_drake.commands.reproduce import script_main

    raise SystemExit(script_main(__file__))
