"""dofs="rhythm" on an OpenSim file: Lumbar_C_210.osim's levels follow `flex_extension` through its own
coordinate couplers, checked against OpenSim 4.6 on the same file with the couplers enforced
(lengths, moment arms about flex_extension, mass and centre of mass along the rhythm; isometric
strength against OpenSim's with the same load points), and run from the command line."""

import json
import os
import re

import numpy as np
import pytest

import trunk_drake as td
from trunk_drake.cli import main
from trunk_drake.model.trunk_model import model_source

osim = pytest.importorskip("opensim", reason="OpenSim 4.6 (pip opensim) is needed for this oracle test")
from osim_oracle import OsimOracle  # noqa: E402

N_POSES = 41


@pytest.fixture(scope="module")
def rhythm(lumbar_c210_path):
    return td.load_model(lumbar_c210_path, dofs="rhythm")


def test_the_files_couplers_are_the_rhythm(rhythm):
    """pelvis_tx + lumbar_FE (= the sum of the level flexions = -flex_extension); the levels move by
    the couplers' ratios, and q maps to and from the file's coordinates."""
    assert rhythm.coordinates == ["pelvis_tx", "lumbar_FE"]
    assert [c.name for c in rhythm.joint_info] == ["pelvis_tx", "L5_S1_FE", "L4_L5_FE", "L3_L4_FE", "L2_L3_FE", "L1_L2_FE"]
    np.testing.assert_allclose(rhythm.level_matrix[:, 1], [0.125, 0.185, 0.204, 0.231, 0.255])  # L5/S1 axis, couplers
    assert rhythm.level_matrix.sum(axis=0)[1] == pytest.approx(1.0)
    values = rhythm.source_coordinates([0.0, 0.4])
    assert values["flex_extension"] == pytest.approx(-0.4)
    assert values["L3_L4_FE"] == pytest.approx(0.204 * -0.4) and values["LB_wrapjnt_r3"] == pytest.approx(0.6 * -0.4)
    np.testing.assert_allclose(rhythm.q_from_source({"flex_extension": -0.4}), [0.0, 0.4])
    assert rhythm.coordinate_info[1].range == pytest.approx((-0.45378561, 1.22173048))  # -flex_extension's range


def test_lengths_moment_arms_mass_and_com_match_opensim_with_couplers(rhythm, lumbar_c210_path):
    oracle = OsimOracle(lumbar_c210_path, couplers=True)
    assert oracle.muscle_names == rhythm.muscles
    lo, hi = rhythm.coordinate_info[1].range
    worst = np.zeros(4)
    for flexion in np.linspace(lo, hi, N_POSES):
        q = np.array([0.0, flexion])
        values = {k: v for k, v in rhythm.source_coordinates(q).items()}
        assert values == pytest.approx(oracle.with_couplers(dict(values)), abs=1e-12)
        oracle.set(values)
        state = rhythm.path_state(q)
        theirs = oracle.generalized_forces() @ oracle.coupling(values, "flex_extension")  # = computeMomentArm
        mass, com = oracle.mass_and_com()
        context = rhythm.plant.CreateDefaultContext()
        rhythm.plant.SetPositions(context, q)
        worst = np.maximum(worst, [np.abs(state.lengths - oracle.lengths()).max(),
                                   np.abs(rhythm.source_moment_arms(q)["flex_extension"] - theirs).max(),
                                   np.abs(-state.moment_arms[:, 1] - theirs).max(),  # lumbar_FE = -flex_extension
                                   max(abs(rhythm.plant.CalcTotalMass(context) - mass),
                                       np.abs(rhythm.center_of_mass(q) - com).max())])
    print(f"\nrhythm on Lumbar_C_210, {N_POSES} poses: max |dL| {worst[0]:.1e} m, max |d moment arm| {worst[1]:.1e} m "
          f"(about lumbar_FE {worst[2]:.1e} m), mass/com {worst[3]:.1e}")
    assert worst[0] < 1e-5 and worst[1] < 1e-4 and worst[2] < 1e-4 and worst[3] < 1e-9


def test_strength_equals_opensims_on_the_same_file(rhythm, lumbar_c210_path):
    """The LP on our rhythm of the .osim vs the same LP on OpenSim's moment arms, muscle forces,
    gravity and load levers (tests/lumbar_c210_oracle.py), couplers enforced."""
    from lumbar_c210_oracle import osim_statics
    from trunk_drake.optim.strength import max_load

    ref = osim_statics(lumbar_c210_path, [rhythm.spec.landmark(n).pos for n in ("T6", "T7")], couplers=True)
    ours = td.isometric_strength(rhythm, ("extension", "flexion"), sweep=False)
    for d, result in ours.items():
        for passive, mine in ((True, result.max_force), (False, result.variants["without_passive"]["max_force_N"])):
            theirs = max_load(ref.balance(passive), ref.load_per_newton[d], 0.0)[0]
            print(f"\n{d} ({'with' if passive else 'without'} passive): Lumbar_C_210 rhythm {mine:.1f} N, OpenSim {theirs:.1f} N")
            assert mine == pytest.approx(theirs, rel=0.01)


def test_bad_coupler_is_refused(lumbar_c210_path, tmp_path):
    text = lumbar_c210_path.read_text()
    start = text.index('<CoordinateCouplerConstraint name="L3_L4_FE_con">')
    offset = re.compile(r"(<coefficients>\s*[-0-9.eE]+\s+)[-0-9.eE]+")
    bad = tmp_path / "offset_coupler.osim"
    bad.write_text(text[:start] + offset.sub(r"\g<1>0.01", text[start:], count=1))
    with pytest.raises(ValueError, match="coordinate coupler 'L3_L4_FE_con'.*not linear with zero offset"):
        td.load_model(bad, dofs="rhythm")


def test_cli_simulate_and_strength_with_the_rhythm(lumbar_c210_path, tmp_path, capsys):
    """The default preset (rhythm, de Leva's arms on the torso body) runs on the .osim; so does strength."""
    with model_source(lumbar_c210_path):
        passenger = td.load_preset("default").model()
    assert passenger.coordinates == ["pelvis_tx", "lumbar_FE"]
    bare = td.load_model(lumbar_c210_path, dofs="rhythm").spec.body("torso").mass
    assert passenger.spec.body("torso").mass > bare + 5.0  # arms and head completion on the torso
    out = tmp_path / "sim"
    assert main(["simulate", "--model", str(lumbar_c210_path), "--duration", "1", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["sim_time_s"] == pytest.approx(1.0) and summary["warning"] is None
    assert abs(summary["lumbar_rotation_deg"]["final"]) < 5.0
    assert (out / "motion.mot").exists()
    assert main(["strength", "--model", str(lumbar_c210_path), "--dofs", "rhythm", "--direction", "extension", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["dofs"] == "rhythm" and "coordinate couplers of Lumbar_C_210" in report["configuration"]
    assert 200.0 < report["results"]["extension"]["max_force_N"] < 300.0


def test_cli_stability_and_strength_batch_with_the_rhythm(rhythm, lumbar_c210_path, tmp_path, capsys):
    """`stability --model` analyses the default preset on the file; `strength-batch --model` runs its cases in worker
    processes, each with the file's model: as strong as the same case on it here."""
    from trunk_drake.batch import load_grid, run_case

    assert main(["stability", "--model", str(lumbar_c210_path), "--no-critical", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    model = report["metadata"]["model"]
    assert model["source"].startswith("Lumbar_C_210.osim") and model["dofs"] == "rhythm"
    assert report["operating_point"]["coordinates"] == ["lumbar_FE"] and isinstance(report["stable"], bool)
    grid = tmp_path / "grid.toml"
    grid.write_text('[grid]\ndirection = ["extension", "flexion"]\ndofs = ["rhythm"]\n')
    assert main(["strength-batch", str(grid), "--model", str(lumbar_c210_path), "--workers", "2", "--no-progress",
                 "--out", str(tmp_path / "batch")]) == 0
    assert json.loads(capsys.readouterr().out)["ok"] == 2
    rows = [json.loads(line) for line in (tmp_path / "batch" / "results.jsonl").read_text().splitlines()]
    assert all(int(r["worker"].rsplit(":", 1)[1]) != os.getpid() for r in rows)
    here = {c["case_id"]: run_case(rhythm, c)["max_force_N"] for c in load_grid(grid)}
    assert {r["case_id"]: r["max_force_N"] for r in rows} == pytest.approx(here, rel=1e-9)


def test_cli_fit_with_the_rhythm(lumbar_c210_path, tmp_path, capsys, monkeypatch):
    """`fit --model` fits the gains of the data's preset (the default passenger) on the file's model (its rhythm)."""
    import trunk_drake.optim.fit
    from trunk_drake.data import models_dir

    fitted, fit = [], trunk_drake.optim.fit.fit_reflex_gains

    def recording(model, *args, **kwargs):
        fitted.append(model)
        return fit(model, *args, **kwargs)

    monkeypatch.setattr(trunk_drake.optim.fit, "fit_reflex_gains", recording)
    trial = models_dir() / "reference" / "trial_1hz_a.csv"
    assert main(["fit", str(trial), "--t-max", "1", "--max-iterations", "1", "--model", str(lumbar_c210_path), "--json",
                 "--out", str(tmp_path)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert [(m.spec.name, m.dofs) for m in fitted] == [("Lumbar_C_210", "rhythm")]
    assert summary["n_simulations"] > 0 and len(summary["gains"]["kp"]) == 7 and (tmp_path / "gains.toml").exists()


def test_cli_reproduce_with_the_file(lumbar_c210_path, tmp_path):
    """`reproduce --model` runs the thesis' experiments on the file's model (the quick co-activation one here; the
    thesis' five independent levels); its report names the file."""
    assert main(["reproduce", "--quick", "--only", "coactivation_fig4_6", "--model", str(lumbar_c210_path),
                 "--out", str(tmp_path)]) == 0
    report = json.loads((tmp_path / "report.json").read_text())
    model = report["metadata"]["model"]
    assert model["source"].startswith("Lumbar_C_210.osim") and model["dofs"] == "sagittal"
    assert report["experiments"]["coactivation_fig4_6"]["status"] == "ok"
