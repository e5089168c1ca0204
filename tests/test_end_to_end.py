"""Every documented command, end to end on short settings (issue 12: what CI must prove)."""

from __future__ import annotations

import json
import shlex
import subprocess
import sys
from pathlib import Path

from test_readme import readme_block

from trunk_drake.cli import main
from trunk_drake.reproduce import EXPERIMENTS

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "models" / "reference"


def test_readme_first_command_simulates(tmp_path):
    """The README's first command (its `trunk-drake simulate`), with a 1 s duration."""
    first = readme_block("## Two commands", "bash")
    command = shlex.split(first[first.index("trunk-drake simulate"):].splitlines()[0])
    assert command[command.index("--duration") + 1] == "20"
    command[command.index("--duration") + 1] = "1"
    command[command.index("--out") + 1] = str(tmp_path / "sim")
    script = Path(sys.executable).with_name("trunk-drake")  # the installed console script
    done = subprocess.run([str(script), *command[1:]], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["sim_time_s"] == 1.0


def test_reproduce_quick_runs_every_experiment(tmp_path, capsys):
    assert main(["reproduce", "--quick", "--out", str(tmp_path)]) == 0, capsys.readouterr().err
    report = json.loads((tmp_path / "report.json").read_text())
    assert {e.name: report["experiments"][e.name]["status"] for e in EXPERIMENTS} == {e.name: "ok" for e in EXPERIMENTS}
    assert "--quick: shortened, not a result" in (tmp_path / "report.md").read_text()
    assert str(tmp_path) not in (tmp_path / "report.json").read_text()  # paths relative to the report: it can move


def test_fit_on_one_short_trial(tmp_path, capsys):
    assert main(["fit", str(REFERENCE / "trial_1hz_a.csv"), "--t-max", "3", "--max-iterations", "1", "--dofs", "rhythm",
                 "--starts", "2", "--workers", "1", "--json", "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert len(json.loads((tmp_path / "fit.json").read_text())["starts"]) == 2
    assert len(summary["gains"]["kp"]) == 7 and (tmp_path / "gains.toml").exists() and (tmp_path / "fit_time.png").exists()


def test_fit_on_a_dask_cluster(tmp_path, capsys, dask_cluster):
    """`trunk-drake fit DATA --cluster ADDRESS`: every simulation of the fit is a job on the cluster's worker."""
    assert main(["fit", str(REFERENCE / "trial_1hz_a.csv"), "--t-max", "3", "--max-iterations", "1",
                 "--cluster", dask_cluster.address, "--json", "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert 0 < dask_cluster.jobs_done() <= summary["n_simulations"]  # a job simulates one point, or several at once
    assert json.loads((tmp_path / "fit.json").read_text())["n_simulations"] == summary["n_simulations"]


def test_strength_batch_on_a_small_grid(tmp_path, capsys):
    grid = tmp_path / "grid.toml"
    grid.write_text('[grid]\ndirection = ["extension", "flexion", "lateral"]\n')
    assert main(["strength-batch", str(grid), "--workers", "2", "--no-progress", "--out", str(tmp_path / "out")]) == 0
    counts = json.loads(capsys.readouterr().out)
    assert counts["ok"] == 3 and Path(counts["csv"]).read_text().count("\n") == 4


def test_gap_benchmark_one_case(tmp_path, capsys):
    # short form: two candidates instead of the eleven (3 min instead of 12)
    assert main(["gap-benchmark", "--case", "no_effect_0", "--candidates", "reflex_delay", "extra_damping",
                 "--workers", "1", "--json", "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["cases"] == 1 and summary["failed"] == []
    assert (tmp_path / "cases" / "no_effect_0" / "report.md").exists()
    assert summary["candidates"] == ["extra_damping", "reflex_delay"]
    row, = [json.loads(line) for line in (tmp_path / "results.jsonl").read_text().splitlines()]
    # no claim; the gains widened beyond the 2 identifiable directions explain the gap, measured from the widened model
    assert row["selected"] == [] and "gains" in [s["action"] for s in row["steps"]]
    assert set(row["gap"]) == {"nominal", "refit", "widened"} and row["gap"]["widened"] < row["gap"]["refit"]
    capsys.readouterr()
    assert main(["gap-benchmark", "--case", "no_effect_0", "--out", str(tmp_path)]) == 2  # would mix two benchmarks
    assert "candidates: ['extra_damping', 'reflex_delay'] there, None now" in capsys.readouterr().err
