"""Write a gap diagnosis: diagnosis.json, report.md and figures (where, ranking, before/after)."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from trunk_drake.metadata import json_default  # noqa: E402
from trunk_drake.gap.search import deciding_ranking  # noqa: E402


def write_diagnosis(diagnosis, out_dir, animations: dict[str, Path] | None = None) -> dict[str, Path]:
    """All files of one diagnosis; returns their paths. `animations`: pages of key runs (label ->
    file in out_dir) that the report links."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    files = {"json": out / "diagnosis.json", "report": out / "report.md"}
    files["json"].write_text(json.dumps(diagnosis.to_dict(), indent=2, default=json_default))
    files["frf_plot"] = _plot_where(diagnosis, out / "where_frf.png")
    files["ranking_plot"] = _plot_ranking(diagnosis, out / "ranking.png")
    if diagnosis.series:
        files["shrink_plot"] = _plot_shrink(diagnosis, out / "before_after.png")
    report = markdown(diagnosis, {k: v.name for k, v in files.items()})
    if animations:
        report += "\n## Animations (open offline in a browser)\n\n" + "".join(
            f"- [{label}]({Path(path).name})\n" for label, path in animations.items())
        files.update({f"animation_{k}": Path(p) for k, p in enumerate(animations.values())})
    files["report"].write_text(report)
    return files


def markdown(d, names: dict) -> str:
    """The report: verdict, where, which (ranking), how far (shrinkage)."""
    s = d.shrink
    lines = ["# Sim-to-real gap diagnosis", "", f"**Verdict: {d.verdict}.**", "",
             f"Measurement noise {np.round(np.degrees(d.noise_rad), 3).tolist()} deg (per output); held-out data: {d.options['held_out']}; "
             f"{d.options['scores']['simulations']} simulations in {d.wall_time_s:.0f} s.", "",
             "## 1. Where the gap lies", "", "| output | VAF (nominal) | chi2 per sample | RMS residual (deg) |", "|---|---|---|---|"]
    for out, row in d.where["per_output"].items():
        lines.append(f"| {out} | {100 * row['vaf']:.2f} % | {row['chi2_per_sample']:.2f} | {row['rms_residual_deg']:.3f} |")
    lines += ["", "chi2 per sample near 1 means the model is within measurement noise.", ""]
    for trial, f in d.where["per_frequency"].items():
        sig = np.asarray(f["significant"])
        freqs = np.asarray(f["frequencies_hz"])
        where = (f"significant FRF errors (beyond 2 SD of the data) at {', '.join(f'{x:.2f}' for x in freqs[sig])} Hz"
                 if sig.any() else "no FRF error beyond 2 SD of the data")
        ratio = f["nonexcited_ratio_data"], f["nonexcited_ratio_model"]
        if ratio[0] is not None and ratio[1] is not None:
            where += f"; power at non-excited lines / excited: data {ratio[0]:.2g}, model {ratio[1]:.2g}"
        lines.append(f"- `{Path(trial).name}`: {where}")
    lines += ["", f"![FRF errors]({names['frf_plot']})", "", "## 2. Which unmodelled effect", "",
              "First step: each candidate is refitted with the nominal reflex gains and scored on held-out data: "
              "dBIC = chi2(gains-only refit) - chi2(candidate) - k ln N (positive favours the candidate; "
              f"claimed above {d.options['threshold']:g}).", "", *_ranking_table(d.ranking)]
    k, deciding = deciding_ranking(d.steps, d.ranking)
    if deciding is not None and deciding is not d.ranking:
        step = d.steps[k]
        claim = f"claimed {step['effect']}" if step["action"] == "add" else "claimed none"
        lines += ["", f"The ranking that decided the selection, step {k + 1} ({claim}): each candidate added to "
                  f"{' + '.join(step['model'][:-1] if step['action'] == 'add' else step['model']) or 'the gains'}"
                  f"{' on all ' + str(step['directions']) + ' gain directions' if 'directions' in step else ''}, dBIC "
                  "against that model. The first step weighs each candidate against the gains refitted along the identifiable "
                  "directions only, and effects that stand in for gains mis-set further can lead it.", "", *_ranking_table(deciding)]
    lines += ["", f"![ranking]({names['ranking_plot']})", "", "Selection, step by step (each effect's own held-out dBIC "
              "against the model without it):", ""]
    lines += [f"{k}. {_step(step)}" + (f" ({step['simulations']} simulations so far)" if "simulations" in step else "")
              for k, step in enumerate(d.steps, 1)] or ["1. nothing to select"]
    lines += ["", "## 3. How far the gap shrinks (held-out data)", ""]
    if s:
        gap = s["gap"]
        lines += ["| model | 1 - VAF (lumbar rotation) | mean abs log FRF error |", "|---|---|---|"]
        for k in gap:
            lines.append(f"| {k} | {gap[k]:.5f} | {s['frf_error'].get(k, float('nan')):.4f} |")
        lines += ["", f"Noise floor of 1 - VAF: {s['noise_floor_gap']:.5f}. Gap reduction from the nominal model: "
                  f"{100 * s['reduction']:.1f} % of 1 - VAF (95 % CI {100 * s['reduction_ci95'][0]:.1f} to "
                  f"{100 * s['reduction_ci95'][1]:.1f} %), {100 * s['reduction_above_noise']:.1f} % of the part above the noise floor.", ""]
        if "shrink_plot" in names:
            lines += [f"![before and after]({names['shrink_plot']})", ""]
    if d.remainder:
        r = d.remainder
        chi2 = ", ".join(f"{o} {v:.3f}" for o, v in r["chi2_per_sample"].items())
        lines += [f"**What remains is {'' if r['is_noise'] else 'not '}measurement noise** (each test at p < {r['p_threshold']:g}): "
                  f"held-out chi2 per sample {chi2} (expected 1); residual whiteness (Ljung-Box) p = {r['ljung_box']['p']:.3g}; "
                  f"FRF errors beyond 2 SD of the data at {r['frf']['significant']} of {r['frf']['lines']} lines "
                  f"(expected {100 * r['frf']['expected_rate']:.0f} %, p = {r['frf']['p']:.3g}).", ""]
    if d.final.get("effects"):
        lines += ["Selected model (fitted on the training halves):", "",
                  *(f"- {n}: " + ", ".join(f"{k} = {v:.4g}" for k, v in vals.items()) for n, vals in d.final["effects"].items()), ""]
    return "\n".join(lines) + "\n"


def _ranking_table(rows: list[dict]) -> list[str]:
    """Candidate rows (best first) as a markdown table."""
    lines = ["| rank | effect | dBIC (nonlinear refit) | dBIC (simulated at the best of three starts) | dBIC (linear screening) | "
             "parameters (refitted, else simulated, else linear) | status |", "|---|---|---|---|---|---|---|"]
    for k, r in enumerate(rows, 1):
        values = r.get("values") or r.get("checked_values") or r.get("linear_values") or {}
        text = ", ".join(f"{n} = {v:.4g}" for n, v in values.items())
        dbic, checked = (f"{r[key]:.1f}" if r.get(key) is not None else "-" for key in ("delta_bic", "checked_delta_bic"))
        lines.append(f"| {k} | {r['effect']} | {dbic} | {checked} | {r['linear_delta_bic']:.1f} | {text} | {r.get('status', '')} |")
    return lines


def _values(by_effect: dict) -> str:
    """Fitted parameter values, effect by effect."""
    return "; ".join(f"{n}: " + ", ".join(f"{k} = {v:.4g}" for k, v in vals.items()) for n, vals in by_effect.items())


def _step(step: dict) -> str:
    model = " + ".join(step["model"]) or "gains only"
    on = f" on all {step['directions']} gain directions" if "directions" in step else ""
    if step["action"] == "add":
        values = _values(step["values"])
        against = _against_gains(step)
        partner = (f"; a partner of {' + '.join(step['partner_of'])}, refitted with it from its own first-step fit or "
                   "a profile over its parameters" if step.get("partner_of") else "")
        return (f"add **{step['effect']}**{on} (dBIC {step['delta_bic']:.1f}{'; ' + against if against else ''}{partner}); "
                f"joint refit of {model}: {values}")
    if step["action"] == "gains":
        return (f"gains refitted along {step['directions']} directions (dBIC {step['delta_bic']:.1f}): mis-set gains beyond "
                f"the identifiable ones; model: {model}")
    if step["action"] == "polish":
        values = _values(step["values"])
        return f"polish: gains along all {step['directions']} directions refitted with the effects{': ' + values if values else ''}; model: {model}"
    if step["action"] == "restart":
        before, after = step["train_chi2"]
        return (f"restart{on}: the effects refitted from the nominal gains fit the training halves better ({before:.0f} -> "
                f"{after:.0f}): {_values(step['values'])}; model: {model}")
    if step["action"] == "regain":
        before, after = step["train_chi2"]
        return (f"regain{on}: the gains refitted from a candidate's fit without it fit the training halves better "
                f"({before:.0f} -> {after:.0f}); the selection goes on from them; model: {model}")
    if step["action"] == "partners":
        tried = ", ".join(f"{n} {v:.1f}" for n, v in step["tried"].items()) or "none refitted"
        return f"partners{on}: each first-step effect refitted with the model (dBIC {tried}): none passes; model: {model}"
    if step["action"] in ("keep", "drop"):
        own = ", ".join(f"{n} {v:.1f}" for n, v in step["own_delta_bic"].items())
        return (f"drop **{step['effect']}**" if step["action"] == "drop" else "keep all") + f" (own dBIC{on}: {own}); model: {model}"
    matched = step.get("matched_by_gains") or []
    if matched:
        names = ", ".join(f"{m['effect']} (dBIC {m['delta_bic']:.1f}; {_against_gains(m)})" for m in matched)
        return f"stop{on}: {names}: mis-set gains explain as much; model: {model}"
    best = f"best remaining {step['best_candidate']} (dBIC {step['delta_bic']:.1f})" if step["best_candidate"] else "no candidate left"
    return f"stop{on}: {best} does not pass; model: {model}"


def _against_gains(tried: dict) -> str:
    """How a candidate fared against the gains: its margin over the gains along as many more directions, and
    its dBIC on top of the gains widened as far as they pass."""
    parts = []
    if tried.get("beats_gain_rival_by") is not None:
        parts.append(f"{tried['beats_gain_rival_by']:+.1f} against the gains along as many more directions")
    nested = tried.get("on_widened_gains")
    if nested:
        parts.append(f"dBIC {nested['delta_bic']:.1f} on top of the gains widened by {nested['directions']} direction(s)")
    if tried.get("delta_bic_against_refit") is not None:
        parts.append(f"dBIC {tried['delta_bic_against_refit']:.1f} against the best model refitted from a candidate's fit without it")
    return ", ".join(parts)


def _plot_where(d, path) -> Path:
    fig, (ax_g, ax_p) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for k, (trial, f) in enumerate(d.where["per_frequency"].items()):
        freq = np.asarray(f["frequencies_hz"])
        sig = np.asarray(f["significant"])
        color = f"C{k}"
        ax_g.semilogx(freq, f["gain_error_percent"], "-o", color=color, ms=3, label=Path(trial).name)
        ax_g.fill_between(freq, -2 * np.asarray(f["sigma_percent"]), 2 * np.asarray(f["sigma_percent"]), color=color, alpha=0.12)
        ax_g.plot(freq[sig], np.asarray(f["gain_error_percent"])[sig], "o", color=color, ms=7, mfc="none")
        ax_p.semilogx(freq, f["phase_error_deg"], "-o", color=color, ms=3)
    ax_g.axhline(0, color="0.5", lw=0.8)
    ax_p.axhline(0, color="0.5", lw=0.8)
    ax_g.set_ylabel("gain error model/data (%)")
    ax_p.set_ylabel("phase error (deg)")
    ax_p.set_xlabel("frequency (Hz)")
    ax_g.legend(fontsize=7)
    ax_g.set_title("nominal model vs data: FRF errors (bands: 2 SD of the data; circles: significant)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _plot_ranking(d, path) -> Path:
    """The ranking that decided the selection (`deciding_ranking`; the first step's where no later one did)."""
    k, rows = deciding_ranking(d.steps, d.ranking)
    rows = d.ranking if rows is None else rows
    fig, ax = plt.subplots(figsize=(7, 3.5))
    names = [r["effect"] for r in rows]
    values = [next(r[key] for key in ("delta_bic", "checked_delta_bic", "linear_delta_bic") if r.get(key) is not None) for r in rows]
    colors = ["C3" if n in d.selected else ("C0" if r.get("delta_bic") is not None else "0.7") for n, r in zip(names, rows)]
    if rows is not d.ranking:
        ax.set_title(f"step {k + 1} of the selection: the ranking that decided it", fontsize=9)
    ax.barh(names[::-1], np.sign(values[::-1]) * np.log10(1 + np.abs(values[::-1])), color=colors[::-1])
    ax.axvline(np.log10(1 + d.options["threshold"]), color="k", ls="--", lw=0.8)
    ax.set_xlabel("sign(dBIC) log10(1 + |dBIC|)\nred: claimed, blue: refitted, grey: simulated or screened only", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _plot_shrink(d, path) -> Path:
    n = len(d.series)
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.4 * n), squeeze=False)
    for ax, (trial, s) in zip(axes[:, 0], d.series.items()):
        t = s["time"]
        half = t.size // 2
        ax.plot(t, np.degrees(s["data"]), color="0.6", lw=1, label="data")
        for key, style in (("nominal", "C0"), ("refit", "C2"), ("effect", "C3"), ("widened", "C3")):
            if s.get(key) is not None:
                ax.plot(t, np.degrees(s[key] - s[key].mean()), color=style, lw=0.8, label=key)
        ax.axvspan(t[half], t[-1], color="0.9", zorder=0)
        ax.set_title(f"{Path(trial).name} (shaded: held out)", fontsize=9)
        ax.set_ylabel("lumbar rotation (deg)")
        ax.legend(loc="upper right", fontsize=7, ncol=4)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)
