"""Thesis Figs. 4.7-4.9: stretch-reflex velocity gain kv, position gain kp and set point l_d,
equal for all muscles; settling under gravity, bushings 100 Nm/rad and 7.5 Nms/rad, no
co-activation (thesis 4.5). kv sweep: kp = 0, l_d = 1; kp sweep: kv = 0, l_d = 1; l_d sweep:
kp = 0.1, kv = 0, against the reflex switched off. Run with the other lumbar levels locked (the
thesis' L5-S1 plots) and with all five levels free."""

import numpy as np

from trunk_drake import thesis

CONFIGS = ("locked", "free")
THESIS = {
    "kv": "kv damps the motion but does not change the end-point rotation (the fiber velocity goes to zero).",
    "kp": "Larger kp lowers the admittance: a stiffer L5-S1 joint; muscles reach a constant fiber length after ~1.5 s.",
    "ld": "l_d stiffens like kp: l_d = 0 (every muscle excited) gives the smallest rotation, l_d = 1 only a minimal decrease "
          "compared with the reflex switched off.",
}
THESIS_SUMMARY = "kv damps without moving the end point; larger kp and smaller l_d stiffen (less rotation), l_d = 0 least."


def _key(kp, kv, ld):
    return f"kp={kp:g} kv={kv:g} ld={ld:g}"


def _sweeps(values, kp_for_ld):
    """{sweep: {legend label: gain key}}; the reflex-off run is the zero of the kv and kp sweeps."""
    off = _key(0.0, 0.0, 1.0)
    return {
        "kv": {f"kv={v:g}": _key(0.0, v, 1.0) if v else off for v in values},
        "kp": {f"kp={v:g}": _key(v, 0.0, 1.0) if v else off for v in values},
        "ld": {**{f"l_d={v:g}": _key(kp_for_ld, 0.0, v) for v in values}, "reflex off": off},
    }


def _plot_groups(ax, tr, field, ylabel):
    for group, series in tr[field].items():
        ax.plot(tr["time"], series, lw=1, label=group)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)


def _listing(finals: dict) -> str:
    return ", ".join(f"{k}: {'diverged' if v is None else thesis.deg(v)}" for k, v in finals.items())


def _smallest(finals: dict) -> str:
    valid = {k: abs(v) for k, v in finals.items() if v is not None}
    return min(valid, key=valid.get) if valid else "none (all diverged)"


def _spread(finals) -> float | None:
    vals = [f for f in finals if f is not None]
    return float(np.ptp(vals)) if len(vals) > 1 else None


def run(out_dir, model=None, workers=2, inputs=None, duration=4.0, values=None, kp_for_ld=0.1):
    values = tuple(values or thesis.reference_value("reflex.thesis.gain_sweep_values"))
    k = thesis.reference_value("intervertebral.thesis_table_3_1.stiffness")
    c = thesis.reference_value("intervertebral.thesis_table_3_1.damping")
    sweeps = _sweeps(values, kp_for_ld)
    keys = sorted({key for sweep in sweeps.values() for key in sweep.values()})
    cases = []
    for config in CONFIGS:
        bushings = thesis.locked_levels(k, c) if config == "locked" else {"stiffness": k, "damping": c}
        for key in keys:
            kp, kv, ld = (float(part.split("=")[1]) for part in key.split())
            cases.append({"label": f"{config} {key}",
                          "simulate": dict(duration=duration, perturbation=None, kp=kp, kv=kv, l_desired=ld, **bushings)})
    traces = thesis.run_cases(cases, model, workers)
    pick = lambda sweep, config: {label: traces[f"{config} {key}"] for label, key in sweeps[sweep].items()}  # noqa: E731

    plt = thesis.pyplot()
    figures = []
    detail = {"kv": ("fiber_velocity", "mean normalised fiber velocity", f"kv={values[1]:g}"),
              "kp": ("fiber_length", "mean normalised fiber length", f"kp={values[1]:g}")}
    for sweep, number in (("kv", "4_7"), ("kp", "4_8"), ("ld", "4_9")):
        rows = 2 if sweep in detail else 1
        fig, axes = plt.subplots(rows, 2, figsize=(12, 3.8 * rows), sharex=True, squeeze=False)
        styles = {"reflex off": {"color": "k", "ls": ":"}}
        thesis.plot_traces(axes[0, 0], pick(sweep, "locked"), "L5_S1_FE", "L5-S1 rotation (deg)", styles)
        thesis.plot_traces(axes[0, 1], pick(sweep, "free"), ylabel="total lumbar rotation (deg)", styles=styles)
        axes[0, 0].set_title("other levels locked (thesis)", fontsize=9)
        axes[0, 1].set_title("all five levels free: S1-L1 (sum of levels)", fontsize=9)
        if sweep in detail:
            field, ylabel, label = detail[sweep]
            for col, config in enumerate(CONFIGS):
                tr = traces[f"{config} {sweeps[sweep][label]}"]
                if "error" not in tr:
                    _plot_groups(axes[1, col], tr, field, f"{ylabel}\n({label}, {config})")
        for ax in axes[-1]:
            ax.set_xlabel("time (s)")
        fig.suptitle(f"Fig. {number.replace('_', '.')}: {sweep} sweep (equal gains for all muscles, no co-activation, "
                     f"k = {k:g} Nm/rad, c = {c:g} Nms/rad)")
        figures.append(thesis.save_figure(fig, f"{out_dir}/fig{number}_{sweep}_sweep.png"))

    def finals(sweep, config, key="L5_S1_FE"):
        return {label: thesis.final_deg(tr, key) for label, tr in pick(sweep, config).items()}

    kv_locked = finals("kv", "locked")
    kv_peaks = {label: None if "error" in tr else float(np.max(np.abs(tr["levels_deg"]["L5_S1_FE"])))
                for label, tr in pick("kv", "locked").items()}
    kp_locked, kp_free = finals("kp", "locked"), finals("kp", "free", "lumbar_rotation_deg")
    ld_locked, ld_free = finals("ld", "locked"), finals("ld", "free", "lumbar_rotation_deg")
    spread = _spread(kv_locked.values())
    kv_short = ("runs diverged" if spread is None else f"{'leaves' if spread < 0.1 else 'moves'} the end point, and the peak "
                f"L5-S1 rotation {thesis.trend(kv_peaks.values())} with kv")
    ours = {
        "kv": f"kv {kv_short} (locked; end-point spread {spread or float('nan'):.2f} deg; peaks {_listing(kv_peaks)} deg).",
        "kp": f"Final L5-S1 rotation (locked) {_listing(kp_locked)} deg; total lumbar rotation (free) {_listing(kp_free)} deg.",
        "ld": (f"Smallest |rotation|: {_smallest(ld_locked)} (locked, L5-S1), {_smallest(ld_free)} (free, total). Final L5-S1 "
               f"(locked) {_listing(ld_locked)} deg; total (free) {_listing(ld_free)} deg."),
    }
    rows = [[key, thesis.describe(traces[f"locked {key}"], "L5_S1_FE"), thesis.describe(traces[f"free {key}"], "L5_S1_FE"),
             thesis.describe(traces[f"free {key}"])] for key in keys]
    neutral = {g: float(series[0]) for g, series in traces[f"locked {_key(0.0, 0.0, 1.0)}"]["fiber_length"].items()} \
        if "error" not in traces[f"locked {_key(0.0, 0.0, 1.0)}"] else {}
    summary = (f"kv {kv_short}; with kp the locked L5-S1 rotation {thesis.trend(kp_locked.values())} and the free total "
               f"rotation {thesis.trend(kp_free.values())}; "
               f"smallest rotation: {_smallest(ld_locked)} (locked), {_smallest(ld_free)} (free).")
    return thesis.section(
        THESIS_SUMMARY, summary,
        comparison=[[f"{s} sweep", THESIS[s], ours[s]] for s in ("kv", "kp", "ld")],
        figures=figures,
        tables=[{"caption": f"Final rotation after {duration:g} s (peak in brackets)",
                 "header": ["gains", "L5-S1 (locked)", "L5-S1 (free)", "total lumbar (free)"], "rows": rows}],
        notes=[f"The l_d sweep uses kp = {kp_for_ld:g} and kv = 0; l_d is normalised by the optimal fiber length (thesis eq. 3.2 "
               "and 3.2.1; its section 4.5.1 also calls it a ratio to the neutral length, which is ambiguous).",
               "The thesis does not give kp during the kv sweep ('kp and l_d remain invariable'); we use kp = 0 so that kv acts alone.",
               "With all levels free, k = 100 Nm/rad and no co-activation the trunk buckles (see Fig. 4.5); equal reflex "
               "gains of at most 1 change how far, not whether.",
               "Why kp can add flexion: at the upright posture the mean normalised fiber length per group is "
               + ", ".join(f"{g} {v:.2f}" for g, v in neutral.items())
               + ". With l_d = 1 the groups above 1 (stretched beyond optimal at rest) receive tonic reflex excitation "
               "at once, the others only once stretched; the balance between them, not the thesis' stiffening alone, sets "
               "the end point."],
        numbers={"final_L5_S1_deg_locked": {"kv": kv_locked, "kp": kp_locked, "ld": ld_locked},
                 "final_total_deg_free": {"kp": kp_free, "ld": ld_free}, "peak_L5_S1_deg_locked_kv": kv_peaks,
                 "neutral_normalized_fiber_length": neutral},
        settings={"duration_s": duration, "stiffness_Nm_per_rad": k, "damping_Nms_per_rad": c, "co-activation": "none",
                  "perturbation": "none (gravity only)", "sweep values": list(values)},
    )


if __name__ == "__main__":
    from trunk_drake.commands.reproduce import script_main

    raise SystemExit(script_main(__file__))
