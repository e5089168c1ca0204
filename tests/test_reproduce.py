"""Smoke test of `trunk-drake reproduce`: runner, sweep pool, report writer (tiny durations)."""

import json

import numpy as np
import pytest

import trunk_drake as td
from trunk_drake import reproduce as rp
from trunk_drake import thesis
from trunk_drake.cli import build_parser
from trunk_drake.commands import reproduce as reproduce_command


@pytest.fixture(scope="module")
def sagittal():
    return td.load_model("sagittal")


def test_runner_writes_sections_figures_and_skips_finished_experiments(tmp_path, sagittal, capsys):
    names = ["strength_fig4_2", "bushing_sweeps_fig4_5"]
    options = {"strength_fig4_2": {"sweep": False},
               "bushing_sweeps_fig4_5": {"duration": 0.3, "k_values": (100.0, 800.0), "c_values": (0.0, 8.0)}}
    report = rp.run_experiments(tmp_path, names, workers=2, model=sagittal, options=options)
    for name in names:
        entry = report["experiments"][name]
        assert entry["status"] == "ok", entry.get("error")
        assert entry["thesis"] and entry["ours"] and entry["comparison"]
        for figure in entry["figures"]:  # stored relative to the report: the folder can move
            assert figure.endswith(".png") and (tmp_path / figure).stat().st_size > 10_000
    text = (tmp_path / "report.md").read_text()
    assert "SYNTHETIC" in text and "## Contents" in text and "| finding |" in text
    for name in names:
        assert f"## {list(names).index(name) + 1}. {rp.experiment(name).title}" in text
        assert f"](#{name})" in text and f'<a id="{name}"></a>' in text
    assert "![fig4_5_bushing_sweeps](bushing_sweeps_fig4_5/fig4_5_bushing_sweeps.png)" in text
    stored = json.loads((tmp_path / "report.json").read_text())
    assert stored["metadata"]["model"]["fingerprint"] and set(names) <= set(stored["experiments"])
    # stiffer bushings: less L5-S1 flexion under gravity (the thesis' trend)
    finals = stored["experiments"]["bushing_sweeps_fig4_5"]["numbers"]["final_L5_S1_deg"]
    assert finals["locked k=800 c=0"] < finals["locked k=100 c=0"]

    again = rp.run_experiments(tmp_path, names, workers=2, model=sagittal)
    assert again["run"]["skipped"] == names
    assert "skipped" in capsys.readouterr().out


def test_sweep_records_divergence_and_goes_on(sagittal):
    cases = [{"label": "diverges", "simulate": dict(duration=5.0, perturbation=None, stiffness=0.0, damping=0.0, strength_scale=1e-3)},
             {"label": "holds", "simulate": dict(duration=0.2, perturbation=None, stiffness=800.0)}]
    traces = thesis.run_cases(cases, sagittal, workers=1)
    assert traces["diverges"]["diverged_at"] > 0 and thesis.describe(traces["diverges"]).startswith("diverged at t=")
    assert thesis.final_deg(traces["diverges"]) is None
    assert np.isfinite(thesis.final_deg(traces["holds"], "L5_S1_FE"))


def test_cli_and_registry():
    args = build_parser().parse_args(["reproduce", "--out", "x", "--only", "validation_fig4_14_4_15"])
    assert args.func is reproduce_command.run
    assert rp._with_requirements(["validation_fig4_14_4_15"]) == ["fitted_gains_tables4_2_4_3", "validation_fig4_14_4_15"]
    assert all((rp.ANALYSES_DIR / f"{e.name}.py").exists() for e in rp.EXPERIMENTS)
    with pytest.raises(ValueError, match="unknown experiment"):
        rp.experiment("fig9_9")
    assert rp.jsonable({"a": np.array([1.0, np.inf]), "b": np.float64(2.0)}) == {"a": [1.0, "inf"], "b": 2.0}
