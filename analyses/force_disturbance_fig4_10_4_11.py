"""Thesis Figs. 4.10-4.11: the force disturbance (fictitious pelvis mass x platform acceleration)
applied to a free pelvis, and the resulting pelvis motion against the platform motion.

The 0.2-1 Hz multisine (20 s period, 2 s fades, seed 0) drives a 10,000 kg pelvis on its
anterior-posterior slide; the same trial with exactly prescribed pelvis motion is the
reference. Two trunk configurations: the thesis' final model (k = 125 Nm/rad, c = 7.5 Nms/rad,
co-activation 0.020, Table 4.3 gains) on the run's model and the synthetic reference data's truth
configuration on its own model (models/reference: the default passenger).
"""

import numpy as np

from trunk_drake import thesis
from trunk_drake.diagram import THESIS_PELVIS_MASS
from trunk_drake.signals import make_multisine

THESIS = ("The force disturbance (platform acceleration x 10,000 kg) has the course of the platform acceleration; the "
          "pelvis motion it produces resembles the platform motion, with modest distinctions.")


def run(out_dir, model=None, workers=2, inputs=None, duration=None, seed=0):
    signal = make_multisine(f_max=1.0, seed=seed, fade_shape="quintic")
    duration = duration or signal.duration
    configs, warning = thesis.final_and_truth_configurations(model)
    traces = thesis.run_cases_per_model(
        [(config_model, [{"label": f"{name}, {pelvis}", "simulate": dict(duration=duration, perturbation=signal,
                                                                         pelvis_mass=THESIS_PELVIS_MASS,
                                                                         **{**options, **gains, "pelvis": pelvis})}
                         for pelvis in ("force", "prescribed")])
         for name, (config_model, options, gains) in configs.items()], workers)

    t = np.linspace(0.0, duration, int(round(duration * 100)) + 1)
    x, _, a = signal.evaluate(t)
    force = THESIS_PELVIS_MASS * np.asarray(a)
    plt = thesis.pyplot()
    fig, ax = plt.subplots(figsize=(10, 3.5))
    ax.plot(t, force / 1000.0, "k", lw=1)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("force on the pelvis (kN, anterior +)")
    ax.set_title(f"Fig. 4.10: force disturbance = {THESIS_PELVIS_MASS:,.0f} kg x platform acceleration (0.2-1 Hz multisine)")
    ax.grid(alpha=0.3)
    fig_force = thesis.save_figure(fig, f"{out_dir}/fig4_10_force_disturbance.png")

    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    axes[0].plot(t, 100 * np.asarray(x), color="0.6", lw=2, label="platform")
    errors, rotation_gap = {}, {}
    for k, name in enumerate(configs):
        forced, exact = traces[f"{name}, force"], traces[f"{name}, prescribed"]
        if "error" in forced or "error" in exact:
            errors[name] = None
            continue
        error = forced["pelvis"] - forced["platform"][:, 0]
        errors[name] = {"max_mm": float(1000 * np.abs(error).max()), "rms_mm": float(1000 * np.sqrt(np.mean(error**2)))}
        rotation_gap[name] = float(np.abs(forced["lumbar_rotation_deg"] - exact["lumbar_rotation_deg"]).max())
        axes[0].plot(forced["time"], 100 * forced["pelvis"], color=f"C{k}", lw=1, ls="--" if k else "-", label=f"pelvis ({name})")
        axes[1].plot(forced["time"], 1000 * error, color=f"C{k}", lw=1, label=name)
        axes[2].plot(forced["time"], forced["lumbar_rotation_deg"], color=f"C{k}", lw=1, label=f"{name}: force-driven pelvis")
        axes[2].plot(exact["time"], exact["lumbar_rotation_deg"], color=f"C{k}", lw=2, alpha=0.35, label=f"{name}: prescribed pelvis")
    axes[0].set_ylabel("displacement (cm)")
    axes[1].set_ylabel("pelvis - platform (mm)")
    axes[2].set_ylabel("lumbar rotation (deg)")
    axes[2].set_xlabel("time (s)")
    for ax in axes:
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper left")
    fig.suptitle("Fig. 4.11: pelvis motion under the force disturbance versus platform motion")
    fig_motion = thesis.save_figure(fig, f"{out_dir}/fig4_11_pelvis_vs_platform.png")

    peak_x = float(np.abs(x).max())
    tracking = "; ".join(f"{n}: max {e['max_mm']:.2f} mm, rms {e['rms_mm']:.2f} mm" if e else f"{n}: diverged"
                         for n, e in errors.items())
    ours = (f"Peak force {np.abs(force).max() / 1000:.2f} kN for a {100 * peak_x:.1f} cm peak platform displacement. The pelvis "
            f"follows the platform within {tracking}; the lumbar rotation differs from the prescribed-pelvis run by at most "
            + ", ".join(f"{v:.2f} deg ({n})" for n, v in rotation_gap.items()) + ".")
    return thesis.section(
        THESIS, ours,
        comparison=[["force", "platform acceleration x 10,000 kg",
                     f"the same ({THESIS_PELVIS_MASS:,.0f} kg; peak {np.abs(force).max() / 1000:.2f} kN)"],
                    ["pelvis vs platform", "resembles it, modest distinctions", tracking],
                    ["platform signal", "van Drunen et al.'s measured 0.2-1 Hz signal, 2 Hz low-pass",
                     f"analytic 0.2-1 Hz multisine (seed {seed}), {1000 * signal.rms:.1f} mm rms (amplitude unsourced)"]],
        figures=[fig_force, fig_motion],
        notes=["The thesis prints the pelvis mass as '10.000 kg' (models/reference_values.toml notes the ambiguity); the "
               "purpose (limiting the effect of the trunk on the pelvis) implies 10,000 kg, used here.",
               "trunk-drake's other experiments prescribe the pelvis motion exactly instead (a generalized force on the "
               "pelvis slide); this section shows the thesis' force-driven variant gives the same lumbar response.",
               *([f"Thesis final model: {warning}."] if warning else [])],
        numbers={"peak_force_N": float(np.abs(force).max()), "peak_platform_m": peak_x, "pelvis_tracking": errors,
                 "max_lumbar_rotation_difference_deg": rotation_gap,
                 "lumbar_rotation": {label: thesis.describe(tr) for label, tr in traces.items()}, "signal": signal.to_dict()},
        settings={"duration_s": duration, "pelvis_mass_kg": THESIS_PELVIS_MASS,
                  "signal": f"0.2-1 Hz multisine, 20 s period, 2 s quintic fades, seed {seed}"},
    )


if __name__ == "__main__":
    from trunk_drake.commands.reproduce import script_main

    raise SystemExit(script_main(__file__))
