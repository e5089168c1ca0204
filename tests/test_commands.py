"""The command layer's promises: --out checked before the work, every bad input one error line,
gains files as shipped, warnings as one plain line, --version (issue 12 items 2, 5, 6, 7, 8)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

import trunk_drake.simulation
from trunk_drake.cli import main
from trunk_drake.io.experiment import load_experiment
from trunk_drake.simulation import load_reflex_gains

ROOT = Path(__file__).resolve().parents[1]
THESIS_GAINS = ROOT / "models" / "reflex_gains_thesis.toml"
REFERENCE = ROOT / "models" / "reference"


def _one_error_line(capsys, *words) -> str:
    captured = capsys.readouterr()
    lines = [line for line in captured.err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in captured.err, captured.err
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def no_simulation(monkeypatch):
    """simulate() must not run: the input is checked before the work starts."""
    def refuse(*args, **kwargs):
        raise AssertionError("the work started before the input was checked")
    monkeypatch.setattr(trunk_drake.simulation, "simulate", refuse)


def test_out_that_is_a_file_fails_before_the_work(tmp_path, capsys, no_simulation):
    taken = tmp_path / "f"
    taken.write_text("")
    for command in (["simulate", "--duration", "1"], ["fit", "--scenario", "settling"], ["diagnose", str(REFERENCE)],
                    ["strength-batch", str(ROOT / "models" / "strength_grid_example.toml")], ["reproduce"]):
        assert main([*command, "--out", str(taken)]) == 2, command
        _one_error_line(capsys, "--out", "is a file")


def test_out_is_created_before_the_work(tmp_path, capsys, monkeypatch):
    out = tmp_path / "new" / "folder"
    seen = {}

    def record(*args, **kwargs):
        seen["exists"] = out.is_dir()
        raise ValueError("stop here")
    monkeypatch.setattr(trunk_drake.simulation, "simulate", record)
    assert main(["simulate", "--duration", "1", "--out", str(out)]) == 2
    assert seen == {"exists": True}


@pytest.mark.parametrize("arguments, words", [
    (["--bandwidth", "7"], ["--bandwidth", "1.0, 3.0, 10.0"]),
    (["--bandwidth", "0.1"], ["--bandwidth"]),
    (["--bandwidth", "1000"], ["--bandwidth"]),
    (["--accuracy", "-1"], ["--accuracy", "> 0"]),
    (["--duration", "0"], ["--duration"]),
])
def test_bad_simulate_options_name_the_option(arguments, words, tmp_path, capsys, no_simulation):
    assert main(["simulate", *arguments, "--out", str(tmp_path)]) == 2
    _one_error_line(capsys, *words)


def test_the_shipped_gains_file_works_without_a_set_name():
    with pytest.warns(UserWarning, match="car_passenger, trunk_settling: using car_passenger"):
        gains = load_reflex_gains(THESIS_GAINS)
    assert gains == load_reflex_gains(f"{THESIS_GAINS}#car_passenger")
    with pytest.raises(ValueError, match=r"no gain set 'bogus'.*car_passenger.*trunk_settling"):
        load_reflex_gains(f"{THESIS_GAINS}#bogus")


def test_a_gains_file_with_some_groups_says_the_others_are_off(tmp_path):
    partial = tmp_path / "gains.toml"
    partial.write_text("[kp]\nsacrospinalis = 0.1\n[kv]\nsacrospinalis = 0.2\npsoas_major = 0.05\n")
    with pytest.warns(UserWarning) as caught:
        gains = load_reflex_gains(partial)
    messages = [str(w.message) for w in caught]
    assert any("[kp] gives no gain for" in m and "psoas_major" in m and "kp is 0" in m for m in messages), messages
    assert any("[kv] gives no gain for" in m and "psoas_major" not in m for m in messages), messages
    assert gains == {"kp": {"sacrospinalis": 0.1}, "kv": {"sacrospinalis": 0.2, "psoas_major": 0.05}}


@pytest.mark.parametrize("text, words", [
    ('[kp]\nsacrospinalis = "0.1"\n[kv]\nsacrospinalis = 0.1\n', ["sacrospinalis", "'0.1'", "not a gain"]),
    ("[kp]\nsacrospinalis = -1\n[kv]\n", ["not a gain"]),
    ("[kp]\nsacrospinals = 0.1\n[kv]\n", ["unknown muscle group", "sacrospinals"]),
    ("[kp]\nsacrospinalis = 0.1\n", ["kv"]),
    ("[kp\n", ["not valid TOML"]),
])
def test_bad_gains_files_give_one_error_line(text, words, tmp_path, capsys, no_simulation):
    bad = tmp_path / "gains.toml"
    bad.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["simulate", "--reflex-gains", str(bad), "--out", str(tmp_path / "out")]) == 2
    _one_error_line(capsys, *words)


def test_diagnose_needs_two_trials(tmp_path, capsys):
    assert main(["diagnose", str(REFERENCE / "trial_1hz_a.csv"), "--out", str(tmp_path)]) == 2
    _one_error_line(capsys, "at least two trials")


def test_diagnose_takes_the_data_presets_reflex_gains_unless_given(capsys):
    """Without --gains the model diagnosed has the gains of the data's preset (said), not none; with neither a
    warning says the model has no stretch reflexes."""
    import dataclasses

    from trunk_drake.commands.diagnose import nominal_gains

    experiment = load_experiment([REFERENCE])
    assert nominal_gains(experiment, None) == experiment.preset_gains() and experiment.preset_gains()["kp"]
    assert "those of the data's preset, default" in capsys.readouterr().out
    thesis = f"{THESIS_GAINS}#car_passenger"
    assert nominal_gains(experiment, thesis) == load_reflex_gains(thesis)
    with pytest.warns(UserWarning, match="no stretch reflexes"):
        assert nominal_gains(dataclasses.replace(experiment, preset=None), None) == {}


def test_trials_of_different_sampling_rates_are_refused(tmp_path):
    t100, t200 = np.arange(0, 2, 0.01), np.arange(0, 2, 0.005)
    for name, t in (("a.csv", t100), ("b.csv", t200)):
        (tmp_path / name).write_text("time,platform_displacement_m,lumbar_rotation_rad\n"
                                     + "".join(f"{x},{0.01 * np.sin(x)},{0.001 * np.sin(x)}\n" for x in t))
    with pytest.raises(ValueError, match=r"different sampling rates \(a.csv: 100 Hz, b.csv: 200 Hz\)"):
        load_experiment([tmp_path])


def test_strength_batch_bad_grids_and_failed_cases(tmp_path, capsys):
    assert main(["strength-batch", str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    _one_error_line(capsys, str(tmp_path), "not a file")
    grid = tmp_path / "grid.toml"
    grid.write_text("[defaults]\nstrenght_scale = 1.0\n")
    assert main(["strength-batch", str(grid), "--out", str(tmp_path / "out")]) == 2
    _one_error_line(capsys, "[defaults]", "strenght_scale")
    grid.write_text('[[cases]]\ndirection = "extension"\n[[cases]]\ndirection = "sideways"\n')
    assert main(["strength-batch", str(grid), "--out", str(tmp_path / "out"), "--workers", "1", "--no-progress"]) == 1
    counts = json.loads(capsys.readouterr().out)
    assert counts["ok"] == 1 and counts["failed"] == 1 and counts["failed_total"] == 1


def test_a_diverging_simulation_is_one_error_line(tmp_path, capsys):
    assert main(["simulate", "--preset", "thesis", "--duration", "3", "--stiffness", "0", "--damping", "0", "--no-reflex", "--coactivation", "0.01",
                 "--out", str(tmp_path)]) == 1
    captured = capsys.readouterr()
    errors = [line for line in captured.err.splitlines() if line.startswith("trunk-drake")]
    assert len(errors) == 1 and "simulation diverged at t=" in errors[0] and "Traceback" not in captured.err


def test_warnings_are_one_plain_line_and_summary_arrays_are_arrays(tmp_path, capsys):
    assert main(["simulate", "--preset", "thesis", "--duration", "0.3", "--out", str(tmp_path)]) == 0  # its co-activation warns
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert lines and all(line.startswith("warning: ") for line in lines), err  # no "UserWarning", no source line
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert isinstance(summary["options"]["feedforward"], list) and len(summary["options"]["feedforward"]) == 210


def test_model_info_says_posterior_for_a_posterior_position(capsys):
    assert main(["model", "info"]) == 0
    out = capsys.readouterr().out
    assert "1.1 cm posterior and" in out and "-1.1 cm" not in out


def test_model_info_of_an_osim_model_without_lumbar_vertebrae(capsys):
    fixture = ROOT / "tests" / "data" / "fixture_trunk.osim"  # bodies pelvis, lumbar, thorax, head, roller
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the reader's notes on this fixture are tested in test_osim_fixture.py
        assert main(["model", "info", "--dofs", "all", "--model", str(fixture)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("model fixture_trunk") and "total mass" in lines[-2]
    assert lines[-1] == "upper body: not summarised (the model has no bodies lumbar5 ... lumbar1, or no mass above lumbar1)"


def test_version(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("trunk-drake 0.1.0 (drake ")


def write_trials(folder: Path, period: float):
    """Two trials (1 and 3 Hz multisines of `period`) as CSV beside the reference data's conditions (the default
    passenger's rhythm), simulated with the preset's gains perturbed and 20 Nms/rad extra damping; returns the
    nominal TrunkOptions."""
    from trunk_drake.diagram import TrunkOptions
    from trunk_drake.gap.benchmark import Case, truth_options
    from trunk_drake.gap.synthetic import synthetic_trials
    from trunk_drake.io.storage import write_csv
    from trunk_drake.io.trials import LUMBAR_LEVELS

    folder.mkdir()
    for name in ("conditions.toml", "truth_feedforward.csv"):
        (folder / name).write_text((REFERENCE / name).read_text().replace("period_s = 20.0", f"period_s = {period}"))
    experiment = load_experiment([REFERENCE])
    nominal = TrunkOptions(**experiment.options, **experiment.preset_gains())
    truth = truth_options(nominal, Case("damping", "single", (("extra_damping", {"damping": 20.0}),), seed=3))
    assert truth.kp != nominal.kp  # the gains are mis-set too
    for trial, name in zip(synthetic_trials(experiment.model(), truth, [("a", 1.0, 1), ("b", 3.0, 2)], np.radians(0.05),
                                            seed=3, period=period), ("a", "b")):
        columns = {"platform_displacement_m": trial.platform_displacement, "lumbar_rotation_rad": trial.lumbar_rotation,
                   **{f"{lvl}_rad": trial.levels[lvl] for lvl in LUMBAR_LEVELS}}
        write_csv(folder / f"trial_{name}.csv", time=trial.time, columns=columns, in_degrees=False)
    return nominal


def test_diagnose_runs_end_to_end_on_data_files(tmp_path):
    """`trunk-drake diagnose` in a short form: two 10 s-period trials written as CSV beside the reference data's
    conditions, simulated with the preset's gains perturbed and 20 Nms/rad extra damping; two candidates."""
    data = tmp_path / "data"
    nominal = write_trials(data, period=10.0)
    out = tmp_path / "out"
    gains = tmp_path / "gains.toml"  # the preset's own, as `--gains` (e.g. a fit's gains.toml) gives them
    gains.write_text("".join(f"[{k}]\n" + "".join(f"{g} = {v!r}\n" for g, v in table.items())
                             for k, table in (("kp", nominal.kp), ("kv", nominal.kv))))
    assert main(["diagnose", str(data), "--out", str(out), "--gains", str(gains), "--candidates", "extra_damping",
                 "reflex_delay", "--refine", "1", "--workers", "2", "--no-animation", "--json"]) == 0
    diagnosis = json.loads((out / "diagnosis.json").read_text())
    assert diagnosis["selected"] == ["extra_damping"], diagnosis["verdict"]
    assert (out / "report.md").exists() and not (out / "simulations.pickle").exists()


@pytest.fixture
def stand_in_search(monkeypatch):
    """The diagnosis' search (minutes: run by the test above and tests/test_gap.py) replaced by one that keeps the
    nominal gains; it records what it was given."""
    import trunk_drake.gap.diagnose
    from trunk_drake.gap.measures import segment_chi2
    from trunk_drake.gap.search import SearchResult
    from trunk_drake.gap.space import Fit
    from trunk_drake.gap.trials import half

    given = {}

    def search(space, screen, fitter, candidates, settings, nominal, nominal_steps, spare, progress=None):
        given.update(settings=settings, model=fitter.simulator.model, cluster=fitter.simulator.cluster)
        trials = fitter.trials
        train, test = (sum(segment_chi2(t.steady_outputs, y, fitter.noise, half(t, which)) for t, y in zip(trials, nominal))
                       for which in ("train", "test"))
        kept = Fit((), np.zeros(space.rank), train, test, {}, outputs=nominal)
        n_test = sum(t.steady_outputs[half(t, "test")].size for t in trials)
        return SearchResult(kept, [], [], kept, [], {"n_heldout": n_test, "penalty": float(np.log(n_test)),
                                                     "refit_heldout_chi2": test}, space)

    monkeypatch.setattr(trunk_drake.gap.diagnose, "search_effects", search)
    return given


def test_diagnose_with_gains_first_on_the_sagittal_levels_on_a_dask_cluster(tmp_path, capsys, stand_in_search, dask_cluster):
    """`trunk-drake diagnose DATA --gains-first --dofs sagittal --cluster ADDRESS` (the data's preset has the rhythm):
    the sagittal model's nominal simulations are jobs on the cluster's worker, the search is the gains-first one,
    and diagnosis.json says so."""
    data = tmp_path / "data"
    write_trials(data, period=2.0)
    out = tmp_path / "out"
    assert main(["diagnose", str(data), "--out", str(out), "--gains-first", "--dofs", "sagittal",
                 "--cluster", dask_cluster.address, "--no-animation", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["selected"] == []
    assert stand_in_search["settings"].gains_first and stand_in_search["cluster"] == dask_cluster.address
    assert stand_in_search["model"].dofs == "sagittal" and dask_cluster.jobs_done() == 2  # one per trial
    diagnosis = json.loads((out / "diagnosis.json").read_text())
    assert diagnosis["options"]["gains_first"] is True and (out / "report.md").exists()


def test_diagnose_on_an_osim_model(tmp_path, capsys, stand_in_search, lumbar_c210_path):
    """`trunk-drake diagnose DATA --model FILE.osim`: the data's preset on the file's model (its rhythm). The
    animations draw MyoTorso's muscle paths only: without --no-animation the command stops before the work."""
    data = tmp_path / "data"
    write_trials(data, period=2.0)
    out = tmp_path / "out"
    assert main(["diagnose", str(data), "--out", str(out), "--model", str(lumbar_c210_path), "--json"]) == 2
    _one_error_line(capsys, "--no-animation")
    assert stand_in_search == {}
    assert main(["diagnose", str(data), "--out", str(out), "--model", str(lumbar_c210_path), "--no-animation", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["selected"] == []
    model = stand_in_search["model"]
    assert model.spec.name == "Lumbar_C_210" and model.dofs == "rhythm" and (out / "diagnosis.json").exists()
