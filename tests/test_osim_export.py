"""`trunk-drake simulate --model Lumbar_C_210.osim` writes a motion OpenSim 4.6 plays back.

The .mot loads as an OpenSim TimeSeriesTable with the model's coordinate names; setting those
values (degrees converted for OpenSim's rotational coordinates) on the OpenSim model gives our
musculotendon lengths within 1e-5 m at 20 sampled times. Controls and activations load too.
"""

import numpy as np
import pytest

import trunk_drake as td
from trunk_drake.cli import main
from trunk_drake.io.storage import read_table


def test_simulate_with_osim_model_writes_a_motion_opensim_reads(lumbar_c210_path, tmp_path):
    osim = pytest.importorskip("opensim")
    out = tmp_path / "sim"
    assert main(["simulate", "--model", str(lumbar_c210_path), "--dofs", "sagittal", "--duration", "0.4", "--out", str(out)]) == 0
    model = td.load_model(lumbar_c210_path, dofs="sagittal")
    kinematics = read_table(out / "kinematics.csv")  # trunk-drake's names and signs (states.sto has the .osim's)
    q = np.column_stack([kinematics.column(f"{c}_{'m' if c == 'pelvis_tx' else 'rad'}") for c in model.coordinates])

    table = osim.TimeSeriesTable(str(out / "motion.mot"))
    assert table.getTableMetaDataAsString("inDegrees") == "yes"
    osim.Logger.setLevelString("error")
    opensim_model = osim.Model(str(lumbar_c210_path))
    state = opensim_model.initSystem()
    coords = opensim_model.getCoordinateSet()
    labels = list(table.getColumnLabels())
    assert labels == [coords.get(i).getName() for i in range(coords.getSize())]
    muscles = opensim_model.getMuscles()
    rows = np.linspace(0, table.getNumRows() - 1, 20).astype(int)
    worst = 0.0
    for r in rows:
        values = table.getRowAtIndex(int(r)).to_numpy()
        for name, v in zip(labels, values):
            c = coords.get(name)
            c.setValue(state, np.radians(v) if c.getMotionType() == 1 else v, False)  # 1: Rotational
        opensim_model.realizePosition(state)
        ref = np.array([muscles.get(i).getLength(state) for i in range(muscles.getSize())])
        worst = max(worst, np.abs(model.muscle_lengths(q[r]) - ref).max())
    print(f"\nmotion.mot played back in OpenSim: max |dL| {worst:.1e} m at 20 times")
    assert worst < 1e-5
    controls = osim.TimeSeriesTable(str(out / "controls.sto"))
    assert list(controls.getColumnLabels()) == model.muscles
    activations = osim.TimeSeriesTable(str(out / "activations.sto"))
    assert list(activations.getColumnLabels())[0] == f"/forceset/{model.muscles[0]}/activation"
