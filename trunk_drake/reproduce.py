"""`trunk-drake reproduce`: run every thesis experiment (the scripts in analyses/) and write a report.

Each script ``analyses/<name>.py`` exposes ``run(out_dir, model=None, workers=2, inputs=None,
**options) -> dict`` (a section: what the thesis found, what we find, numbers, figures, notes)
and runs alone (``python analyses/<name>.py --out DIR``). This module holds the registry, the
runner (results written as each experiment finishes, reruns skip finished ones) and the
Markdown/JSON report writer; what the scripts share is in trunk_drake.thesis.
"""

from __future__ import annotations

import datetime
import importlib.util
import json
import os
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from trunk_drake.thesis import SYNTHETIC_NOTE, log

ANALYSES_DIR = Path(__file__).resolve().parents[1] / "analyses"
REPORT_JSON, REPORT_MD = "report.json", "report.md"


@dataclass(frozen=True)
class Experiment:
    """One thesis experiment: the script analyses/<name>.py; `requires` must run first (its entry
    is passed in ``inputs``); `quick`: run() keywords that shorten it to seconds (a smoke run
    of every code path, not a result)."""

    name: str
    title: str
    requires: tuple[str, ...] = ()
    quick: dict = field(default_factory=dict)


EXPERIMENTS = (
    Experiment("strength_fig4_2", "Isometric strength versus in vivo (Fig. 4.2)", quick={"sweep": False}),
    Experiment("bushing_sweeps_fig4_5", "Intervertebral stiffness and damping (Fig. 4.5)",
               quick={"duration": 0.5, "k_values": (100.0, 800.0), "c_values": (0.0, 8.0)}),
    Experiment("coactivation_fig4_6", "Co-activation levels (Fig. 4.6)", quick={"duration": 1.0, "levels": (0.02,)}),
    Experiment("reflex_sweeps_fig4_7_4_9", "Reflex gains kv, kp and set point l_d (Figs. 4.7-4.9)",
               quick={"duration": 0.5, "values": (0.1, 0.5)}),
    Experiment("force_disturbance_fig4_10_4_11", "Force disturbance and pelvis versus platform motion (Figs. 4.10-4.11)",
               quick={"duration": 2.0}),
    Experiment("fitted_gains_tables4_2_4_3", "Fitted reflex gains (Tables 4.2-4.3)",
               quick={"settling_duration": 0.5, "trials": ("trial_1hz_a.csv",), "max_iterations": 1, "t_max": 2.0}),
    Experiment("intrinsic_vs_reflex_fig4_13", "Intrinsic properties alone versus with reflexes (Fig. 4.13)", quick={"duration": 2.0}),
    Experiment("validation_fig4_14_4_15", "Validation: time-domain fit and VAF, FRF (Figs. 4.14-4.15)",
               requires=("fitted_gains_tables4_2_4_3",)),
    Experiment("computation_time_table4_1", "Computation time (Table 4.1)", quick={"step_duration": 0.2, "trial_duration": 1.0},
               requires=("fitted_gains_tables4_2_4_3",)),  # quotes the fits' times
)


def experiment(name: str) -> Experiment:
    for e in EXPERIMENTS:
        if e.name == name:
            return e
    raise ValueError(f"unknown experiment {name!r}; experiments: {[e.name for e in EXPERIMENTS]}")


def jsonable(obj):
    """Plain JSON data: arrays to lists, non-finite floats to strings ("inf", "nan")."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return jsonable(obj.item())
    if isinstance(obj, float) and not np.isfinite(obj):
        return str(obj)
    if isinstance(obj, Path):
        return str(obj)
    return obj


def _markdown_table(header, rows) -> list[str]:
    cell = lambda x: str(x).replace("|", "\\|").replace("\n", " ")  # noqa: E731
    return ["| " + " | ".join(map(cell, header)) + " |", "|" + "---|" * len(header)] + \
           ["| " + " | ".join(map(cell, r)) + " |" for r in rows]


def _relative(path: str, out: Path) -> str:
    """`path` relative to the report folder `out` (as stored: the folder can move), else unchanged."""
    if not Path(path).is_absolute():
        return str(path)
    try:
        return str(Path(path).resolve().relative_to(out.resolve()))
    except ValueError:
        return str(path)


def _relative_paths(value, out: Path):
    """`value` (an experiment's entry) with every path string into the report folder `out` made relative to it
    (figures, the files a fit wrote): the folder can move, and a committed report names no machine's folders."""
    if isinstance(value, dict):
        return {k: _relative_paths(v, out) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_relative_paths(v, out) for v in value)
    if isinstance(value, (str, Path)) and str(value):
        try:  # a file or folder the run wrote; text is left as it is
            return _relative(str(Path(value).resolve(strict=True)), out)
        except OSError:
            return value
    return value


def write_report(out_dir, report: dict) -> Path:
    """report.md from the report dict of run_experiments (sections in registry order)."""
    out = Path(out_dir)
    meta = report["metadata"]
    entries = report["experiments"]
    done = [e for e in EXPERIMENTS if e.name in entries]
    lines = ["# trunk-drake reproduction of the thesis' results (chapter 4)", "",
             f"> **Synthetic data.** {SYNTHETIC_NOTE}", "",
             f"Model: {meta['model']['source']} ({meta['model']['dofs']}, fingerprint `{meta['model']['fingerprint']}`, where a "
             "section names no other configuration: the fits, the validation and the synthetic truth run on the data's); "
             f"created {meta['created']} on {meta['machine']}, Python {meta['python']}; "
             + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()) + ".", "",
             "MyoTorso is not the thesis' model (Schmid et al.'s full-body OpenSim model): it has 7 of the thesis' 9 muscle "
             "groups (no latissimus dorsi, no transversus abdominis), no arms, and its upper-body centre of mass lies "
             "1.1 cm posterior to L4/L5 where the thesis' lies 9.1 cm anterior. Numbers are reported as measured, never "
             "tuned towards the thesis.", "", "## Wall time", ""]
    rows = [[e.title, f"{entries[e.name].get('elapsed_s', float('nan')):.1f}",
             entries[e.name].get("status", "?") + (" (--quick: shortened, not a result)" if entries[e.name].get("quick") else "")]
            for e in done]
    lines += _markdown_table(["experiment", "wall time (s)", "status"], rows)
    lines += ["", f"Sum over experiments (the cost of a full reproduction): "
              f"**{sum(entries[e.name].get('elapsed_s', 0.0) for e in done) / 60:.1f} min**.", "",
              "Invocations of `trunk-drake reproduce` into this folder (1-minute load average at start and end on "
              f"{os.cpu_count()} cores; above the worker count, other processes competed for the CPU and inflated the times):", ""]
    runs = [[r.get("started", "?"), f"{r['wall_time_s'] / 60:.1f}", r["workers"],
             ", ".join(n for n in r["selected"] if n not in r["skipped"]) or "none", ", ".join(r["skipped"]) or "none",
             " / ".join("-" if r.get(k) is None else f"{r[k]:.1f}" for k in ("load_average_at_start", "load_average_at_end"))]
            for r in report.get("runs", [report["run"]])]
    lines += _markdown_table(["started (UTC)", "wall time (min)", "workers", "computed", "skipped", "load average"], runs)
    lines += ["", "## Contents", ""]
    lines += [f"{i}. [{e.title}](#{e.name})" for i, e in enumerate(done, 1)]
    for i, e in enumerate(done, 1):
        entry = entries[e.name]
        lines += ["", f'<a id="{e.name}"></a>', f"## {i}. {e.title}", "",
                  f"Script: `analyses/{e.name}.py`; wall time {entry.get('elapsed_s', float('nan')):.1f} s.", ""]
        if entry.get("status") != "ok":
            lines += [f"**This experiment failed:** `{entry.get('error', 'unknown error')}`", ""]
            continue
        lines += _markdown_table(["", "Thesis", "trunk-drake"], [["finding", entry["thesis"], entry["ours"]], *entry["comparison"]])
        for fig in entry["figures"]:
            lines += ["", f"![{Path(fig).stem}]({_relative(fig, out)})"]
        for table in entry["tables"]:
            lines += ["", f"**{table['caption']}**", ""] + _markdown_table(table["header"], table["rows"])
        if entry["notes"]:
            lines += ["", "Notes:", ""] + [f"- {n}" for n in entry["notes"]]
        if entry["settings"]:
            lines += ["", "Settings: " + "; ".join(f"{k} = {v}" for k, v in entry["settings"].items()) + "."]
    path = out / REPORT_MD
    path.write_text("\n".join(lines) + "\n")
    return path


# ------------------------------------------------------------------------------ runner

def load_script(name: str):
    """Import analyses/<name>.py (it is a script folder, not a package)."""
    path = ANALYSES_DIR / f"{name}.py"
    if not path.exists():
        raise FileNotFoundError(f"analysis script {path} not found: `trunk-drake reproduce` needs a source checkout")
    spec = importlib.util.spec_from_file_location(f"trunk_drake_analyses.{name}", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _with_requirements(names) -> list[str]:
    wanted = set()

    def add(name):
        for req in experiment(name).requires:
            add(req)
        wanted.add(name)

    for name in names:
        add(name)
    return [e.name for e in EXPERIMENTS if e.name in wanted]


def run_experiments(out_dir, names=None, force: bool = False, workers: int = 2, model=None, options: dict | None = None,
                    quick: bool = False) -> dict:
    """Run the experiments `names` (default: all; requirements are added) into `out_dir`.

    Each finished experiment is stored in report.json and report.md at once; an experiment
    whose entry is already there (status ok, same `quick`) is skipped unless `force` (or a
    requirement was recomputed). `options` maps an experiment name to extra keyword arguments
    of its run(); `quick` shortens every experiment (Experiment.quick).
    """
    from trunk_drake.metadata import run_metadata
    from trunk_drake.model.trunk_model import load_model

    wall = time.perf_counter()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / REPORT_JSON
    report = json.loads(path.read_text()) if path.exists() else {"experiments": {}}
    model = model if model is not None else load_model("sagittal")
    report["metadata"] = run_metadata(model)
    report["synthetic_data"] = SYNTHETIC_NOTE
    selected = _with_requirements(names or [e.name for e in EXPERIMENTS])
    report["run"] = {"started": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"), "workers": workers,
                     "quick": quick, "selected": selected, "skipped": [], "wall_time_s": 0.0, "load_average_at_start": os.getloadavg()[0]}
    report["runs"] = [*report.get("runs", []), report["run"]]
    recomputed: set[str] = set()
    for k, name in enumerate(selected, 1):
        exp = experiment(name)
        old = report["experiments"].get(name, {})
        if not force and old.get("status") == "ok" and old.get("quick", False) == quick and not recomputed.intersection(exp.requires):
            log(f"[{k}/{len(selected)}] {name}: already in {path}, skipped (--force recomputes)")
            report["run"]["skipped"].append(name)
            continue
        log(f"[{k}/{len(selected)}] {name}: {exp.title} ...")
        start = time.perf_counter()
        try:
            entry = load_script(name).run(out / name, model=model, workers=workers, inputs=report["experiments"],
                                          **{**(exp.quick if quick else {}), **(options or {}).get(name, {})})
            entry = _relative_paths({**entry, "status": "ok"}, out)
        except Exception as err:  # a failed experiment is reported and the others still run
            traceback.print_exc()
            entry = {"status": "failed", "error": f"{type(err).__name__}: {err}"}
        entry.update(elapsed_s=time.perf_counter() - start, quick=quick)
        report["experiments"][name] = jsonable(entry)
        recomputed.add(name)
        report["run"]["wall_time_s"] = time.perf_counter() - wall
        path.write_text(json.dumps(report, indent=2))
        write_report(out, report)
        log(f"[{k}/{len(selected)}] {name}: {entry['status']} in {entry['elapsed_s']:.1f} s")
    report["run"]["wall_time_s"] = time.perf_counter() - wall
    report["run"]["load_average_at_end"] = os.getloadavg()[0]
    path.write_text(json.dumps(report, indent=2))
    write_report(out, report)
    log(f"report: {out / REPORT_MD} ({report['run']['wall_time_s'] / 60:.1f} min)")
    return report
