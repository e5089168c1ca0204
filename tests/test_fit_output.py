"""What a fit writes: gains.toml usable by `simulate --reflex-gains` (fixed groups kept), plots
of a constant target (settling: VAF undefined), fit.json."""

from __future__ import annotations

import json

import numpy as np
import pytest

from trunk_drake.diagram import TrunkOptions
from trunk_drake.model.trunk_model import load_model
from trunk_drake.optim.fit import fit_reflex_gains, settling_target, write_fit
from trunk_drake.optim.static import coactivation
from trunk_drake.simulation import load_reflex_gains


@pytest.fixture(scope="module")
def settling_fit():
    model = load_model("sagittal")
    fixed = {"kp": {"psoas_major": 0.05}, "kv": {"psoas_major": 0.02}}
    result = fit_reflex_gains(model, [settling_target(duration=0.5)], groups=("sacrospinalis",), fixed_gains=fixed,
                              scenario="settling", options=TrunkOptions(feedforward=coactivation(model, 0.02)),
                              max_iterations=1, workers=1, progress=False)
    return model, result


def test_settling_fit_writes_its_plots_although_its_vaf_is_undefined(settling_fit, tmp_path):
    _, result = settling_fit
    assert result.vaf["settling"]["lumbar_rotation"] is None  # a constant target: VAF about the mean is undefined
    files = write_fit(result, tmp_path)
    assert files["time_plot"].stat().st_size > 10_000
    assert json.loads(files["json"].read_text())["vaf"]["settling"]["lumbar_rotation"] is None


def test_gains_file_keeps_the_fixed_groups(settling_fit, tmp_path):
    _, result = settling_fit
    assert result.gains["kp"]["psoas_major"] == 0.05 and result.gains["kv"]["psoas_major"] == 0.02
    gains = load_reflex_gains(write_fit(result, tmp_path)["gains"])
    assert gains["kp"]["psoas_major"] == 0.05 and gains["kv"]["psoas_major"] == 0.02
    assert np.isclose(gains["kp"]["sacrospinalis"], result.gains["kp"]["sacrospinalis"], rtol=1e-5)
    assert "fixed, not fitted" in (tmp_path / "gains.toml").read_text()
