"""Thesis Table 4.1 and section 4.3: integrator steps as muscle groups are added one by one (1 s,
intrinsic properties only), 'oscillating' muscles, and wall times against the thesis' (4 s of
simulation took 4.5 h, later 30 s; the reflex-gain fit ~70 h)."""

import time
import warnings

import numpy as np

from trunk_drake import thesis
from trunk_drake.diagnostics import THESIS_GROUP_ORDER, extreme_muscles, steps_by_group
from trunk_drake.simulation import MAX_STEP, simulate

# seed thesis Table 4.1: (group, muscles, integrator steps before and after the tendon slack length changes), 1 s each;
# without muscles the integrator took 16 steps (section 4.3)
THESIS_TABLE_4_1 = (
    ("sacrospinalis", 76, 322, 43), ("transversospinalis", 74, 640, 77), ("latissimus_dorsi", 28, 1311, 107),
    ("quadratus_lumborum", 36, 1367, 141), ("internal_oblique", 12, 1458, 156), ("external_oblique", 14, 1547, 218),
    ("transversus_abdominis", 10, 1670, 245), ("rectus_abdominis", 2, 2021, 299), ("psoas_major", 22, 2548, 318),
)
THESIS_NO_MUSCLE_STEPS = 16
THESIS_WALL_4S = {"initial": "4.5 h", "after inertia and DOF changes": "2.1 h", "final (tendon slack lengths changed)": "30 s"}
THESIS_FIT = "~70 h"
THESIS = ("Initially 4 s took 4.5 h; after raising L4/L5 inertia and removing DOF 2.1 h; muscles with unreasonable fiber "
          "velocities (e.g. iliocostalis) were tamed by lengthening tendon slack lengths, cutting the 1 s integrator steps "
          "with all groups from 2548 to 318; finally 4 s took 30 s. The reflex-gain fit took ~70 h.")
FIT = "fitted_gains_tables4_2_4_3"


def run(out_dir, model=None, workers=2, inputs=None, step_duration=1.0, trial_duration=4.0):
    if model is None:
        from trunk_drake.model.trunk_model import load_model

        model = load_model("sagittal")
    rows = steps_by_group(model, duration=step_duration)
    final, _ = thesis.thesis_final_options(model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        start = time.perf_counter()
        trial = simulate(model, duration=trial_duration, bandwidth=1.0, **final, **thesis.thesis_gains())
        trial_wall = time.perf_counter() - start
    flagged = extreme_muscles(trial)
    fit = (inputs or {}).get(FIT, {})
    fit_numbers = fit.get("numbers") if fit.get("status") == "ok" else None

    ours_by_group = {r["added_group"]: r for r in rows}
    table = [["(no muscles)", 0, THESIS_NO_MUSCLE_STEPS, THESIS_NO_MUSCLE_STEPS, 0, ours_by_group["(no muscles)"]["steps"],
              ours_by_group["(no muscles)"]["derivative_evaluations"], f"{ours_by_group['(no muscles)']['wall_time_s']:.2f}"]]
    for group, n, old, new in THESIS_TABLE_4_1:
        r = ours_by_group.get(group)
        table.append([group, n, old, new, *((r["n_muscles"], r["steps"], r["derivative_evaluations"], f"{r['wall_time_s']:.2f}")
                                           if r else ("absent in MyoTorso",) + ("-",) * 3)])

    plt = thesis.pyplot()
    fig, ax = plt.subplots(figsize=(10, 4.5))
    labels = ["(no muscles)", *(g for g, *_ in THESIS_TABLE_4_1)]
    x = np.arange(len(labels))
    thesis_old = [THESIS_NO_MUSCLE_STEPS, *(old for _, _, old, _ in THESIS_TABLE_4_1)]
    thesis_new = [THESIS_NO_MUSCLE_STEPS, *(new for *_, new in THESIS_TABLE_4_1)]
    ours = [ours_by_group[g]["steps"] if g in ours_by_group else np.nan for g in labels]
    ax.bar(x - 0.27, thesis_old, 0.27, color="0.75", label="thesis, original tendon slack lengths")
    ax.bar(x, thesis_new, 0.27, color="0.45", label="thesis, changed tendon slack lengths")
    ax.bar(x + 0.27, ours, 0.27, color="C0", label="trunk-drake (Radau3, rigid tendons)")
    ax.set_xticks(x, [f"+{g.replace('_', ' ')}" if i else g for i, g in enumerate(labels)], rotation=30, ha="right", fontsize=8)
    ax.set_yscale("log")
    ax.set_ylabel(f"integrator steps for {step_duration:g} s")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    ax.set_title("Table 4.1: muscle groups added one by one (cumulative), intrinsic properties only")
    figure = thesis.save_figure(fig, f"{out_dir}/table4_1_steps.png")

    all_groups = ours_by_group[THESIS_GROUP_ORDER[-1]]
    floor = int(np.ceil(step_duration / MAX_STEP))
    fit_text = (f"settling {fit_numbers['settling']['wall_time_s'] / 60:.1f} min, "
                f"car passenger {fit_numbers['car']['wall_time_s'] / 60:.1f} min "
                f"({fit_numbers['car']['n_simulations']} simulations)" if fit_numbers else "not run in this report")
    ours_text = (f"With all {all_groups['n_muscles']} muscles, {step_duration:g} s takes {all_groups['steps']} steps "
                 f"({all_groups['wall_time_s']:.2f} s wall) without touching any tendon slack length (Christophy et al.'s "
                 f"published derivation). {trial_duration:g} s of the thesis' final model with reflexes and the 1 Hz "
                 f"perturbation: {trial_wall:.1f} s wall ({trial.stats['steps']} steps, real-time factor "
                 f"{trial_duration / trial_wall:.1f}). Reflex-gain fits: {fit_text}. {len(flagged)} muscles flagged as extreme.")
    return thesis.section(
        THESIS, ours_text,
        comparison=[["steps, 1 s, all groups", "2548 (original), 318 (changed tendon slack lengths)", f"{all_groups['steps']}"],
                    ["steps, 1 s, no muscles", f"{THESIS_NO_MUSCLE_STEPS}", f"{ours_by_group['(no muscles)']['steps']}"],
                    ["wall time, 4 s with reflexes", "; ".join(f"{k}: {v}" for k, v in THESIS_WALL_4S.items()),
                     f"{trial_wall * 4.0 / trial_duration:.1f} s"],
                    ["reflex-gain fit", THESIS_FIT, fit_text],
                    ["muscles with extreme fiber states", "iliocostalis oscillated (fixed by tendon slack lengths, Appendix B)",
                     ", ".join(r["muscle"] for r in flagged) or "none"]],
        figures=[figure],
        tables=[{"caption": f"Integrator steps for {step_duration:g} s as groups are added (cumulative)",
                 "header": ["added group", "thesis muscles", "thesis steps (original)", "thesis steps (changed)", "our muscles",
                            "our steps", "our derivative evaluations", "our wall (s)"], "rows": table},
                {"caption": f"Muscles whose normalised fiber length leaves 0.5-1.5 or whose |velocity| exceeds 0.5 "
                            f"(the {trial_duration:g} s trial)",
                 "header": ["muscle", "min length", "max length", "peak |velocity|", "velocity sign changes"],
                 "rows": [[r["muscle"], f"{r['min_normalized_length']:.2f}", f"{r['max_normalized_length']:.2f}",
                           f"{r['peak_normalized_velocity']:.2f}", r["velocity_sign_changes"]] for r in flagged]}],
        notes=["Step counts of different integrators are not comparable one to one: the thesis used OpenSim's variable-step "
               f"integrator; trunk-drake uses Drake's L-stable Radau3 with error control (accuracy 1e-2), rigid tendons and a "
               f"{1000 * MAX_STEP:g} ms maximum step, i.e. at least {floor} steps per {step_duration:g} s: our counts "
               f"({min(r['steps'] for r in rows)}-{max(r['steps'] for r in rows)}) sit at that floor, so adding muscle groups "
               "costs time per step (derivative evaluations), not extra steps.",
               "Group runs: no perturbation, no reflexes, minimum activation 0.01, bushings 100 Nm/rad and 7.5 Nms/rad "
               "(diagnostics.steps_by_group).",
               f"Wall times are this machine's ({workers} worker processes for sweeps and fits; single process for this table)."],
        numbers={"steps_by_group": rows, "trial": {"duration_s": trial_duration, "wall_time_s": trial_wall, **trial.stats},
                 "extreme_muscles": flagged,
                 "fit_wall_time_s": {k: fit_numbers[k]["wall_time_s"] for k in ("settling", "car")} if fit_numbers else None,
                 "thesis": {"table_4_1": THESIS_TABLE_4_1, "no_muscle_steps": THESIS_NO_MUSCLE_STEPS, "wall_4s": THESIS_WALL_4S,
                            "fit": THESIS_FIT}},
        settings={"group runs": f"{step_duration:g} s each", "trial": f"{trial_duration:g} s, thesis final model with Table 4.3 gains, "
                  "0.2-1 Hz multisine"},
    )


if __name__ == "__main__":
    from trunk_drake.commands.reproduce import script_main

    raise SystemExit(script_main(__file__))
