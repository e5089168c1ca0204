"""Every script in analyses/ and benchmarks/ runs here in a short form, as its own process, as a user types it (into a
temporary folder): a documented command that no test runs breaks unnoticed. A new script goes into SHORT_FORMS, or,
if it cannot run in seconds, into BY_HAND with the reason."""

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RUNS = ROOT / "docs" / "gap_benchmark"  # published gap-benchmark runs: the analyses/gap_*.py checks read their cases
SHORT_FORMS = {  # script: the arguments of its short form ("{tmp}": a temporary folder)
    "benchmarks/accuracy_reference.py": ["--duration", "0.2", "--out", "{tmp}/reference.csv"],
    "benchmarks/cpu_time.py": ["--duration", "0.2"],
    "benchmarks/default_passenger.py": ["--quick"],
    "benchmarks/differentiable_steps.py": ["--quick"],
    "benchmarks/fit.py": ["--t-max", "3", "--max-iterations", "1"],
    "benchmarks/gap.py": ["{tmp}/progress.log", "--quick"],
    "benchmarks/integrators.py": ["--duration", "0.2", "--quick"],
    "benchmarks/memory.py": ["--repeats", "1", "--duration", "0.1"],
    "benchmarks/paths.py": ["--quick"],
    "benchmarks/simulate.py": ["--duration", "0.3", "--compliant-duration", "0.05"],
    "benchmarks/stability.py": ["--quick"],
    "benchmarks/static.py": ["--quick"],
    "analyses/gap_lm_scaling_check.py": ["stiffening_discs_cubic400", "stiffening_discs", "--folder", f"{RUNS}/search_ca892f7",
                                         "--rounds", "1", "--quick"],
    "analyses/gap_pair_profile.py": ["0.04", f"{RUNS}/all_gains", "--quick"],
    "analyses/gap_partner_check.py": ["reflex_delay_delay0.04", f"{RUNS}/all_gains", "--quick"],
    "analyses/gap_polish_check.py": ["reflex_delay_delay0.04", f"{RUNS}/default_passenger", "--quick"],
    "analyses/gap_restart_check.py": ["reflex_delay_delay0.04", f"{RUNS}/search_640a2ea", "--quick"],
    "analyses/gap_trial_halves.py": ["--quick"],
    "analyses/make_reference_data.py": ["--out", "{tmp}", "--duration", "0.3"],
    "analyses/stability_configurations.py": ["--quick", "--out", "{tmp}"],
    "analyses/stability_vs_simulation.py": ["--quick", "--out", "{tmp}"],
    "analyses/strength_fig4_2.py": ["--quick", "--out", "{tmp}"],
    "analyses/vertebra_balance.py": [],
}
PRINTS_JSON = {s for s in SHORT_FORMS if s.startswith("benchmarks/")} | {"analyses/vertebra_balance.py"}
ANIMATION = {"benchmarks/animate.py", "analyses/animation_screenshot.py"}  # test_animation_scripts: one writes, one shoots
BY_HAND = {  # script: why CI does not run it
    "benchmarks/instructions.py": "runs Python under valgrind: still running after a CPU-minute for 0.02 s simulated",
}


def _reproduce_experiments() -> list[str]:
    """analyses/ scripts that are thesis experiments: their `__main__` is `script_main(__file__)` of `reproduce`."""
    return sorted(f"analyses/{p.name}" for p in (ROOT / "analyses").glob("*.py") if "script_main(__file__)" in p.read_text())


def run_script(script: str, args: list[str], tmp_path: Path) -> str:
    command = [sys.executable, str(ROOT / script), *(a.replace("{tmp}", str(tmp_path)) for a in args)]
    done = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 0, f"{' '.join(command)} failed:\n{done.stderr[-3000:]}"
    return done.stdout


def test_every_script_has_a_short_form_or_a_reason():
    scripts = {f"{folder}/{p.name}" for folder in ("analyses", "benchmarks") for p in (ROOT / folder).glob("*.py")}
    experiments = set(_reproduce_experiments())
    unlisted = scripts - SHORT_FORMS.keys() - BY_HAND.keys() - ANIMATION - experiments
    assert unlisted == set(), "add its short form to SHORT_FORMS"
    assert (SHORT_FORMS.keys() | BY_HAND.keys() | ANIMATION) - scripts == set(), "a listed script no longer exists"


def test_thesis_experiment_scripts_share_reproduce_entry():
    """Each thesis-experiment script is `reproduce --only NAME` (run by `reproduce --quick` in test_end_to_end) behind
    one entry, `script_main`, which analyses/strength_fig4_2.py runs here: its `__main__` block is only that call."""
    experiments = _reproduce_experiments()
    assert "analyses/strength_fig4_2.py" in experiments and len(experiments) >= 9
    for script in experiments:
        tree = ast.parse((ROOT / script).read_text())
        main = [n for n in tree.body if isinstance(n, ast.If) and "__main__" in ast.unparse(n.test)]
        assert len(main) == 1 and ast.unparse(main[0].body[-1]) == "raise SystemExit(script_main(__file__))", script


@pytest.mark.parametrize("script", sorted(SHORT_FORMS))
def test_script_runs_in_its_short_form(script, tmp_path):
    out = run_script(script, SHORT_FORMS[script], tmp_path)
    if script in PRINTS_JSON:
        json.loads(out[out.index("{"):])


def test_animation_scripts(tmp_path):
    """benchmarks/animate.py writes a page; analyses/animation_screenshot.py, the README's picture command, shoots it."""
    from trunk_drake.visual import browser

    run_script("benchmarks/animate.py", ["--duration", "0.3", "--out", "{tmp}/animation.html"], tmp_path)
    if browser.chromium_path() is None:
        pytest.skip("no chromium on PATH for animation_screenshot.py: .ci/run installs Debian's chromium with apt-get")
    run_script("analyses/animation_screenshot.py", ["{tmp}/animation.html", "{tmp}/shot.png", "--time", "0.2"], tmp_path)
    assert (tmp_path / "shot.png").stat().st_size > 0
