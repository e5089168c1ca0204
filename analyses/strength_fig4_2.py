"""Thesis Fig. 4.2 (and 4.1, appendix A.2): maximal isometric extension, flexion and lateral-bending
strength with the pelvis locked, against in vivo values.

Solved directly as a linear program and by the thesis' 10 N static-optimisation sweep
(trunk_drake.optim.strength), on the 3-D spine (pelvis welded)."""

from collections import Counter

from trunk_drake import reproduce as rp
from trunk_drake.optim.strength import DIRECTIONS, isometric_strength, strength_report

THESIS = ("Model predictions lie within the in vivo ranges (Paalanne et al. for sagittal, Thomas et al. for lateral "
          "bending) and exceed Schmid et al.'s; extension strength is excessive, lateral flexion the lowest prediction; "
          "in vivo, extension is strongest and sagittal flexion weakest. Flexion: 900 N with the load at T6/T7 (880 N at "
          "the sternum). Abdominal muscles saturate first in flexion, lumbar extensors in extension, left-side muscles "
          "in lateral bending.")


def _plot(path, summaries):
    plt = rp.pyplot()
    fig, ax = plt.subplots(figsize=(11, 4.8))
    ticks, names = [], []
    pos = 0.0
    for direction, s in summaries.items():
        bars = [("trunk-drake", s["max_force_N"], None, "C4")]
        bars += [(f"trunk-drake, {name}", v["max_force_N"], None, "C9") for name, v in s.get("variants", {}).items()]
        for row in s["in_vivo"]:
            if isinstance(row["mean_N"], (int, float)):
                sd = row["sd_N"] if isinstance(row["sd_N"], (int, float)) else None
                parts = row["reference"].split(".")
                label = parts[-1] if row["kind"] == "in vivo" else f"{parts[1]}: {parts[2]}"
                bars.append((label, row["mean_N"], sd, "C1" if row["kind"] == "in vivo" else "C8"))
        start = pos
        for label, value, sd, color in bars:
            ax.bar(pos, value, 0.8, yerr=sd, color=color, capsize=3)
            ax.text(pos, value + (sd or 0) + 15, f"{value:.0f}", ha="center", fontsize=7)
            ticks.append(pos)
            names.append(label)
            pos += 1.0
        ax.text((start + pos - 1) / 2, 0.95, direction, transform=ax.get_xaxis_transform(), ha="center", fontsize=10, weight="bold")
        pos += 1.0
    ax.set_xticks(ticks, names, rotation=35, ha="right", fontsize=7)
    ax.set_ylabel("maximal isometric force (N)")
    ax.grid(alpha=0.3, axis="y")
    ax.set_ylim(top=ax.get_ylim()[1] * 1.1)
    ax.set_title("Fig. 4.2: trunk-drake (purple; cyan: load at the acromion) vs in vivo comparators (orange, ±1 SD) "
                 "and the thesis' model (olive)", fontsize=10)
    return rp.save_figure(fig, path)


def run(out_dir, model=None, workers=2, inputs=None, sweep=True):
    from trunk_drake.model.trunk_model import load_model

    spine = load_model("spine3d", spec=model.spec if model is not None else None)
    results = isometric_strength(spine, DIRECTIONS, sweep=sweep)
    report = strength_report(results, spine, {"sweep": sweep})
    summaries = report["results"]
    figure = _plot(f"{out_dir}/fig4_2_strength.png", summaries)

    def in_vivo(direction, kind="in vivo"):
        rows = [r for r in summaries[direction]["in_vivo"] if r["kind"] == kind]
        return "; ".join(f"{r['reference'].split('.', 1)[1]}: " + (f"{r['mean_N']:.0f} N" if isinstance(r["mean_N"], (int, float))
                                                                   else "no number available") for r in rows) or "none"

    rows = []
    for d, s in summaries.items():
        sweep_cell = "not run" if not s["sweep"]["solves"] else f"{s['sweep']['last_feasible_N']} N ({s['sweep']['solves']} solves)"
        top = next(iter(s["sensitivity_N_per_Nm"].items()))
        rows.append([d, f"{s['max_force_N']:.1f}", sweep_cell, s["limiting_coordinate"], f"{top[1]:+.2f}",
                     len(s["muscles_at_upper_bound"]), ", ".join(s["muscles_at_upper_bound"][:6])
                     + (" ..." if len(s["muscles_at_upper_bound"]) > 6 else "")])
    group_of = {m: g for g, members in spine.groups.items() for m in members}
    saturated = {d: Counter(group_of[m] for m in s["muscles_at_upper_bound"]).most_common(3) for d, s in summaries.items()}
    sides = {d: [sum(m.endswith(end) for m in s["muscles_at_upper_bound"]) for end in ("_l", "_r")] for d, s in summaries.items()}
    forces = {d: s["max_force_N"] for d, s in summaries.items()}
    order = sorted(forces, key=forces.get, reverse=True)
    ours = (f"Extension {forces['extension']:.0f} N, flexion {forces['flexion']:.0f} N, lateral bending {forces['lateral']:.0f} N "
            f"(order: {' > '.join(order)}); limiting coordinate(s): "
            f"{', '.join(sorted({s['limiting_coordinate'] for s in summaries.values()}))}. "
            + "; ".join(f"{d}: {v['max_force_N']:.0f} N with the load at the acromion" for d, s in summaries.items()
                        for v in s.get("variants", {}).values()) + ".")
    return rp.section(
        THESIS, ours,
        comparison=[["extension", "excessive (above in vivo), strongest",
                     f"{forces['extension']:.0f} N; in vivo comparators: {in_vivo('extension')}"],
                    ["flexion", "900 N (T6/T7 load); in vivo the weakest",
                     f"{forces['flexion']:.0f} N; in vivo comparators: {in_vivo('flexion')}"],
                    ["lateral bending", "lowest model prediction", f"{forces['lateral']:.0f} N; in vivo comparators: {in_vivo('lateral')}"],
                    ["muscles at the upper bound (fig. 4.1, appendix A.2)", "flexion: abdominals; extension: sacrospinalis "
                     "and transversospinalis; lateral: left-side muscles",
                     "; ".join(f"{d}: " + ", ".join(f"{g} {n}" for g, n in top) + f" (left {sides[d][0]}, right {sides[d][1]})"
                               for d, top in saturated.items())],
                    ["thesis' in vivo sources", "Paalanne et al. 2009, Thomas et al.",
                     "their numbers could not be read (models/reference_values.toml): Kocjan & Sarabon 2014 and Sinaki 1996 "
                     "are shown as order-of-magnitude comparators (other populations)"]],
        figures=[figure],
        tables=[{"caption": "Maximal isometric strength (pelvis locked, upright)",
                 "header": ["direction", "direct maximum (N)", "10 N sweep: last feasible", "limiting coordinate",
                            "dF/d(extra moment) (N/Nm)", "muscles at upper bound", "first of them"], "rows": rows}],
        notes=[*report["notes"],
               "MyoTorso lumps thorax, arms and head into one body, and its upper-body centre of mass lies 1.1 cm posterior to "
               "L4/L5 (the thesis' model: 9.1 cm anterior); the thesis raised 54 muscles' maximal forces (appendix A.1), we "
               "keep MyoTorso's. Every lumbar level must balance the load on its own (static optimisation of all "
               "lumbar coordinates); the weakest level limits the whole trunk."],
        numbers={"max_force_N": forces, "saturated_by_group": saturated, "report": report},
        settings={"model": "spine3d (15 lumbar DOF), pelvis welded", "static optimisation": "sum of squared activations, "
                  "min activation 0.01", "load": "T6/T7 landmarks (sagittal), left shoulder site (lateral)"},
    )


if __name__ == "__main__":
    from trunk_drake.commands.reproduce import script_main

    raise SystemExit(script_main(__file__))
