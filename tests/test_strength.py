"""Isometric strength: direct maximum vs the thesis' 10 N sweep, load geometry, in vivo comparison, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest

from trunk_drake.cli import main
from trunk_drake.model.trunk_model import load_model
from trunk_drake.optim.static import MomentBalance, StaticOptimizer, with_required
from trunk_drake.optim.strength import (
    DEFLECTION_TOLERANCE_DEG, DIRECTIONS, VARIANTS, StrengthProblem, acromion_half_breadth, in_vivo_comparison,
    isometric_strength, load_case, max_load, strength_variants,
)


@pytest.fixture(scope="module")
def spine3d():
    return load_model(dofs="spine3d")


@pytest.fixture(scope="module")
def results(spine3d):
    return isometric_strength(spine3d, sweep=True)


def test_max_load_matches_the_analytic_one_joint_answer():
    # flexor 40 Nm capacity, extensor -24 Nm; a load 0.3 m from the joint needs a 0.3 F flexor moment
    amin = 0.01
    balance = MomentBalance([[0.05], [-0.04]], [800.0, 600.0], [0.0, 0.0], [0.0], ("hinge",), ("flexor", "extensor"))
    force, sensitivity = max_load(balance, [-0.3], amin)
    assert force == pytest.approx((40.0 - 24.0 * amin) / 0.3, rel=1e-7)
    assert sensitivity[0] == pytest.approx(1 / 0.3, rel=1e-5)  # one extra Nm holds 1/0.3 N more


@pytest.mark.parametrize("direction", DIRECTIONS)
def test_direct_maximum_equals_the_sweep_within_one_step(results, direction):
    r = results[direction]
    assert r.sweep_force is not None and r.sweep_force % 10.0 == 0.0
    assert r.sweep_force <= r.max_force < r.sweep_force + 10.0
    assert r.sweep_first_failure == r.sweep_force + 10.0 and r.parity
    assert r.limiting_coordinate in r.sensitivity and r.muscles_at_upper_bound


def test_sensitivity_is_the_derivative_of_the_maximum(spine3d, results):
    optimizer = StaticOptimizer(spine3d, min_activation=0.0)  # as isometric_strength's maxima
    problem = StrengthProblem(optimizer, load_case(spine3d, "extension"))
    coordinate = results["extension"].limiting_coordinate
    help_ = np.zeros(len(problem.coordinates))
    help_[problem.coordinates.index(coordinate)] = 1e-3  # 1 mNm of extra generalized force, supplied
    helped = StrengthProblem(optimizer, problem.case, balance=with_required(problem.balance, -help_))
    assert (helped.maximum()[0] - problem.maximum()[0]) / 1e-3 == pytest.approx(results["extension"].sensitivity[coordinate], rel=1e-3)


def test_load_points_and_directions(spine3d):
    ext, flex, lat = (load_case(spine3d, d) for d in DIRECTIONS)
    assert sum(ext.shares) == pytest.approx(1.0) and len(ext.points) == 2
    np.testing.assert_allclose(ext.points[0], spine3d.spec.landmark("T6").pos)
    np.testing.assert_allclose(ext.unit_force, -np.asarray(flex.unit_force))
    assert abs(ext.unit_force[2]) < 1e-12  # horizontal
    np.testing.assert_allclose(ext.unit_force, [0.0, -1.0, 0.0], atol=1e-9)  # pelvis anterior = world -y at rest
    np.testing.assert_allclose(lat.unit_force, [0.0, 0.0, 1.0])
    acromion = load_case(spine3d, "lateral", shoulder="acromion")
    assert acromion.points[0][2] == pytest.approx(-acromion_half_breadth()) and acromion_half_breadth() == pytest.approx(0.2)
    with pytest.raises(ValueError, match="spine3d"):
        load_case(load_model("sagittal"), "lateral")
    with pytest.raises(ValueError, match="direction"):
        load_case(spine3d, "sideways")


def test_muscles_at_the_upper_bound(results, spine3d):
    groups = spine3d.groups
    back = set(groups["sacrospinalis"]) | set(groups["transversospinalis"])
    abdominal = set(groups["rectus_abdominis"]) | set(groups["external_oblique"]) | set(groups["internal_oblique"])
    assert back & set(results["extension"].muscles_at_upper_bound)
    assert not abdominal & set(results["extension"].muscles_at_upper_bound)
    # MyoTorso's flexion is limited by how the abdominals' moment is shared between levels:
    # psoas (flexes the lower levels, extends the upper ones) saturates, not the abdominals
    assert set(groups["psoas_major"]) & set(results["flexion"].muscles_at_upper_bound)
    left = [m for m in results["lateral"].muscles_at_upper_bound if m.endswith("_l")]
    assert len(left) > len(results["lateral"].muscles_at_upper_bound) / 2  # the left side bends against the load


def test_in_vivo_comparison_never_invents_values():
    rows = in_vivo_comparison("extension", 300.0)
    assert rows[0]["thesis_source"] and rows[0]["mean_N"] == "no reference" and rows[0]["ratio_model_to_reference"] == "no reference"
    kocjan = next(r for r in rows if r["reference"].endswith("kocjan2014_standing_mixed"))
    assert kocjan["ratio_model_to_reference"] == pytest.approx(300.0 / 504.0)
    assert kocjan["within_one_sd"] is False  # |300 - 504| > 165.4
    lateral = in_vivo_comparison("lateral", 300.0)
    assert lateral[0]["reference"] == "strength.lateral.thomas" and lateral[0]["within_one_sd"] == "no reference"
    thesis = next(r for r in in_vivo_comparison("flexion", 450.0) if r["reference"].endswith("flexion_T6T7_load"))
    assert thesis["kind"] == "model" and thesis["ratio_model_to_reference"] == pytest.approx(0.5)


def test_cli_strength_json(capsys):
    assert main(["strength", "--json", "--no-sweep"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report["results"]) == set(DIRECTIONS)
    for r in report["results"].values():
        assert r["max_force_N"] > 0 and r["in_vivo"] and r["limiting_coordinate"]
    assert "acromion" in report["results"]["lateral"]["variants"]


# ------------------------------------------------------------------ rhythm, deflection, passive force

def test_deflection_tolerance_adds_the_bushing_moment_to_the_one_joint_answer():
    # flexor 40 Nm capacity; the joint's bushing may carry up to 100 Nm/rad x 2 deg more
    limit = 100.0 * np.radians(2.0)
    exact = MomentBalance([[0.05], [-0.04]], [800.0, 600.0], [0.0, 0.0], [0.0], ("hinge",), ("flexor", "extensor"))
    deflecting = MomentBalance([[0.05], [-0.04]], [800.0, 600.0], [0.0, 0.0], [0.0], ("hinge",), ("flexor", "extensor"),
                               deflection=[[1.0]], deflection_limit=[limit])
    assert max_load(exact, [-0.3], 0.0)[0] == pytest.approx(40.0 / 0.3, rel=1e-7)
    assert max_load(deflecting, [-0.3], 0.0)[0] == pytest.approx((40.0 + limit) / 0.3, rel=1e-7)


@pytest.fixture(scope="module")
def variants():
    return strength_variants()


def test_every_variant_reports_both_directions_with_and_without_passive_force(variants):
    assert set(variants) == set(VARIANTS)
    for name, results in variants.items():
        assert set(results) == {"extension", "flexion"}, name
        for r in results.values():
            assert r.max_force > 0 and r.variants["without_passive"]["max_force_N"] > 0


def test_the_rhythm_balances_one_coordinate_and_is_strongest_in_flexion(variants):
    rhythm, exact = variants["rhythm"], variants["independent levels, exact"]
    assert rhythm["flexion"].limiting_coordinate == "lumbar_FE" and list(rhythm["flexion"].sensitivity) == ["lumbar_FE"]
    # one weighted balance instead of five: the levels help each other
    assert rhythm["flexion"].max_force > 5 * exact["flexion"].max_force


def test_tolerated_deflection_lies_between_exact_balance_and_what_the_bushings_allow(spine3d, variants):
    name = f"independent levels, {DEFLECTION_TOLERANCE_DEG:g} deg deflection"
    for direction in ("extension", "flexion"):
        exact, tolerant = variants["independent levels, exact"][direction], variants[name][direction]
        assert exact.max_force < tolerant.max_force
    tolerance = np.radians(DEFLECTION_TOLERANCE_DEG)
    optimizer = StaticOptimizer(spine3d, min_activation=0.0, deflection_tolerance=tolerance)
    problem = StrengthProblem(optimizer, load_case(spine3d, "flexion"))
    frame = problem.solve(0.99 * variants[name]["flexion"].max_force)
    assert np.abs(frame.deflection_moments).max() <= 100.0 * tolerance + 1e-9  # each bushing within 2 deg
    assert np.abs(frame.deflection_moments).max() > 0.5 * 100.0 * tolerance  # and the bushings are used
    assert np.abs(frame.residuals).max() < 1e-6


def test_an_activation_floor_costs_strength(variants):
    floor = variants["independent levels, exact, activation floor 0.01 (thesis)"]
    for direction in ("extension", "flexion"):
        assert floor[direction].max_force < variants["independent levels, exact"][direction].max_force


def test_cli_strength_rhythm(capsys):
    assert main(["strength", "--dofs", "rhythm", "--json", "--no-sweep"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["dofs"] == "rhythm" and set(report["results"]) == {"extension", "flexion"}
    assert "lumbar rhythm" in report["configuration"] and "activations in [0, 1]" in report["configuration"]
    for r in report["results"].values():
        assert r["limiting_coordinate"] == "lumbar_FE" and "without_passive" in r["variants"]
    assert main(["strength", "--dofs", "rhythm", "--tolerance-deg", "2", "--no-sweep"]) == 2
    assert "independent levels" in capsys.readouterr().err
    assert main(["strength", "--dofs", "spine3d", "--tolerance-deg", "2", "--no-passive", "--direction", "flexion", "--json",
                 "--no-sweep"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert "2 deg on its bushing" in report["configuration"] and "without passive" in report["configuration"]
    assert "with_passive" in report["results"]["flexion"]["variants"]
    assert main(["strength", "--dofs", "rhythm", "--direction", "extension", "--min-activation", "0.01", "--no-sweep",
                 "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert set(report["results"]) == {"extension"} and "activations in [0.01, 1]" in report["configuration"]
