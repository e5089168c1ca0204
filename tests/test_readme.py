"""The README's Python API block runs as written (extracted from README.md, so the two cannot drift)."""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def readme_block(heading: str, language: str, readme: Path = ROOT / "README.md") -> str:
    """The first ```language block after `heading` in `readme`."""
    text = readme.read_text()
    section = text[text.index(heading):]
    return re.search(rf"```{language}\n(.*?)```", section, re.S).group(1)


def test_python_api_block_runs(tmp_path, monkeypatch):
    shared = ROOT.parent / "shared"
    if not (shared / "reference" / "lumbar_c_210" / "Lumbar_C_210.osim").exists():
        pytest.skip(f"the block reads Lumbar_C_210.osim from {shared} (the repository's ../shared folder)")
    root = tmp_path / "repository"  # "from the repository's root", without writing into it
    root.mkdir()
    os.symlink(ROOT / "models", root / "models")
    os.symlink(shared, tmp_path / "shared")
    monkeypatch.chdir(root)
    scope: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the co-activation's residual-moment note
        exec(compile(readme_block("## Python API", "python"), "README.md (Python API)", "exec"), scope)
    assert scope["upright"].sim_time_s == 2.0 and scope["seated"].dofs == "rhythm"
    assert scope["result"].sim_time_s == 20.0 and (root / "results" / "sim" / "states.sto").exists()
    assert set(scope["strength"]) == {"extension", "flexion", "lateral"}
    assert 0.001 <= scope["fit"].gains["kp"]["sacrospinalis"] <= 1.0


def test_models_readme_block_gives_the_values_it_shows(monkeypatch):
    """models/README.md's tomllib block, run from the repository's root: each expression equals the number its
    comment shows."""
    monkeypatch.chdir(ROOT)
    block = readme_block("Load it with the standard library", "python", ROOT / "models" / "README.md")
    scope: dict = {}
    shown = [line.split("#", 1) for line in block.splitlines() if re.search(r"#\s*[-0-9.]+", line)]
    exec(compile("\n".join(line for line in block.splitlines() if "#" not in line), "models/README.md", "exec"), scope)
    assert len(shown) == 2
    for expression, comment in shown:
        assert eval(expression, scope) == pytest.approx(float(comment.split()[0])), expression
