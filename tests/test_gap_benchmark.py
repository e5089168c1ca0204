"""Gap benchmark bookkeeping: noise, effect signatures and the summary's rates."""

import json
import os

import numpy as np
import pytest

from trunk_drake.gap.benchmark import best_gains_only_chi2, cases, select_cases, summarize, summary_markdown
from trunk_drake.gap.synthetic import add_noise, signature_chi2
from trunk_drake.io.trials import LUMBAR_LEVELS, Trial


def _trial(scale: float) -> Trial:
    t = np.arange(0.0, 10.0, 0.01)
    y = scale * np.sin(2 * np.pi * t)
    return Trial(time=t, fs=100.0, platform_displacement=0.01 * np.sin(t), lumbar_rotation=y,
                 levels={lvl: y / 5 for lvl in LUMBAR_LEVELS})


def test_signature_is_the_noise_normalised_difference_and_noise_is_added():
    a, b = [_trial(1e-3)], [_trial(2e-3)]
    noise = 1e-3
    keep = a[0].time >= 2.0
    d = 1e-3 * np.sin(2 * np.pi * a[0].time[keep])
    expected = (np.sum((d - d.mean()) ** 2) + 5 * np.sum((d / 5 - d.mean() / 5) ** 2)) / noise**2
    assert abs(signature_chi2(a, b, noise, skip=2.0) / expected - 1) < 1e-12
    assert signature_chi2(a, a, noise) == 0.0
    noisy = add_noise(a, noise, seed=1)
    assert abs(np.std(noisy[0].lumbar_rotation - a[0].lumbar_rotation) / noise - 1) < 0.1
    assert np.array_equal(noisy[0].platform_displacement, a[0].platform_displacement)


def test_summary_rates_per_class_and_unobservable_cases_left_out():
    def row(case, kind, truth, first, selected, unexplained=False, observable=True, distinguishable=True):
        step = {"action": "add", "effect": selected[0]} if selected else {"action": "stop"}
        return {"case": case, "kind": kind, "truth": truth, "withheld": [[n, {}] for n in truth], "ranked_first": first,
                "ranking": [{"effect": first}], "steps": [step], "selected": selected, "unexplained": unexplained,
                "observable": observable, "verdict": "v", "reduction": 0.5, "reduction_above_noise": 0.9,
                "wall_time_s": 1.0, "signature_chi2": 100.0, "distinguishable_from_gains": distinguishable}
    rows = [row("d1", "single", ["reflex_delay"], "reflex_delay", ["reflex_delay"]),
            row("g1", "single", ["golgi_feedback"], "reflex_delay", [], distinguishable=False),
            row("g2", "single", ["bushing_stiffness"], "reflex_delay", ["reflex_delay"], distinguishable=False),
            row("d2", "single", ["extra_damping"], "extra_damping", ["extra_damping", "reflex_delay"]),
            row("d3", "single", ["golgi_feedback"], "reflex_delay", ["reflex_delay"], unexplained=True),
            row("s1", "single", ["stiffening_discs"], "reflex_delay", [], observable=False),
            row("p1", "pair", ["reflex_delay", "slow_activation"], "reflex_delay", ["slow_activation", "reflex_delay"]),
            row("p2", "pair", ["golgi_feedback", "muscle_strength"], "golgi_feedback", ["golgi_feedback"], unexplained=True),
            row("o1", "outside", [], "reflex_delay", ["reflex_delay"], unexplained=True),
            row("o2", "outside", [], "reflex_delay", ["reflex_delay"]),
            row("o3", "outside", [], "reflex_delay", []),
            row("n1", "none", [], "reflex_delay", []), row("n2", "none", [], "golgi_feedback", ["golgi_feedback"])]
    s = summarize(rows, 0.1)
    m = s["measures"]
    assert s["unobservable"] == ["s1"]
    # as well explained by mis-set gains: out of the single rates, on their own (g2 claims another effect)
    assert s["as_gains"] == ["g1", "g2"] and m["as_gains_nothing_else"]["failed"] == ["g2"]
    assert m["single_ranked_first"]["rate"] == 2 / 3 and m["single_ranked_first"]["failed"] == ["d3"]
    assert m["single_ranked_first_alone"] == m["single_ranked_first"]  # each decided in its first step
    assert m["single_exactly_claimed"]["rate"] == 1 / 3 and m["single_exactly_claimed"]["failed"] == ["d2", "d3"]
    assert m["pair_both_exactly"]["rate"] == 0.5 and m["none_no_claim"]["rate"] == 0.5
    assert m["outside_honest"]["rate"] == 2 / 3 and m["outside_honest"]["failed"] == ["o2"]
    # the truth is fully in the selected model in d1, d2 and p1: each verdict calls the remainder noise
    assert m["noise_verdict_when_complete"]["n"] == 3 and m["noise_verdict_when_complete"]["rate"] == 1.0
    assert s["gap_reduction_above_noise"]["cases"] == 2  # exactly identified: d1 and p1
    text = summary_markdown(s)
    assert "unobservable" in text and "| p2 | pair |" in text and "o2" in text and "100 (as gains)" in text


def test_ranked_first_reads_the_ranking_that_decided_the_selection():
    """The first step ranks each candidate alone against the gains refitted along the identifiable directions; where
    the gains are mis-set further, the effects that mimic them lead there, lose to the gain rival, and the truth is
    claimed later on more gain directions. "Ranked first" reads the ranking of the step that added the first effect
    (a partner's does not count), else of the last step that weighed the candidates; the first step's is reported
    beside it. A later step recorded without its ranking is not counted as ranked first."""
    from trunk_drake.gap.search import deciding_ranking

    first = [{"effect": "short_range_stiffness"}, {"effect": "golgi_feedback"}]
    later = [{"effect": "golgi_feedback"}, {"effect": "seat_compliance"}]
    stop, gains = {"action": "stop"}, {"action": "gains"}
    claimed = [stop, gains, {"action": "polish"}, {"action": "add", "effect": "golgi_feedback", "ranking": later},
               {"action": "stop", "ranking": first[::-1]}, {"action": "partners"}]
    assert deciding_ranking(claimed, first) == (3, later)
    assert deciding_ranking([stop, gains, {"action": "stop", "ranking": later}], first) == (2, later)
    assert deciding_ranking([{"action": "add", "effect": "e"}, {"action": "add", "partner_of": ["e"]}], first) == (0, first)
    assert deciding_ranking([stop, {"action": "add", "effect": "golgi_feedback"}], first) == (1, None)
    assert deciding_ranking([gains], first) == (None, None)

    def row(case, steps):
        return {"case": case, "kind": "single", "truth": ["golgi_feedback"], "withheld": [["golgi_feedback", {}]],
                "ranked_first": "short_range_stiffness", "ranking": first, "steps": steps, "selected": ["golgi_feedback"],
                "unexplained": False, "verdict": "v", "reduction": 1.0, "reduction_above_noise": 1.0, "wall_time_s": 1.0}
    m = summarize([row("recorded", claimed), row("unrecorded", [stop, {"action": "add", "effect": "golgi_feedback"}])], 0.1)["measures"]
    assert m["single_ranked_first"]["failed"] == ["unrecorded"]
    assert m["single_ranked_first_alone"]["failed"] == ["recorded", "unrecorded"]


def test_the_summary_covers_every_case_done_in_the_folder_in_benchmark_order(tmp_path):
    """Written after each case: a run of some cases (`--case NAME`) adds to the folder's summary, never replaces it."""
    import json

    from trunk_drake.gap import benchmark

    every = benchmark.cases()
    names = [c.name for c in every]
    done = {c.name: benchmark._error_row(c, "stopped") for c in (every[5], every[0])}
    benchmark._write_summary(tmp_path, done, 0.1, None, False)
    assert [r["case"] for r in json.loads((tmp_path / "summary.json").read_text())["rows"]] == [names[0], names[5]]
    assert (tmp_path / "summary.md").read_text().count("| failed: stopped |") == 2


def test_a_case_resumes_in_its_folder_and_its_simulation_log_goes_once_the_case_is_saved(tmp_path, monkeypatch):
    """A case interrupted in an earlier run finds its progress file (appended to, not restarted) and its simulation log
    (`checkpoint`, from which the diagnosis resumes) in its folder; the log is removed once the case's row is saved."""
    from trunk_drake.gap import benchmark
    from trunk_drake.gap.checkpoint import LOG_NAME

    case = benchmark.cases()[0]
    folder = tmp_path / "cases" / case.name
    folder.mkdir(parents=True)
    (folder / "progress.log").write_text("[ 99.0 s,  120 sims] a line of the interrupted run\n")
    (folder / LOG_NAME).write_bytes(b"the interrupted run's simulations")
    seen = {}

    def job(model, args):
        progress = args[-1]
        seen.update(progress=progress.read_text(), log=(progress.parent / LOG_NAME).read_bytes())
        return {**benchmark._identity(case), "selected": []}, "a diagnosis"

    monkeypatch.setattr(benchmark, "_case_job", job)
    monkeypatch.setattr(benchmark, "write_diagnosis", lambda diagnosis, folder: None)
    monkeypatch.setattr(benchmark, "_write_summary", lambda *args: {})
    benchmark.run_benchmark(tmp_path, only=[case.name], progress=None)
    assert seen == {"progress": "[ 99.0 s,  120 sims] a line of the interrupted run\n",
                    "log": b"the interrupted run's simulations"}
    assert not (folder / LOG_NAME).exists()
    assert '"selected": []' in (tmp_path / "results.jsonl").read_text()


def test_cases_start_with_their_classes_mixed_and_a_folder_refuses_other_code(tmp_path):
    from trunk_drake.gap import benchmark

    order = benchmark.mixed(benchmark.cases())
    assert [c.kind for c in order[:4]] == ["single", "pair", "outside", "none"]
    assert sorted(c.name for c in order) == sorted(c.name for c in benchmark.cases())
    settings = {"noise_deg": 0.1, "candidates": None, "code": "a"}
    benchmark._check_settings(tmp_path / "settings.json", settings)
    with pytest.raises(ValueError, match="code: a there, b now"):
        benchmark._check_settings(tmp_path / "settings.json", {**settings, "code": "b"})


def test_a_resumed_run_takes_up_the_cases_it_was_running_before_new_ones():
    from trunk_drake.gap import benchmark

    order = benchmark.mixed(benchmark.cases())
    # two workers: order[0] and order[1] started, order[2] when order[0] finished, order[3] when order[1] finished,
    # order[4] when order[3] finished; the run stopped with order[2] and order[4] running
    done = {c.name: {"case": c.name} for c in (order[0], order[1], order[3])}
    done[order[5].name] = {"case": order[5].name, "error": "worker lost"}
    pending = benchmark.pending_cases(benchmark.cases(), done)
    assert [c.name for c in pending[:2]] == [order[2].name, order[4].name]
    assert order[5] in pending and len(pending) == len(order) - 3


def test_the_code_fingerprint_ignores_docstrings_and_comments_only(tmp_path):
    from trunk_drake.metadata import source_fingerprint

    module = tmp_path / "m.py"
    module.write_text('"""Doc."""\n\ndef f(x):\n    """Doc."""\n    return x + 1\n')
    before = source_fingerprint(tmp_path)
    module.write_text('"""Other doc."""\n\n\ndef f(x):  # a comment\n    """Another doc, longer."""\n    return x + 1\n')
    assert source_fingerprint(tmp_path) == before
    module.write_text('def f(x):\n    return x + 2\n')
    assert source_fingerprint(tmp_path) != before


def test_the_gains_only_rival_of_the_truth_is_the_best_gains_only_model_the_diagnosis_recorded():
    """`best_gains_only_chi2`: the lowest held-out chi2 among the diagnosis' gains-only models, the polished one
    included (golgi_feedback_gain0.15 on 9b5788c: 17,510 polished against 17,723 widened), not models with effects."""
    from types import SimpleNamespace

    steps = [{"action": "stop", "model": [], "heldout_chi2": 42991.0}, {"action": "gains", "model": [], "heldout_chi2": 17723.0},
             {"action": "polish", "model": [], "heldout_chi2": 17510.0}, {"action": "add", "model": ["golgi_feedback"],
                                                                         "heldout_chi2": 17400.0},
             {"action": "partners", "model": ["golgi_feedback"]}]
    diagnosis = SimpleNamespace(options={"scores": {"refit_heldout_chi2": 42991.0}}, steps=steps)
    assert best_gains_only_chi2(diagnosis) == 17510.0


def test_the_readme_case_counts_quick_run_and_class_selection():
    """README: 34 cases (18 single, 8 pairs, 4 outside the catalogue, 4 without an effect); `--quick` runs 20;
    `--case pair outside` selects whole classes."""
    every = cases()
    assert {k: sum(c.kind == k for c in every) for k in ("single", "pair", "outside", "none")} == {
        "single": 18, "pair": 8, "outside": 4, "none": 4}
    assert len(cases(quick=True)) == 20
    assert [c.name for c in select_cases(["pair", "outside"])] == [c.name for c in every if c.kind in ("pair", "outside")]


def stand_in_case(model, job):
    """`benchmark._case_job` without its diagnosis (minutes per case; one runs in test_end_to_end): the row of a case
    that claims nothing, with what the job and the worker running it were given."""
    from trunk_drake.gap import benchmark

    case, nominal, noise_rad, workers, candidates, gains_first, progress = job
    return {**benchmark._identity(case), "selected": [], "ranked_first": None, "ranking": [], "steps": [], "unexplained": False,
            "verdict": "stand-in", "reduction": None, "reduction_above_noise": None, "wall_time_s": 0.0,
            "job": {"gains_first": gains_first, "progress": progress and str(progress)},
            "worker": {"pid": os.getpid(), "model": model.spec.name, "dofs": model.dofs}}, None


def test_the_command_runs_the_quick_cases_with_gains_first_on_a_dask_cluster(tmp_path, capsys, monkeypatch, dask_cluster):
    """`trunk-drake gap-benchmark --quick --gains-first --cluster ADDRESS`: the 20 quick cases, each a job on the
    cluster's worker with the gains-first search (each case's diagnosis stands in); the settings, rows and summary
    record the variant."""
    from trunk_drake.cli import main
    from trunk_drake.gap import benchmark

    monkeypatch.setattr(benchmark, "_case_job", stand_in_case)
    assert main(["gap-benchmark", "--quick", "--gains-first", "--cluster", dask_cluster.address, "--json",
                 "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    rows = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert sorted(r["case"] for r in rows) == sorted(c.name for c in cases(quick=True)) and dask_cluster.jobs_done() == 20
    assert all(r["job"] == {"gains_first": True, "progress": None} for r in rows)  # no progress.log: the cluster's own disks
    assert summary["gains_first"] is True and summary["cases"] == 20 and summary["failed"] == []
    assert json.loads((tmp_path / "settings.json").read_text())["gains_first"] is True
    assert "search: gains widened first" in (tmp_path / "summary.md").read_text()


def test_the_command_runs_its_cases_on_an_osim_model_in_worker_processes(tmp_path, monkeypatch, lumbar_c210_path):
    """`trunk-drake gap-benchmark --model FILE.osim`: the truth configuration (the reference data's preset) on the
    file's model, rebuilt by each local worker process that runs a case (each case's diagnosis stands in)."""
    from trunk_drake.cli import main
    from trunk_drake.gap import benchmark

    monkeypatch.setattr(benchmark, "_case_job", stand_in_case)
    assert main(["gap-benchmark", "--case", "no_effect_0", "no_effect_1", "--workers", "2", "--model", str(lumbar_c210_path),
                 "--out", str(tmp_path)]) == 0
    rows = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    assert sorted(r["case"] for r in rows) == ["no_effect_0", "no_effect_1"]
    assert all(r["worker"]["model"] == "Lumbar_C_210" and r["worker"]["dofs"] == "rhythm" for r in rows)
    assert os.getpid() not in {r["worker"]["pid"] for r in rows}
