"""Command-line smoke tests: the documented commands run and fail clearly on bad input."""

import json
from pathlib import Path

from trunk_drake.cli import main

GAINS = str(Path(__file__).resolve().parents[1] / "models" / "reflex_gains_thesis.toml") + "#trunk_settling"


def test_model_info_json(capsys):
    assert main(["model", "info", "--dofs", "spine3d", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert len(info["coordinates"]) == 15 and info["n_muscles"] == 210
    assert abs(info["upper_body"]["com_anterior_of_L4_L5_joint_m"]) < 0.05


def test_simulate_writes_files_and_json(tmp_path, capsys):
    assert main(["simulate", "--duration", "1", "--out", str(tmp_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    for key in ("wall_time_s", "sim_time_s", "steps", "real_time_factor"):
        assert key in summary
    assert summary["sim_time_s"] == 1.0
    for name in ("states.sto", "muscle_forces.sto", "kinematics.csv", "simulation.png", "summary.json"):
        assert (tmp_path / name).exists(), name


def test_bad_input_exits_with_a_message(tmp_path, capsys):
    assert main(["diagnose", str(tmp_path / "missing.csv"), "--out", str(tmp_path)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["simulate", "--duration", "-1", "--out", str(tmp_path)]) == 2
    assert "duration" in capsys.readouterr().err
    bad = tmp_path / "gains.toml"
    bad.write_text("[kp]\nsacrospinalis = 0.1\n")
    assert main(["simulate", "--duration", "1", "--reflex-gains", str(bad), "--out", str(tmp_path)]) == 2
    assert "kv" in capsys.readouterr().err


def test_stability_answers_with_json_and_plots(tmp_path, capsys):
    assert main(["stability", "--no-critical", "--srs", "--out", str(tmp_path), "--json"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert isinstance(summary["stable"], bool) and summary["dynamic"]["margin_per_s"] is not None
    assert set(summary["static"]["terms_along_least_stable_mode_nm_per_rad"]) >= {"gravity", "bushings", "short_range"}
    for name in ("stability.json", "stability_roots.png", "stability_mode.png"):
        assert (tmp_path / name).exists(), name
    assert "Traceback" not in captured.err and all(line.startswith("warning: ") for line in captured.err.splitlines())
    assert main(["stability", "--l-desired", "long", "--no-critical"]) == 2
    assert "--l-desired 'long'" in capsys.readouterr().err


def test_every_passenger_option_reaches_the_preset():
    """The options the README's command table lists for `simulate` and `stability`, read back as the preset's settings."""
    from trunk_drake.cli import build_parser
    from trunk_drake.commands import passenger_preset

    for command in (["simulate", "--out", "x"], ["stability"]):
        args = build_parser().parse_args(command + [
            "--preset", "thesis", "--dofs", "rhythm", "--reflex-gains", GAINS,
            "--gain-scale", "2", "--coactivation", "0.05", "--stiffness", "200", "--damping", "5", "--l-desired", "neutral",
            "--reflex-delay", "0.02", "--no-srs"])
        preset = passenger_preset(args)
        assert (preset.dofs, preset.gain_scale, preset.coactivation, preset.stiffness, preset.damping, preset.l_desired,
                preset.reflex_delay, preset.srs) == ("rhythm", 2.0, 0.05, 200.0, 5.0, "neutral", 0.02, False), command
        assert preset.reflex_gains == GAINS


def test_simulate_runs_with_the_documented_options(tmp_path, capsys):
    """`simulate` with the options of its row in the README's command table no other test passes with valid values."""
    assert main(["simulate", "--dofs", "rhythm", "--bandwidth", "3", "--reflex-gains", GAINS, "--gain-scale", "9",
                 "--duration", "0.3", "--out", str(tmp_path / "rhythm"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["sim_time_s"] == 0.3
    assert main(["simulate", "--tendon", "compliant", "--duration", "0.05", "--out", str(tmp_path / "compliant"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["sim_time_s"] == 0.05


def test_stability_runs_with_the_documented_options(capsys):
    assert main(["stability", "--preset", "thesis", "--gain-scale", "2", "--coactivation", "0.05", "--stiffness", "200",
                 "--damping", "5", "--reflex-delay", "0.02", "--no-srs", "--l-desired", "1", "--no-critical", "--json"]) == 0
    assert isinstance(json.loads(capsys.readouterr().out)["stable"], bool)
