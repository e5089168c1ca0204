"""Thesis Tables 4.2-4.3: reflex gains (kp, kv per muscle group) fitted for trunk settling and for
car-passenger interaction.

Settling (4.8.1): no perturbation, target zero lumbar rotation, co-activation 0.020, bushings
100 Nm/rad and 7.5 Nms/rad. Car passenger (4.8.2): the two 0.2-1 Hz trials of the SYNTHETIC
reference data (models/reference) with their known conditions, on their model (the default
passenger), from the preset's gains; the fitted gains are compared
with the data's truth (error in standard deviations) and shown beside the thesis' Table 4.3,
which belongs to another model and other (measured) data. The car fit's time series and FRFs
are saved for the validation section (no second fit).
"""

import numpy as np

from trunk_drake import thesis
from trunk_drake.data import models_dir
from trunk_drake.diagram import TrunkOptions
from trunk_drake.io.experiment import load_experiment
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.optim.fit import MAX_ITERATIONS, fit_reflex_gains, settling_target, targets_from_trials, write_fit
from trunk_drake.optim.gains import GAIN_BOUNDS

TRIALS = ("trial_1hz_a.csv", "trial_1hz_b.csv")
THESIS = {
    "settling": "Table 4.2: small gains (0.001-0.10) since co-activation already holds the posture; largest kv for "
                "transversospinalis (0.10), largest kp for quadratus lumborum (0.059) and external oblique (0.053).",
    "car": "Table 4.3: the settling gains cannot stabilise the perturbed model; gains rise (0.01-0.70), largest for the spinal "
           "groups; the Gauss-Newton fit took ~70 h.",
}


def _thesis_table(number: str) -> dict:
    """{group: {"kp", "kv"}} of thesis Table 4.2 or 4.3 (models/reference_values.toml), all 9 groups."""
    from trunk_drake.data import load_toml

    return {g: {"kp": e["kp"], "kv": e["kv"]} for g, e in load_toml("reference_values.toml")["reflex"][f"thesis_table_{number}"].items()}


def _bounded(value) -> str:
    return f"{value:.3g}" + (" (lower bound)" if value <= 1.001 * GAIN_BOUNDS[0] else "")


def _gain(value, sd) -> str:
    return f"{value:.3g} ± {sd:.2g}" if np.isfinite(sd) else f"{value:.3g} (not identifiable)"


def _fit_summary(result) -> dict:
    return {"gains": result.gains, "std": result.std, "cost": result.cost, "vaf": result.vaf,
            "n_simulations": result.n_simulations, "wall_time_s": result.wall_time_s,
            "iterations": [s.iterations for s in result.starts], "status": [s.status for s in result.starts]}


def _gain_figure(path, settling, car, truth, tables):
    plt = thesis.pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(13, 7.5), sharey=True)
    panels = (("settling (Table 4.2)", settling, tables["4_2"]), ("car passenger (Table 4.3)", car, tables["4_3"]))
    for row, (name, result, table) in enumerate(panels):
        groups = list(result.gains["kp"])
        x = np.arange(len(groups))
        for col, key in enumerate(("kp", "kv")):
            ax = axes[row, col]
            values = np.array([result.gains[key][g] for g in groups])
            sd = np.array([result.std[key][g] for g in groups])
            finite = np.isfinite(sd)
            lower = np.where(finite, np.minimum(sd, values * (1 - 1e-3)), 0.0)  # log axis: keep the bar above zero
            ax.bar(x - 0.27, values, 0.27, yerr=[lower, np.where(finite, sd, 0.0)], color="C0", label="trunk-drake fit (±1 SD)")
            if row == 1:
                ax.bar(x, [truth[key][g] for g in groups], 0.27, color="C2", label="synthetic-data truth")
            ax.bar(x + 0.27, [table.get(g, {}).get(key, np.nan) for g in groups], 0.27, color="0.6",
                   label="thesis (other model, other data)")
            ax.set_yscale("log")
            ax.set_xticks(x, [g.replace("_", "\n") for g in groups], fontsize=7)
            ax.set_title(f"{name}: {key}", fontsize=9)
            ax.grid(alpha=0.3, axis="y")
            ax.legend(fontsize=7)
    fig.suptitle(f"Fitted reflex gains (log scale); bounds {GAIN_BOUNDS[0]:g}-{GAIN_BOUNDS[1]:g} (the thesis: 0.001-1)")
    return thesis.save_figure(fig, path)


def run(out_dir, model=None, workers=2, inputs=None, settling_duration=5.0, trials=TRIALS, max_iterations=MAX_ITERATIONS, t_max=None):
    if model is None:
        from trunk_drake.model.trunk_model import load_model

        model = load_model("sagittal")
    feedforward, warning = thesis.coactivation_quiet(model, thesis.reference_value("muscle.thesis.min_activation_retained"))
    thesis.log("  settling fit (thesis 4.8.1) ...")
    target = settling_target(duration=settling_duration)
    settling = fit_reflex_gains(model, [target], scenario="settling",
                                options=TrunkOptions(feedforward=feedforward), n_starts=1, workers=workers,
                                max_iterations=max_iterations, progress=False)
    settling_files = write_fit(settling, f"{out_dir}/settling")
    thesis.log(f"  settling fit: {settling.wall_time_s:.0f} s, {settling.n_simulations} simulations; car-passenger fit (4.8.2) ...")
    ref = models_dir() / "reference"
    experiment = load_experiment([ref / t for t in trials], ref / "conditions.toml")
    targets = targets_from_trials(experiment.trials, OUTPUT_NAMES, experiment.noise_rad, period=experiment.period,
                                  steady_start=experiment.fade, t_max=t_max)
    car = fit_reflex_gains(experiment.model(), targets, options=TrunkOptions(**experiment.options), start=experiment.preset_gains(),
                           n_starts=1, workers=workers, max_iterations=max_iterations, progress=False)
    car_files = write_fit(car, f"{out_dir}/car")
    arrays = thesis.save_fit_arrays(car, f"{out_dir}/car/fit_arrays.npz")
    thesis.log(f"  car fit: {car.wall_time_s:.0f} s, {car.n_simulations} simulations")

    truth = thesis.truth_gains()
    tables = {"4_2": _thesis_table("4_2"), "4_3": _thesis_table("4_3")}
    z = {key: {g: (car.gains[key][g] - truth[key][g]) / car.std[key][g] if np.isfinite(car.std[key][g]) else float("nan")
               for g in car.gains[key]} for key in ("kp", "kv")}
    finite_z = [abs(v) for d in z.values() for v in d.values() if np.isfinite(v)]
    determined = {f"{k}.{g}": (car.gains[k][g] - truth[k][g]) / truth[k][g] for k in ("kp", "kv") for g in car.gains[k]
                  if car.std[k][g] < 0.5 * car.gains[k][g]}
    unidentified = [f"{k}.{g}" for k in ("kp", "kv") for g in car.gains[k] if not np.isfinite(car.std[k][g])]
    largest = max(((settling.gains[k][g], f"{g} {k}") for k in ("kp", "kv") for g in settling.gains[k]))
    within = sum(v <= 2.0 for v in finite_z)
    floor = 0.5 * sum(t.time.size * len(t.outputs) for t in targets)
    absent = sorted(set(tables["4_3"]) - set(car.gains["kp"]))
    rows_42 = [[g, *(_bounded(settling.gains[k][g]) if g in settling.gains[k] else "absent in MyoTorso" for k in ("kp", "kv")),
                tables["4_2"][g]["kp"], tables["4_2"][g]["kv"]] for g in tables["4_2"]]
    rows_43 = []
    for g in tables["4_3"]:
        if g not in car.gains["kp"]:
            rows_43.append([g, "absent in MyoTorso", "-", "-", tables["4_3"][g]["kp"],
                            "absent in MyoTorso", "-", "-", tables["4_3"][g]["kv"]])
            continue
        cells = [g]
        for key in ("kp", "kv"):
            err = z[key][g]
            cells += [_gain(car.gains[key][g], car.std[key][g]), truth[key][g], f"{err:+.1f}" if np.isfinite(err) else "n/a",
                      tables["4_3"][g][key]]
        rows_43.append(cells)
    figure = _gain_figure(f"{out_dir}/tables4_2_4_3_gains.png", settling, car, truth, tables)
    settling_rms = float(np.degrees(target.noise["lumbar_rotation"] * np.sqrt(2 * settling.cost / target.time.size)))
    settling_values = [*settling.gains["kp"].values(), *settling.gains["kv"].values()]
    ours = (f"Settling: {settling.n_simulations} simulations in {settling.wall_time_s:.0f} s; residual lumbar rotation "
            f"{settling_rms:.2f} deg rms about its mean, largest gain {largest[1]} {largest[0]:.3g}, the others near the 0.001 "
            f"bound. Car passenger (synthetic data): {car.n_simulations} simulations in {car.wall_time_s / 60:.1f} min; cost "
            f"{car.cost:.0f} vs noise floor {floor:.0f}; {within} of {len(finite_z)} identifiable gains within 2 SD of the truth "
            f"(largest error {max(finite_z, default=float('nan')):.1f} SD); well determined (SD < 50 % of the value): "
            + (", ".join(f"{n} ({100 * e:+.0f} % from the truth)" for n, e in determined.items()) or "none")
            + f"; not identifiable: {', '.join(unidentified) or 'none'}.")
    return thesis.section(
        f"{THESIS['settling']} {THESIS['car']}", ours,
        comparison=[
            ["data", "van Drunen et al., 6 subjects averaged (not public)", "SYNTHETIC trials of models/reference (known truth)"],
            ["settling gains", "0.0012-0.10", f"{min(settling_values):.3g}-{max(settling_values):.3g}"],
            ["car-passenger gains vs truth", "no truth (measured data)", f"{within}/{len(finite_z)} identifiable gains within 2 SD"],
            ["fit wall time", "~70 h (MATLAB + OpenSim)",
             f"settling {settling.wall_time_s / 60:.1f} min, car {car.wall_time_s / 60:.1f} min "
                                                          f"({workers} {'process' if workers == 1 else 'processes'})"],
            ["muscle groups", "9 (incl. latissimus dorsi, transversus abdominis)", f"{len(car.gains['kp'])} (absent: {', '.join(absent)})"],
        ],
        figures=[figure, settling_files["convergence_plot"], car_files["convergence_plot"]],
        tables=[{"caption": "Table 4.2 (trunk settling): trunk-drake fit beside the thesis",
                 "header": ["group", "kp (ours)", "kv (ours)", "kp (thesis)", "kv (thesis)"], "rows": rows_42},
                {"caption": "Table 4.3 (car passenger): fit on the synthetic data ± 1 SD, its truth, error in SD, and the thesis' values",
                 "header": ["group", "kp fitted", "kp truth", "kp error (SD)", "kp thesis",
                            "kv fitted", "kv truth", "kv error (SD)", "kv thesis"],
                 "rows": rows_43}],
        notes=[thesis.SYNTHETIC_NOTE,
               "The thesis' Tables 4.2/4.3 come from a different model (Schmid et al., 274 muscles, 9 groups) and measured data; "
               "they are shown for orientation, not as a target.",
               f"Car-passenger fit conditions and model are the synthetic data's ({thesis.reference_truth_label()}; "
               "feed-forward from truth_feedforward.csv; conditions.toml); the fit starts from the preset's gains. Residuals "
               f"are weighted by the known {np.degrees(experiment.noise_rad):.2f} deg noise, so the cost's noise floor is half "
               "the number of samples. Outputs: total lumbar rotation and the five level angles (in the lumbar rhythm fixed "
               "shares of one lumbar flexion angle, each with its own noise).",
               "The settling target is zero rotation; its VAF is undefined (no variance) and not reported.",
               "'not identifiable' = infinite standard deviation: the data do not constrain that gain (a kp whose group's "
               "fibers never exceed the set point l_d in the trials); 'well determined' = SD below half the fitted value. "
               "With the set point at the neutral length every group's length reflex engages on one side of the sway, so "
               "every SD is finite, but one lumbar angle cannot tell 14 gains apart: the weakly determined ones are "
               "combinations of groups acting alike (benchmarks/results/fit.json).",
               f"Settling: the zero-rotation target is reached (cost {settling.cost:.3g} against a noise floor of "
               f"{0.5 * target.time.size:.0f}), so standard deviations carry no information there and are not shown.",
               *([f"Settling co-activation: {warning}."] if warning else [])],
        numbers={"settling": _fit_summary(settling), "car": {**_fit_summary(car), "truth": truth, "error_sd": z,
                                                              "noise_floor_cost": floor, "trials": list(trials),
                                                              "well_determined_relative_error": determined,
                                                              "not_identifiable": unidentified},
                 "thesis_table_4_2": tables["4_2"], "thesis_table_4_3": tables["4_3"],
                 "files": {"car_arrays": arrays, **{f"car_{k}": v for k, v in car_files.items()},
                           **{f"settling_{k}": v for k, v in settling_files.items()}}},
        settings={"settling": f"{settling_duration:g} s, target 0 deg, co-activation 0.020, k = 100 Nm/rad, c = 7.5 Nms/rad",
                  "car": f"{', '.join(trials)}" + (f" (first {t_max:g} s)" if t_max else "")
                         + "; conditions from models/reference/conditions.toml",
                  "fit": f"bounded secant Levenberg-Marquardt, 1 start (settling: the thesis' initial values; car: the data's "
                         f"preset gains), <= {max_iterations} iterations, {workers} worker {'process' if workers == 1 else 'processes'}"},
    )


if __name__ == "__main__":
    from trunk_drake.commands.reproduce import script_main

    raise SystemExit(script_main(__file__))
