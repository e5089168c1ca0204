"""OpenSim conventions (issue 12 item 7): states.sto in Lumbar_C_210.osim's names and signs
(checked by OpenSim 4.6 itself), OpenSim .mot trials read with inDegrees and the flexion sign,
kinematics.csv with units, compliant fiber lengths, PointLoad's world frame."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from trunk_drake.io.storage import read_table, write_storage
from trunk_drake.io.trials import load_trial
from trunk_drake.model.trunk_model import load_model
from trunk_drake.optim.static import PointLoad, StaticOptimizer
from trunk_drake.simulation import simulate

FLEXED = 0.06  # rad per level


@pytest.fixture(scope="module")
def sagittal():
    return load_model("sagittal")


@pytest.fixture(scope="module")
def flexed_result(sagittal):
    """A result held at 0.06 rad of flexion per level (the posture of a short simulation, replaced)."""
    result = simulate(sagittal, duration=0.05, perturbation=None)
    q = np.array([0.0] + [FLEXED] * 5)
    return dataclasses.replace(result, q=np.tile(q, (result.time.size, 1)), lumbar_rotation=np.full(result.time.size, 5 * FLEXED))


def test_states_sto_plays_back_in_opensim_as_the_same_posture(lumbar_c210_path, sagittal, flexed_result, tmp_path):
    import opensim

    opensim.Logger.setLevelString("error")
    flexed_result.write(tmp_path, plot=False)
    osim = opensim.Model(str(lumbar_c210_path))
    table = opensim.TimeSeriesTable(str(tmp_path / "states.sto"))
    labels, row = list(table.getColumnLabels()), table.getRowAtIndex(0)
    coordinates = osim.getCoordinateSet()
    played = [lab for lab in labels if coordinates.contains(lab)]
    assert played == ["flex_extension", "L4_L5_FE", "L3_L4_FE", "L2_L3_FE", "L1_L2_FE"]

    def lengths(values):
        state = osim.initSystem()
        for name, value in values.items():
            coordinates.get(name).setValue(state, value, False)
        osim.realizePosition(state)
        muscles = osim.getMuscles()
        by_name = {muscles.get(i).getName(): muscles.get(i).getLength(state) for i in range(muscles.getSize())}
        return np.array([by_name[m] for m in sagittal.muscles])

    opensim_change = lengths({lab: row[labels.index(lab)] for lab in played}) - lengths({})
    ours_change = sagittal.muscle_lengths(flexed_result.q[0]) - sagittal.muscle_lengths(np.zeros(6))
    slope = ours_change @ opensim_change / (ours_change @ ours_change)
    assert np.corrcoef(ours_change, opensim_change)[0, 1] > 0.95 and 0.7 < slope < 1.3  # a mirrored motion gives -1


def test_states_sto_header_and_trial_round_trips(flexed_result, tmp_path):
    files = flexed_result.write(tmp_path, plot=False)
    states = read_table(files["states"])
    assert np.allclose(states.column("flex_extension"), -FLEXED) and states.in_degrees is False
    assert "flexion is negative" in states.header["convention"]
    from_sto = load_trial(files["states"])  # flex_extension: the .osim's convention, flipped back
    assert np.allclose(from_sto.levels["L5_S1_FE"], FLEXED) and np.allclose(from_sto.levels["L1_L2_FE"], FLEXED)
    kinematics = read_table(files["kinematics"])
    assert {"lumbar_rotation_rad", "platform_x_m", "L5_S1_FE_rad", "pelvis_tx_m"} <= set(kinematics.labels)
    from_csv = load_trial(files["kinematics"])
    assert np.allclose(from_csv.lumbar_rotation, 5 * FLEXED) and np.allclose(from_csv.levels["L3_L4_FE"], FLEXED)


def test_an_opensim_inverse_kinematics_mot_is_read_in_degrees_with_its_sign(tmp_path):
    t = np.arange(0.0, 1.0, 0.01)
    extension_deg = 3.0 * np.sin(2 * np.pi * t)  # the .osim's flex_extension: extension positive
    columns = {"flex_extension": extension_deg, "L4_L5_FE": 0.185 * extension_deg, "platform_displacement_m": 0.01 * t}
    path = tmp_path / "ik.mot"
    write_storage(path, time=t, columns=columns, in_degrees=True, name="Coordinates")
    trial = load_trial(path)
    assert np.allclose(trial.levels["L5_S1_FE"], -np.radians(extension_deg))
    assert np.allclose(trial.levels["L4_L5_FE"], -np.radians(0.185 * extension_deg))
    assert trial.conversions["L5_S1_FE"] == pytest.approx(-np.pi / 180)


def test_compliant_states_carry_fiber_lengths(sagittal, tmp_path):
    result = simulate(sagittal, duration=0.02, perturbation=None, tendon="compliant")
    states = read_table(result.write(tmp_path, plot=False)["states"])
    fibers = [lab for lab in states.labels if lab.endswith(".fiber_length")]
    assert len(fibers) == 210
    assert np.allclose(states.column(fibers[0]), result.fiber_length[:, 0])


def test_point_load_world_frame_is_z_up_minus_y_forward():
    model = load_model("spine3d")
    optimizer = StaticOptimizer(model)
    optimizer.set_state(np.zeros(len(model.coordinates)), None, None)
    site = model.spec.landmark("T6")

    def moments(force):
        tau = optimizer.generalized_load([PointLoad(site.body, tuple(site.pos), force)])[optimizer.free]
        coords = optimizer.coordinates
        return {kind: np.abs(tau[[c.endswith(kind) for c in coords]]).sum() for kind in ("_FE", "_LB")}

    forward, sideways = moments((0.0, -100.0, 0.0)), moments((100.0, 0.0, 0.0))
    assert forward["_FE"] > 10 * forward["_LB"] and sideways["_LB"] > 10 * sideways["_FE"]
