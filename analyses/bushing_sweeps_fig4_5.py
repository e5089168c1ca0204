"""Thesis Fig. 4.5: intervertebral stiffness (100-800 Nm/rad, damping 0) and damping (0-8 Nms/rad,
stiffness 100 Nm/rad) sweeps; settling under gravity, no reflexes, no co-activation.

The thesis locked the other lumbar joints and plotted L5-S1. We emulate the lock with very
stiff bushings at the other four levels (thesis.locked_levels) and also run the model with
all five levels free, the configuration every later experiment uses.
"""

import numpy as np

from trunk_drake import thesis

K_VALUES = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)  # Nm/rad, thesis 4.4.1
C_VALUES = (0.0, 2.0, 4.0, 6.0, 8.0)  # Nms/rad
THESIS = ("Higher intervertebral stiffness gives less L5-S1 flexion; more damping reduces the amplitude (oscillation). "
          "Table 3.1's k = 100 Nm/rad and c = 7.5 Nms/rad were kept (other lumbar joints locked).")


def _label(config, k, c):
    return f"{config} k={k:g} c={c:g}"


def _cases(k_values, c_values, duration):
    """One run per (configuration, k, c); the k sweep has c = 0, the c sweep k = K_VALUES[0]."""
    cases = {}
    for config in ("locked", "free"):
        for k, c in [(k, 0.0) for k in k_values] + [(k_values[0], c) for c in c_values]:
            bushings = thesis.locked_levels(k, c) if config == "locked" else {"stiffness": k, "damping": c}
            cases[_label(config, k, c)] = dict(duration=duration, perturbation=None, **bushings)
    return [{"label": label, "simulate": kwargs} for label, kwargs in cases.items()]


def run(out_dir, model=None, workers=2, inputs=None, duration=4.0, k_values=K_VALUES, c_values=C_VALUES):
    traces = thesis.run_cases(_cases(k_values, c_values, duration), model, workers)
    k0 = k_values[0]

    def pick(config, sweep, values):
        return {f"{sweep}={v:g}": traces[_label(config, v, 0.0) if sweep == "k" else _label(config, k0, v)] for v in values}

    plt = thesis.pyplot()
    fig, axes = plt.subplots(2, 3, figsize=(14, 7.5), sharex=True)
    for row, (sweep, values, unit) in enumerate((("k", k_values, "Nm/rad, c = 0"), ("c", c_values, "Nms/rad, k = 100"))):
        thesis.plot_traces(axes[row, 0], pick("locked", sweep, values), "L5_S1_FE", "L5-S1 rotation (deg)")
        thesis.plot_traces(axes[row, 1], pick("free", sweep, values), "L5_S1_FE", "L5-S1 rotation (deg)")
        thesis.plot_traces(axes[row, 2], pick("free", sweep, values), ylabel="total lumbar rotation (deg)")
        axes[row, 0].set_title(f"{sweep} sweep ({unit}): other levels locked", fontsize=9)
        axes[row, 1].set_title(f"{sweep} sweep: all five levels free, L5-S1", fontsize=9)
        axes[row, 2].set_title(f"{sweep} sweep: all free, S1-L1 (sum of levels)", fontsize=9)
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.suptitle("Fig. 4.5: intervertebral stiffness and damping, settling under gravity (no reflexes, no co-activation)")
    figure = thesis.save_figure(fig, f"{out_dir}/fig4_5_bushing_sweeps.png")

    finals = {label: thesis.final_deg(tr, "L5_S1_FE") for label, tr in traces.items()}
    totals = {label: thesis.final_deg(tr) for label, tr in traces.items()}
    locked_c = [traces[_label("locked", k0, c)] for c in c_values]
    peaks_c = [None if "error" in tr else float(np.abs(tr["levels_deg"]["L5_S1_FE"]).max()) for tr in locked_c]
    rows = [[label, thesis.describe(tr, "L5_S1_FE"), "-" if label.startswith("locked") else thesis.describe(tr)] for label, tr in traces.items()]
    k_trend = thesis.trend([finals[_label("locked", k, 0.0)] for k in k_values])
    c_trend = thesis.trend(peaks_c)
    free_k100 = traces[_label("free", k0, 0.0)]
    holding = [k for k in k_values if (final := totals[_label("free", k, 0.0)]) is not None and abs(final) < 10.0]
    ours = (f"Locked emulation: final L5-S1 rotation {k_trend} with stiffness "
            f"({thesis.describe(traces[_label('locked', k0, 0.0)], 'L5_S1_FE')} at {k0:g} Nm/rad, "
            f"{thesis.describe(traces[_label('locked', k_values[-1], 0.0)], 'L5_S1_FE')} at {k_values[-1]:g}); peak L5-S1 rotation {c_trend} "
            f"with damping. With all five levels free and k = {k0:g} Nm/rad, c = 0 the whole lumbar spine flexes to "
            f"{thesis.describe(free_k100)} in {duration:g} s: bushings alone do not hold MyoTorso's trunk.")
    return thesis.section(
        THESIS, ours,
        comparison=[
            ["configuration", "L5-S1 free, other lumbar joints locked", "locked emulated with k = 1e5 Nm/rad, c = 1e3 Nms/rad at "
             "L4-L5 ... L1-L2; and all five levels free"],
            ["stiffness effect on L5-S1", "higher k, less flexion", f"final L5-S1 rotation {k_trend} with k (locked)"],
            ["damping effect", "amplitude decreases with c", f"peak L5-S1 rotation {c_trend} with c (locked)"],
            [f"k = {k0:g}, c = 0, all levels free", "not simulated", thesis.describe(free_k100)],
        ],
        figures=[figure],
        tables=[{"caption": f"Final rotation after {duration:g} s (peak in brackets)", "header": ["run", "L5-S1", "total lumbar (free)"],
                 "rows": rows}],
        notes=["With all levels free, the smallest stiffness holding the total lumbar rotation within 10 deg is "
               + (f"{min(holding):g} Nm/rad per level ({min(holding) / 5:g} Nm/rad for the five levels in series)" if holding
                  else "not in the sweep")
               + ": five levels of 100 Nm/rad in series (20 Nm/rad) cannot carry the gravitational destabilisation of "
               "MyoTorso's 21 kg upper body, so the trunk buckles until passive muscle forces stop it. The thesis' locked "
               "configuration hides this.",
               "Thesis plots have no numbers; only the trends can be compared."],
        numbers={"final_L5_S1_deg": finals, "final_total_deg": totals, "peak_L5_S1_locked_c_deg": dict(zip(map(str, c_values), peaks_c)),
                 "wall_time_s": {label: tr.get("wall_time_s") for label, tr in traces.items()}},
        settings={"duration_s": duration, "perturbation": "none (gravity only)", "reflexes": "off",
                  "feed-forward": "minimum activation 0.01, no co-activation", "k sweep damping": "0 Nms/rad",
                  "c sweep stiffness": "100 Nm/rad"},
    )


if __name__ == "__main__":
    from trunk_drake.commands.reproduce import script_main

    raise SystemExit(script_main(__file__))
