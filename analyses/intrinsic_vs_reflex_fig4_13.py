"""Thesis Fig. 4.13: intrinsic properties alone (bushings + co-activation) versus intrinsic
properties plus stretch reflexes, under the 0.2-1 Hz pelvis perturbation.

Two configurations: the thesis' final model (k = 125 Nm/rad, c = 7.5 Nms/rad, co-activation
0.020, Table 4.3 gains, l_d = 1) on the run's model, and the synthetic reference data's truth
configuration on its own model (models/reference: the default passenger with the truth gains)."""

import numpy as np

from trunk_drake import thesis
from trunk_drake.signals import make_multisine

THESIS = ("Intrinsic properties alone cannot stabilise the spine under the force disturbance: the model moves away "
          "from its equilibrium (unstable). With the stretch reflexes (Table 4.3) the spine stays stable.")
UPRIGHT_DEG = 5.0  # |mean lumbar rotation over the last 4 s| below this counts as holding the upright posture
FADE = 2.0  # s


def _metrics(tr) -> dict | None:
    if "error" in tr:
        return None
    rot, t = tr["lumbar_rotation_deg"], tr["time"]
    steady = t >= FADE
    return {"rms_deg": float(np.sqrt(np.mean(rot[steady] ** 2))), "sd_deg": float(np.std(rot[steady])),
            "final_mean_deg": float(rot[t >= t[-1] - 4.0].mean()), "max_abs_deg": float(np.abs(rot).max())}


def _verdict(m) -> str:
    if m is None:
        return "diverged"
    return ("holds the upright posture" if abs(m["final_mean_deg"]) < UPRIGHT_DEG
            else f"leaves the upright posture (settles at {m['final_mean_deg']:+.1f} deg)")


def run(out_dir, model=None, workers=2, inputs=None, duration=None, seed=0):
    signal = make_multisine(f_max=1.0, seed=seed, fade_shape="quintic")
    duration = duration or signal.duration
    configs, warning = thesis.final_and_truth_configurations(model)
    traces = thesis.run_cases_per_model(
        [(config_model, [{"label": f"{name}, {kind}", "simulate": dict(duration=duration, perturbation=signal, **options, **gains)}
                         for kind, gains in (("intrinsic only", {"kp": 0.0, "kv": 0.0}), ("intrinsic + reflexes", reflex))])
         for name, (config_model, options, reflex) in configs.items()], workers)
    metrics = {label: _metrics(tr) for label, tr in traces.items()}

    plt = thesis.pyplot()
    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    t = np.linspace(0.0, duration, int(round(100 * duration)) + 1)
    axes[0].plot(t, 100 * np.asarray(signal.evaluate(t)[0]), color="0.5")
    axes[0].set_ylabel("platform (cm)")
    axes[0].grid(alpha=0.3)
    styles = {"intrinsic only": {"color": "0.6", "lw": 2}, "intrinsic + reflexes": {"color": "k"}}
    for ax, name in zip(axes[1:], configs):
        thesis.plot_traces(ax, {kind: traces[f"{name}, {kind}"] for kind in styles}, ylabel="lumbar rotation (deg)", styles=styles)
        ax.set_title(name, fontsize=9)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("Fig. 4.13: intrinsic properties alone (grey) versus with stretch reflexes (black), 0.2-1 Hz perturbation")
    figure = thesis.save_figure(fig, f"{out_dir}/fig4_13_intrinsic_vs_reflex.png")

    def cell(label):
        m = metrics[label]
        return "diverged" if m is None else f"{_verdict(m)}; sd {m['sd_deg']:.2f} deg, max {m['max_abs_deg']:.1f} deg"

    ours = " ".join(f"{name}: intrinsic only {_verdict(metrics[f'{name}, intrinsic only'])}, with reflexes "
                    f"{_verdict(metrics[f'{name}, intrinsic + reflexes'])}." for name in configs)
    rows = [[label, *(("diverged",) * 4 if m is None else (f"{m['final_mean_deg']:+.2f}", f"{m['sd_deg']:.2f}", f"{m['rms_deg']:.2f}",
                                                         f"{m['max_abs_deg']:.2f}"))] for label, m in metrics.items()]
    return thesis.section(
        THESIS, ours,
        comparison=[["thesis final model (k 125, c 7.5, co-activation 0.020), intrinsic only", "unstable: moves away from equilibrium",
                     cell("thesis final model, intrinsic only")],
                    ["... with Table 4.3 reflexes", "stable", cell("thesis final model, intrinsic + reflexes")],
                    [f"{thesis.reference_truth_label()}, intrinsic only", "-",
                     cell("reference-data truth, intrinsic only")],
                    ["... with the truth reflex gains", "-", cell("reference-data truth, intrinsic + reflexes")]],
        figures=[figure],
        tables=[{"caption": f"Lumbar rotation (deg): mean over the last 4 s, SD and rms after the {FADE:g} s fade-in, maximum",
                 "header": ["run", "final mean", "SD", "rms", "max |.|"], "rows": rows}],
        notes=[*([] if _verdict(metrics["thesis final model, intrinsic + reflexes"]) == "holds the upright posture" else [
                   "On MyoTorso the thesis' final configuration does not reproduce Fig. 4.13's stable black line. Its co-activated "
                   "upright posture is an unstable equilibrium (Fig. 4.6 section), and with l_d = 1 the Table 4.3 gains tonically "
                   "excite the muscles whose fibers are longer than optimal at rest (Figs. 4.7-4.9 section). The thesis' gains "
                   "were fitted to its own model, not to MyoTorso."]),
               f"'Holds the upright posture' = mean lumbar rotation over the last 4 s within {UPRIGHT_DEG:g} deg.",
               *([f"Thesis final model: {warning}."] if warning else [])],
        numbers={"metrics": metrics},
        settings={"duration_s": duration, "signal": f"0.2-1 Hz multisine, 20 s period, 2 s quintic fades, seed {seed}",
                  "pelvis": "prescribed"},
    )


if __name__ == "__main__":
    from trunk_drake.commands.reproduce import script_main

    raise SystemExit(script_main(__file__))
