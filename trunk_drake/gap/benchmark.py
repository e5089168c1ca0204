"""Gap benchmark: diagnose "measured" data from truth diagrams whose effects are withheld from the model.

Every case simulates a truth = the benchmark's truth configuration (`truth_configuration`) with
randomly perturbed reflex gains, plus: one catalogued effect ("single", two magnitudes for the
first seven effects), two at once ("pair": pairs whose signatures overlap in frequency or trade off
against the gains), a mechanism that is deliberately not a candidate ("outside"), or nothing
("none": a mis-set parameter only). White measurement noise is added and the diagnosis runs
blind with the nominal model. Results are written case by case (results.jsonl), so an
interrupted run resumes.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from trunk_drake.diagram import TrunkOptions
from trunk_drake.gap.catalogue import effect
from trunk_drake.gap.checkpoint import LOG_NAME
from trunk_drake.gap.diagnose import diagnose_gap
from trunk_drake.gap.measures import segment_chi2
from trunk_drake.gap.refit import simulate_outputs
from trunk_drake.gap.report import write_diagnosis
from trunk_drake.gap.space import SearchSpace
from trunk_drake.gap.search import deciding_ranking
from trunk_drake.gap.synthetic import add_noise, clean_trials, signature_chi2
from trunk_drake.gap.trials import half, prepare_trials
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.metadata import json_default, source_fingerprint
from trunk_drake.optim.gains import GAIN_BOUNDS
from trunk_drake.parallel import WorkerLost, WorkerPool
from trunk_drake.signals import DEFAULT_FADE_S, DEFAULT_PERIOD_S
from trunk_drake.thesis import reference_model, reference_truth_options, truth_gains

DEFAULT_NOISE_DEG = 0.1  # motion-capture angle noise (modelling choice: ~0.2 mm marker noise over a few cm)
GAIN_SPREAD = 0.2  # SD of log(gain factor) of the perturbed nominal gains
THRESHOLD = 10.0  # held-out dBIC needed to claim an effect (the diagnosis' default)
CLASSES = ("single", "pair", "outside", "none")


def truth_configuration():
    """The benchmark's truth, in one place: (the reference data's model, built from the preset of
    its conditions; `nominal_options()`). Regenerating models/reference for another default
    passenger moves the benchmark with it."""
    return reference_model(), nominal_options()


def nominal_options() -> TrunkOptions:
    """The reference data set's conditions and truth reflex gains (models/reference): the
    nominal model of every benchmark case, before its gains are perturbed."""
    return TrunkOptions(**reference_truth_options(), **truth_gains())


# mechanisms that are NOT candidates of the catalogue: what the diagnosis has never heard of
def _compliant_tendons(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, tendon="compliant")


def _coactivation(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, feedforward=np.minimum(np.asarray(options.feedforward, float) * values["factor"], 1.0))


def _reflex_set_point(options: TrunkOptions, values: dict) -> TrunkOptions:
    return dataclasses.replace(options, l_desired=values["l_desired"])


OUTSIDE = {
    "compliant_tendons": (_compliant_tendons, "compliant instead of rigid tendons (the model's tendons are rigid)"),
    "coactivation": (_coactivation, "more co-activation: every feed-forward excitation scaled"),
    "reflex_set_point": (_reflex_set_point, "the stretch reflex' set point l_d moved below optimal fiber length"),
    "kinematics_lag": (None, "the angle recordings lag the platform recording (a synchronisation error of the data)"),
}


@dataclass(frozen=True)
class Case:
    name: str
    kind: str  # single, pair, outside or none
    effects: tuple  # ((effect or mechanism name, values), ...) withheld from the model
    seed: int

    @property
    def truth(self) -> list[str]:
        """The catalogued effects the diagnosis should find."""
        return [n for n, _ in self.effects] if self.kind in ("single", "pair") else []


SINGLE = [
    ("reflex_delay", {"delay": 0.04}), ("reflex_delay", {"delay": 0.08}),
    ("golgi_feedback", {"gain": 0.15}), ("golgi_feedback", {"gain": 0.3}),
    ("trunk_in_space", {"gain": 0.15, "delay": 0.15}), ("trunk_in_space", {"gain": 0.3, "delay": 0.1}),
    ("stiffening_discs", {"cubic": 400.0}), ("stiffening_discs", {"cubic": 1000.0}),
    ("seat_compliance", {"stiffness": 3e4, "damping": 500.0}), ("seat_compliance", {"stiffness": 1.5e4, "damping": 300.0}),
    ("slow_activation", {"scale": 2.5}), ("slow_activation", {"scale": 4.0}),
    ("extra_damping", {"damping": 8.0}), ("extra_damping", {"damping": 16.0}),
    ("bushing_stiffness", {"scale": 1.6}), ("muscle_strength", {"scale": 0.75}),
    ("upper_body_mass", {"scale": 1.15}), ("short_range_stiffness", {"gain": 40.0}),
]
PAIRS = [  # why a reviewer would find each hard
    (("reflex_delay", {"delay": 0.04}), ("slow_activation", {"scale": 2.5})),  # both add phase lag in the reflex loop
    (("reflex_delay", {"delay": 0.06}), ("trunk_in_space", {"gain": 0.15, "delay": 0.15})),  # two delayed loops
    (("extra_damping", {"damping": 8.0}), ("short_range_stiffness", {"gain": 40.0})),  # SRS is a high-passed stiffness, damping-like
    (("golgi_feedback", {"gain": 0.15}), ("muscle_strength", {"scale": 1.3})),  # both rescale the muscles' force response
    (("stiffening_discs", {"cubic": 1000.0}), ("bushing_stiffness", {"scale": 1.5})),  # stiffening vs a stiffness error
    (("seat_compliance", {"stiffness": 3e4, "damping": 500.0}), ("extra_damping", {"damping": 8.0})),  # two dampers in series/parallel
    (("slow_activation", {"scale": 2.5}), ("golgi_feedback", {"gain": 0.15})),  # both act on the activation loop
    (("upper_body_mass", {"scale": 1.15}), ("bushing_stiffness", {"scale": 0.7})),  # gravity vs stiffness
]
OUTSIDE_CASES = [("compliant_tendons", {}), ("coactivation", {"factor": 1.5}), ("reflex_set_point", {"l_desired": 0.97}),
                 ("kinematics_lag", {"lag_s": 0.03})]
N_NONE = 4


def cases(quick: bool = False) -> list[Case]:
    """All cases, or (quick) one magnitude per effect, half the pairs, three outside mechanisms and two no-effect cases."""
    out = [Case(_name((c,)), "single", (c,), 100 + i) for i, c in enumerate(SINGLE) if not quick or i % 2 == 1 or i >= 14]
    out += [Case(_name(p), "pair", p, 300 + i) for i, p in enumerate(PAIRS) if not quick or i % 2 == 1]
    out += [Case(f"outside_{_name((c,))}", "outside", (c,), 400 + i) for i, c in enumerate(OUTSIDE_CASES) if not quick or i < 3]
    out += [Case(f"no_effect_{k}", "none", (), 200 + k) for k in range(2 if quick else N_NONE)]
    return out


def select_cases(names) -> list[Case]:
    """The cases named in `names` (case names or classes: single, pair, outside, none), in benchmark order."""
    every = cases()
    unknown = set(names) - {c.name for c in every} - set(CLASSES)
    if unknown:
        raise ValueError(f"unknown gap-benchmark case(s) {sorted(unknown)}; give case names or classes {list(CLASSES)} "
                         "(trunk-drake gap-benchmark --help lists the cases)")
    return [c for c in every if c.name in names or c.kind in names]


def _name(effects) -> str:
    return "+".join(f"{n}_{'_'.join(f'{k}{v:g}' for k, v in values.items())}".rstrip("_") for n, values in effects)


def truth_options(nominal: TrunkOptions, case: Case) -> TrunkOptions:
    """The case's truth: perturbed gains plus its withheld effects or mechanisms (data-level ones excepted)."""
    rng = np.random.default_rng(case.seed)
    perturbed = {k: {g: float(np.clip(v * np.exp(rng.normal(0.0, GAIN_SPREAD)), *GAIN_BOUNDS)) for g, v in getattr(nominal, k).items()}
                 for k in ("kp", "kv")}
    truth = dataclasses.replace(nominal, **perturbed)
    for name, values in case.effects:
        apply = OUTSIDE[name][0] if case.kind == "outside" else effect(name).apply
        if apply is not None:
            truth = apply(truth, values)
    return truth


def _lag_kinematics(trials, lag_s: float):
    """The angle records delayed by `lag_s` against the platform record (first samples held)."""
    out = []
    for t in trials:
        k = int(round(lag_s * t.fs))
        lag = lambda y: np.concatenate([np.full(k, y[0]), y[:-k]]) if k else y  # noqa: E731
        out.append(dataclasses.replace(t, lumbar_rotation=lag(t.lumbar_rotation), levels={n: lag(y) for n, y in t.levels.items()}))
    return out


def trial_timing(quick: bool = False) -> dict:
    """The "period" and "fade" (s) of the cases' multisines: the benchmark's, or (quick) those of 2 s trials, one period
    of 1 s after a 0.5 s fade-in, for a check that a script runs (`published_case`), not a result."""
    return {"period": 1.0, "fade": 0.5} if quick else {"period": DEFAULT_PERIOD_S, "fade": DEFAULT_FADE_S}


def case_trials(model, case: Case, nominal: TrunkOptions, noise_rad: float, period: float = DEFAULT_PERIOD_S,
                fade: float = DEFAULT_FADE_S):
    """The case's multisine designs, truth options, noise-free trials and "measured" trials (noise added)."""
    designs = [("1hz_a", 1.0, case.seed), ("1hz_b", 1.0, case.seed + 1000), ("3hz", 3.0, case.seed + 2000)]
    truth = truth_options(nominal, case)
    clean = clean_trials(model, truth, designs, period=period, fade=fade)
    if case.kind == "outside" and case.effects[0][0] == "kinematics_lag":
        clean = _lag_kinematics(clean, case.effects[0][1]["lag_s"])
    return designs, truth, clean, add_noise(clean, noise_rad, seed=case.seed)


def published_case(name: str, folder, quick: bool = False) -> dict:
    """A case of the benchmark run in `folder`, for checks offline (analyses/gap_*_check.py): its data regenerated at
    the default noise ("model", "nominal", "truth" options, prepared "data", "noise" per output in rad), the run's "diagnosis"
    (diagnosis.json), the "space" around the nominal gains with every gain direction, and the run's final model
    there: "effects" and "x" (gain coordinates, then each effect's). `quick`: the trials of `trial_timing`'s quick
    check."""
    model, nominal = truth_configuration()
    noise_rad, timing = float(np.radians(DEFAULT_NOISE_DEG)), trial_timing(quick)
    _, truth, _, noisy = case_trials(model, select_cases([name])[0], nominal, noise_rad, **timing)
    diagnosis = json.loads((Path(folder) / "cases" / name / "diagnosis.json").read_text())
    final, space = diagnosis["final"], SearchSpace.around(model, nominal)
    effects = tuple(effect(n) for n in final["effects"])
    gains = space.layout.vector(final["gains"]) - space.layout.vector(space.layout.fixed)
    x = np.concatenate([gains] + [e.coordinates(final["effects"][e.name]) for e in effects])
    return {"model": model, "nominal": nominal, "truth": truth, "data": prepare_trials(noisy, OUTPUT_NAMES, **timing),
            "noise": np.full(len(OUTPUT_NAMES), noise_rad), "diagnosis": diagnosis, "space": space, "effects": effects, "x": x}


def run_case(model, case: Case, nominal: TrunkOptions, noise_rad: float, workers: int, candidates=None,
             gains_first: bool = False, progress: Path | None = None):
    """Simulate the case's truth, diagnose it blind (among `candidates`, default the whole
    catalogue; `gains_first`: see `diagnose_gap`; its steps appended to the file `progress` if given, and its
    simulations logged beside it, so that the case resumes where it stopped); returns (result row, diagnosis)."""
    start = time.perf_counter()
    designs, truth, clean, noisy = case_trials(model, case, nominal, noise_rad)
    observability = _observability(model, case, nominal, designs, clean, noise_rad) if case.effects else {}
    diagnosis = diagnose_gap(model, noisy, nominal, noise=noise_rad, candidates=candidates, threshold=THRESHOLD, workers=workers,
                             gains_first=gains_first, progress=progress or False,
                             checkpoint=progress.parent / LOG_NAME if progress else None)
    if case.kind == "single":
        observability.update(_versus_gains(model, case, truth, noisy, diagnosis, noise_rad))
    top = diagnosis.ranking[0]["effect"] if diagnosis.ranking else None
    left = diagnosis.remainder
    row = {**_identity(case), "selected": diagnosis.selected, "ranked_first": top, "verdict": diagnosis.verdict,
           "unexplained": not left["is_noise"], "remainder": {k: left[k] for k in ("chi2_per_sample", "ljung_box", "frf")},
           "on_bounds": diagnosis.final["on_bounds"], "steps": diagnosis.steps, "fitted": diagnosis.final["effects"],
           "ranking": [{k: r.get(k) for k in ("effect", "delta_bic", "checked_delta_bic", "linear_delta_bic", "values")} for r in diagnosis.ranking],
           "gap": diagnosis.shrink.get("gap"), "reduction": diagnosis.shrink.get("reduction"),
           "reduction_above_noise": diagnosis.shrink.get("reduction_above_noise"),
           "noise_floor_gap": diagnosis.shrink.get("noise_floor_gap"), **observability,
           "simulations": diagnosis.options["scores"]["simulations"],
           "replayed_simulations": diagnosis.options["scores"]["replayed_simulations"],
           "wall_time_s": time.perf_counter() - start + diagnosis.options["scores"]["earlier_runs_wall_s"]}
    return row, diagnosis


def _case_job(model, job):
    """Worker job: one case, or its error row (a failing case is recorded and the benchmark goes on)."""
    case, nominal, noise_rad, workers, candidates, gains_first, progress = job
    try:
        return run_case(model, case, nominal, noise_rad, workers, candidates, gains_first, progress)
    except Exception as err:  # noqa: BLE001
        return {**_error_row(case, f"{type(err).__name__}: {err}"), "traceback": traceback.format_exc(limit=3)}, None


def _identity(case: Case) -> dict:
    """The fields of a result row that name the case."""
    return {"case": case.name, "kind": case.kind, "truth": case.truth, "withheld": [list(e) for e in case.effects]}


def _error_row(case: Case, message: str) -> dict:
    return {**_identity(case), "error": message}


def _observability(model, case: Case, nominal: TrunkOptions, designs, clean, noise_rad: float) -> dict:
    """Is the withheld change visible in the data at all? The truth without it is simulated on
    the same inputs; its noise-free difference from the truth, in chi-square units
    (`signature_chi2`), must beat what a claim needs on the held-out half: the threshold plus
    k ln N per withheld parameter. Otherwise no method can attribute the case."""
    without = clean_trials(model, truth_options(nominal, Case(case.name, "none", (), case.seed)), designs)
    chi2 = signature_chi2(clean, without, noise_rad, skip=DEFAULT_FADE_S)
    n_heldout = sum(int(np.sum(t.time >= DEFAULT_FADE_S)) * (1 + len(t.levels)) for t in clean) / 2
    k = sum(len(values) for _, values in case.effects) or 1
    return {"signature_chi2": chi2, "observable": bool(chi2 / 2 > THRESHOLD + k * np.log(n_heldout))}


def _versus_gains(model, case: Case, truth: TrunkOptions, noisy, diagnosis, noise_rad: float) -> dict:
    """Can these trials tell the withheld effect from mis-set gains? The truth's held-out chi-square
    (simulated as the diagnosis simulates its refits) against that of the best gains-only model the
    diagnosis found (the lowest of its gains-only models: the nominal gains refitted, widened, polished on every
    direction or regained; the polished one alone took the recorded advantage of golgi_feedback_gain0.15 on 9b5788c
    from 272 to 59): unless
    the truth beats it by the threshold plus k ln N, the data are as well explained by mis-set gains as
    by the effect, and no method can attribute the case to the effect. Such cases are left out of the
    single-effect rates and reported on their own."""
    data = prepare_trials(noisy, OUTPUT_NAMES)
    chi2 = 0.0
    for t in data:
        y, *_ = simulate_outputs(model, truth, t, OUTPUT_NAMES)
        chi2 += segment_chi2(t.steady_outputs, y, noise_rad, half(t, "test"))
    scores = diagnosis.options["scores"]
    gains = best_gains_only_chi2(diagnosis)
    k = sum(len(values) for _, values in case.effects)
    dbic = float(gains - chi2 - k * scores["penalty"])
    return {"truth_heldout_chi2": float(chi2), "gains_only_heldout_chi2": float(gains), "truth_over_gains_delta_bic": dbic,
            "distinguishable_from_gains": dbic > THRESHOLD}


def best_gains_only_chi2(diagnosis) -> float:
    """The lowest held-out chi-square of the gains-only models a diagnosis recorded (its refit of the nominal
    gains and every step whose model has no effect)."""
    return min([diagnosis.options["scores"]["refit_heldout_chi2"]] + [
        s["heldout_chi2"] for s in diagnosis.steps if s.get("model") == [] and s.get("heldout_chi2") is not None])


def run_benchmark(out_dir, quick: bool = False, noise_deg: float = DEFAULT_NOISE_DEG, workers: int = 2, progress=print,
                  cluster: str | None = None, only=None, candidates=None, gains_first: bool = False) -> dict:
    """Run (or resume) every case, or those of `only` (case names or classes: single, pair, outside,
    none); returns the summary of the cases done so far (also written to summary.json/.md, after each case). Each
    diagnosis chooses among `candidates` (effect names; default the whole catalogue). The cases run
    in parallel, one per worker: on `workers` local processes, or on the Dask cluster at `cluster`;
    a single case runs its diagnosis on the `workers` instead. They start in an order that mixes the
    classes, so that an interrupted run already covers each. `gains_first`: the search variant of
    `diagnose_gap`. A folder resumes only with the noise, candidates, search variant and code
    (`source_fingerprint`) it was started with."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    candidates = sorted(candidates) if candidates else None
    _check_settings(out / "settings.json", {"noise_deg": noise_deg, "candidates": candidates, "gains_first": gains_first,
                                            "code": source_fingerprint()})
    results_path = out / "results.jsonl"
    done = {}
    if results_path.exists():
        for line in results_path.read_text().splitlines():
            row = json.loads(line)
            done[row["case"]] = row
    all_cases = select_cases(only) if only else cases(quick)
    model, nominal = truth_configuration()
    noise = float(np.radians(noise_deg))
    pending = pending_cases(all_cases, done)
    in_parallel = bool(cluster) or len(pending) > 1  # the cases on the workers, else the one case's diagnosis
    # each case's steps in a file to follow, appended to when it resumes (local workers only: a cluster's may not see
    # this folder), its simulations logged beside it
    logs = {c.name: None if cluster else out / "cases" / c.name / "progress.log" for c in pending}
    jobs = [(case, nominal, noise, 1 if in_parallel else workers, candidates, gains_first, logs[case.name]) for case in pending]
    if progress and not cluster and pending:
        progress(f"{len(pending)} case(s) to run; each one's steps: tail -f {out / 'cases' / 'CASE' / 'progress.log'}")
    with WorkerPool(model, workers if in_parallel else 1, cluster) as pool, _resumable():
        for finished, (i, result, error) in enumerate(pool.completed(_case_job, jobs), 1):
            case = pending[i]
            row, diagnosis = result if error is None else (_error_row(case, f"worker lost: {type(error).__name__}: {error}"), None)
            if diagnosis is not None:
                write_diagnosis(diagnosis, out / "cases" / case.name)
            done[case.name] = row
            with results_path.open("a") as f:
                f.write(json.dumps(row, default=json_default) + "\n")
            if diagnosis is not None and logs[case.name] is not None:  # saved: its simulations are no longer needed
                (logs[case.name].parent / LOG_NAME).unlink(missing_ok=True)  # (a failed case's resume when it reruns)
            if progress:
                progress(f"[{finished + len(all_cases) - len(pending)}/{len(all_cases)}] {case.name}: " + (row.get("error") or
                         f"claimed {row['selected'] or 'none'}{', unexplained remainder' if row['unexplained'] else ''} "
                         f"({row['wall_time_s']:.0f} s)"))
            _write_summary(out, done, noise_deg, candidates, gains_first)
    return _write_summary(out, done, noise_deg, candidates, gains_first)


def _write_summary(out: Path, done: dict, noise_deg: float, candidates, gains_first: bool) -> dict:
    """summary.json and summary.md of every case done in the folder so far, in benchmark order (rewritten as each
    case finishes; a run of some cases adds to the folder's summary)."""
    order = {c.name: i for i, c in enumerate(cases())}
    rows = sorted(done.values(), key=lambda r: order.get(r["case"], len(order)))
    summary = summarize(rows, noise_deg, candidates, gains_first)
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=json_default))
    (out / "summary.md").write_text(summary_markdown(summary))
    return summary


@contextlib.contextmanager
def _resumable():
    """A local worker that died (out of memory, a crash in native code) stops the run with what to do: the
    finished cases are in the folder, and the same command resumes it."""
    try:
        yield
    except WorkerLost as err:
        raise RuntimeError(f"{err}; the finished cases are saved: rerun the same command to resume, "
                           "with --workers 1 to find the case if it recurs") from err


def mixed(cases_: list[Case]) -> list[Case]:
    """`cases_` with their classes interleaved: the first of each class, then the second of each, ..."""
    seen = dict.fromkeys(CLASSES, 0)
    keyed = []
    for c in cases_:
        keyed.append((seen[c.kind], CLASSES.index(c.kind)))
        seen[c.kind] += 1
    return [c for _, c in sorted(zip(keyed, cases_), key=lambda kc: kc[0])]


def pending_cases(all_cases: list[Case], done: dict) -> list[Case]:
    """The cases of `all_cases` not done (or failed), in the run's one mixed order (`mixed` of all of them): a resumed
    run takes up the cases it was running first, since they were the first not done in that order. (Mixing only the
    cases left reorders them: it had put new cases before the interrupted ones.)"""
    return [c for c in mixed(all_cases) if c.name not in done or "error" in done[c.name]]


SETTINGS_BEFORE_RECORDED = {"gains_first": False}  # settings.json of folders started before these were recorded


def _check_settings(path: Path, settings: dict) -> None:
    """Write the run's settings, or refuse to resume a folder started with others (its rows would mix)."""
    if path.exists():
        before = json.loads(path.read_text())
        before = {**SETTINGS_BEFORE_RECORDED, **before}
        changed = {k: (before.get(k), v) for k, v in settings.items() if before.get(k) != v}
        if changed:
            raise ValueError(f"{path.parent} holds a gap benchmark run with other settings ("
                             + ", ".join(f"{k}: {a} there, {b} now" for k, (a, b) in changed.items())
                             + "): resume it with those, or give another --out")
    else:
        path.write_text(json.dumps(settings, indent=2))


def _rate(rows, test):
    return {"rate": float(np.mean([bool(test(r)) for r in rows])) if rows else None, "n": len(rows),
            "passed": int(sum(bool(test(r)) for r in rows)), "failed": [r["case"] for r in rows if not test(r)]}


def summarize(rows: list[dict], noise_deg: float, candidates=None, gains_first: bool = False) -> dict:
    """Per-class rates against the targets (only observable withheld changes count in the rates)."""
    ok = [r for r in rows if "error" not in r]
    unobservable = [r["case"] for r in ok if r["kind"] != "none" and not r.get("observable", True)]
    as_gains = [r for r in ok if r["kind"] == "single" and not r.get("distinguishable_from_gains", True) and r["case"] not in unobservable]
    by = {k: [r for r in ok if r["kind"] == k and r["case"] not in unobservable and r not in as_gains] for k in CLASSES}
    single, pair = by["single"], by["pair"]
    exact = lambda r: sorted(r["selected"]) == sorted(r["truth"])  # noqa: E731
    complete = [r for r in single + pair if set(r["truth"]) <= set(r["selected"])]
    identified = [r for r in single + pair if exact(r)]
    reductions = [r["reduction_above_noise"] for r in identified if r.get("reduction_above_noise") is not None]
    measures = {
        "single_ranked_first": _rate(single, lambda r: _deciding_first(r) == r["truth"][0]),
        "single_ranked_first_alone": _rate(single, lambda r: r["ranked_first"] == r["truth"][0]),
        "single_exactly_claimed": _rate(single, exact),
        "pair_both_exactly": _rate(pair, exact),
        "none_no_claim": _rate(by["none"], lambda r: not r["selected"]),
        "outside_honest": _rate(by["outside"], lambda r: r["unexplained"] or not r["selected"]),
        "noise_verdict_when_complete": _rate(complete, lambda r: not r["unexplained"]),
        "as_gains_nothing_else": _rate(as_gains, lambda r: set(r["selected"]) <= set(r["truth"])),
    }
    return {
        "noise_deg": noise_deg, "candidates": candidates or "catalogue", "gains_first": gains_first, "cases": len(rows), "failed": [r["case"] for r in rows if "error" in r],
        "unobservable": unobservable, "as_gains": [r["case"] for r in as_gains], "measures": measures,
        "gap_reduction_above_noise": {"median": float(np.median(reductions)) if reductions else None,
                                      "min": float(np.min(reductions)) if reductions else None,
                                      "cases": len(reductions)},
        "gap_reduction_raw_median": float(np.median([r["reduction"] for r in identified])) if identified else None,
        "targets": TARGETS, "mean_wall_time_s": float(np.mean([r["wall_time_s"] for r in ok])) if ok else None,
        "rows": rows,
    }


def _deciding_first(row: dict) -> str | None:
    """The effect ranked first where the case's selection was decided (`deciding_ranking`), None where not recorded."""
    rows = deciding_ranking(row.get("steps", []), row.get("ranking", []))[1]
    return rows[0]["effect"] if rows else None


TARGETS = {"single_ranked_first": 0.9, "single_exactly_claimed": 0.85, "pair_both_exactly": 0.75, "none_no_claim": 0.9,
           "outside_honest": 0.8, "noise_verdict_when_complete": 0.9, "gap_reduction_median": 0.9, "gap_reduction_min": 0.7}
_LABELS = {"single_ranked_first": "single catalogued effect ranked first (in the ranking that decided the selection)",
           "single_ranked_first_alone": "single catalogued effect ranked first in the first step (each candidate alone, "
                                        "against the gains refitted along the identifiable directions only)",
           "single_exactly_claimed": "single catalogued effect: exactly it claimed, nothing added",
           "pair_both_exactly": "pairs: both effects selected, nothing else",
           "none_no_claim": "no-effect cases with no claim",
           "outside_honest": "out-of-catalogue cases: verdict says an unexplained gap remains, or claims nothing",
           "noise_verdict_when_complete": "verdict says the remainder is noise when the truth is fully in the selected model",
           "as_gains_nothing_else": "single effect as well explained by mis-set gains: no other effect claimed"}


def summary_markdown(s: dict) -> str:
    g = s["gap_reduction_above_noise"]
    candidates = s.get("candidates", "catalogue")
    among = "the whole catalogue" if candidates == "catalogue" else ", ".join(candidates)
    search = "; search: gains widened first" if s.get("gains_first") else ""
    lines = ["# Gap benchmark", "", f"Noise {s['noise_deg']} deg, candidates: {among}{search}; {s['cases']} cases ({len(s['failed'])} failed"
             + (f": {', '.join(s['failed'])}" if s["failed"] else "") + "); unobservable withheld changes (left out of the "
             f"rates): {', '.join(s['unobservable']) or 'none'}; single effects the trials cannot tell from mis-set gains "
             f"(the truth beats the diagnosis' gains-only refit on held-out data by at most the threshold; left out of the "
             f"single-effect rates, reported on their own): {', '.join(s.get('as_gains', [])) or 'none'}.", "",
             "| measure | measured | target | failing cases |", "|---|---|---|---|"]
    for key, label in _LABELS.items():
        m = s["measures"][key]
        target = f">= {_pct(TARGETS[key])}" if key in TARGETS else "-"
        lines.append(f"| {label} | {m['passed']} / {m['n']} = {_pct(m['rate'])} | {target} | "
                     f"{', '.join(m['failed']) or '-'} |")
    lines.append(f"| gap above the noise floor removed, identified cases ({g['cases']}) | median {_pct(g['median'])}, "
                 f"minimum {_pct(g['min'])} | median >= 90 %, each >= 70 % | - |")
    lines += ["", "| case | class | withheld | signature (chi2) | claimed | remainder | gap removed above noise | verdict |",
              "|---|---|---|---|---|---|---|---|"]
    for r in s["rows"]:
        withheld = " + ".join(n for n, _ in r.get("withheld", [])) or "-"
        if "error" in r:
            lines.append(f"| {r['case']} | {r['kind']} | {withheld} | | failed: {r['error'][:60]} | | | |")
            continue
        signature = "-" if r.get("signature_chi2") is None else (
            f"{r['signature_chi2']:.0f}" + ("" if r.get("observable", True) else " (unobservable)")
            + ("" if r.get("distinguishable_from_gains", True) else " (as gains)"))
        lines.append(f"| {r['case']} | {r['kind']} | {withheld} | {signature} | {', '.join(r['selected']) or 'none'} | "
                     f"{'unexplained' if r['unexplained'] else 'noise'} | {_pct(r.get('reduction_above_noise'))} | {r['verdict']} |")
    return "\n".join(lines) + "\n"


def _pct(x) -> str:
    return "n/a" if x is None else f"{100 * x:.0f} %"
